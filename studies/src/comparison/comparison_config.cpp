// Reading a `touchstone study` file: the problem (and its variants), imposed on the FEM
// reference and on every MFS series, so that both models solve the same one; and its checks.
#include "touchstone/studies/study_runner.hpp"

#include "touchstone/studies/output_files.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>
#include <sstream>
#include <stdexcept>

namespace touchstone::studies {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

/// `path` relative to the study file's folder, unless it is absolute.
std::string resolve(const std::string& directory, const std::string& path) {
  fs::path p(path);
  if (p.is_relative() && !directory.empty()) p = fs::path(directory) / p;
  return p.lexically_normal().string();
}

// ---------------------------------------------------------------------------------------------
// Reading: the problem is imposed on every sub-study, so that both models solve the same one.

/// Reads a `touchstone fem` file and imposes the problem. `same_domain`: the file must be on
/// the problem's benchmark (the reference); otherwise its own domain is kept (Table 2's B2).
ReferenceStudy read_fem_file(const std::string& path, const std::string& key, const ComparisonProblem& problem,
                             bool same_domain) {
  ConfigTable table = ConfigTable::from_file(path);
  ReferenceStudy study = read_reference_study(table, /*problem_imposed=*/true);
  if (same_domain && study.geometry.benchmark != problem.benchmark)
    throw ConfigError(key + ": '" + path + "' is a " + meshes::to_string(study.geometry.benchmark) +
                      " study, but problem.benchmark is " + meshes::to_string(problem.benchmark));
  meshes::MeshParameters& g = study.geometry;
  g.body_radius_m = problem.body_radius_m;
  g.tool_radius_m = problem.tool_radius_m;
  if (g.benchmark == meshes::Benchmark::B3) g.local_radius_m = problem.local_radius_m;
  if (g.benchmark == meshes::Benchmark::B5) g.contact_polar_angle_rad = problem.contact_polar_angle_rad;
  study.material = problem.material;
  study.punch.depth_m = problem.max_depth_m();
  study.punch.direction = problem.direction;
  study.punch.contact = problem.contact;
  study.contacts.clear();
  study.poisson_ratios.clear();
  study.body_radii_m.clear();
  try {
    study.validate();
  } catch (const std::invalid_argument& e) {
    throw ConfigError(key + ": '" + path + "' with the study's problem: " + e.what());
  }
  return study;
}

/// One [mfs.<name>] table → a `touchstone mfs` study with the problem's geometry, material and
/// tool (written into the TOML, so every default the MFS reader derives from them follows).
MfsSeries read_series(const std::string& path, const std::string& name, const toml::table& section,
                      const ComparisonProblem& problem) {
  toml::table t = section;
  for (const char* key : {"study", "geometry", "material", "tool"})
    if (t.contains(key))
      throw ConfigError(path + ": mfs." + name + "." + key + ": set by [problem] (both models solve the same problem)");
  t.insert_or_assign("study", name);
  toml::table geometry{{"benchmark", meshes::to_string(problem.benchmark)},
                       {"body_radius", problem.body_radius_m},
                       {"tool_radius", problem.tool_radius_m}};
  // L: B3's domain is the MFS ball; on B1, B2 and B5 the problem's L is the ball unless the series
  // sets its own ([sprinkling] local_radius, e.g. a truncation study).
  const toml::node* own_l = t.at_path("sprinkling.local_radius").node();
  if (problem.benchmark == meshes::Benchmark::B3 || own_l == nullptr) geometry.insert("local_radius", problem.local_radius_m);
  if (problem.benchmark == meshes::Benchmark::B5) geometry.insert("contact_polar_angle", problem.contact_polar_angle_rad);
  t.insert_or_assign("geometry", geometry);
  // B3's domain is the ball with its cut clamped: the enriched model's exterior is that domain's
  // (a series cannot compare another exterior with it).
  if (problem.benchmark == meshes::Benchmark::B3) {
    if (t.at_path("enriched.exterior").node() != nullptr && t.at_path("enriched.exterior").value_or(std::string()) != "clamped")
      throw ConfigError(path + ": mfs." + name + ".enriched.exterior: B3's cut is clamped (set by [problem])");
    if (!t.contains("enriched")) t.insert("enriched", toml::table{});
    t["enriched"].as_table()->insert_or_assign("exterior", "clamped");
  }
  t.insert_or_assign("material", toml::table{{"youngs_modulus", problem.material.youngs_modulus_Pa},
                                             {"poisson_ratio", problem.material.poisson_ratio}});
  const Eigen::Vector3d& d = problem.direction;
  t.insert_or_assign("tool", toml::table{{"depth", problem.max_depth_m()},
                                         {"direction", toml::array{d[0], d[1], d[2]}},
                                         {"contact", geometry::to_string(problem.contact)}});
  std::ostringstream text;
  text << t << "\n";
  MfsSeries series;
  series.name = name;
  series.config_text = text.str();
  ConfigTable table = ConfigTable::from_string(series.config_text, path + " [mfs." + name + "]");
  series.study = read_mfs_study(table, fs::path(path).parent_path().string());
  return series;
}

}  // namespace

