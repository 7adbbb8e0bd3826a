// What an MFS case says about its own accuracy without a reference (the accuracy indicator),
// the force ramp of a tool stiffness, a series' convergence in N, and probe comparisons.
#include "touchstone/studies/study_runner.hpp"

#include "touchstone/studies/output_files.hpp"

#include "../fem_reference/least_squares_line.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace touchstone::studies {
using nlohmann::json;

std::vector<double> mfs_force_ramp_N(const Eigen::Matrix3d& tool_stiffness_N_per_m, const Eigen::Vector3d& direction,
                                     const std::vector<double>& depths_m) {
  const Eigen::Vector3d d = direction.normalized();
  std::vector<double> forces;
  forces.reserve(depths_m.size());
  for (const double depth : depths_m) forces.push_back((tool_stiffness_N_per_m * (depth * d)).dot(d));
  return forces;
}

namespace {
constexpr double nan_value = std::numeric_limits<double>::quiet_NaN();
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
  const json& methods = json_at_path(c, {"qoi", "forces_by_method_N"});
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
  a.support_scale_max = value_or_nan(json_at_path(c, {"diagnostics"}), "max_support_scale_used");
  a.rcond_min = value_or_nan(json_at_path(c, {"qoi"}), "min_rcond");
  const json& params = json_at_path(c, {"params"});
  const double e = value_or_nan(params, "youngs_modulus_Pa"), nu = value_or_nan(params, "poisson_ratio");
  const double radius = value_or_nan(params, "tool_radius_m"), depth = value_or_nan(params, "depth_m");
  const double half_space_N_per_m = 2 * e * radius / (1 - nu * nu);
  a.stiffness_ratio = std::abs(axial(json_at_path(c, {"qoi", "force_N"}), d)) / depth / half_space_N_per_m;
  if (!std::isfinite(a.stiffness_ratio)) a.stiffness_ratio = nan_value;
  if (a.force_method_spread > force_method_spread_limit) a.flags.push_back("force_methods_disagree");
  if (a.support_scale_max > 1 + support_growth_tolerance) a.flags.push_back("supports_grew");
  const double threshold = value_or_nan(json_at_path(c, {"params"}), "min_rcond_threshold");
  if (std::isfinite(a.rcond_min) && std::isfinite(threshold) && a.rcond_min < rcond_margin * threshold)
    a.flags.push_back("ill_conditioned");
  if (a.stiffness_ratio < stiffness_ratio_min || a.stiffness_ratio > stiffness_ratio_max)
    a.flags.push_back("stiffness_implausible");
  const json& enriched = json_at_path(c, {"diagnostics", "enriched"});
  if (enriched.is_object()) {
    a.mls_energy_share = value_or_nan(enriched, "mls_energy_share");
    const json& amplitudes = enriched.value("amplitudes_per_depth", json::array());
    if (!amplitudes.empty() && amplitudes.at(0).is_number()) a.normal_amplitude = amplitudes.at(0).get<double>();
    a.exterior_used = enriched.value("exterior_used", "");
    if (a.mls_energy_share > mls_energy_share_limit) a.flags.push_back("mls_dominated");
    if (a.normal_amplitude < normal_amplitude_min || a.normal_amplitude > normal_amplitude_max)
      a.flags.push_back("amplitude_implausible");
    if (a.exterior_used != value_or(params, "exterior", a.exterior_used)) a.flags.push_back("exterior_fallback");
    // What the build applied (an automatic choice is made per material); results written before
    // the diagnostic existed name it in the params only.
    if (enriched.value("gradient_correction", value_or(params, "gradient_correction", "none")) != "none") {
      a.gradient_correction_left = value_or_nan(enriched, "gradient_correction_left");
      if (!(a.gradient_correction_left <= gradient_correction_left_limit)) a.flags.push_back("rules_disagree");
    }
  }
  if (previous != nullptr && previous->value("status", "") == "ok") {
    const double f = axial(json_at_path(c, {"qoi", "force_N"}), d), f_previous = axial(json_at_path(*previous, {"qoi", "force_N"}), d);
    const double change = std::abs(f - f_previous) / std::abs(f);
    if (std::isfinite(change)) {
      a.force_change_from_previous_n = change;
      a.previous_node_count = json_at_path(*previous, {"params"}).value("node_count_requested", 0);
      if (change > force_change_limit) a.flags.push_back("unconverged_in_n");
    }
  }
  return a;
}

json to_json(const AccuracyIndicator& a) {
  return {{"force_method_spread", json_number(a.force_method_spread)},
          {"force_methods", a.force_methods},
          {"support_scale_max", json_number(a.support_scale_max)},
          {"rcond_min", json_number(a.rcond_min)},
          {"stiffness_ratio", json_number(a.stiffness_ratio)},
          {"force_change_from_previous_n", json_number(a.force_change_from_previous_n)},
          {"previous_node_count", a.previous_node_count},
          {"mls_energy_share", json_number(a.mls_energy_share)},
          {"normal_amplitude", json_number(a.normal_amplitude)},
          {"exterior_used", a.exterior_used.empty() ? json(nullptr) : json(a.exterior_used)},
          {"gradient_correction_left", json_number(a.gradient_correction_left)},
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
