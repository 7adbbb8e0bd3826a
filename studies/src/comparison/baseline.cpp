// CI accuracy regression: a baseline of a study's errors with provenance, the check of a new
// run against it, and the diff that `touchstone study accept` prints.
#include "touchstone/studies/study_runner.hpp"

#include "touchstone/studies/output_files.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>

namespace touchstone::studies {
using nlohmann::json;

namespace {

std::string percent(double relative) {
  if (!std::isfinite(relative)) return "n/a";
  char text[32];
  std::snprintf(text, sizeof text, "%.3f %%", 100 * relative);
  return text;
}

/// The numbers a baseline keeps, flattened: "<case> <quantity>" → value.
std::map<std::string, double> flatten(const json& baseline) {
  std::map<std::string, double> values;
  for (const auto& c : baseline.value("cases", json::array()))
    for (const char* q : {"force_rel", "disp_rel_l2", "axial_force_N"})
      if (c.contains(q)) values[c.at("id").get<std::string>() + " " + q] = value_or_nan(c, q);
  if (baseline.contains("reference"))
    values["reference axial_force_N"] = value_or_nan(baseline.at("reference"), "axial_force_N");
  return values;
}

}  // namespace

void RegressionTolerances::validate() const {
  const auto positive = [](const char* field, double v) {
    if (!std::isfinite(v) || v <= 0) throw std::invalid_argument(std::string("ci.") + field + " must be finite and > 0");
  };
  positive("force_error_points", force_error_points);
  positive("displacement_error_points", displacement_error_points);
  positive("reference_force_rel", reference_force_rel);
}

json make_baseline(const json& results, const RegressionTolerances& tolerances) {
  tolerances.validate();
  json cases = json::array();
  for (const auto& c : results.at("cases")) {
    if (c.at("model") != "mfs") continue;
    const json& e = c.at("error");
    cases.push_back({{"id", c.at("id")},
                     {"axial_force_N", c.at("qoi").value("axial_force_N", json(nullptr))},
                     {"force_rel", e.value("force_rel", json(nullptr))},
                     {"disp_rel_l2", e.value("disp_rel_l2", json(nullptr))},
                     {"status", c.at("status")}});
  }
  const json& summary = results.at("reference_summary");
  return {{"study", results.at("study")},
          {"what", "CI accuracy baseline: errors of the MFS cases against the FEM reference. Rewritten only by "
                   "`touchstone study accept`."},
          {"tolerances",
           {{"force_error_points", tolerances.force_error_points},
            {"displacement_error_points", tolerances.displacement_error_points},
            {"reference_force_rel", tolerances.reference_force_rel}}},
          {"reference",
           {{"case", summary.at("case")},
            {"axial_force_N", summary.at("axial_force_N")},
            {"uncertainty_rel", summary.at("uncertainty_rel")}}},
          {"cases", cases},
          {"provenance", results.at("provenance")}};
}

std::vector<RegressionFinding> check_against_baseline(const json& results, const json& baseline) {
  std::vector<RegressionFinding> findings;
  const json& tol = baseline.at("tolerances");
  const double force_points = tol.at("force_error_points").get<double>();
  const double disp_points = tol.at("displacement_error_points").get<double>();
  const double reference_rel = tol.at("reference_force_rel").get<double>();

  // The reference itself: a changed FEM would move every error.
  {
    RegressionFinding f;
    f.case_id = "reference";
    f.quantity = "axial_force_N";
    f.baseline = value_or_nan(baseline.at("reference"), "axial_force_N");
    f.current = value_or_nan(results.at("reference_summary"), "axial_force_N");
    f.allowed = reference_rel;
    const double change = std::abs(f.current - f.baseline) / std::abs(f.baseline);
    f.passed = change <= reference_rel;
    std::ostringstream m;
    m << "reference force: " << f.baseline * 1e3 << " mN -> " << f.current * 1e3 << " mN (change " << percent(change)
      << ", allowed " << percent(reference_rel) << ")";
    f.message = m.str();
    findings.push_back(f);
  }
  for (const auto& b : baseline.at("cases")) {
    const std::string id = b.at("id");
    const json* current = nullptr;
    for (const auto& c : results.at("cases"))
      if (c.at("id") == id) current = &c;
    if (current == nullptr || current->at("status") != "ok") {
      RegressionFinding f;
      f.case_id = id;
      f.quantity = "status";
      f.passed = b.value("status", "ok") != "ok" && current != nullptr;
      f.message = id + ": " + (current == nullptr ? "missing from the results" : "status " + current->at("status").dump());
      findings.push_back(f);
      continue;
    }
    for (const auto& [quantity, points] : {std::pair<const char*, double>{"force_rel", force_points},
                                           std::pair<const char*, double>{"disp_rel_l2", disp_points}}) {
      RegressionFinding f;
      f.case_id = id;
      f.quantity = quantity;
      f.baseline = value_or_nan(b, quantity);
      f.current = value_or_nan(current->at("error"), quantity);
      f.allowed = points / 100;
      if (!std::isfinite(f.baseline) && !std::isfinite(f.current)) continue;
      f.passed = std::isfinite(f.baseline) && std::isfinite(f.current) && std::abs(f.current - f.baseline) <= f.allowed;
      std::ostringstream m;
      m << id << " " << quantity << ": " << percent(f.baseline) << " -> " << percent(f.current) << " (allowed +/- " << points
        << " percentage points)";
      f.message = m.str();
      findings.push_back(f);
    }
  }
  return findings;
}

std::string describe_baseline_change(const json& old_baseline, const json& new_baseline) {
  const auto before = flatten(old_baseline), after = flatten(new_baseline);
  std::ostringstream text;
  int changes = 0;
  for (const auto& [key, value] : after) {
    const auto it = before.find(key);
    const bool is_force = key.size() > 13 && key.compare(key.size() - 13, 13, "axial_force_N") == 0;
    const auto show = [&](double v) { return is_force ? (std::isfinite(v) ? std::to_string(v * 1e3) + " mN" : "n/a") : percent(v); };
    if (it == before.end()) {
      text << "  + " << key << " = " << show(value) << "\n";
      ++changes;
    } else if (!(it->second == value) && !(std::isnan(it->second) && std::isnan(value))) {
      text << "  ~ " << key << ": " << show(it->second) << " -> " << show(value) << "\n";
      ++changes;
    }
  }
  for (const auto& [key, value] : before)
    if (after.find(key) == after.end()) {
      text << "  - " << key << " (was " << value << ")\n";
      ++changes;
    }
  if (changes == 0) return "  unchanged\n";
  return text.str();
}

}  // namespace touchstone::studies