// ---------------------------------------------------------------------------------------------

Eigen::Vector3d ComparisonProblem::outward_normal() const {
  const double theta = benchmark == meshes::Benchmark::B5 ? contact_polar_angle_rad : 0.0;
  return {std::sin(theta), 0.0, std::cos(theta)};
}

double ComparisonProblem::angle_to_normal_rad() const {
  const double c = std::clamp(direction.normalized().dot(-outward_normal()), -1.0, 1.0);
  return std::acos(c);
}

bool ComparisonProblem::ball_reaches_base() const {
  return body_radius_m * outward_normal().z() < local_radius_m;
}

void ComparisonProblem::validate() const {
  const auto positive = [](const std::string& field, double value) {
    if (!std::isfinite(value) || value <= 0)
      throw std::invalid_argument(field + " = " + format_number(value) + " must be finite and > 0");
  };
  positive("problem.body_radius", body_radius_m);
  positive("problem.tool_radius", tool_radius_m);
  positive("problem.local_radius", local_radius_m);
  material.validate();
  if (benchmark != meshes::Benchmark::B1 && benchmark != meshes::Benchmark::B2 && benchmark != meshes::Benchmark::B3 &&
      benchmark != meshes::Benchmark::B5)
    throw std::invalid_argument("problem.benchmark = " + meshes::to_string(benchmark) + " must be B1, B2, B3, B4 or B5");
  if (point_tool && benchmark != meshes::Benchmark::B2)
    throw std::invalid_argument("problem.benchmark B4 is the point tool on B2; its domain must be B2");
  if (!(tool_radius_m < 0.5 * local_radius_m))
    throw std::invalid_argument("problem.tool_radius must be < problem.local_radius / 2");
  // Both meshes need room for the patch on the body (as meshes::MeshParameters requires).
  if (!(tool_radius_m < 0.5 * body_radius_m))
    throw std::invalid_argument("problem.tool_radius = " + format_number(tool_radius_m) +
                                " m must be < problem.body_radius / 2 = " + format_number(0.5 * body_radius_m) + " m");
  if (benchmark == meshes::Benchmark::B5 &&
      !(std::isfinite(contact_polar_angle_rad) && contact_polar_angle_rad >= 0 && contact_polar_angle_rad < M_PI / 2))
    throw std::invalid_argument("problem.contact_polar_angle = " + format_number(contact_polar_angle_rad) +
                                " rad must be in [0, pi/2)");
  if (benchmark != meshes::Benchmark::B5 && contact_polar_angle_rad != 0)
    throw std::invalid_argument("problem.contact_polar_angle = " + format_number(contact_polar_angle_rad) +
                                " rad is for benchmark B5 only (B1 pushes at the centre of its top face, B2 and B3 "
                                "at the pole)");
  if (!direction.allFinite() || direction.norm() < 1e-12) throw std::invalid_argument("problem.direction must be non-zero");
  // The tool must push into the body: d·n < 0 (a grazing d is allowed, a pulling one is not).
  if (!(direction.normalized().dot(outward_normal()) < 0))
    throw std::invalid_argument("problem.direction must point into the body (d . n < 0 at the contact point)");
  if (depths_m.empty()) throw std::invalid_argument("problem.depths is empty");
  for (std::size_t i = 0; i < depths_m.size(); ++i) {
    positive("problem.depths[" + std::to_string(i) + "]", depths_m[i]);
    if (i > 0 && !(depths_m[i] > depths_m[i - 1])) throw std::invalid_argument("problem.depths must be ascending");
  }
  // Both models are linear (small strain): any depth only scales the force. Up to L/2 is
  // allowed to test numerical stability; beyond that the tool would leave the MFS ball.
  if (depths_m.back() > 0.5 * local_radius_m)
    throw std::invalid_argument("problem.depths: the largest depth " + format_number(depths_m.back()) +
                                " m must be <= L/2 = " + format_number(0.5 * local_radius_m) + " m (problem.local_radius / 2)");
}

