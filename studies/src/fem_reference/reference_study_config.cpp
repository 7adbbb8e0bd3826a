// A `touchstone fem` study file: its settings table (one definition per setting for the reader
// and config.resolved.toml), the defaults a study file does not state, and validation. The
// results.json params of each solve are its cache key (problem_params in reference_study.cpp):
// one problem after the sweeps are expanded, not the study's settings.
#include "touchstone/studies/fem_reference/reference_study.hpp"

#include "setting_fields.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <sstream>

namespace touchstone::studies {

namespace {

using S = ReferenceStudy;

const std::vector<Named<meshes::Benchmark>> benchmarks{{"B1", meshes::Benchmark::B1},
                                                       {"B2", meshes::Benchmark::B2},
                                                       {"B3", meshes::Benchmark::B3},
                                                       {"B5", meshes::Benchmark::B5},
                                                       {"box", meshes::Benchmark::Box},
                                                       {"organ", meshes::Benchmark::Organ}};
// "mixed" is the recommended name of the mixed formulation (P2–P0, condensed) for ν ≥ 0.49,
// where the displacement formulation locks.
const std::vector<Named<fem::Formulation>> formulations{{"displacement", fem::Formulation::displacement},
                                                        {"mixed_p0disc", fem::Formulation::mixed_p0disc},
                                                        {"mixed", fem::Formulation::mixed_p0disc}};

/// A non-negative integer setting held as unsigned int.
template <class Get>
SettingField<S> count(FieldNames n, Get get) {
  const std::string key = n.key;
  return {n.section, n.key, n.params_key, n.unit, n.doc,
          [get, key](ConfigTable& t, S& s) {
            const std::int64_t value = t.integer(key, static_cast<std::int64_t>(get(s)));
            if (value < 0 || value > std::numeric_limits<unsigned int>::max())
              throw ConfigError(t.where(key) + ": " + std::to_string(value) + " must be >= 0");
            get(s) = static_cast<unsigned int>(value);
          },
          [get](const S& s) { return nlohmann::json(get(s)); }};
}

std::vector<SettingField<S>> make_fields() {
  const auto length = [](FieldNames n, auto get) { return field::quantity<S>(n, Dimension::length, get); };
  const auto real = [](FieldNames n, auto get) { return field::real<S>(n, get); };
  std::vector<SettingField<S>> f;
  f.push_back(field::text<S>({"", "study", "", "the study's name"}, [](auto& s) -> auto& { return s.name; }));

  f.push_back(field::choice<S>({"geometry", "benchmark", "", "B1, B2, B3, B5, box, or organ (a surface file: [organ])"}, benchmarks,
                               [](auto& s) -> auto& { return s.geometry.benchmark; }));
  f.push_back(length({"geometry", "body_radius", "m", "R (B2, B3, B5) or W (B1)"}, [](auto& s) -> auto& { return s.geometry.body_radius_m; }));
  f.push_back(length({"geometry", "tool_radius", "m", "radius a of the tool patch"}, [](auto& s) -> auto& { return s.geometry.tool_radius_m; }));
  // Dependent defaults (read after tool_radius): the paper's local ball L = 5a.
  SettingField<S> local_radius = length({"geometry", "local_radius", "m", "radius L of the local ball (default 5 a)"},
                                        [](auto& s) -> auto& { return s.geometry.local_radius_m; });
  local_radius.read = [](ConfigTable& t, S& s) {
    s.geometry.local_radius_m = t.quantity("local_radius", Dimension::length, 5 * s.geometry.tool_radius_m);
  };
  f.push_back(local_radius);
  f.push_back(field::quantity<S>({"geometry", "contact_polar_angle", "rad", "polar angle of the patch centre (B5)"},
                                 Dimension::angle, [](auto& s) -> auto& { return s.geometry.contact_polar_angle_rad; }));

  // A user's organ (benchmark = "organ"): its surface, the contact and the attachment.
  f.push_back(field::file<S>({"organ", "surface", "", "closed surface file (.msh, .obj, .stl, .vtk, .vtp), relative to this file"},
                         [](auto& s) -> auto& { return s.geometry.organ.surface_path; }));
  f.push_back(real({"organ", "unit_scale", "m per file unit", "1e-3 for a file in millimetres"},
                   [](auto& s) -> auto& { return s.geometry.organ.unit_scale; }));
  f.push_back(field::vector3<S>({"organ", "contact_point", "m", "the patch is centred at the surface point nearest to this"},
                           Dimension::length, [](auto& s) -> auto& { return s.geometry.organ.contact_point_m; }));
  f.push_back(field::vector3<S>({"organ", "tool_axis", "", "tool axis into the organ ([0, 0, 0]: the inward normal)"},
                           Dimension::dimensionless, [](auto& s) -> auto& { return s.geometry.organ.tool_axis; }));
  f.push_back(field::vector3<S>({"organ", "attachment_plane_point", "m", "held: triangles below the plane through this point"},
                           Dimension::length, [](auto& s) -> auto& { return s.geometry.organ.attachment.plane_point_m; }));
  f.push_back(field::vector3<S>({"organ", "attachment_plane_normal", "", "the plane's normal (\"below\": against it; [0, 0, 0]: no plane)"},
                           Dimension::dimensionless, [](auto& s) -> auto& { return s.geometry.organ.attachment.plane_normal; }));
  f.push_back(field::text<S>({"organ", "attachment_group", "", "held: this physical group of a .msh surface"},
                             [](auto& s) -> auto& { return s.geometry.organ.attachment.msh_group; }));
  f.push_back(field::file<S>({"organ", "attachment_triangles", "", "held: the triangle numbers (from 0) listed in this file"},
                         [](auto& s) -> auto& { return s.geometry.organ.attachment.triangles_path; }));
  f.push_back(field::text<S>({"organ", "generate", "", "no surface file: generate this organ (hemisphere of radius body_radius, or stomach)"},
                             [](auto& s) -> auto& { return s.generated_organ; }));
  f.push_back({"organ", "generate_triangles", "", "triangles", "the generated organ's triangle count",
               [](ConfigTable& t, S& s) { s.generated_organ_triangles = read_int(t, "generate_triangles", s.generated_organ_triangles); },
               [](const S& s) { return nlohmann::json(s.generated_organ_triangles); }});
  f.push_back(field::quantity<S>({"organ", "feature_angle", "rad", "creases sharper than this are kept when remeshing"},
                                 Dimension::angle, [](auto& s) -> auto& { return s.geometry.organ.feature_angle_rad; }));

  // Mesh families: one level-0 edge size, or several (each its own Richardson sequence).
  SettingField<S> edge_size = field::quantity_list<S>({"mesh", "edge_size", "m", "level-0 element size at the patch rim (default a / 16)"},
                                                      Dimension::length, [](auto& s) -> auto& { return s.edge_sizes_m; });
  edge_size.read = [](ConfigTable& t, S& s) {
    s.edge_sizes_m = t.quantity_list("edge_size", Dimension::length, {s.geometry.tool_radius_m / 16});
    s.geometry.edge_size_m = s.edge_sizes_m.empty() ? 0.0 : s.edge_sizes_m.front();
    if (s.edge_sizes_m.size() == 1) s.edge_sizes_m.clear();
  };
  edge_size.value = [](const S& s) {
    return nlohmann::json(s.edge_sizes_m.empty() ? std::vector<double>{s.geometry.edge_size_m} : s.edge_sizes_m);
  };
  f.push_back(edge_size);
  f.push_back(real({"mesh", "size_growth", "", "h(d) = edge_size + size_growth a g(d / a)"},
                   [](auto& s) -> auto& { return s.geometry.size_growth; }));
  f.push_back(real({"mesh", "size_exponent", "", "grading exponent beta of g(t) = t^beta"},
                   [](auto& s) -> auto& { return s.geometry.size_exponent; }));
  f.push_back(real({"mesh", "power_grading_extent", "tool radii", "g is a power law up to this, then its tangent"},
                   [](auto& s) -> auto& { return s.geometry.power_grading_extent; }));
  // B3's cut sphere is faceted by the largest elements: keep them well below L.
  SettingField<S> max_size = length({"mesh", "max_size", "m", "largest element (default R / 5; B3: min(R / 5, L / 8))"},
                                    [](auto& s) -> auto& { return s.geometry.max_size_m; });
  max_size.read = [](ConfigTable& t, S& s) {
    const meshes::MeshParameters& g = s.geometry;
    const double default_max = g.benchmark == meshes::Benchmark::B3 ? std::min(g.body_radius_m / 5, g.local_radius_m / 8)
                                                                    : g.body_radius_m / 5;
    s.geometry.max_size_m = t.quantity("max_size", Dimension::length, default_max);
  };
  f.push_back(max_size);
  f.push_back(field::integer_list<S>({"mesh", "refinements", "levels", "refinement levels (>= 3 for Richardson)"},
                                     [](auto& s) -> auto& { return s.refinements; }));

  f.push_back(field::quantity<S>({"material", "youngs_modulus", "Pa", "Young's modulus E"}, Dimension::pressure,
                                 [](auto& s) -> auto& { return s.material.youngs_modulus_Pa; }));
  f.push_back(real({"material", "poisson_ratio", "", "Poisson's ratio"}, [](auto& s) -> auto& { return s.material.poisson_ratio; }));

  SettingField<S> depth = length({"tool", "depth", "m", "indentation depth (required in a fem file; a study imposes its own)"}, [](auto& s) -> auto& { return s.punch.depth_m; });
  depth.read = [](ConfigTable& t, S& s) { s.punch.depth_m = t.quantity("depth", Dimension::length, 0.1 * s.geometry.tool_radius_m); };
  f.push_back(depth);
  f.push_back({"tool", "direction", "", "", "direction of the patch displacement (normalised on use)",
               [](ConfigTable& t, S& s) {
                 const Eigen::Vector3d& d = s.punch.direction;
                 const auto v = t.vector3("direction", Dimension::dimensionless, {{d.x(), d.y(), d.z()}});
                 s.punch.direction = Eigen::Vector3d(v[0], v[1], v[2]);
               },
               [](const S& s) { return nlohmann::json{s.punch.direction.x(), s.punch.direction.y(), s.punch.direction.z()}; }});
  f.push_back(field::choice<S>({"tool", "contact", "", "frictionless or bonded"}, contact_conditions,
                               [](auto& s) -> auto& { return s.punch.contact; }));

  f.push_back(count({"solver", "degree", "", "polynomial degree of the elements (1 or 2)"}, [](auto& s) -> auto& { return s.solver.degree; }));
  f.push_back(field::choice<S>({"solver", "formulation", "", "displacement, or mixed for nu >= 0.49"}, formulations,
                               [](auto& s) -> auto& { return s.solver.formulation; }));
  f.push_back(field::choice<S>({"solver", "method", "", "cg_amg_trilinos, cg_gamg_petsc or direct_mumps"}, linear_solvers,
                               [](auto& s) -> auto& { return s.solver.solver; }));
  f.push_back(real({"solver", "relative_tolerance", "", "iterative solvers: |r| <= tol |b|"},
                   [](auto& s) -> auto& { return s.solver.relative_tolerance; }));
  f.push_back(count({"solver", "max_iterations", "iterations", "iterative solvers' limit"},
                    [](auto& s) -> auto& { return s.solver.max_iterations; }));

  f.push_back(field::boolean<S>({"output", "vtu", "", "VTU/PVD of every solve"}, [](auto& s) -> auto& { return s.write_vtu; }));

  f.push_back({"sweep", "contact", "", "", "contact conditions, one problem each (empty: tool.contact)",
               [](ConfigTable& t, S& s) {
                 std::vector<std::string> current;
                 for (const auto c : s.contacts) current.push_back(name_of(contact_conditions, c));
                 s.contacts.clear();
                 for (const auto& name : t.choice_list("contact", names(contact_conditions), current))
                   s.contacts.push_back(value_of(contact_conditions, name));
               },
               [](const S& s) {
                 nlohmann::json list = nlohmann::json::array();
                 for (const auto c : s.contacts) list.push_back(name_of(contact_conditions, c));
                 return list;
               }});
  f.push_back(field::quantity_list<S>({"sweep", "poisson_ratio", "", "Poisson's ratios, one problem each"},
                                      Dimension::dimensionless, [](auto& s) -> auto& { return s.poisson_ratios; }));
  f.push_back(field::quantity_list<S>({"sweep", "body_radius", "m", "body radii (W for B1: the a / W sweep), one problem each"},
                                      Dimension::length, [](auto& s) -> auto& { return s.body_radii_m; }));
  assign_params_keys(f, "FEM study");
  return f;
}

const std::vector<SettingField<S>>& study_fields() {
  static const auto fields = make_fields();
  return fields;
}

/// The one default of a study file that differs from the structs': the graded-mesh exponent
/// β = 3/4 of the benchmark meshes.
ReferenceStudy default_study() {
  ReferenceStudy study;
  study.geometry.size_exponent = 0.75;
  return study;
}

}  // namespace

/// What defines the indentation problem, which a study file must set: a default would be a
/// guess. The body's size only for the benchmarks, whose shape it sets (an organ file has its own).
void require_problem_keys(ConfigTable& config, const ReferenceStudy& study) {
  const meshes::Benchmark benchmark = study.geometry.benchmark;
  std::vector<std::pair<std::string, std::string>> keys{{"material", "youngs_modulus"}, {"material", "poisson_ratio"}};
  if (benchmark != meshes::Benchmark::Box) {
    keys.insert(keys.end(), {{"geometry", "tool_radius"}, {"tool", "depth"}});
    if (benchmark != meshes::Benchmark::Organ) keys.emplace_back("geometry", "body_radius");
  }
  for (const auto& [section, key] : keys) config.table(section).require(key);
}

ReferenceStudy read_reference_study(ConfigTable& config, bool problem_imposed) {
  ReferenceStudy study = default_study();
  read_fields(study_fields(), config, study);
  config.finish();  // a misspelt key first: it may be the missing one
  if (!problem_imposed) require_problem_keys(config, study);
  finish_and_validate(config, study);
  return study;
}

std::string resolved_reference_study_toml(const ReferenceStudy& study) {
  toml::table document;
  write_fields(study_fields(), document, study);
  std::ostringstream text;
  text << "# " << study.name << ", resolved by `touchstone fem`: every default filled in, quantities in SI (m, Pa, rad).\n"
       << document << "\n";
  return text.str();
}

}  // namespace touchstone::studies
