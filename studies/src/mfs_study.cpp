// `touchstone mfs`: TOML → MfsStudy (sections map one-to-one onto the engine's parameter
// structs), the cases of the sweep, results.json (the study contract) and the node clouds as VTU.
#include "touchstone/studies/mfs_study.hpp"
#include "touchstone/studies/study_runner.hpp"

#include "touchstone/realtime/mfs/organ_atlas.hpp"

#include "touchstone/geometry/triangle_surface.hpp"
#include "touchstone/meshes/msh_reader.hpp"
#include "touchstone/meshes/point_field_vtu.hpp"
#include "touchstone/meshes/surface_mesh_io.hpp"
#include "touchstone/realtime/mfs/node_cloud_vtk.hpp"
#include "touchstone/studies/fem_reference/probes.hpp"
#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/provenance.hpp"

#include "mfs_settings_fields.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace touchstone::studies {
namespace fs = std::filesystem;
namespace mfs = realtime::mfs;
using nlohmann::json;

namespace {

// ---------------------------------------------------------------------------------------------
// JSON that never holds NaN: a non-finite number becomes null (and the case is not "ok").

/// Replaces every non-finite number in `j` by null; true if there was one.
bool scrub_non_finite(json& j) {
  bool found = false;
  if (j.is_number_float() && !std::isfinite(j.get<double>())) {
    j = nullptr;
    return true;
  }
  if (j.is_structured())
    for (auto& element : j) found = scrub_non_finite(element) || found;
  return found;
}

// ---------------------------------------------------------------------------------------------
// The organ surface.

struct Organ {
  geometry::TriangleSurface surface;
  mfs::ClampedSurface clamped;
  json info;
};

Organ load_organ(const MfsStudy& study, const std::string& output_directory) {
  const auto start = std::chrono::steady_clock::now();
  json info;
  std::string path = study.surface_path;
  if (path.empty()) {
    const meshes::MeshParameters g = organ_surface_geometry(study);
    path = (fs::path(output_directory) / "organ_surface.msh").string();
    fs::create_directories(output_directory);
    const meshes::MeshSummary summary = meshes::generate_mesh(g, path);
    info = {{"source", "generated"},
            {"benchmark", meshes::to_string(g.benchmark)},
            {"edge_size_m", g.edge_size_m},
            {"size_growth", g.size_growth},
            {"max_size_m", g.max_size_m},
            {"mesh_s", summary.seconds}};
  } else {
    info = {{"source", "file"}};
  }
  // Any surface format the readers know (.msh, .obj, .stl, .vtk, .vtp), by its extension.
  geometry::TriangleSurface surface = meshes::load_surface(path);
  info["path"] = path;
  info["sha256"] = sha256_hex(read_file(path));
  info["vertices"] = surface.vertices().size();
  info["triangles"] = surface.triangles().size();
  info["area_m2"] = json_number(surface.area_m2());
  info["volume_m3"] = json_number(surface.volume_m3());
  mfs::ClampedSurface clamped;
  if (!study.clamped_group.empty()) {
    meshes::SurfaceReadOptions group;
    group.msh_groups = {study.clamped_group};
    meshes::SurfaceMesh mesh = meshes::read_surface_mesh(path, group);
    clamped = {std::move(mesh.vertices), std::move(mesh.triangles)};
  }
  info["clamped_group"] = study.clamped_group;
  info["clamped_triangles"] = clamped.triangles.size();
  info["time_s"] = seconds_since(start);
  return {std::move(surface), std::move(clamped), std::move(info)};
}

Eigen::Vector3d study_contact_point(const MfsStudy& study) {
  return study.contact_point_m ? *study.contact_point_m : contact_point(study.geometry);
}

mfs::ToolContact tool_contact(const MfsStudy& study, geometry::ContactCondition condition) {
  mfs::ToolContact contact;
  contact.point = study_contact_point(study);
  contact.direction = study.direction.normalized();
  contact.radius_m = study.geometry.tool_radius_m;
  contact.condition = condition;
  return contact;
}

// ---------------------------------------------------------------------------------------------
// One case: build the local model, push the tool δ d, extract every force.

json case_params(const MfsStudy& study, const mfs::LocalModelSettings& s, const mfs::ToolContact& contact,
                 int node_count_requested) {
  json params{{"node_count_requested", node_count_requested},
          {"node_count", nullptr},
          {"extra_points", nullptr},
          {"benchmark", meshes::to_string(study.geometry.benchmark)},
          {"body_radius_m", study.geometry.body_radius_m},
          {"tool_radius_m", contact.radius_m},
          {"contact_polar_angle_rad", study.geometry.contact_polar_angle_rad},
          {"contact_point_m", vector_json(contact.point)},
          {"youngs_modulus_Pa", study.material.youngs_modulus_Pa},
          {"poisson_ratio", study.material.poisson_ratio},
          {"depth_m", study.depth_m},
          {"direction", vector_json(contact.direction)},
          {"contact", geometry::to_string(contact.condition)},
          {"local_radius_m", s.sprinkling.local_radius_m}};
  // Every engine setting, from the one table that also reads and resolves them.
  add_local_model_params(params, s);
  return params;
}

/// What the enrichment offers the accuracy indicator: the exterior actually used, the
/// amplitudes per metre of depth (1 for the normal mode on a half-space; a clamped cut at 5a
/// raises it to about 1.4), and the MLS part's share of the strain energy (small when the
/// singular fields carry the solution).
json enriched_diagnostics(const mfs::LocalModel& model, const mfs::LocalSolution& solution, const mfs::ToolContact& contact) {
  const mfs::EnrichedModel& e = model.enriched;
  const Eigen::Index nodal = 3 * static_cast<Eigen::Index>(model.cloud.size());
  json amplitudes = json::array();
  const Eigen::Index modes = static_cast<Eigen::Index>(e.modes.size());
  const Eigen::VectorXd per_depth = e.unit_response.bottomRows(e.unit_response.rows() - nodal) * contact.direction.normalized();
  for (Eigen::Index i = 0; i < modes; ++i) amplitudes.push_back(json_number(per_depth[i]));
  json shift = nullptr;  // the cut's rigid shift along e₃, e₁, e₂ per metre of depth
  if (e.cut_translations) shift = json::array({json_number(per_depth[modes]), json_number(per_depth[modes + 1]), json_number(per_depth[modes + 2])});
  const Eigen::VectorXd mls = solution.parameters.head(nodal);
  const double mls_energy = 0.5 * mls.dot(e.stiffness.topLeftCorner(nodal, nodal) * mls);
  const double total = 0.5 * solution.parameters.dot(e.stiffness * solution.parameters);
  return {{"exterior_used", model.exterior_used},
          {"exterior_note", model.exterior_note},
          {"amplitudes_per_depth", amplitudes},
          {"cut_shift_per_depth", shift},
          {"mls_energy_share", json_number(total > 0 ? mls_energy / total : 0.0)},
          {"volumetric_projected", e.volumetric_projected},
          {"volumetric_space", e.volumetric_space},
          {"multipliers", e.multipliers},
          {"mls_evaluations", e.mls_evaluations},
          {"volume_points", e.volume_points},
          {"mean_volume_point_nodes", json_number(e.mean_volume_point_nodes)},
          {"gram_product_overhead", json_number(e.gram_product_overhead)},
          {"gradient_correction", e.gradient_correction == mfs::GradientCorrection::linear ? "linear" : "none"},
          {"gradient_correction_left", json_number(e.gradient_correction_left)},
          {"volume_rule", json::array({e.volume_rule[0], e.volume_rule[1], e.volume_rule[2]})},
          {"cut_rule", json::array({e.cut_rule[0], e.cut_rule[1]})},
          {"boundary_points", e.boundary_points},
          {"kkt_relative_residual", json_number(e.kkt_relative_residual)}};
}

json null_qoi() {
  return {{"force_N", nullptr},
          {"axial_force_N", nullptr},
          {"stiffness_N_per_m", nullptr},
          {"energy_J", nullptr},
          {"k_star", nullptr},
          {"forces_by_method_N",
           {{"traction_integral", nullptr},
            {"traction_surface", nullptr},
            {"reaction", nullptr},
            {"paper_partition", nullptr},
            {"energy_along_tool", nullptr}}},
          {"tool_stiffness_matrix_N_per_m", nullptr},
          {"probes", json::array()},
          {"min_rcond", nullptr}};
}

/// rcond of the moment matrix A at each node: where the shape functions are close to failing.
std::vector<double> node_rcond(const mfs::NodeCloud& cloud, const mfs::MlsSettings& settings) {
  std::vector<double> rcond(cloud.size(), 0.0);
  mfs::MlsEvaluation scratch;
  for (std::size_t j = 0; j < cloud.size(); ++j) {
    mfs::evaluate_mls(cloud.positions[j], cloud.positions, cloud.radii, {}, settings, mfs::Derivatives::values, scratch);
    rcond[j] = std::isfinite(scratch.rcond) ? scratch.rcond : 0.0;
  }
  return rcond;
}

class CaseRunner {
 public:
  CaseRunner(const MfsStudy& study, const Organ& organ, const MfsRunOptions& options)
      : study_(study), organ_(organ), options_(options) {
    if (!study.atlas_path.empty()) atlas_ = std::make_shared<const mfs::OrganAtlas>(mfs::read_organ_atlas(study.atlas_path));
  }

