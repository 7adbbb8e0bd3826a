// TOML → ReferenceStudy. Sections map one-to-one onto the parameter structs; every key is
// checked, and defaults are the struct defaults.
#include "touchstone/studies/fem_reference/reference_study.hpp"

#include <algorithm>

namespace touchstone::studies {

namespace {

meshes::MeshParameters read_geometry(ConfigTable& geometry, ConfigTable& mesh) {
  meshes::MeshParameters g;
  g.benchmark = meshes::benchmark_from_string(
      geometry.choice("benchmark", {"B1", "B2", "B3", "B5", "box"}, "B2"));
  g.body_radius_m = geometry.quantity("body_radius", Dimension::length, g.body_radius_m);
  g.tool_radius_m = geometry.quantity("tool_radius", Dimension::length, g.tool_radius_m);
  g.local_radius_m = geometry.quantity("local_radius", Dimension::length, 5 * g.tool_radius_m);
  g.contact_polar_angle_rad = geometry.quantity("contact_polar_angle", Dimension::angle, 0.0);
  g.size_growth = mesh.number("size_growth", g.size_growth);
  g.size_exponent = mesh.number("size_exponent", 0.75);
  g.power_grading_extent = mesh.number("power_grading_extent", g.power_grading_extent);
  // B3's cut sphere is faceted by the largest elements: keep them well below L.
  const double default_max = g.benchmark == meshes::Benchmark::B3 ? std::min(g.body_radius_m / 5, g.local_radius_m / 8)
                                                                  : g.body_radius_m / 5;
  g.max_size_m = mesh.quantity("max_size", Dimension::length, default_max);
  return g;
}

}  // namespace

ReferenceStudy read_reference_study(ConfigTable& config) {
  ReferenceStudy study;
  study.name = config.string("study", study.name);
  ConfigTable geometry = config.table("geometry");
  ConfigTable mesh = config.table("mesh");
  study.geometry = read_geometry(geometry, mesh);
  study.edge_sizes_m = mesh.quantity_list("edge_size", Dimension::length, {study.geometry.tool_radius_m / 16});
  study.geometry.edge_size_m = study.edge_sizes_m.front();
  if (study.edge_sizes_m.size() == 1) study.edge_sizes_m.clear();
  std::vector<std::int64_t> levels =
      mesh.integer_list("refinements", {study.refinements.begin(), study.refinements.end()});
  study.refinements.assign(levels.begin(), levels.end());

  ConfigTable material = config.table("material");
  study.material.youngs_modulus_Pa =
      material.quantity("youngs_modulus", Dimension::pressure, study.material.youngs_modulus_Pa);
  study.material.poisson_ratio = material.number("poisson_ratio", study.material.poisson_ratio);

  ConfigTable tool = config.table("tool");
  study.punch.depth_m = tool.quantity("depth", Dimension::length, 0.1 * study.geometry.tool_radius_m);
  const auto direction = tool.vector3("direction", Dimension::dimensionless, {{0.0, 0.0, -1.0}});
  study.punch.direction = Eigen::Vector3d(direction[0], direction[1], direction[2]);
  study.punch.contact = geometry::contact_condition_from_string(tool.choice("contact", {"frictionless", "bonded"}, "frictionless"));

  ConfigTable solver = config.table("solver");
  study.solver.degree = static_cast<unsigned int>(solver.integer("degree", study.solver.degree));
  // "mixed" (P2–P0, condensed) for ν ≥ 0.49, where the displacement formulation locks.
  study.solver.formulation = fem::formulation_from_string(
      solver.choice("formulation", {"displacement", "mixed", "mixed_p0disc"}, "displacement"));
  study.solver.solver = fem::linear_solver_from_string(
      solver.choice("method", {"cg_amg_trilinos", "cg_gamg_petsc", "direct_mumps"}, "cg_amg_trilinos"));
  study.solver.relative_tolerance = solver.number("relative_tolerance", study.solver.relative_tolerance);
  study.solver.max_iterations = static_cast<unsigned int>(solver.integer("max_iterations", study.solver.max_iterations));

  ConfigTable output = config.table("output");
  study.write_vtu = output.boolean("vtu", study.write_vtu);

  ConfigTable sweep = config.table("sweep");
  for (const auto& contact : sweep.choice_list("contact", {"frictionless", "bonded"}, {}))
    study.contacts.push_back(geometry::contact_condition_from_string(contact));
  study.poisson_ratios = sweep.quantity_list("poisson_ratio", Dimension::dimensionless, {});
  study.body_radii_m = sweep.quantity_list("body_radius", Dimension::length, {});
  finish_and_validate(config, study);
  return study;
}

}  // namespace touchstone::studies