void ComparisonStudy::validate() const {
  if (name.empty()) throw std::invalid_argument("study name is empty");
  if (problems.empty()) throw std::invalid_argument("no problem");
  for (const auto& sp : problems) {
    const std::string where = sp.id_prefix.empty() ? "" : "problems." + sp.name + ": ";
    try {
      sp.problem.validate();
      sp.reference.validate();
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(where + e.what());
    }
    // Three levels give the Richardson value and its error estimate; two (a quick CI
    // reference) give the finest mesh, reported without an error estimate.
    if (sp.reference.refinements.size() < 2)
      throw std::invalid_argument(where + "reference: needs >= 2 refinement levels (>= 3 for Richardson extrapolation)");
    if (sp.series.empty()) throw std::invalid_argument(where + "no [mfs.<name>] series");
    for (const auto& s : sp.series) {
      s.study.validate();
      // B4's FEM punch is the tip node's spacing: only the paper's tool has one.
      if (sp.problem.point_tool && !s.study.model.paper_mode)
        throw std::invalid_argument(where + "benchmark B4 (the point tool): series '" + s.name +
                                    "' is not in paper mode; set paper_mode = true in [mfs." + s.name +
                                    "] or leave it out of this problem (problems.<name>.series)");
    }
  }
  bool found = table2_mfs_series.empty();
  for (const auto& s : first().series) found = found || s.name == table2_mfs_series;
  if (!found)
    throw std::invalid_argument("table2.mfs_series = '" + table2_mfs_series + "' names no [mfs.<name>] series of the first problem");
  tolerances.validate();
}

namespace {

/// The [problem] keys of `table` (the base [problem] or a merged [problems.<name>]).
ComparisonProblem read_problem(ConfigTable& problem) {
  ComparisonProblem p;
  const std::string benchmark = problem.choice("benchmark", {"B1", "B2", "B3", "B4", "B5"}, "B3");
  p.point_tool = benchmark == "B4";
  p.benchmark = meshes::benchmark_from_string(p.point_tool ? "B2" : benchmark);
  // What defines the problem is required: a default would be a guess.
  p.body_radius_m = problem.quantity("body_radius", Dimension::length);
  p.tool_radius_m = problem.quantity("tool_radius", Dimension::length);
  p.local_radius_m = problem.quantity("local_radius", Dimension::length, 5 * p.tool_radius_m);
  p.contact_polar_angle_rad = problem.quantity("contact_polar_angle", Dimension::angle, 0.0);
  p.material.youngs_modulus_Pa = problem.quantity("youngs_modulus", Dimension::pressure);
  p.material.poisson_ratio = problem.number("poisson_ratio");
  p.contact = geometry::contact_condition_from_string(problem.choice("contact", {"frictionless", "bonded"}, "frictionless"));
  // The direction: given, or the inward normal tilted by `tilt` toward the base in the
  // meridian plane (e_θ = (cos θ, 0, −sin θ)); at the pole with no tilt exactly (0, 0, −1).
  if (problem.has("direction") && problem.has("tilt"))
    throw ConfigError(problem.where("tilt") + ": give direction or tilt, not both");
  const double tilt = problem.quantity("tilt", Dimension::angle, 0.0);
  const double theta = p.benchmark == meshes::Benchmark::B5 ? p.contact_polar_angle_rad : 0.0;
  const Eigen::Vector3d inward(0.0 - std::sin(theta), 0.0, -std::cos(theta));
  const Eigen::Vector3d toward_base(std::cos(theta), 0.0, 0.0 - std::sin(theta));
  const Eigen::Vector3d tilted = tilt == 0 ? inward : Eigen::Vector3d(std::cos(tilt) * inward + std::sin(tilt) * toward_base);
  const auto direction = problem.vector3("direction", Dimension::dimensionless, {{tilted[0], tilted[1], tilted[2]}});
  p.direction = Eigen::Vector3d(direction[0], direction[1], direction[2]);
  problem.require("depths");
  p.depths_m = problem.quantity_list("depths", Dimension::length, p.depths_m);
  return p;
}

/// The [reference] keys (a `touchstone fem` file with mesh overrides) → the reference study.
ReferenceStudy read_reference(ConfigTable& reference, const std::string& key, const std::string& directory,
                              const ComparisonProblem& p) {
  const std::string reference_path = resolve(directory, reference.string("config"));
  const bool has_edges = reference.has("edge_sizes"), has_levels = reference.has("refinements");
  const std::vector<double> edges = reference.quantity_list("edge_sizes", Dimension::length, {});
  const std::vector<std::int64_t> levels = reference.integer_list("refinements", {});
  ReferenceStudy study = read_fem_file(reference_path, key, p, true);
  if (has_edges && !edges.empty()) {
    // Mesh overrides keep the reference file's grading; edge sizes are the mesh families.
    study.geometry.edge_size_m = edges.front();
    study.edge_sizes_m = edges.size() > 1 ? edges : std::vector<double>{};
  }
  if (has_levels) study.refinements.assign(levels.begin(), levels.end());
  return study;
}

/// The series of a problem: every [mfs.<name>] (or those `only` names) with the problem imposed,
/// each marked when its resolved engine settings are the engine defaults.
std::vector<MfsSeries> read_problem_series(const std::string& path, const toml::table& mfs_sections,
                                           const std::vector<std::string>& only, const ComparisonProblem& p) {
  std::vector<MfsSeries> list;
  const MfsSeries defaults = read_series(path, "engine_defaults", toml::table{}, p);  // with B3's exterior imposed
  const auto normalised = [&](MfsStudy s) {
    // Everything but the name, the node counts and the output switch: the engine's settings
    // and the problem (identical for every series of the problem).
    s.name = defaults.study.name;
    s.node_counts = defaults.study.node_counts;
    s.model.sprinkling.node_count = defaults.study.model.sprinkling.node_count;
    s.write_vtu = defaults.study.write_vtu;
    s.atlas_path = defaults.study.atlas_path;  // the organ's data, not an engine setting
    return resolved_config_toml(s);
  };
  const std::string default_text = normalised(defaults.study);
  for (const auto& [key, node] : mfs_sections) {
    const std::string name(key.str());
    if (!only.empty() && std::find(only.begin(), only.end(), name) == only.end()) continue;
    if (!node.is_table()) throw ConfigError(path + ": mfs." + name + ": must be a table ([mfs." + name + "])");
    MfsSeries s = read_series(path, name, *node.as_table(), p);
    s.engine_default = normalised(s.study) == default_text;
    list.push_back(std::move(s));
  }
  return list;
}

}  // namespace