  json run(geometry::ContactCondition condition, int node_count) const {
    const mfs::ToolContact contact = tool_contact(study_, condition);
    mfs::LocalModelSettings settings = study_.model;
    settings.sprinkling.node_count = node_count;

    const std::string id = mfs_case_id(condition, node_count);
    json c{{"id", id},
           {"model", "mfs"},
           {"params", case_params(study_, settings, contact, node_count)},
           {"qoi", null_qoi()},
           // No reference in this study: the study runner pairs these cases with the FEM's.
           {"error", {{"force_rel", nullptr}, {"disp_rel_l2", nullptr}, {"disp_max_m", nullptr}}},
           {"reference", nullptr},
           {"time_s", {{"build", 0.0}, {"solve", 0.0}, {"total", 0.0}, {"sprinkle", 0.0}, {"assembly", 0.0},
                       {"factorize", 0.0}, {"condense", 0.0}, {"force", 0.0}}},
           {"vtu", nullptr},
           {"status", "ok"}};
    const auto start = std::chrono::steady_clock::now();
    try {
      solve(c, contact, settings);
    } catch (const std::exception& e) {
      // Setup errors of one case (e.g. a contact point off a user's surface) fail that case only.
      c["status"] = std::string("error: ") + e.what();
      c["time_s"]["total"] = seconds_since(start);
    }
    if (scrub_non_finite(c) && c["status"] == "ok") c["status"] = "non_finite_result";
    return c;
  }

