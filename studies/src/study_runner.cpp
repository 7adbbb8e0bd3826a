// `touchstone study`: one study file → the FEM reference (cached), the MFS series, the errors
// of every MFS case against the reference next to the reference's own error estimate, Table 2,
// the speed and accuracy targets, results.json, CSV tables and the report.
#include "touchstone/studies/study_runner.hpp"

#include "touchstone/studies/probes.hpp"
#include "touchstone/studies/provenance.hpp"
#include "touchstone/version.hpp"

#include "least_squares_line.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <thread>

#ifndef TOUCHSTONE_SOURCE_DIR
#define TOUCHSTONE_SOURCE_DIR "."
#endif

namespace touchstone::studies {
namespace fs = std::filesystem;
namespace mfs = realtime::mfs;
using nlohmann::json;

namespace {

constexpr double nan_value = std::numeric_limits<double>::quiet_NaN();

json number(double value) { return std::isfinite(value) ? json(value) : json(nullptr); }
json vector_json(const Eigen::Vector3d& v) { return json::array({number(v[0]), number(v[1]), number(v[2])}); }

/// A JSON number or NaN (null, absent, not a number).
double value_or_nan(const json& j) { return j.is_number() ? j.get<double>() : nan_value; }
double value_or_nan(const json& j, const char* key) { return j.is_object() && j.contains(key) ? value_or_nan(j.at(key)) : nan_value; }

/// F·d of a JSON 3-vector; NaN when it is not one.
double axial(const json& vector, const Eigen::Vector3d& d) {
  if (!vector.is_array() || vector.size() != 3) return nan_value;
  double sum = 0;
  for (int i = 0; i < 3; ++i) sum += value_or_nan(vector.at(i)) * d[i];
  return sum;
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// A number for the console; "-" for a missing one (a failed case has no force: never print
/// "nan", which reads like a numerical failure of a case that reported its status instead).
std::string format_number(double value) {
  if (!std::isfinite(value)) return "-";
  std::ostringstream text;
  text << value;
  return text.str();
}

/// A fixed-width table cell: `value` with `decimals`, or "-" right-aligned when it is missing.
/// A speed-up target of 10⁴ (FEM time over MFS time): measured, met and shortfall when both
/// times are known; false, and `target` untouched, when one is missing.
bool score_speedup(json& target, double fem_time_s, double mfs_time_s) {
  if (!std::isfinite(fem_time_s) || !std::isfinite(mfs_time_s)) return false;
  const double speedup = fem_time_s / mfs_time_s;
  target["measured"] = speedup;
  target["met"] = speedup >= 1e4;
  target["shortfall"] = speedup >= 1e4 ? "" : "missed: " + format_number(std::round(speedup)) + "x";
  return true;
}

std::string table_cell(double value, int width, int decimals) {
  char text[64];
  if (std::isfinite(value)) std::snprintf(text, sizeof text, "%*.*f", width, decimals, value);
  else std::snprintf(text, sizeof text, "%*s", width, "-");
  return text;
}

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
  ReferenceStudy study = read_reference_study(table);
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

// ---------------------------------------------------------------------------------------------
// The reference of a `touchstone fem` run: the extrapolated force and its error estimate.

struct ReferenceValue {
  std::string id;              ///< prefixed case id in the study's results
  std::string part;            ///< its FEM run: the folder under <out>/fem/ and the id prefix
  double force_N = nan_value;  ///< axial, at max δ
  double uncertainty_rel = nan_value;
  double disp_uncertainty_rel = nan_value;  ///< probe change, second-finest → finest mesh
  json probes = json::array();
  std::string field_vtu;  ///< the probes' level's solution file, relative to its FEM output folder
  /// The half-space closed form at max δ (Sneddon or Mossakovskii), which the reference study
  /// adds on B1 and B2 as an "analytic" case; NaN on the other benchmarks.
  double half_space_force_N = nan_value;
  std::string half_space_id;
  std::string half_space_formula;
  json summary;
};

ReferenceValue pick_reference(const json& document, const std::string& prefix, const Eigen::Vector3d& d) {
  ReferenceValue r;
  // The mean over mesh families ("-reference") when there are several, else the one family's
  // Richardson value.
  const json* chosen = nullptr;
  const json* richardson = nullptr;
  for (const auto& c : document.at("cases")) {
    const std::string id = c.at("id");
    const auto ends_with = [&](const std::string& tail) {
      return id.size() >= tail.size() && id.compare(id.size() - tail.size(), tail.size(), tail) == 0;
    };
    if (ends_with("-reference")) chosen = &c;
    if (ends_with("-richardson")) richardson = &c;
  }
  if (chosen == nullptr) chosen = richardson;
  if (chosen == nullptr) throw std::runtime_error("FEM study " + document.value("study", "") + " has no reference case");
  r.id = prefix + chosen->at("id").get<std::string>();
  r.part = prefix.substr(0, prefix.size() - 1);
  r.force_N = axial(chosen->at("qoi").at("force_N"), d);
  r.probes = chosen->at("qoi").value("probes", json::array());
  // Discretisation error of the extrapolated force: the larger of the family spread and each
  // family's Richardson uncertainty (the change of f_R between observed and theoretical order).
  double uncertainty = 0;
  json families = json::array();
  bool asymptotic = true;
  for (const auto& s : document.value("convergence", json::array())) {
    // A family without an extrapolation (fewer than three levels) has no error estimate.
    const double family = value_or_nan(s, "extrapolated_relative_uncertainty");
    uncertainty = std::isfinite(family) ? std::max(uncertainty, family) : nan_value;
    asymptotic = asymptotic && s.value("asymptotic", false);
    families.push_back({{"problem", s.at("problem")},
                        {"extrapolated_force_N", s.value("extrapolated_force_N", json(nullptr))},
                        {"observed_order", s.value("observed_order", json(nullptr))},
                        {"extrapolated_relative_uncertainty", s.value("extrapolated_relative_uncertainty", json(nullptr))},
                        {"finest_relative_error", s.value("finest_relative_error", json(nullptr))},
                        {"levels", s.at("levels")}});
  }
  double spread = nan_value;
  if (document.contains("references") && !document.at("references").empty()) {
    spread = value_or_nan(document.at("references").at(0), "relative_uncertainty");
    uncertainty = std::max(uncertainty, spread);
  }
  r.uncertainty_rel = families.empty() ? nan_value : uncertainty;
  // Probe reference: the finest level of the last family; its error estimate is how much the
  // probes moved from the second-finest level (its disp_rel_l2 against the finest).
  std::string last_family;
  std::vector<const json*> levels;
  for (const auto& c : document.at("cases")) {
    if (c.at("model") != "fem" || !c.at("params").at("refinement").is_number()) continue;
    const std::string id = c.at("id");
    const std::string family = id.substr(0, id.rfind("-L"));
    if (family != last_family) levels.clear();
    last_family = family;
    levels.push_back(&c);
  }
  if (levels.size() >= 2) r.disp_uncertainty_rel = value_or_nan(levels[levels.size() - 2]->at("error"), "disp_rel_l2");
  if (!levels.empty()) r.field_vtu = levels.back()->value("vtu", "");
  for (const auto& c : document.at("cases"))
    if (c.at("model") == "analytic") {
      r.half_space_force_N = axial(c.at("qoi").at("force_N"), d);
      r.half_space_id = prefix + c.at("id").get<std::string>();
      r.half_space_formula = c.at("params").value("formula", "");
    }
  r.summary = {{"case", r.id},
               {"study", document.value("study", "")},
               {"axial_force_N", number(r.force_N)},
               {"uncertainty_rel", number(r.uncertainty_rel)},
               {"family_spread_rel", number(spread)},
               {"asymptotic", asymptotic && !families.empty()},
               {"families", families},
               {"disp_uncertainty_rel", number(r.disp_uncertainty_rel)},
               {"probes_from", levels.empty() ? json(nullptr) : json(prefix + levels.back()->at("id").get<std::string>())}};
  if (std::isfinite(r.half_space_force_N)) {
    r.summary["half_space_case"] = r.half_space_id;
    r.summary["half_space_formula"] = r.half_space_formula;
    r.summary["half_space_force_N"] = r.half_space_force_N;
    r.summary["ratio_to_half_space"] = number(r.force_N / r.half_space_force_N);
  }
  return r;
}

// ---------------------------------------------------------------------------------------------

std::string csv_escape(const std::string& text) {
  if (text.find_first_of(",\"\n") == std::string::npos) return text;
  std::string out = "\"";
  for (const char c : text) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

std::string csv_value(const json& j) {
  if (j.is_null()) return "";
  if (j.is_string()) return csv_escape(j.get<std::string>());
  if (j.is_number_float()) {
    char text[40];
    std::snprintf(text, sizeof text, "%.10g", j.get<double>());
    return text;
  }
  return csv_escape(j.dump());
}

const json& at_path(const json& j, const std::vector<std::string>& path) {
  static const json null_json;
  const json* node = &j;
  for (const auto& key : path) {
    if (!node->is_object() || !node->contains(key)) return null_json;
    node = &node->at(key);
  }
  return *node;
}

/// One problem while the study runs: its reference once computed, its selected MFS cases.
struct ProblemRun {
  const StudyProblem* sp = nullptr;
  Eigen::Vector3d d;  ///< the tool direction, normalised
  ReferenceValue reference;  ///< B4: the first case's (every case has its own, below)
  std::string reference_part;  ///< "reference" or "<name>/reference": the FEM folder and id prefix
  std::vector<std::pair<const MfsSeries*, int>> mfs_cases;
  /// B4 (point tool): each selected case's tip spacing s [m], parallel to mfs_cases, the FEM
  /// punch radius it is paired with (s to the micrometre, so that equal spacings share a solve)
  /// and that punch's converged reference, by the radius in µm.
  std::vector<double> tip_spacing_m;
  std::map<long long, ReferenceValue> punch_references;
  const ComparisonProblem& problem() const { return sp->problem; }
  static long long micrometres(double length_m) { return std::llround(length_m * 1e6); }
  /// The FEM punch radius paired with a tip spacing [m]: the spacing to the micrometre.
  static double punch_radius_m(double tip_spacing_m) { return 1e-6 * static_cast<double>(micrometres(tip_spacing_m)); }
  const ReferenceValue& reference_of(std::size_t case_index) const {
    return problem().point_tool ? punch_references.at(micrometres(tip_spacing_m.at(case_index))) : reference;
  }
};

/// The report's notes on a problem: what its numbers mean beyond the errors.
json problem_notes(const ComparisonProblem& p) {
  json notes = json::array();
  if (p.beyond_small_strain())
    notes.push_back({{"id", "depth_beyond_small_strain"},
                     {"text", "the largest depth " + format_number(1e3 * p.max_depth_m()) + " mm exceeds a/2 = " +
                                  format_number(0.5e3 * p.tool_radius_m) +
                                  " mm: both models are linear (small strain), so the force just scales with the depth; "
                                  "such depths test numerical stability, not physics"}});
  if (p.benchmark != meshes::Benchmark::B3)
    notes.push_back({{"id", "local_model_truncation"},
                     {"text", "the FEM reference solves the whole " +
                                  std::string(p.benchmark == meshes::Benchmark::B1 ? "cylinder B1" : "hemisphere " + meshes::to_string(p.benchmark)) +
                                  "; each MFS case solves organ ∩ ball(contact, L) with u = 0 on the cut sphere (L = its "
                                  "series' local radius), so its error against this reference is truncation plus "
                                  "discretisation (a B3 problem isolates the discretisation)"}});
  // Where the MFS ball reaches the clamped base: B5 near it, B1 with W < L (base z = −W).
  const bool b1 = p.benchmark == meshes::Benchmark::B1;
  if ((b1 || p.benchmark == meshes::Benchmark::B5) && p.ball_reaches_base())
    notes.push_back({{"id", "ball_reaches_base"},
                     {"text", "the MFS ball(contact, L) reaches the clamped base " +
                                  std::string(b1 ? "z = −W (W = " : "z = 0 (R cos θ = ") +
                                  format_number(1e3 * p.body_radius_m * p.outward_normal().z()) + " mm < L = " +
                                  format_number(1e3 * p.local_radius_m) +
                                  " mm). The FEM clamps the base; the MFS holds it only where its engine supports a "
                                  "clamped surface (each case's diagnostics.clamped_quadrature_points > 0: held as u = 0; "
                                  "collocation cannot hold it and ends with a failure status); an MFS that leaves the base "
                                  "free inside its ball is softer by construction"}});
  if (p.point_tool)
    notes.push_back({{"id", "point_tool"},
                     {"text", "B4, the paper's point tool: a point displacement has no finite force in the continuum, so "
                              "each MFS case is compared with the FEM of a flat punch whose radius is that case's tip-node "
                              "spacing s (params.fem_punch_radius_m; the radius of eq. 9's tributary disc). s shrinks as N "
                              "grows, and both forces shrink with it: neither model has a resolution-independent limit, and "
                              "the error column compares two resolution-dependent numbers"}});
  if (p.angle_to_normal_rad() > 45.0 * M_PI / 180.0)
    notes.push_back({{"id", "grazing"},
                     {"text", "the tool direction is " + format_number(std::round(p.angle_to_normal_rad() * 1800 / M_PI) / 10) +
                                  " deg from the inward normal (grazing); both models prescribe " +
                                  std::string(p.contact == geometry::ContactCondition::bonded ? "u = δ d on the patch" : "u·d = δ on the patch (frictionless)")}});
  return notes;
}

class StudyRun {
 public:
  StudyRun(const ComparisonStudy& study, const StudyRunOptions& options) : study_(study), options_(options) {
    out_ = options.output_directory.empty() ? "output/" + study.name : options.output_directory;
    for (const auto& sp : study.problems) {
      ProblemRun r;
      r.sp = &sp;
      r.d = sp.problem.direction.normalized();
      r.reference_part = sp.id_prefix + "reference";
      problems_.push_back(std::move(r));
    }
  }

  json run() {
    start_ = std::chrono::steady_clock::now();
    const bool rank0 = fem::MpiSession::rank() == 0;
    if (rank0) fs::create_directories(out_);
    config_text_ = study_.config_path.empty() ? std::string() : read_file(study_.config_path);
    if (rank0 && !config_text_.empty()) write_file_atomically(out_ + "/study.toml", config_text_);

    // The cases of every problem; a problem with none selected skips its reference (unless it
    // is the only one: every error and the summary need it).
    total_ = (study_.table2_fem ? 1 : 0) + (study_.table2_reference ? 1 : 0);
    for (auto& r : problems_) {
      for (const auto& s : r.sp->series)
        for (const int n : s.study.node_counts)
          if (selected(mfs_id(r, s, n))) r.mfs_cases.push_back({&s, n});
      total_ += r.mfs_cases.size() + (runs_reference(r) ? 1 : 0);
    }

    ProblemRun& first = problems_.front();
    json document{{"study", study_.name},
                  {"provenance", provenance(config_text_)},
                  {"problem", problem_json(first.problem())},
                  {"cases", json::array()}};
    json& cases = document["cases"];

    // The references first: every error needs them. Each FEM solve comes from the cache when the
    // same inputs were solved by the same code version (identical problems share it).
    json problems = json::array();
    for (auto& r : problems_) {
      json entry{{"name", r.sp->name},
                 {"id_prefix", r.sp->id_prefix},
                 {"problem", problem_json(r.problem())},
                 {"overridden_keys", r.sp->overridden_keys},
                 {"notes", problem_notes(r.problem())},
                 {"reference_config", r.sp->reference.name},
                 {"series", json::array()},
                 {"mfs_cases", r.mfs_cases.size()}};
      for (const auto& s : r.sp->series) entry["series"].push_back(s.name);
      if (runs_reference(r) && r.problem().point_tool) {
        entry["punch_references"] = run_point_tool_references(r, cases);
        entry["reference_summary"] = r.reference.summary;
      } else if (runs_reference(r)) {
        const json reference_doc = run_fem(r.reference_part, r.sp->reference);
        r.reference = pick_reference(reference_doc, r.reference_part + "/", r.d);
        add_fem_cases(reference_doc, r.reference_part + "/", r.reference, r.problem(), r, cases);
        entry["reference_summary"] = r.reference.summary;
      } else {
        entry["reference_summary"] = nullptr;
      }
      problems.push_back(entry);
    }
    document["problems"] = problems;
    document["reference_summary"] = first.reference.summary;

    std::optional<ReferenceValue> full_reference;
    if (study_.table2_reference) {
      const json doc = run_fem("table2_reference", *study_.table2_reference);
      full_reference = pick_reference(doc, "table2_reference/", first.d);
      add_fem_cases(doc, "table2_reference/", *full_reference, first.problem(), first, cases);
      document["table2_reference_summary"] = full_reference->summary;
    }
    const ReferenceValue& fe_row_reference = full_reference ? *full_reference : first.reference;
    if (study_.table2_fem) {
      const json doc = run_fem("table2_fem", *study_.table2_fem);
      add_fem_cases(doc, "table2_fem/", fe_row_reference, first.problem(), first, cases);
    }

    // Under mpirun every rank takes part in the FEM solves; the MFS cases, the files and the
    // report are rank 0's.
    if (fem::MpiSession::rank() != 0) return document;
    // The organ surfaces first (gmsh, one at a time), then the cases, `jobs` at a time; each
    // writes only its own folder. Results keep the study's order.
    struct Job {
      ProblemRun* run;
      const MfsSeries* series;
      int n;
      const ReferenceValue* reference;
      std::size_t case_index;  ///< in run->mfs_cases
    };
    std::vector<Job> jobs_list;
    for (auto& r : problems_)
      for (std::size_t k = 0; k < r.mfs_cases.size(); ++k) {
        const auto& [series, n] = r.mfs_cases[k];
        organ_path(series->study);
        jobs_list.push_back({&r, series, n, &r.reference_of(k), k});
      }
    std::vector<json> computed(jobs_list.size());
    const int jobs = std::max(1, std::min<int>(options_.jobs, static_cast<int>(jobs_list.size())));
    document["mfs_jobs"] = jobs;
    const auto compute = [&](std::size_t i) {
      const Job& job = jobs_list[i];
      computed[i] = run_mfs_case(*job.run, *job.series, job.n, *job.reference);
    };
    if (jobs == 1) {
      for (std::size_t i = 0; i < jobs_list.size(); ++i) compute(i);
    } else {
      std::atomic<std::size_t> next{0};
      std::vector<std::exception_ptr> errors(static_cast<std::size_t>(jobs));
      std::vector<std::thread> workers;
      for (int w = 0; w < jobs; ++w)
        workers.emplace_back([&, w] {
          try {
            for (std::size_t i; (i = next.fetch_add(1)) < jobs_list.size();) compute(i);
          } catch (...) {
            errors[static_cast<std::size_t>(w)] = std::current_exception();
          }
        });
      for (auto& worker : workers) worker.join();
      for (const auto& error : errors)
        if (error) std::rethrow_exception(error);
    }
    // Each case's predecessor in its series (the next smaller N), for the convergence-in-N flag.
    std::vector<json> previous(jobs_list.size());
    for (std::size_t i = 0; i < jobs_list.size(); ++i)
      for (std::size_t j = 0; j < jobs_list.size(); ++j) {
        const Job &a = jobs_list[i], &b = jobs_list[j];
        if (a.run != b.run || a.series != b.series || !(b.n < a.n)) continue;
        if (previous[i].is_null() || b.n > previous[i].at("params").at("node_count_requested").get<int>())
          previous[i] = {{"status", computed[j].at("status")},
                         {"qoi", {{"force_N", at_path(computed[j], {"qoi", "force_N"})}}},
                         {"params", {{"node_count_requested", b.n}}}};
      }
    for (std::size_t i = 0; i < jobs_list.size(); ++i) {
      json c = std::move(computed[i]);
      const ProblemRun& r = *jobs_list[i].run;
      const ReferenceValue& reference = *jobs_list[i].reference;
      add_mfs_errors(c, r, reference, &r == &first && full_reference ? &*full_reference : nullptr,
                     previous[i].is_null() ? nullptr : &previous[i]);
      if (r.problem().point_tool) {
        const std::size_t k = jobs_list[i].case_index;
        c["params"]["tip_spacing_m"] = r.tip_spacing_m.at(k);
        c["params"]["fem_punch_radius_m"] = ProblemRun::punch_radius_m(r.tip_spacing_m.at(k));
      }
      const json& flags = c.at("accuracy").at("flags");
      std::string flag_text;
      for (const auto& f : flags) flag_text += (flag_text.empty() ? " [" : ", ") + f.get<std::string>();
      if (!flag_text.empty()) flag_text += "]";
      progress(c.at("id").get<std::string>() + (c.value("resumed", false) ? " (resumed)" : ""),
               "F = " + format_number(1e3 * value_or_nan(c.at("qoi"), "axial_force_N")) + " mN, error " +
                   format_number(100 * value_or_nan(c.at("error"), "force_rel")) + " % (reference's own error " +
                   (std::isfinite(reference.uncertainty_rel) ? format_number(100 * reference.uncertainty_rel) + " %"
                                                             : std::string("not estimated")) +
                   ")  " + c.at("status").get<std::string>() + flag_text);
      cases.push_back(std::move(c));
    }

    document["table2"] = table2(cases, fe_row_reference);
    document["targets"] = targets(cases, document["table2"], full_reference.has_value());
    document["depths_m"] = first.problem().depths_m;
    document["default_formulation"] = mfs::to_string(mfs::LocalModelSettings{}.formulation);
    document["series"] = series_json();
    document["accuracy_thresholds"] = {{"force_method_spread_limit", force_method_spread_limit},
                                       {"support_growth_tolerance", support_growth_tolerance},
                                       {"rcond_margin", rcond_margin},
                                       {"force_change_limit", force_change_limit},
                                       {"stiffness_ratio_min", stiffness_ratio_min},
                                       {"stiffness_ratio_max", stiffness_ratio_max}};
    document["elapsed_s"] = seconds_since(start_);

    write_file_atomically(out_ + "/results.json", document.dump(2) + "\n");
    write_csv(document);
    write_comparison_pvds(cases);
    if (!options_.quiet) print_summary(document);
    if (options_.write_report) make_report();
    return document;
  }

 private:
  bool runs_reference(const ProblemRun& r) const { return problems_.size() == 1 || !r.mfs_cases.empty(); }

  static std::string mfs_id(const ProblemRun& r, const MfsSeries& s, int n) {
    return r.sp->id_prefix + "MFS-" + s.name + "-N" + std::to_string(n);
  }

  bool selected(const std::string& id) const {
    if (options_.only.empty()) return true;
    return std::any_of(options_.only.begin(), options_.only.end(),
                       [&](const std::string& part) { return id.find(part) != std::string::npos; });
  }

  void progress(const std::string& what, const std::string& detail) {
    ++done_;
    if (options_.quiet || fem::MpiSession::rank() != 0) return;
    const double elapsed = seconds_since(start_);
    std::printf("[%zu/%zu] %-34s %s  (elapsed %.0f s, ~%.0f s left)\n", done_, total_, what.c_str(), detail.c_str(),
                elapsed, elapsed / static_cast<double>(done_) * static_cast<double>(total_ - done_));
    std::fflush(stdout);
  }

  static json problem_json(const ComparisonProblem& p) {
    meshes::MeshParameters g;
    g.benchmark = p.benchmark;
    g.body_radius_m = p.body_radius_m;
    g.contact_polar_angle_rad = p.contact_polar_angle_rad;
    return {{"benchmark", p.point_tool ? std::string("B4") : meshes::to_string(p.benchmark)},
            {"domain", meshes::to_string(p.benchmark)},
            {"point_tool", p.point_tool},
            {"body_radius_m", p.body_radius_m},
            {"tool_radius_m", p.tool_radius_m},
            {"local_radius_m", p.local_radius_m},
            {"contact_polar_angle_rad", p.contact_polar_angle_rad},
            {"youngs_modulus_Pa", p.material.youngs_modulus_Pa},
            {"poisson_ratio", p.material.poisson_ratio},
            {"contact", geometry::to_string(p.contact)},
            {"direction", vector_json(p.direction.normalized())},
            {"angle_to_normal_rad", number(p.angle_to_normal_rad())},
            {"contact_point_m", vector_json(contact_point(g))},
            {"depths_m", p.depths_m}};
  }

  json series_json() const {
    const auto entry = [](const MfsSeries& s) {
      return json{{"name", s.name},
                  {"formulation", mfs::to_string(s.study.model.formulation)},
                  {"paper_mode", s.study.model.paper_mode},
                  {"basis", s.study.model.collocation.mls.basis == mfs::Basis::quadratic ? "quadratic" : "linear"},
                  {"haptic_method", mfs::to_string(s.study.model.force.haptic_method)},
                  {"node_counts", s.study.node_counts},
                  {"engine_default", s.engine_default}};
    };
    json list = json::array();
    for (const auto& s : study_.first().series) list.push_back(entry(s));
    // Series that run on other problems only (a variant's `series` subset) are listed too.
    for (const auto& sp : study_.problems)
      for (const auto& s : sp.series)
        if (std::none_of(list.begin(), list.end(), [&](const json& e) { return e.at("name") == s.name; }))
          list.push_back(entry(s));
    return list;
  }

  json run_fem(const std::string& part, const ReferenceStudy& fem_study) {
    RunOptions o;
    o.output_directory = out_ + "/fem/" + part;
    o.cache_directory = options_.cache_directory;
    o.config_text = config_text_;
    o.quiet = options_.quiet;
    if (!options_.quiet && fem::MpiSession::rank() == 0) {
      std::printf("FEM %s: %s, %zu mesh famil%s x %zu levels\n", part.c_str(), fem_study.name.c_str(),
                  std::max<std::size_t>(1, fem_study.edge_sizes_m.size()), fem_study.edge_sizes_m.size() > 1 ? "ies" : "y",
                  fem_study.refinements.size());
      std::fflush(stdout);
    }
    const json doc = run_reference_study(fem_study, o);
    progress("FEM " + part, "done");
    return doc;
  }

  /// B4: a point displacement has no finite force in the continuum, so B4 pairs the paper's
  /// tool-tip node with a flat punch of radius equal to the tip's node spacing s (the radius of
  /// eq. 9's tributary disc π s²). s changes with N and the layout, so each distinct
  /// s gets its own converged reference (the problem's FEM file, every mesh size scaled by s/a,
  /// so that each punch is resolved alike), and both models' forces move with the resolution.
  /// Returns one entry per punch for results.json.
  json run_point_tool_references(ProblemRun& r, json& cases) {
    std::vector<double> spacing;
    if (fem::MpiSession::rank() == 0)
      for (const auto& [series, n] : r.mfs_cases) {
        MfsStudy s = series->study;
        s.surface_path = organ_path(series->study);
        spacing.push_back(paper_tip_spacing_m(s, n));
      }
    // Only rank 0 meshes the organ; every rank takes part in the FEM solves below.
    fem::MpiSession::broadcast_from_root(spacing);
    r.tip_spacing_m = spacing;
    // The progress count had one reference for the problem: it has one per distinct spacing.
    std::set<long long> distinct;
    for (const double s : spacing) distinct.insert(ProblemRun::micrometres(s));
    if (!distinct.empty()) total_ += distinct.size() - 1;
    json entries = json::array();
    const ComparisonProblem& problem = r.problem();
    for (const long long key : distinct) {
      const double radius_m = 1e-6 * static_cast<double>(key);
      const double scale = radius_m / problem.tool_radius_m;
      ComparisonProblem punch = problem;
      punch.tool_radius_m = radius_m;
      ReferenceStudy fem_study = r.sp->reference;
      fem_study.name += "_a" + std::to_string(key) + "um";
      fem_study.geometry.tool_radius_m = radius_m;
      fem_study.geometry.edge_size_m *= scale;
      for (double& edge : fem_study.edge_sizes_m) edge *= scale;
      try {
        fem_study.validate();
      } catch (const std::invalid_argument& e) {
        throw std::invalid_argument("problem " + r.sp->name + " (B4): the FEM punch of radius " + format_number(1e3 * radius_m) +
                                    " mm (a tip spacing): " + e.what());
      }
      const std::string part = r.reference_part + "_a" + std::to_string(key) + "um";
      const json doc = run_fem(part, fem_study);
      ReferenceValue value = pick_reference(doc, part + "/", r.d);
      add_fem_cases(doc, part + "/", value, punch, r, cases);
      entries.push_back({{"punch_radius_m", radius_m}, {"summary", value.summary}});
      r.punch_references.emplace(key, std::move(value));
    }
    if (!spacing.empty()) r.reference = r.reference_of(0);
    return entries;
  }

  /// FEM cases under a prefix; level errors are taken against `reference` (the study's
  /// reference for this domain), the ramp is F δ_i / δ_max. `problem`: the one solved (r's,
  /// or for B4 r's with the punch radius of a tip spacing).
  void add_fem_cases(const json& doc, const std::string& prefix, const ReferenceValue& reference,
                     const ComparisonProblem& problem, const ProblemRun& r, json& cases) const {
    const Eigen::Vector3d& d = r.d;
    for (json c : doc.at("cases")) {
      c["id"] = prefix + c.at("id").get<std::string>();
      // The part without the problem's prefix ("reference", "table2_fem"), the problem apart.
      const std::string part = prefix.substr(0, prefix.size() - 1);
      c["part"] = part.substr(part.rfind('/') == std::string::npos ? 0 : part.rfind('/') + 1);
      if (c.at("params").is_object()) {
        c["params"]["problem"] = r.sp->name;
        c["params"]["problem_values"] = problem_json(problem);
      }
      if (c.contains("reference") && c.at("reference").is_string())
        c["reference"] = prefix + c.at("reference").get<std::string>();
      const double f = axial(c.at("qoi").at("force_N"), d);
      const bool level = c.at("model") == "fem" && c.at("params").contains("refinement") &&
                         c.at("params").at("refinement").is_number();
      if (level) {
        c["reference"] = reference.id;
        c["error"]["force_rel"] = number(std::abs(f - reference.force_N) / std::abs(reference.force_N));
        c["error"]["force_signed_rel"] = number((f - reference.force_N) / std::abs(reference.force_N));
        c["error"]["reference_uncertainty_rel"] = number(reference.uncertainty_rel);
        c["time_s"]["model"] = value_or_nan(c["time_s"], "read_mesh") + value_or_nan(c["time_s"], "setup") +
                               value_or_nan(c["time_s"], "assembly");
        c["time_s"]["solution"] = c["time_s"]["solve"];
      }
      json ramp = json::array();
      for (const double depth : problem.depths_m) ramp.push_back(number(f * depth / problem.max_depth_m()));
      c["depths_m"] = problem.depths_m;
      c["force_depth_N"] = ramp;
      cases.push_back(std::move(c));
    }
  }

  /// The organ surface of a series, generated once per distinct organ (as `touchstone mfs`
  /// does: B3 cuts the local ball from the whole hemisphere; B1, B2 and B5 are their own organ).
  std::string organ_path(const MfsStudy& s) {
    if (!s.surface_path.empty()) return s.surface_path;
    meshes::MeshParameters g = s.geometry;
    if (g.benchmark == meshes::Benchmark::B3) g.benchmark = meshes::Benchmark::B2;
    g.refinement = 0;
    const std::string key = sha256_hex(meshes::to_string(g.benchmark) + format_number(g.body_radius_m) + "|" +
                                       format_number(g.tool_radius_m) + "|" + format_number(g.edge_size_m) + "|" +
                                       format_number(g.size_growth) + "|" + format_number(g.max_size_m) + "|" +
                                       format_number(g.size_exponent) + "|" + format_number(g.contact_polar_angle_rad))
                                .substr(0, 16);
    const std::string path = fs::absolute(fs::path(out_) / "organ" / (key + ".msh")).lexically_normal().string();
    if (!fs::exists(path)) {
      fs::create_directories(fs::path(path).parent_path());
      const std::string temporary = path + ".partial.msh";
      meshes::generate_mesh(g, temporary);
      fs::rename(temporary, path);
    }
    return path;
  }

  /// The problem a case belongs to: its name and values in params (results.json groups by it).
  static void label_problem(json& c, const ProblemRun& r) {
    c["problem"] = r.sp->name;
    c["params"]["problem"] = r.sp->name;
    c["params"]["problem_values"] = problem_json(r.problem());
  }

  /// One MFS case: reused from <out>/mfs/<id>/case.json when its hash matches, else run by
  /// the MFS study (one node count).
  json run_mfs_case(const ProblemRun& r, const MfsSeries& series, int n, const ReferenceValue& reference) {
    const std::string id = mfs_id(r, series, n);
    MfsStudy s = series.study;
    s.name = id;
    s.node_counts = {n};
    s.model.sprinkling.node_count = n;
    const std::string hash = sha256_hex(resolved_config_toml(s) + touchstone::version::git_hash +
                                        touchstone::version::build_type);
    s.surface_path = organ_path(series.study);
    const std::string directory = out_ + "/mfs/" + id;
    const std::string record_path = directory + "/case.json";
    if (fs::exists(record_path)) {
      try {
        json record = json::parse(read_file(record_path));
        if (record.value("case_sha256", "") == hash) {
          json c = record.at("case");
          c["resumed"] = true;
          label_problem(c, r);
          return c;
        }
      } catch (const std::exception&) {
        // An unreadable record is recomputed.
      }
    }
    MfsRunOptions o;
    o.output_directory = directory;
    o.config_text = series.config_text;
    o.quiet = true;
    // The MFS field on the reference's finest mesh, for ParaView (and a field error).
    if (!reference.field_vtu.empty()) o.reference_field_path = out_ + "/fem/" + reference.part + "/" + reference.field_vtu;
    const json doc = run_mfs_study(s, o);
    json c = doc.at("cases").at(0);
    c["id"] = id;
    c["series"] = series.name;
    c["part"] = "mfs";
    label_problem(c, r);
    if (c.value("vtu", json(nullptr)).is_string()) c["vtu"] = "mfs/" + id + "/" + c.at("vtu").get<std::string>();
    if (c.value("comparison_vtu", json(nullptr)).is_string())
      c["comparison_vtu"] = "mfs/" + id + "/" + c.at("comparison_vtu").get<std::string>();
    const json& t = c["time_s"];
    // Table 2's split: model = sprinkle + shape functions + assembly (the paper's "time to
    // generate the stiffness matrix"); solution = factorisation + condensation to K_t + solve.
    c["time_s"]["model"] = value_or_nan(t, "sprinkle") + value_or_nan(t, "assembly");
    c["time_s"]["solution"] = value_or_nan(t, "factorize") + value_or_nan(t, "condense") + value_or_nan(t, "solve");
    write_file_atomically(record_path, json{{"case_sha256", hash}, {"case", c}}.dump(2) + "\n");
    c["resumed"] = false;
    return c;
  }

  /// One PVD per MFS series, its cases' fields on the reference mesh with the node count as the
  /// time step: ParaView steps through N and shows MFS, FEM and their difference.
  void write_comparison_pvds(const json& cases) const {
    std::map<std::string, std::vector<std::pair<double, std::string>>> by_series;
    for (const auto& c : cases)
      if (c.value("part", "") == "mfs" && c.value("comparison_vtu", json(nullptr)).is_string())
        by_series[c.at("id").get<std::string>().substr(0, c.at("id").get<std::string>().rfind('/') + 1) +
                  c.at("series").get<std::string>()].push_back(
            {c.at("params").value("node_count", 0.0), c.at("comparison_vtu").get<std::string>()});
    for (auto& [series, files] : by_series) {
      std::sort(files.begin(), files.end());
      std::ostringstream pvd;
      pvd << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n  <Collection>\n";
      for (const auto& [n, file] : files) pvd << "    <DataSet timestep=\"" << n << "\" group=\"\" part=\"0\" file=\"" << file << "\"/>\n";
      pvd << "  </Collection>\n</VTKFile>\n";
      // A variant's series: "<name>/<series>" → mfs_on_reference_<name>_<series>.pvd.
      std::string file_name = series;
      std::replace(file_name.begin(), file_name.end(), '/', '_');
      write_file_atomically(out_ + "/mfs_on_reference_" + file_name + ".pvd", pvd.str());
    }
  }

  void add_mfs_errors(json& c, const ProblemRun& r, const ReferenceValue& reference, const ReferenceValue* full,
                      const json* previous) const {
    const Eigen::Vector3d& d = r.d;
    json& qoi = c["qoi"];
    const double f = axial(qoi.value("force_N", json(nullptr)), d);
    qoi["axial_force_N"] = number(f);
    const double fr = reference.force_N;
    json error{{"force_rel", number(std::abs(f - fr) / std::abs(fr))},
               {"force_signed_rel", number((f - fr) / std::abs(fr))},
               {"reference_uncertainty_rel", number(reference.uncertainty_rel)},
               {"disp_rel_l2", nullptr},
               {"disp_max_m", nullptr},
               {"disp_probes", 0},
               {"reference_disp_uncertainty_rel", number(reference.disp_uncertainty_rel)}};
    json by_method = json::object();
    const json& methods = at_path(qoi, {"forces_by_method_N"});
    if (methods.is_object())
      for (const auto& [name, value] : methods.items()) {
        const double fm = value.is_number() ? value.get<double>() : axial(value, d);
        by_method[name] = number((fm - fr) / std::abs(fr));
      }
    error["by_method_signed_rel"] = by_method;
    if (qoi.contains("probes") && qoi.at("probes").is_array() && !qoi.at("probes").empty()) {
      const ProbeComparison p = compare_probes(qoi.at("probes"), reference.probes);
      if (p.count > 0) {
        error["disp_rel_l2"] = number(p.rel_l2);
        error["disp_max_m"] = number(p.max_abs_m);
        error["disp_probes"] = p.count;
      }
    }
    error["field_rel_l2"] = c.value("error", json::object()).value("field_rel_l2", json(nullptr));
    c["error"] = error;
    c["reference"] = reference.id;
    // B1 and B2: the closed form the FEM reference itself is checked against, next to it.
    const double fh = reference.half_space_force_N;
    if (std::isfinite(fh))
      c["error_half_space"] = {{"force_rel", number(std::abs(f - fh) / std::abs(fh))},
                               {"force_signed_rel", number((f - fh) / std::abs(fh))},
                               {"reference", reference.half_space_id},
                               {"formula", reference.half_space_formula}};
    if (full != nullptr && r.problem().benchmark != study_.table2_reference->geometry.benchmark) {
      c["error_full_domain"] = {{"force_rel", number(std::abs(f - full->force_N) / std::abs(full->force_N))},
                                {"force_signed_rel", number((f - full->force_N) / std::abs(full->force_N))},
                                {"reference", full->id},
                                {"reference_uncertainty_rel", number(full->uncertainty_rel)}};
    }
    Eigen::Matrix3d kt = Eigen::Matrix3d::Constant(nan_value);
    const json& m = at_path(qoi, {"tool_stiffness_matrix_N_per_m"});
    if (m.is_array() && m.size() == 3)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) kt(i, j) = value_or_nan(m.at(i).at(j));
    json ramp = json::array();
    for (const double v : mfs_force_ramp_N(kt, d, r.problem().depths_m)) ramp.push_back(number(v));
    c["depths_m"] = r.problem().depths_m;
    c["force_depth_N"] = ramp;
    // What the engine says about its own accuracy, next to the status (a case can end "ok"
    // far from the reference; these flags need no reference).
    c["accuracy"] = to_json(accuracy_indicator(c, d, previous));
  }

  const json* find_case(const json& cases, const std::string& id) const {
    for (const auto& c : cases)
      if (c.at("id") == id) return &c;
    return nullptr;
  }

  /// Table 2: the paper's numbers next to ours (same node counts), with the force error each
  /// achieves and the reference's own error estimate.
  json table2(const json& cases, const ReferenceValue& fe_reference) const {
    const ProblemRun& first = problems_.front();
    const ReferenceValue& reference = first.reference;
    json t{{"paper",
            {{"fe", {{"nodes", 4045}, {"model_s", 6.44}, {"solution_s", 11.88}, {"total_s", 18.32}}},
             {"mfs", {{"nodes", 34}, {"model_s", 0.0021}, {"solution_s", 0.0015}, {"total_s", 0.0036}}},
             {"machine", "600-900 MHz Pentium (2002)"}}},
           {"ours", json::object()}};
    json& ours = t["ours"];
    for (const auto& c : cases) {
      if (c.value("part", "") != "table2_fem" || c.at("model") != "fem" || !c.at("params").contains("refinement") ||
          !c.at("params").at("refinement").is_number())
        continue;
      const json& ts = c.at("time_s");
      ours["fe"] = {{"case", c.at("id")},
                    {"nodes", c.at("mesh").at("fe_nodes")},
                    {"mesh_vertices", c.at("mesh").at("vertices")},
                    {"dofs", c.at("mesh").at("dofs")},
                    {"mesh_s", ts.at("mesh")},
                    {"model_s", ts.at("model")},
                    {"solution_s", ts.at("solve")},
                    {"total_s", number(value_or_nan(ts, "model") + value_or_nan(ts, "solve"))},
                    {"end_to_end_s", ts.at("total")},
                    {"axial_force_N", c.at("qoi").at("axial_force_N")},
                    {"force_rel", c.at("error").at("force_rel")},
                    {"reference", fe_reference.id},
                    {"reference_force_N", number(fe_reference.force_N)},
                    {"reference_uncertainty_rel", number(fe_reference.uncertainty_rel)}};
    }
    const auto mfs_row = [&](const std::string& series_name) -> json {
      for (const auto& s : first.sp->series) {
        if (s.name != series_name) continue;
        const json* c = find_case(cases, mfs_id(first, s, s.study.node_counts.front()));
        if (c == nullptr) return nullptr;
        const json& ts = c->at("time_s");
        json row{{"case", c->at("id")},
                 {"series", s.name},
                 {"formulation", mfs::to_string(s.study.model.formulation)},
                 {"paper_mode", s.study.model.paper_mode},
                 {"nodes", c->at("params").at("node_count")},
                 {"nodes_requested", c->at("params").at("node_count_requested")},
                 {"model_s", ts.at("model")},
                 {"solution_s", ts.at("solution")},
                 {"total_s", number(value_or_nan(ts, "model") + value_or_nan(ts, "solution"))},
                 {"axial_force_N", c->at("qoi").at("axial_force_N")},
                 {"force_rel", c->at("error").at("force_rel")},
                 {"reference", reference.id},
                 {"reference_uncertainty_rel", number(reference.uncertainty_rel)},
                 {"disp_rel_l2", c->at("error").at("disp_rel_l2")},
                 {"status", c->at("status")}};
        if (c->contains("error_full_domain")) row["force_rel_full_domain"] = c->at("error_full_domain").at("force_rel");
        return row;
      }
      return nullptr;
    };
    if (!study_.table2_mfs_series.empty()) ours["mfs"] = mfs_row(study_.table2_mfs_series);
    // The "engine default" row: the series whose resolved settings are the engine's defaults
    // (by value, not by name); none such, and Table 2 says so instead of guessing.
    const auto is_default = [](const MfsSeries& s) { return s.engine_default; };
    const auto found = std::find_if(first.sp->series.begin(), first.sp->series.end(), is_default);
    if (found != first.sp->series.end()) {
      ours["mfs_default"] = mfs_row(found->name);
      t["mfs_default_series"] = found->name;
    } else {
      ours["mfs_default"] = nullptr;
      t["mfs_default_series"] = nullptr;
      t["mfs_default_note"] =
          "no series of this study runs the engine defaults (realtime::mfs::LocalModelSettings{} with the MFS "
          "reader's defaults); Table 2 has no engine-default row";
    }
    return t;
  }

  /// The speed and accuracy targets: each with the measured value, met or not, and by how much.
  json targets(const json& cases, const json& table2, bool have_full_reference) const {
    json list = json::array();
    const auto add = [&](const std::string& id, const std::string& what, double target, double measured,
                         const std::string& unit, const std::string& basis) {
      json t{{"id", id}, {"what", what}, {"target", target}, {"unit", unit}, {"measured", number(measured)}, {"basis", basis}};
      if (!std::isfinite(measured)) {
        t["met"] = nullptr;
        t["shortfall"] = "not measured";
      } else {
        t["met"] = measured <= target;
        t["ratio_to_target"] = measured / target;
        if (measured <= target)
          t["shortfall"] = "";
        else if (unit == "relative")
          t["shortfall"] = "missed by " + format_number(std::round(1e4 * (measured - target)) / 100) + " percentage points";
        else
          t["shortfall"] = "missed: " + format_number(std::round(10 * measured / target) / 10) + "x the target";
      }
      list.push_back(t);
    };
    for (const ProblemRun& r : problems_) {
    // B4 without a selected case has no punch, so no reference.
    if (!runs_reference(r) || r.reference.id.empty()) continue;
    // B4: the least accurate of its punch references.
    const ReferenceValue* worst = &r.reference;
    for (const auto& [key, punch] : r.punch_references)
      if (!(punch.uncertainty_rel <= worst->uncertainty_rel)) worst = &punch;
    const ReferenceValue& reference = *worst;
    // One problem: the ids as always; several: each id and label names its problem.
    const std::string tag = r.sp->id_prefix;
    const std::string where = tag.empty() ? "" : " [" + r.sp->name + "]";
    add("fem_reference_uncertainty" + (tag.empty() ? "" : ":" + r.sp->name),
        "FEM reference force: estimated discretisation error (Richardson, " +
            reference.summary.at("study").get<std::string>() + ")" + where +
            (r.punch_references.size() > 1 ? ", the largest of its punch references" : ""),
        0.003, reference.uncertainty_rel, "relative", reference.id);

    for (const auto& s : r.sp->series) {
      if (s.study.model.paper_mode) continue;
      std::vector<const json*> series_cases;
      for (const auto& c : cases)
        if (c.value("series", "") == s.name && c.value("problem", "") == r.sp->name && c.at("status") == "ok")
          series_cases.push_back(&c);
      const auto best = [&](const char* field, int max_n, std::string& basis) {
        double value = nan_value;
        for (const json* c : series_cases) {
          const int n = c->at("params").at("node_count_requested").get<int>();
          const double e = value_or_nan(c->at("error"), field);
          if (n <= max_n && std::isfinite(e) && !(e >= value)) {
            value = e;
            basis = c->at("id");
          }
        }
        return value;
      };
      const std::string label = "MFS " + s.name + " (" + mfs::to_string(s.study.model.formulation) +
                                (s.engine_default ? ", engine default" : "") + ")" + where;
      // The force targets are stated on B3, the MFS's own domain; on a whole body the same
      // numbers measure the local model's truncation as well.
      const std::string domain = r.problem().benchmark == meshes::Benchmark::B3
                                     ? "on the identical domain"
                                     : "on the whole body " + meshes::to_string(r.problem().benchmark) + " (truncation included)";
      // A missed force target says how far off it is in N too: the series' own rate, extrapolated.
      std::vector<std::pair<double, double>> n_and_error;
      for (const json* c : series_cases)
        n_and_error.push_back({value_or_nan(c->at("params"), "node_count"), value_or_nan(c->at("error"), "force_rel")});
      const auto add_rate = [&](double target) {
        json& t = list.back();
        if (t.at("met") != false) return;
        const ConvergenceInN fit = convergence_in_n(n_and_error, target);
        t["convergence_in_n"] = {{"order", number(fit.order)}, {"n_at_target", number(fit.n_at_target)},
                                 {"node_counts", fit.node_counts}};
        if (std::isfinite(fit.n_at_target))
          t["shortfall"] = t.at("shortfall").get<std::string>() + "; the series' error falls as N^" +
                           format_number(std::round(100 * fit.order) / 100) + " (fit over N = " +
                           format_number(fit.node_counts.front()) + "-" + format_number(fit.node_counts.back()) +
                           "), which reaches the target at N ~ " + format_number(std::round(fit.n_at_target));
        else if (std::isfinite(fit.order))
          t["shortfall"] = t.at("shortfall").get<std::string>() + "; the series' error does not fall with N (fit over N = " +
                           format_number(fit.node_counts.front()) + "-" + format_number(fit.node_counts.back()) + ")";
      };
      std::string basis;
      double v = best("force_rel", 60, basis);
      add("mfs_force_n60:" + tag + s.name, label + " vs FEM " + domain + ", tool force, best N <= 60", 0.05, v, "relative", basis);
      add_rate(0.05);
      basis.clear();
      v = best("force_rel", 300, basis);
      add("mfs_force_n300:" + tag + s.name, label + " vs FEM " + domain + ", tool force, best N <= 300", 0.01, v, "relative", basis);
      add_rate(0.01);
      basis.clear();
      v = best("disp_rel_l2", std::numeric_limits<int>::max(), basis);
      add("mfs_displacement:" + tag + s.name, label + " vs FEM, displacement at probes (relative L2), best N", 0.02, v, "relative", basis);
      if (have_full_reference) {
        double full = nan_value;
        std::string full_basis;
        for (const json* c : series_cases) {
          const double e = value_or_nan(at_path(*c, {"error_full_domain"}), "force_rel");
          if (std::isfinite(e) && !(e >= full)) {
            full = e;
            full_basis = c->at("id");
          }
        }
        if (&r == &problems_.front())
          add("mfs_vs_full_domain:" + tag + s.name, label + " local model vs the full hemisphere B2, tool force, best N",
              0.03, full, "relative", full_basis);
      }
    }
    }

    // Run time against error: the cheapest MFS and the cheapest reference FEM level reaching 5 %.
    double mfs_time = nan_value, fem_time = nan_value;
    std::string mfs_case, fem_case;
    for (const auto& c : cases) {
      const double e = value_or_nan(c.at("error"), "force_rel");
      const double t = value_or_nan(c.at("time_s"), "total");
      if (!(e <= 0.05) || !std::isfinite(t)) continue;
      if (c.at("model") == "mfs" && c.at("status") == "ok" && c.value("problem", "") == problems_.front().sp->name &&
          !(t >= mfs_time)) {
        mfs_time = t;
        mfs_case = c.at("id");
      }
      if (c.value("part", "") == "reference" && c.at("id").get<std::string>().rfind(problems_.front().reference_part + "/", 0) == 0 &&
          c.at("params").contains("refinement") &&
          c.at("params").at("refinement").is_number() && !(t >= fem_time)) {
        fem_time = t;
        fem_case = c.at("id");
      }
    }
    {
      json t{{"id", "speedup_at_5_percent"},
             {"what", "at 5 % force error, MFS at least 10^4 x faster than the FEM that reaches 5 %"},
             {"target", 1e4},
             {"unit", "speedup (higher is better)"},
             {"basis", mfs_case + " vs " + fem_case}};
      if (!score_speedup(t, fem_time, mfs_time)) {
        t["measured"] = nullptr;
        t["met"] = std::isfinite(fem_time) ? json(false) : json(nullptr);
        t["shortfall"] = std::isfinite(mfs_time) ? "no FEM level reached 5 %" : "missed: no MFS case reached 5 % force error";
      }
      list.push_back(t);
    }

    // The same at the default model's own accuracy: its fastest case within 1 %, against the
    // cheapest FEM level at least as accurate; when no level is (the references' finest mesh
    // rarely is), the finest level's time makes the ratio a lower bound.
    {
      double mfs_t = nan_value, mfs_error = nan_value;
      std::string mfs_id_best;
      for (const auto& c : cases) {
        if (c.at("model") != "mfs" || c.at("status") != "ok" || c.value("problem", "") != problems_.front().sp->name) continue;
        const auto series = std::find_if(problems_.front().sp->series.begin(), problems_.front().sp->series.end(),
                                         [&](const MfsSeries& s) { return s.name == c.value("series", ""); });
        if (series == problems_.front().sp->series.end() || !series->engine_default) continue;
        const double e = value_or_nan(c.at("error"), "force_rel"), t = value_or_nan(c.at("time_s"), "total");
        if (!(e <= 0.01) || !std::isfinite(t) || t >= mfs_t) continue;
        mfs_t = t, mfs_error = e, mfs_id_best = c.at("id");
      }
      double fem_t = nan_value, finest_t = nan_value, finest_dofs = -1;
      std::string fem_id, finest_id;
      for (const auto& c : cases) {
        if (c.value("part", "") != "reference" ||
            c.at("id").get<std::string>().rfind(problems_.front().reference_part + "/", 0) != 0 ||
            !c.at("params").contains("refinement") || !c.at("params").at("refinement").is_number())
          continue;
        const double e = value_or_nan(c.at("error"), "force_rel"), t = value_or_nan(c.at("time_s"), "total");
        const double dofs = value_or_nan(at_path(c, {"mesh"}), "dofs");
        if (!std::isfinite(t)) continue;
        if (dofs > finest_dofs) finest_dofs = dofs, finest_t = t, finest_id = c.at("id");
        if (e <= mfs_error && !(t >= fem_t)) fem_t = t, fem_id = c.at("id");
      }
      const bool bound = !std::isfinite(fem_t);
      const double fem_time_used = bound ? finest_t : fem_t;
      json t{{"id", "speedup_at_default_error"},
             {"what", "at the default MFS's own force error (its fastest case within 1 %), MFS at least 10^4 x faster "
                      "than the FEM that reaches that error" + std::string(bound ? " (no FEM level does: the finest level's "
                                                                                   "time, a lower bound)" : "")},
             {"target", 1e4},
             {"unit", "speedup (higher is better)"},
             {"mfs_force_error", number(mfs_error)},
             {"lower_bound", bound},
             {"basis", mfs_id_best + " vs " + (bound ? finest_id : fem_id)}};
      if (!score_speedup(t, fem_time_used, mfs_t)) {
        t["measured"] = nullptr;
        t["met"] = nullptr;
        t["shortfall"] = "no default MFS case within 1 %, or no FEM level";
      }
      list.push_back(t);
    }

    // Speed, from single wall-clock samples of this run (the benchmarks are authoritative).
    const json& mfs_row = at_path(table2, {"ours", "mfs"});
    if (mfs_row.is_object())
      add("mfs34_time", "MFS local model, 34 nodes (" + mfs_row.at("series").get<std::string>() +
                            "): sprinkle + shape functions + assembly + solve (one sample; benchmarks are authoritative)",
          20e-6, value_or_nan(mfs_row, "total_s"), "s", mfs_row.at("case"));
    for (const auto& s : problems_.front().sp->series) {
      if (!s.engine_default || s.study.model.collocation.mls.basis != mfs::Basis::quadratic) continue;
      const json* c = find_case(cases, mfs_id(problems_.front(), s, 200));
      if (c != nullptr)
        add("mfs200_time", "MFS local model, 200 nodes, quadratic basis (one sample)", 1e-3,
            value_or_nan(c->at("time_s"), "total"), "s", c->at("id"));
      break;
    }
    const json& fe_row = at_path(table2, {"ours", "fe"});
    if (fe_row.is_object())
      add("fem_paper_size_time", "FEM reference at the paper's size (~4045 nodes), end to end (mesh + assembly + solve)",
          0.2, value_or_nan(fe_row, "end_to_end_s"), "s", fe_row.at("case"));
    return list;
  }

  void write_csv(const json& document) const {
    const std::vector<std::pair<std::string, std::vector<std::string>>> columns{
        {"id", {"id"}},
        {"model", {"model"}},
        {"part", {"part"}},
        {"series", {"series"}},
        {"formulation", {"params", "formulation"}},
        {"nodes_requested", {"params", "node_count_requested"}},
        {"nodes", {"params", "node_count"}},
        {"dofs", {"mesh", "dofs"}},
        {"axial_force_N", {"qoi", "axial_force_N"}},
        {"force_rel", {"error", "force_rel"}},
        {"force_signed_rel", {"error", "force_signed_rel"}},
        {"reference_uncertainty_rel", {"error", "reference_uncertainty_rel"}},
        {"disp_rel_l2", {"error", "disp_rel_l2"}},
        {"disp_max_m", {"error", "disp_max_m"}},
        {"force_rel_full_domain", {"error_full_domain", "force_rel"}},
        {"force_signed_rel_half_space", {"error_half_space", "force_signed_rel"}},
        {"model_s", {"time_s", "model"}},
        {"solution_s", {"time_s", "solution"}},
        {"total_s", {"time_s", "total"}},
        {"reference", {"reference"}},
        {"status", {"status"}},
        {"problem", {"params", "problem"}},
        {"force_method_spread", {"accuracy", "force_method_spread"}},
        {"accuracy_flags", {"accuracy", "flags"}}};
    std::ostringstream text;
    for (std::size_t i = 0; i < columns.size(); ++i) text << (i ? "," : "") << columns[i].first;
    text << "\n";
    for (const auto& c : document.at("cases")) {
      for (std::size_t i = 0; i < columns.size(); ++i) text << (i ? "," : "") << csv_value(at_path(c, columns[i].second));
      text << "\n";
    }
    write_file_atomically(out_ + "/cases.csv", text.str());

    std::ostringstream ramp;
    ramp << "id,model,depth_m,axial_force_N\n";
    for (const auto& c : document.at("cases")) {
      const json& depths = at_path(c, {"depths_m"});
      const json& forces = at_path(c, {"force_depth_N"});
      for (std::size_t i = 0; depths.is_array() && i < depths.size() && i < forces.size(); ++i)
        ramp << csv_value(c.at("id")) << "," << csv_value(c.at("model")) << "," << csv_value(depths[i]) << ","
             << csv_value(forces[i]) << "\n";
    }
    write_file_atomically(out_ + "/force_depth.csv", ramp.str());

    std::ostringstream probes;
    probes << "id,probe,x_m,y_m,z_m,ux_m,uy_m,uz_m\n";
    for (const auto& c : document.at("cases")) {
      const json& list = at_path(c, {"qoi", "probes"});
      const bool reference_case = std::any_of(problems_.begin(), problems_.end(), [&](const ProblemRun& r) {
        return c.at("id") == r.reference.id ||
               std::any_of(r.punch_references.begin(), r.punch_references.end(),
                           [&](const auto& punch) { return c.at("id") == punch.second.id; });
      });
      if (!list.is_array() || (c.at("model") != "mfs" && !reference_case)) continue;
      for (const auto& p : list) {
        const json& x = p.at("position_m");
        const json& u = p.value("displacement_m", json(nullptr));
        probes << csv_value(c.at("id")) << "," << csv_value(p.at("name"));
        for (int i = 0; i < 3; ++i) probes << "," << csv_value(x.at(i));
        for (int i = 0; i < 3; ++i) probes << "," << (u.is_array() ? csv_value(u.at(i)) : std::string());
        probes << "\n";
      }
    }
    write_file_atomically(out_ + "/probes.csv", probes.str());

    std::ostringstream targets;
    targets << "id,what,target,unit,measured,met,shortfall,basis\n";
    for (const auto& t : document.at("targets"))
      targets << csv_value(t.at("id")) << "," << csv_value(t.at("what")) << "," << csv_value(t.at("target")) << ","
              << csv_value(t.at("unit")) << "," << csv_value(t.at("measured")) << "," << csv_value(t.at("met")) << ","
              << csv_value(t.at("shortfall")) << "," << csv_value(t.at("basis")) << "\n";
    write_file_atomically(out_ + "/targets.csv", targets.str());
  }

  void print_summary(const json& document) const {
    for (const ProblemRun& r : problems_) {
      if (!runs_reference(r)) continue;
      std::printf("\nreference %s: F = %.6f mN, estimated discretisation error %s", r.reference.id.c_str(),
                  1e3 * r.reference.force_N,
                  std::isfinite(r.reference.uncertainty_rel) ? (format_number(100 * r.reference.uncertainty_rel) + " %").c_str()
                                                             : "not estimated (fewer than three levels)");
      if (std::isfinite(r.reference.half_space_force_N))
        std::printf("\n  half-space closed form (%s): F = %.6f mN; reference / half-space = %.5f",
                    r.reference.half_space_formula.c_str(), 1e3 * r.reference.half_space_force_N,
                    r.reference.force_N / r.reference.half_space_force_N);
    }
    std::printf("\n");
    // A signed error against the half-space closed form where the problem has one (B1, B2).
    const bool half_space = std::any_of(problems_.begin(), problems_.end(), [](const ProblemRun& r) {
      return std::isfinite(r.reference.half_space_force_N);
    });
    std::printf("%-28s %6s %12s %10s %10s %11s%s\n", "case", "N", "F [mN]", "F err [%]", "u err [%]", "time [ms]",
                half_space ? "  vs half-space [%]" : "");
    for (const auto& c : document.at("cases")) {
      if (c.at("model") != "mfs") continue;
      std::string flags;
      for (const auto& f : c.at("accuracy").at("flags")) flags += " " + f.get<std::string>();
      const std::string versus =
          half_space ? " " + table_cell(100 * value_or_nan(at_path(c, {"error_half_space"}), "force_signed_rel"), 18, 2) : "";
      std::printf("%-28s %6s %s %s %s %s%s  %s%s\n", c.at("id").get<std::string>().c_str(),
                  c.at("params").at("node_count").dump().c_str(),
                  table_cell(1e3 * value_or_nan(c.at("qoi"), "axial_force_N"), 12, 5).c_str(),
                  table_cell(100 * value_or_nan(c.at("error"), "force_rel"), 10, 2).c_str(),
                  table_cell(100 * value_or_nan(c.at("error"), "disp_rel_l2"), 10, 2).c_str(),
                  table_cell(1e3 * value_or_nan(c.at("time_s"), "total"), 11, 2).c_str(), versus.c_str(),
                  c.at("status").get<std::string>().c_str(), flags.c_str());
    }
    std::printf("\nTargets:\n");
    for (const auto& t : document.at("targets")) {
      const std::string met = t.at("met").is_null() ? "n/a " : (t.at("met").get<bool>() ? "MET " : "MISS");
      std::printf("  %s %s: %s %s\n", met.c_str(), t.at("what").get<std::string>().c_str(),
                  t.at("measured").is_null() ? "-" : format_number(t.at("measured").get<double>()).c_str(),
                  t.at("shortfall").get<std::string>().c_str());
    }
    std::fflush(stdout);
  }

  void make_report() const {
    std::string script = options_.report_script;
    if (script.empty()) {
      const char* env = std::getenv("TOUCHSTONE_REPORT_SCRIPT");
      script = env != nullptr ? env : std::string(TOUCHSTONE_SOURCE_DIR) + "/reports/make_report.py";
    }
    if (!fs::exists(script)) throw std::runtime_error("report generator not found: " + script);
    const auto quote = [](const std::string& s) {
      std::string q = "'";
      for (const char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
      return q + "'";
    };
    const std::string command = quote(options_.python) + " " + quote(script) + " " + quote(out_);
    std::fflush(stdout);
    const int status = std::system(command.c_str());
    if (status != 0)
      throw std::runtime_error("the report generator failed (" + command + ", status " + std::to_string(status) +
                               "); results.json and the CSV tables are written");
  }

  const ComparisonStudy& study_;
  const StudyRunOptions& options_;
  std::string out_, config_text_;
  std::vector<ProblemRun> problems_;
  std::chrono::steady_clock::time_point start_;
  std::size_t done_ = 0, total_ = 0;
};

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
  p.body_radius_m = problem.quantity("body_radius", Dimension::length, p.body_radius_m);
  p.tool_radius_m = problem.quantity("tool_radius", Dimension::length, p.tool_radius_m);
  p.local_radius_m = problem.quantity("local_radius", Dimension::length, 5 * p.tool_radius_m);
  p.contact_polar_angle_rad = problem.quantity("contact_polar_angle", Dimension::angle, 0.0);
  p.material.youngs_modulus_Pa = problem.quantity("youngs_modulus", Dimension::pressure, p.material.youngs_modulus_Pa);
  p.material.poisson_ratio = problem.number("poisson_ratio", p.material.poisson_ratio);
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
  // Syntax errors with the file and line, as every other study file.
  { ConfigTable syntax_check = ConfigTable::from_file(path); }
  toml::table document = toml::parse_file(path);
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

nlohmann::json run_comparison_study(const ComparisonStudy& study, const StudyRunOptions& options) {
  study.validate();
  return StudyRun(study, options).run();
}

std::vector<double> mfs_force_ramp_N(const Eigen::Matrix3d& tool_stiffness_N_per_m, const Eigen::Vector3d& direction,
                                     const std::vector<double>& depths_m) {
  const Eigen::Vector3d d = direction.normalized();
  std::vector<double> forces;
  forces.reserve(depths_m.size());
  for (const double depth : depths_m) forces.push_back((tool_stiffness_N_per_m * (depth * d)).dot(d));
  return forces;
}

namespace {
std::string value_or(const json& object, const char* key, const std::string& fallback) {
  return object.is_object() && object.contains(key) && object.at(key).is_string() ? object.at(key).get<std::string>()
                                                                                   : fallback;
}
}  // namespace

AccuracyIndicator accuracy_indicator(const json& c, const Eigen::Vector3d& direction, const json* previous) {
  AccuracyIndicator a;
  // A failed case has no result to judge: its status says what went wrong, and the numbers
  // it reported before failing (e.g. the forces of a model that then could not hold a clamped
  // surface) would raise flags about a result nobody receives.
  if (c.contains("status") && c.at("status") != "ok") return a;
  const Eigen::Vector3d d = direction.normalized();
  const json& methods = at_path(c, {"qoi", "forces_by_method_N"});
  const auto force = [&](const char* method) {
    if (!methods.is_object() || !methods.contains(method)) return nan_value;
    const json& v = methods.at(method);
    return v.is_number() ? v.get<double>() : axial(v, d);
  };
  // The weak form's pair when both exist (Galerkin: K u at the tool and 2U/δ), else the
  // strong form's pair (collocation's traction integral and the paper's partition).
  for (const auto& pair : {std::pair<const char*, const char*>{"reaction", "energy_along_tool"},
                           std::pair<const char*, const char*>{"traction_integral", "paper_partition"}}) {
    const double f1 = force(pair.first), f2 = force(pair.second);
    if (!std::isfinite(f1) || !std::isfinite(f2)) continue;
    const double scale = std::max(std::abs(f1), std::abs(f2));
    a.force_method_spread = scale > 0 ? std::abs(f1 - f2) / scale : 0.0;
    a.force_methods = {pair.first, pair.second};
    break;
  }
  // The moment-matrix statistics: over the collocation points (collocation) or the volume
  // quadrature points (Galerkin); missing (NaN) in a case that failed before reporting them.
  a.support_scale_max = value_or_nan(at_path(c, {"diagnostics"}), "max_support_scale_used");
  a.rcond_min = value_or_nan(at_path(c, {"qoi"}), "min_rcond");
  const json& params = at_path(c, {"params"});
  const double e = value_or_nan(params, "youngs_modulus_Pa"), nu = value_or_nan(params, "poisson_ratio");
  const double radius = value_or_nan(params, "tool_radius_m"), depth = value_or_nan(params, "depth_m");
  const double half_space_N_per_m = 2 * e * radius / (1 - nu * nu);
  a.stiffness_ratio = std::abs(axial(at_path(c, {"qoi", "force_N"}), d)) / depth / half_space_N_per_m;
  if (!std::isfinite(a.stiffness_ratio)) a.stiffness_ratio = nan_value;
  if (a.force_method_spread > force_method_spread_limit) a.flags.push_back("force_methods_disagree");
  if (a.support_scale_max > 1 + support_growth_tolerance) a.flags.push_back("supports_grew");
  const double threshold = value_or_nan(at_path(c, {"params"}), "min_rcond_threshold");
  if (std::isfinite(a.rcond_min) && std::isfinite(threshold) && a.rcond_min < rcond_margin * threshold)
    a.flags.push_back("ill_conditioned");
  if (a.stiffness_ratio < stiffness_ratio_min || a.stiffness_ratio > stiffness_ratio_max)
    a.flags.push_back("stiffness_implausible");
  const json& enriched = at_path(c, {"diagnostics", "enriched"});
  if (enriched.is_object()) {
    a.mls_energy_share = value_or_nan(enriched, "mls_energy_share");
    const json& amplitudes = enriched.value("amplitudes_per_depth", json::array());
    if (!amplitudes.empty() && amplitudes.at(0).is_number()) a.normal_amplitude = amplitudes.at(0).get<double>();
    a.exterior_used = enriched.value("exterior_used", "");
    if (a.mls_energy_share > mls_energy_share_limit) a.flags.push_back("mls_dominated");
    if (a.normal_amplitude < normal_amplitude_min || a.normal_amplitude > normal_amplitude_max)
      a.flags.push_back("amplitude_implausible");
    if (a.exterior_used != value_or(params, "exterior", a.exterior_used)) a.flags.push_back("exterior_fallback");
  }
  if (previous != nullptr && previous->value("status", "") == "ok") {
    const double f = axial(at_path(c, {"qoi", "force_N"}), d), f_previous = axial(at_path(*previous, {"qoi", "force_N"}), d);
    const double change = std::abs(f - f_previous) / std::abs(f);
    if (std::isfinite(change)) {
      a.force_change_from_previous_n = change;
      a.previous_node_count = at_path(*previous, {"params"}).value("node_count_requested", 0);
      if (change > force_change_limit) a.flags.push_back("unconverged_in_n");
    }
  }
  return a;
}

json to_json(const AccuracyIndicator& a) {
  return {{"force_method_spread", number(a.force_method_spread)},
          {"force_methods", a.force_methods},
          {"support_scale_max", number(a.support_scale_max)},
          {"rcond_min", number(a.rcond_min)},
          {"stiffness_ratio", number(a.stiffness_ratio)},
          {"force_change_from_previous_n", number(a.force_change_from_previous_n)},
          {"previous_node_count", a.previous_node_count},
          {"mls_energy_share", number(a.mls_energy_share)},
          {"normal_amplitude", number(a.normal_amplitude)},
          {"exterior_used", a.exterior_used.empty() ? json(nullptr) : json(a.exterior_used)},
          {"flags", a.flags}};
}

ConvergenceInN convergence_in_n(std::vector<std::pair<double, double>> n_and_error, double target, std::size_t max_points) {
  ConvergenceInN fit;
  n_and_error.erase(std::remove_if(n_and_error.begin(), n_and_error.end(),
                                   [](const auto& p) { return !(p.first > 0 && p.second > 0 && std::isfinite(p.second)); }),
                    n_and_error.end());
  std::sort(n_and_error.begin(), n_and_error.end());
  if (n_and_error.size() > max_points) n_and_error.erase(n_and_error.begin(), n_and_error.end() - max_points);
  if (n_and_error.size() < 3) return fit;
  std::vector<std::pair<double, double>> log_log;
  for (const auto& [n, e] : n_and_error) {
    log_log.push_back({std::log(n), std::log(e)});
    fit.node_counts.push_back(n);
  }
  const std::optional<Line> line = least_squares_line(log_log);
  if (!line) return fit;
  fit.order = line->slope;
  if (fit.order < 0 && target > 0) fit.n_at_target = std::exp((std::log(target) - line->intercept) / fit.order);
  return fit;
}

ProbeComparison compare_probes(const json& probes, const json& reference_probes) {
  ProbeComparison result;
  double diff2 = 0, ref2 = 0;
  const auto vector = [](const json& j, Eigen::Vector3d& v) {
    if (!j.is_array() || j.size() != 3) return false;
    for (int i = 0; i < 3; ++i) {
      if (!j.at(i).is_number()) return false;
      v[i] = j.at(i).get<double>();
    }
    return true;
  };
  for (const auto& p : probes) {
    if (!p.value("found", false)) continue;
    for (const auto& r : reference_probes) {
      if (r.at("name") != p.at("name") || !r.value("found", false)) continue;
      Eigen::Vector3d u, ur;
      if (!vector(p.value("displacement_m", json(nullptr)), u) || !vector(r.value("displacement_m", json(nullptr)), ur)) break;
      diff2 += (u - ur).squaredNorm();
      ref2 += ur.squaredNorm();
      result.max_abs_m = std::max(result.max_abs_m, (u - ur).norm());
      ++result.count;
      break;
    }
  }
  result.rel_l2 = ref2 > 0 ? std::sqrt(diff2 / ref2) : (result.count > 0 ? nan_value : 0.0);
  return result;
}

}  // namespace touchstone::studies
