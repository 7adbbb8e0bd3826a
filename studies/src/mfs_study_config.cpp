// Reading a `touchstone mfs` study (sections map one-to-one onto the engine's parameter
// structs; the engine's own settings through the settings table), its validation, and the
// resolved config that reads back to the same study.
#include "touchstone/studies/mfs_study.hpp"

#include "touchstone/meshes/surface_mesh_io.hpp"

#include "touchstone/realtime/mfs/organ_atlas.hpp"
#include "touchstone/studies/output_files.hpp"

#include "mfs_settings_fields.hpp"

#include <toml++/toml.h>

#include <cmath>
#include <filesystem>
#include <sstream>
#include <stdexcept>

namespace touchstone::studies {
namespace fs = std::filesystem;
namespace mfs = realtime::mfs;

// ---------------------------------------------------------------------------------------------

std::string mfs_case_id(geometry::ContactCondition contact, int node_count) {
  return "MFS-" + geometry::to_string(contact) + "-N" + std::to_string(node_count);
}

void MfsStudy::validate() const {
  if (name.empty()) throw std::invalid_argument("study name is empty");
  const auto positive = [](const std::string& field, double value) {
    if (!std::isfinite(value) || value <= 0)
      throw std::invalid_argument(field + " = " + format_number(value) + " must be finite and > 0");
  };
  positive("geometry.body_radius_m", geometry.body_radius_m);
  positive("geometry.tool_radius_m", geometry.tool_radius_m);
  if (surface_path.empty()) organ_surface_geometry(*this).validate();
  material.validate();
  positive("tool.depth_m", depth_m);
  if (!direction.allFinite() || direction.norm() < 1e-12)
    throw std::invalid_argument("tool.direction must be finite and non-zero");
  if (contact_point_m && !contact_point_m->allFinite()) throw std::invalid_argument("tool.point must be finite");
  if (contacts.empty()) throw std::invalid_argument("tool.contact is an empty list");
  if (node_counts.empty()) throw std::invalid_argument("sprinkling.node_count is an empty list");
  const double L = model.sprinkling.local_radius_m;
  positive("sprinkling.local_radius_m", L);
  if (!(geometry.tool_radius_m < 0.5 * L))
    throw std::invalid_argument("geometry.tool_radius_m = " + format_number(geometry.tool_radius_m) +
                                " must be < sprinkling.local_radius_m / 2 = " + format_number(0.5 * L));
  // Both models are linear, so any depth only scales the force; beyond L/2 the tool would leave
  // the local ball (the comparison study allows the same range).
  if (depth_m > 0.5 * L)
    throw std::invalid_argument("tool.depth_m = " + format_number(depth_m) + " must be <= sprinkling.local_radius_m / 2 = " +
                                format_number(0.5 * L) + " (the tool would leave the local ball)");
  // Each node count names its case and its output files: a repeated one would overwrite them.
  for (std::size_t i = 0; i < node_counts.size(); ++i)
    for (std::size_t j = 0; j < i; ++j)
      if (node_counts[i] == node_counts[j])
        throw std::invalid_argument("sprinkling.node_count lists " + std::to_string(node_counts[i]) + " twice");
  for (const int n : node_counts) {
    mfs::LocalModelSettings s = model;
    s.sprinkling.node_count = n;
    s.validate();
  }
}

MfsStudy read_mfs_study(ConfigTable& config, const std::string& config_directory) {
  MfsStudy study;
  study.name = config.string("study", study.name);

  // paper_mode picks the defaults of every other section, so it is read first.
  ConfigTable model = config.table("model");
  const bool top_level = config.has("paper_mode"), in_model = model.has("paper_mode");
  if (top_level && in_model)
    throw ConfigError(config.where("paper_mode") + ": given both at the top level and in [model]; keep one");
  const bool top_level_value = config.boolean("paper_mode", false), model_value = model.boolean("paper_mode", false);
  const bool paper_mode = top_level_value || model_value;
  mfs::LocalModelSettings& s = study.model;
  s = paper_mode ? mfs::paper_settings() : mfs::LocalModelSettings{};
  s.paper_mode = paper_mode;
  read_local_model_settings(config, s);

  ConfigTable geometry = config.table("geometry");
  meshes::MeshParameters& g = study.geometry;
  g.benchmark = meshes::benchmark_from_string(geometry.choice("benchmark", {"B1", "B2", "B3", "B5"}, "B2"));
  // What defines the problem is required (a default would be a guess): the body's size unless an
  // organ surface gives it, the tool's radius, the material and the depth below.
  const bool surface_given = geometry.has("surface") || config.table("organ").has("surface");
  g.body_radius_m = surface_given ? geometry.quantity("body_radius", Dimension::length, g.body_radius_m)
                                  : geometry.quantity("body_radius", Dimension::length);
  g.tool_radius_m = geometry.quantity("tool_radius", Dimension::length);
  g.contact_polar_angle_rad = geometry.quantity("contact_polar_angle", Dimension::angle, 0.0);
  const bool geometry_has_l = geometry.has("local_radius");
  const double geometry_l = geometry.quantity("local_radius", Dimension::length, 5 * g.tool_radius_m);

  // The organ: a surface file, or the benchmark's surface meshed with these sizes.
  ConfigTable organ = config.table("organ");
  if (geometry.has("surface") && organ.has("surface"))
    throw ConfigError(geometry.where("surface") + ": given both in [geometry] and [organ]; keep one");
  std::string surface = geometry.string("surface", "");
  if (surface.empty()) surface = organ.string("surface", "");
  const std::string surface_key = geometry.has("surface") ? geometry.where("surface") : organ.where("surface");
  if (!surface.empty()) {
    fs::path path(surface);
    if (path.is_relative() && !config_directory.empty()) path = fs::path(config_directory) / path;
    require_input_file(surface_key, path.string());
    study.surface_path = fs::absolute(path).lexically_normal().string();
    try {
      meshes::surface_format_of(study.surface_path);
    } catch (const std::exception& e) {
      throw ConfigError(surface_key + ": " + e.what());
    }
  }
  study.clamped_group = organ.string("clamped_group", study.surface_path.empty() ? "base" : "");
  // Named groups exist only in gmsh files; the other formats (.obj, .stl, .vtk, .vtp) carry the
  // surface alone.
  if (!study.clamped_group.empty() && !study.surface_path.empty() &&
      meshes::surface_format_of(study.surface_path) != meshes::SurfaceFormat::msh)
    throw ConfigError(organ.where("clamped_group") + ": '" + study.clamped_group + "' names a gmsh physical group, and " +
                      study.surface_path + " is not a .msh file (its format has no groups)");
  const std::string atlas = organ.string("atlas", "");
  if (!atlas.empty()) {
    fs::path path(atlas);
    if (path.is_relative() && !config_directory.empty()) path = fs::path(config_directory) / path;
    require_input_file(organ.where("atlas"), path.string(), "make it with touchstone atlas");
    study.atlas_path = fs::absolute(path).lexically_normal().string();
    mfs::read_organ_atlas(study.atlas_path);  // a broken atlas is a config error, named now
  }
  // A few thousand triangles: fine (a/8) where the tool and the local ball are, coarse far away.
  g.edge_size_m = organ.quantity("edge_size", Dimension::length, g.tool_radius_m / 8);
  g.size_growth = organ.quantity("size_growth", Dimension::dimensionless, 0.2);
  g.max_size_m = organ.quantity("max_size", Dimension::length, g.body_radius_m / 10);
  g.size_exponent = 1.0;

  ConfigTable material = config.table("material");
  study.material.youngs_modulus_Pa = material.quantity("youngs_modulus", Dimension::pressure);
  study.material.poisson_ratio = material.number("poisson_ratio");

  ConfigTable tool = config.table("tool");
  study.depth_m = tool.quantity("depth", Dimension::length);
  const auto direction = tool.vector3("direction", Dimension::dimensionless, {{0.0, 0.0, -1.0}});
  study.direction = Eigen::Vector3d(direction[0], direction[1], direction[2]);
  if (tool.has("point")) {
    const auto point = tool.vector3("point", Dimension::length, {{0.0, 0.0, 0.0}});
    study.contact_point_m = Eigen::Vector3d(point[0], point[1], point[2]);
  }
  study.contacts.clear();
  for (const auto& contact : tool.choice_list("contact", {"frictionless", "bonded"}, {"frictionless"}))
    study.contacts.push_back(geometry::contact_condition_from_string(contact));

  ConfigTable sprinkling = config.table("sprinkling");
  mfs::SprinklingSettings& sp = s.sprinkling;
  study.node_counts.clear();
  const auto counts = sprinkling.integer_list("node_count", {sp.node_count});
  for (std::size_t i = 0; i < counts.size(); ++i)
    study.node_counts.push_back(checked_int(sprinkling.where("node_count") + "[" + std::to_string(i) + "]", counts[i]));
  sp.local_radius_m = sprinkling.quantity("local_radius", Dimension::length, geometry_l);
  if (geometry_has_l && sprinkling.has("local_radius") && sp.local_radius_m != geometry_l)
    throw ConfigError(sprinkling.where("local_radius") + " = " + format_number(sp.local_radius_m) +
                      " m differs from geometry.local_radius = " + format_number(geometry_l) + " m; keep one");
  g.local_radius_m = sp.local_radius_m;
  ConfigTable output = config.table("output");
  study.write_vtu = output.boolean("vtu", study.write_vtu);

  sp.node_count = study.node_counts.front();
  finish_and_validate(config, study);
  return study;
}

std::string resolved_config_toml(const MfsStudy& study) {
  const mfs::LocalModelSettings& s = study.model;
  const meshes::MeshParameters& g = study.geometry;
  const auto array3 = [](const Eigen::Vector3d& v) { return toml::array{v[0], v[1], v[2]}; };

  toml::table geometry{{"benchmark", meshes::to_string(g.benchmark)},
                       {"body_radius", g.body_radius_m},
                       {"tool_radius", g.tool_radius_m},
                       {"contact_polar_angle", g.contact_polar_angle_rad}};
  toml::table organ;
  organ.insert("clamped_group", study.clamped_group);
  if (!study.atlas_path.empty()) organ.insert("atlas", study.atlas_path);
  if (study.surface_path.empty()) {
    organ.insert("edge_size", g.edge_size_m);
    organ.insert("size_growth", g.size_growth);
    organ.insert("max_size", g.max_size_m);
  } else {
    organ.insert("surface", study.surface_path);
  }
  toml::array contacts;
  for (const auto c : study.contacts) contacts.push_back(geometry::to_string(c));
  toml::table tool{{"depth", study.depth_m}, {"direction", array3(study.direction)}, {"contact", contacts}};
  if (study.contact_point_m) tool.insert("point", array3(*study.contact_point_m));
  toml::array node_counts;
  for (const int n : study.node_counts) node_counts.push_back(n);
  toml::table document{{"study", study.name},
                       {"geometry", geometry},
                       {"organ", organ},
                       {"material", toml::table{{"youngs_modulus", study.material.youngs_modulus_Pa},
                                                {"poisson_ratio", study.material.poisson_ratio}}},
                       {"tool", tool},
                       {"sprinkling", toml::table{{"node_count", node_counts}, {"local_radius", s.sprinkling.local_radius_m}}},
                       {"output", toml::table{{"vtu", study.write_vtu}}}};
  // Every engine setting, from the one table that also reads them.
  write_local_model_settings(document, s);
  std::ostringstream text;
  text << "# " << study.name << ", resolved by `touchstone mfs`: every default filled in, quantities in SI (m, Pa, rad).\n"
       << document << "\n";
  return text.str();
}

}  // namespace touchstone::studies