 private:
  void solve(json& c, const mfs::ToolContact& contact, const mfs::LocalModelSettings& settings) const {
    const mfs::LocalModel model =
        mfs::build_local_model(organ_.surface, contact, study_.material, settings, organ_.clamped, exterior_source());
    // The build time is the median of repeated builds of the same model: the first build in a
    // process runs on cold caches and reads slower than the steady state that the model loop
    // sees and mfs_benchmark measures. Up to five builds, stopping once they have taken a
    // quarter of a second, so that the slow formulations are still built once.
    constexpr std::size_t max_build_samples = 5;
    constexpr double build_timing_budget_s = 0.25;
    std::vector<mfs::BuildTimes> builds{model.times};
    for (double spent = model.times.total_s; model.ok() && builds.size() < max_build_samples && spent < build_timing_budget_s;) {
      const mfs::LocalModel again =
          mfs::build_local_model(organ_.surface, contact, study_.material, settings, organ_.clamped, exterior_source());
      builds.push_back(again.times);
      spent += again.times.total_s;
    }
    std::sort(builds.begin(), builds.end(), [](const mfs::BuildTimes& l, const mfs::BuildTimes& r) { return l.total_s < r.total_s; });
    const mfs::BuildTimes& build_times = builds[(builds.size() - 1) / 2];
    const mfs::NodeCloud& cloud = model.cloud;
    json& params = c["params"];
    params["node_count"] = cloud.size();
    params["extra_points"] = cloud.extra_points.size();
    int kinds[4] = {0, 0, 0, 0};
    for (const auto kind : cloud.kinds) ++kinds[static_cast<int>(kind)];
    params["nodes_by_kind"] = {{"interior", kinds[0]}, {"free_surface", kinds[1]}, {"tool_patch", kinds[2]}, {"cut", kinds[3]}};
    // Collocation: over its collocation points; Galerkin: over its volume quadrature points.
    const bool galerkin = settings.formulation == mfs::Formulation::galerkin;
    const bool enriched = settings.formulation == mfs::Formulation::enriched;
    c["qoi"]["min_rcond"] = json_number(enriched ? model.enriched.min_rcond
                                   : galerkin ? model.galerkin.min_rcond
                                              : model.system.status.min_rcond);
    c["diagnostics"] = {{"max_support_scale_used",
                         json_number(enriched ? model.enriched.max_support_scale
                                : galerkin ? model.galerkin.max_support_scale
                                           : model.system.status.max_support_scale)},
                        {"max_neighbours", model.system.status.max_neighbours},
                        {"mean_neighbours", json_number(model.system.status.mean_neighbours)},
                        {"clamped_quadrature_points", model.clamped_points}};
    json& time = c["time_s"];
    time["sprinkle"] = build_times.sprinkle_s;
    time["assembly"] = build_times.assembly_s;
    time["factorize"] = build_times.factorize_s;
    time["condense"] = build_times.condense_s;
    time["force_diagnostics"] = model.times.diagnostics_s;  // the traction integral when not haptic; not in "build"
    // One build serves every tool displacement (the factorisation and K_t are part of it), so
    // "solve" is what a new U_tool costs: combining the stored unit responses.
    time["build"] = build_times.total_s;
    time["build_samples"] = builds.size();
    time["build_first"] = model.times.total_s;
    time["total"] = build_times.total_s;

    const std::string vtu_name = c["id"].get<std::string>() + ".vtu";
    if (!model.ok()) {
      c["status"] = model.status;
      if (cloud.size() > 0) write_vtu(c, cloud, {}, vtu_name);
      return;
    }

    const Eigen::Vector3d tool_displacement = study_.depth_m * contact.direction;
    const mfs::LocalSolution solution = mfs::solve_local_model(model, tool_displacement);
    time["solve"] = solution.solve_s;
    time["force"] = solution.force_s;
    time["total"] = build_times.total_s + solution.solve_s + solution.force_s;
    if (solution.status != "ok") {
      c["status"] = solution.status;
      write_vtu(c, cloud, {}, vtu_name);
      return;
    }

    if (enriched) c["diagnostics"]["enriched"] = enriched_diagnostics(model, solution, contact);
    const mfs::ToolForces& f = solution.forces;
    const Eigen::Vector3d& d = contact.direction;
    const double axial = f.haptic_N.dot(d);
    const double a = contact.radius_m, e = study_.material.youngs_modulus_Pa;
    json& qoi = c["qoi"];
    qoi["force_N"] = vector_json(f.haptic_N);
    qoi["axial_force_N"] = json_number(axial);
    qoi["stiffness_N_per_m"] = json_number(std::abs(axial) / study_.depth_m);
    qoi["energy_J"] = settings.force.energy || enriched ? json_number(f.energy_J) : json(nullptr);
    qoi["k_star"] = json_number(axial / (e * a * study_.depth_m));
    qoi["forces_by_method_N"] = {
        {"traction_integral", model.traction_available ? vector_json(f.traction_integral_N) : json(nullptr)},
        {"traction_surface", vector_json(f.traction_surface_N)},
        {"reaction", (enriched ? model.enriched.exterior == mfs::ExteriorCondition::clamped : settings.force.reaction)
                         ? vector_json(f.reaction_N)
                         : json(nullptr)},
        {"paper_partition", enriched ? json(nullptr) : vector_json(f.paper_partition_N)},
        {"energy_along_tool", settings.force.energy || enriched ? json_number(f.energy_force_N) : json(nullptr)}};
    qoi["tool_stiffness_matrix_N_per_m"] = matrix_json(model.tool_stiffness_N_per_m);
    qoi["probes"] = probes(model, solution.parameters, contact);
    if (settings.paper_mode) {
      qoi["paper_tip_residual_Pa"] = vector_json(f.paper_tip_residual_Pa);
      qoi["paper_tip_spacing_m"] = json_number(cloud.spacing[static_cast<std::size_t>(model.tip_node)]);
    }
    if (!f.haptic_N.allFinite() || !f.traction_integral_N.allFinite()) c["status"] = "non_finite_force";

    mfs::NodeCloudFields fields;
    std::vector<Eigen::Vector3d> nodal;
    mfs::displacement_at(model, solution.parameters, cloud.positions, nodal);
    fields.displacement_m.resize(3 * static_cast<Eigen::Index>(cloud.size()));
    for (std::size_t j = 0; j < cloud.size(); ++j) fields.displacement_m.segment<3>(3 * static_cast<Eigen::Index>(j)) = nodal[j];
    fields.parameters_m = solution.parameters.head(3 * static_cast<Eigen::Index>(cloud.size()));
    fields.rcond = node_rcond(cloud, settings.collocation.mls);
    write_vtu(c, cloud, fields, vtu_name);
    if (!options_.reference_field_path.empty()) compare_with_reference(c, model, solution.parameters, contact);
  }