ComparisonStudy read_comparison_study(const std::string& path) {
  // Syntax errors with the file and line, as every other study file; the file is read once, and
  // its text is what the run's provenance records.
  const std::string text = ConfigTable::from_file(path).source_text();
  toml::table document = toml::parse(text, path);
  const std::string directory = fs::path(path).parent_path().string();
  const auto take_table = [&](const char* key, const std::string& what) {
    toml::table t;
    if (const toml::node* node = document.get(key)) {
      if (!node->is_table()) throw ConfigError(path + ": " + key + ": must be a table of " + what);
      t = *node->as_table();
      document.erase(key);
    }
    return t;
  };
  // Variants in file order: a TOML table is a sorted map, the source lines keep the order
  // (read before the tables are copied, which drops them).
  std::map<std::string, std::uint32_t> variant_lines;
  if (const toml::table* t = document.get_as<toml::table>("problems"))
    for (const auto& [key, node] : *t) variant_lines[std::string(key.str())] = node.source().begin.line;
  const toml::table mfs_sections = take_table("mfs", "series, [mfs.<name>]");
  const toml::table variant_sections = take_table("problems", "problem variants, [problems.<name>]");
  const bool has_problem = document.contains("problem") && document.get("problem")->is_table();
  const bool has_reference = document.contains("reference") && document.get("reference")->is_table();
  const toml::table base_problem = has_problem ? *document.get("problem")->as_table() : toml::table{};
  const toml::table base_reference = has_reference ? *document.get("reference")->as_table() : toml::table{};

  std::ostringstream rest;
  rest << document << "\n";
  ConfigTable config = ConfigTable::from_string(rest.str(), path);

  ComparisonStudy study;
  study.config_path = path;
  study.config_text = text;
  study.name = config.string("study", fs::path(path).stem().string());

  // The base [problem] and [reference]: every key checked here; the problem itself is one of
  // the study's problems only when there are no variants.
  ConfigTable problem = config.table("problem", true);
  ComparisonProblem p = read_problem(problem);
  ConfigTable reference = config.table("reference", true);

  ConfigTable table2 = config.table("table2");
  const std::string fem_path = table2.string("fem", "");
  const std::string full_path = table2.string("reference", "");
  const bool has_full_edges = table2.has("reference_edge_sizes");
  const std::vector<double> full_edges = table2.quantity_list("reference_edge_sizes", Dimension::length, {});
  study.table2_mfs_series = table2.string("mfs_series", "");

  ConfigTable ci = config.table("ci");
  const std::string baseline = ci.string("baseline", "");
  if (!baseline.empty()) study.baseline_path = resolve(directory, baseline);
  RegressionTolerances& tol = study.tolerances;
  tol.force_error_points = ci.number("force_error_points", tol.force_error_points);
  tol.displacement_error_points = ci.number("displacement_error_points", tol.displacement_error_points);
  tol.reference_force_rel = ci.number("reference_force_rel", tol.reference_force_rel);

  if (variant_sections.empty()) {
    try {
      p.validate();
    } catch (const std::invalid_argument& e) {
      throw ConfigError(path + ": " + e.what());
    }
    StudyProblem sp;
    sp.problem = p;
    sp.reference = read_reference(reference, path + ": reference.config", directory, p);
    config.finish();
    sp.series = read_problem_series(path, mfs_sections, {}, p);
    study.problems.push_back(std::move(sp));
  } else {
    // The base [reference] is only checked here (config is required in it too); each variant
    // reads its own merged copy below.
    (void)reference.string("config");
    (void)reference.quantity_list("edge_sizes", Dimension::length, {});
    (void)reference.integer_list("refinements", {});
    config.finish();
    std::vector<std::pair<std::string, const toml::table*>> variants;
    std::vector<std::uint32_t> lines;
    for (const auto& [key, node] : variant_sections) {
      const std::string name(key.str());
      if (!node.is_table()) throw ConfigError(path + ": problems." + name + ": must be a table ([problems." + name + "])");
      if (name.empty() || name.find_first_of("/\\ \t\"'") != std::string::npos)
        throw ConfigError(path + ": problems." + name + ": a variant name is a case-id prefix and a folder: no '/', spaces or quotes");
      variants.push_back({name, node.as_table()});
      lines.push_back(variant_lines[name]);
    }
    std::vector<std::size_t> order(variants.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) { return lines[x] < lines[y]; });
    std::vector<std::string> series_names;
    for (const auto& [key, node] : mfs_sections) series_names.emplace_back(key.str());
    for (const std::size_t i : order) {
      const auto& [name, variant] = variants[i];
      // [problems.<name>] = [problem] with the variant's keys replaced; its `reference` table
      // replaces keys of [reference]. Read under the variant's name, so that a wrong key is
      // reported as problems.<name>.<key>.
      toml::table merged = base_problem;
      toml::table merged_reference = base_reference;
      StudyProblem sp;
      sp.name = name;
      sp.id_prefix = name + "/";
      for (const auto& [k, v] : *variant) {
        const std::string key(k.str());
        if (key == "reference" && v.is_table()) {
          for (const auto& [rk, rv] : *v.as_table()) {
            merged_reference.insert_or_assign(rk, rv);
            sp.overridden_keys.push_back("reference." + std::string(rk.str()));
          }
          continue;
        }
        merged.insert_or_assign(k, v);
        if (key != "series") sp.overridden_keys.push_back(key);
      }
      merged.insert_or_assign("reference", merged_reference);
      std::ostringstream text;
      text << toml::table{{"problems", toml::table{{name, merged}}}} << "\n";
      ConfigTable variant_config = ConfigTable::from_string(text.str(), path);
      ConfigTable vt = variant_config.table("problems").table(name);
      sp.problem = read_problem(vt);
      const std::vector<std::string> only = vt.choice_list("series", series_names, {});
      ConfigTable vr = vt.table("reference", true);
      try {
        sp.problem.validate();
      } catch (const std::invalid_argument& e) {
        throw ConfigError(path + ": problems." + name + ": " + e.what());
      }
      sp.reference = read_reference(vr, path + ": problems." + name + ".reference.config", directory, sp.problem);
      variant_config.finish();
      sp.series = read_problem_series(path, mfs_sections, only, sp.problem);
      study.problems.push_back(std::move(sp));
    }
  }

  const ComparisonProblem& first = study.problems.front().problem;
  if (!fem_path.empty()) study.table2_fem = read_fem_file(resolve(directory, fem_path), path + ": table2.fem", first, false);
  if (!full_path.empty()) {
    study.table2_reference = read_fem_file(resolve(directory, full_path), path + ": table2.reference", first, false);
    if (has_full_edges && !full_edges.empty()) {
      study.table2_reference->geometry.edge_size_m = full_edges.front();
      study.table2_reference->edge_sizes_m = full_edges.size() > 1 ? full_edges : std::vector<double>{};
    }
  }
  try {
    study.validate();
  } catch (const std::invalid_argument& e) {
    throw ConfigError(path + ": " + e.what());
  }
  return study;
}
}  // namespace touchstone::studies
