// The reference value of a `touchstone fem` run: the extrapolated force along the tool
// direction and its error estimate, the probes and the half-space closed form beside it.
#include "comparison_parts.hpp"

#include "touchstone/studies/output_files.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace touchstone::studies::comparison {
using nlohmann::json;

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
               {"axial_force_N", json_number(r.force_N)},
               {"uncertainty_rel", json_number(r.uncertainty_rel)},
               {"family_spread_rel", json_number(spread)},
               {"asymptotic", asymptotic && !families.empty()},
               {"families", families},
               {"disp_uncertainty_rel", json_number(r.disp_uncertainty_rel)},
               {"probes_from", levels.empty() ? json(nullptr) : json(prefix + levels.back()->at("id").get<std::string>())}};
  if (std::isfinite(r.half_space_force_N)) {
    r.summary["half_space_case"] = r.half_space_id;
    r.summary["half_space_formula"] = r.half_space_formula;
    r.summary["half_space_force_N"] = r.half_space_force_N;
    r.summary["ratio_to_half_space"] = json_number(r.force_N / r.half_space_force_N);
  }
  return r;
}

}  // namespace touchstone::studies::comparison