  /// The MFS field on the reference's points, beside the reference's own and their difference
  /// (inside the local domain; outside it the MFS has no field and the difference is set to 0).
  void compare_with_reference(json& c, const mfs::LocalModel& model, const Eigen::VectorXd& parameters,
                              const mfs::ToolContact& contact) const {
    try {
      const meshes::PointField reference = meshes::read_point_field(options_.reference_field_path, "displacement_m");
      const std::size_t count = reference.points_m.size();
      const double radius = model.settings.sprinkling.local_radius_m;
      std::vector<Eigen::Vector3d> inside_points;
      std::vector<std::size_t> inside_index;
      for (std::size_t i = 0; i < count; ++i)
        if ((reference.points_m[i] - contact.point).norm() < radius) {
          inside_points.push_back(reference.points_m[i]);
          inside_index.push_back(i);
        }
      std::vector<Eigen::Vector3d> sampled;
      mfs::displacement_at(model, parameters, inside_points, sampled);
      std::vector<Eigen::Vector3d> mfs_field(count, Eigen::Vector3d::Zero()), difference(count, Eigen::Vector3d::Zero());
      std::vector<double> mask(count, 0.0), magnitude(count, 0.0);
      double difference_sq = 0, reference_sq = 0;
      for (std::size_t k = 0; k < inside_index.size(); ++k) {
        const std::size_t i = inside_index[k];
        mfs_field[i] = sampled[k];
        difference[i] = sampled[k] - reference.values[i];
        magnitude[i] = difference[i].norm();
        mask[i] = 1.0;
        difference_sq += difference[i].squaredNorm();
        reference_sq += reference.values[i].squaredNorm();
      }
      const std::string name = c["id"].get<std::string>() + "_on_reference.vtu";
      meshes::write_with_point_arrays(options_.reference_field_path,
                                      (fs::path(options_.output_directory) / name).string(),
                                      {{"mfs_displacement_m", mfs_field}, {"difference_m", difference}},
                                      {{"difference_magnitude_m", magnitude}, {"in_local_domain", mask}});
      c["comparison_vtu"] = name;
      c["comparison_points"] = inside_index.size();
      c["error"]["field_rel_l2"] = reference_sq > 0 ? json_number(std::sqrt(difference_sq / reference_sq)) : json(nullptr);
    } catch (const std::exception& e) {
      // The comparison picture is extra: its failure is recorded, the case's numbers stand.
      c["comparison_error"] = e.what();
    }
  }

  /// The study's probe points inside the local ball. The 0.9 L reach is the one the FEM uses
  /// for B3 (points next to the clamped cut say little), so both models report the same set.
  json probes(const mfs::LocalModel& model, const Eigen::VectorXd& parameters, const mfs::ToolContact& contact) const {
    json list = json::array();
    const double reach = 0.9 * model.settings.sprinkling.local_radius_m;
    for (const Probe& probe : indentation_probes(study_.geometry, contact.direction)) {
      if ((probe.position_m - contact.point).norm() >= reach) continue;
      std::vector<Eigen::Vector3d> u;
      const bool found = mfs::displacement_at(model, parameters, {probe.position_m}, u);
      list.push_back({{"name", probe.name},
                      {"position_m", vector_json(probe.position_m)},
                      {"displacement_m", found ? vector_json(u.front()) : json(nullptr)},
                      {"found", found}});
    }
    return list;
  }

  void write_vtu(json& c, const mfs::NodeCloud& cloud, const mfs::NodeCloudFields& fields, const std::string& name) const {
    if (!study_.write_vtu) return;
    try {
      mfs::write_node_cloud_vtu(cloud, fields, (fs::path(options_.output_directory) / name).string());
      c["vtu"] = name;
    } catch (const std::exception& e) {
      // A missing picture does not invalidate the numbers; say why it is missing.
      c["vtu_error"] = e.what();
    }
  }

  /// The body-aware exterior from the organ atlas, if one was given.
  mfs::ExteriorStiffnessSource exterior_source() const { return mfs::exterior_from_atlas(atlas_); }

  const MfsStudy& study_;
  const Organ& organ_;
  std::shared_ptr<const mfs::OrganAtlas> atlas_;
  const MfsRunOptions& options_;
};

/// F·d of a JSON vector; NaN (printed as "-") when it is null.
double axial_or_nan(const json& vector, const Eigen::Vector3d& d) {
  double sum = 0;
  for (int i = 0; i < 3; ++i) {
    if (!vector.is_array() || !vector.at(i).is_number()) return std::numeric_limits<double>::quiet_NaN();
    sum += vector.at(i).get<double>() * d[i];
  }
  return sum;
}

void print_table(const json& cases, const Eigen::Vector3d& d) {
  std::printf("\nforce on the tissue along d [mN]\n");
  std::printf("%-28s %6s %6s %11s %11s %11s %11s %11s %10s  %s\n", "case", "N", "extra", "haptic", "traction",
              "reaction", "paper", "energy", "build[ms]", "status");
  const auto milli = [](double value) {
    char text[32];
    if (std::isfinite(value))
      std::snprintf(text, sizeof text, "%.5f", 1e3 * value);
    else
      std::snprintf(text, sizeof text, "-");
    return std::string(text);
  };
  for (const auto& c : cases) {
    const json& q = c.at("qoi");
    const json& by = q.at("forces_by_method_N");
    const json& energy = by.at("energy_along_tool");
    std::printf("%-28s %6s %6s %11s %11s %11s %11s %11s %10.2f  %s\n", c.at("id").get<std::string>().c_str(),
                c.at("params").at("node_count").dump().c_str(), c.at("params").at("extra_points").dump().c_str(),
                milli(axial_or_nan(q.at("force_N"), d)).c_str(), milli(axial_or_nan(by.at("traction_integral"), d)).c_str(),
                milli(axial_or_nan(by.at("reaction"), d)).c_str(), milli(axial_or_nan(by.at("paper_partition"), d)).c_str(),
                milli(energy.is_number() ? energy.get<double>() : std::numeric_limits<double>::quiet_NaN()).c_str(),
                1e3 * c.at("time_s").at("build").get<double>(), c.at("status").get<std::string>().c_str());
  }
}

}  // namespace

meshes::MeshParameters organ_surface_geometry(const MfsStudy& study) {
  meshes::MeshParameters g = study.geometry;
  if (g.benchmark == meshes::Benchmark::B3) g.benchmark = meshes::Benchmark::B2;
  g.refinement = 0;
  return g;
}

double paper_tip_spacing_m(const MfsStudy& study, int node_count) {
  if (study.surface_path.empty()) throw std::invalid_argument("paper_tip_spacing_m: the study has no surface file");
  if (!study.model.paper_mode) throw std::invalid_argument("paper_tip_spacing_m: study '" + study.name + "' is not in paper mode");
  const auto organ = meshes::load_surface(study.surface_path);
  mfs::LocalModelSettings settings = study.model;
  settings.sprinkling.node_count = node_count;
  // The tip spacing does not depend on the patch condition (the sprinkler never reads it).
  const mfs::NodeCloud cloud = mfs::sprinkle_local_nodes(organ, tool_contact(study, study.contacts.front()), settings);
  return cloud.spacing.at(0);
}

nlohmann::json run_mfs_study(const MfsStudy& study, const MfsRunOptions& options) {
  study.validate();
  const auto start = std::chrono::steady_clock::now();
  fs::create_directories(options.output_directory);

  const Organ organ = load_organ(study, options.output_directory);
  if (!options.quiet)
    std::printf("organ: %s, %zu triangles (%.2f s)\n", organ.info.at("path").get<std::string>().c_str(),
                organ.info.at("triangles").get<std::size_t>(), organ.info.at("time_s").get<double>());

  json document{{"study", study.name},
                {"provenance", provenance(options.config_text)},
                {"config_resolved", "config.resolved.toml"},
                {"organ", organ.info},
                {"cases", json::array()}};
  const CaseRunner runner(study, organ, options);
  const std::size_t total = study.contacts.size() * study.node_counts.size();
  std::size_t done = 0;
  const Eigen::Vector3d d = study.direction.normalized();
  for (const auto contact : study.contacts) {
    // What each case says about its own accuracy (no reference needed): the flags `study` gives
    // the same case, judged against the previous node count of the same contact.
    json previous;
    for (const int n : study.node_counts) {
      json c = runner.run(contact, n);
      c["accuracy"] = to_json(accuracy_indicator(c, d, previous.is_null() ? nullptr : &previous));
      previous = c;
      ++done;
      if (!options.quiet) {
        const double elapsed = seconds_since(start);
        const json& force = c.at("qoi").at("force_N");
        std::string flags;
        for (const auto& flag : c.at("accuracy").at("flags")) flags += (flags.empty() ? " [" : ", ") + flag.get<std::string>();
        if (!flags.empty()) flags += "]";
        std::printf("[%zu/%zu] %-26s N = %-5s F·d = %s N  build %.1f ms  %s%s  (elapsed %.1f s, ~%.0f s left)\n", done,
                    total, c.at("id").get<std::string>().c_str(), c.at("params").at("node_count").dump().c_str(),
                    force.is_array() ? format_number(axial_or_nan(force, d)).c_str() : "-",
                    1e3 * c.at("time_s").at("build").get<double>(), c.at("status").get<std::string>().c_str(),
                    flags.c_str(), elapsed, elapsed / done * (total - done));
        std::fflush(stdout);
      }
      document["cases"].push_back(std::move(c));
    }
  }
  // Written with the results, so that a run that fails leaves no resolved config without them.
  write_file_atomically(options.output_directory + "/config.resolved.toml", resolved_config_toml(study));
  write_file_atomically(options.output_directory + "/results.json", document.dump(2) + "\n");
  if (!options.quiet) print_table(document["cases"], d);
  return document;
}

}  // namespace touchstone::studies
