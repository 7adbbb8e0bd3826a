// The errors of every case against its reference: the FEM levels against the extrapolated
// value, the MFS cases against it, the half-space closed form and the full domain, with their
// force ramps and the MFS accuracy indicator.
#include "comparison_parts.hpp"

#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/fem_reference/probes.hpp"

#include <cmath>
#include <string>

namespace touchstone::studies::comparison {
using nlohmann::json;

std::string mfs_case_id(const ProblemRun& r, const MfsSeries& s, int n) {
  return r.sp->id_prefix + "MFS-" + s.name + "-N" + std::to_string(n);
}

json problem_json(const ComparisonProblem& p) {
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
          {"angle_to_normal_rad", json_number(p.angle_to_normal_rad())},
          {"contact_point_m", vector_json(contact_point(g))},
          {"depths_m", p.depths_m}};
}

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
                                  "; each MFS case solves organ ∩ ball(contact, L) (L = its series' local radius) with the "
                                  "rest of the body held on the cut sphere by its series' exterior (body_aware: the organ "
                                  "atlas's stiffness of the body outside the ball; half_space: a half-space's; clamped: u = 0, "
                                  "the paper's local domain), so its error against this reference is the exterior's "
                                  "approximation plus the discretisation (a B3 problem isolates the discretisation)"}});
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

void add_fem_cases(const json& doc, const std::string& prefix, const ReferenceValue& reference,
                   const ComparisonProblem& problem, const ProblemRun& r, json& cases) {
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
      c["error"]["force_rel"] = json_number(std::abs(f - reference.force_N) / std::abs(reference.force_N));
      c["error"]["force_signed_rel"] = json_number((f - reference.force_N) / std::abs(reference.force_N));
      c["error"]["reference_uncertainty_rel"] = json_number(reference.uncertainty_rel);
      c["time_s"]["model"] = value_or_nan(c["time_s"], "read_mesh") + value_or_nan(c["time_s"], "setup") +
                             value_or_nan(c["time_s"], "assembly");
      c["time_s"]["solution"] = c["time_s"]["solve"];
    }
    json ramp = json::array();
    for (const double depth : problem.depths_m) ramp.push_back(json_number(f * depth / problem.max_depth_m()));
    c["depths_m"] = problem.depths_m;
    c["force_depth_N"] = ramp;
    cases.push_back(std::move(c));
  }
}

void add_mfs_errors(json& c, const ProblemRun& r, const ReferenceValue& reference, const ReferenceValue* full,
                    const json* previous) {
  const Eigen::Vector3d& d = r.d;
  json& qoi = c["qoi"];
  const double f = axial(qoi.value("force_N", json(nullptr)), d);
  qoi["axial_force_N"] = json_number(f);
  const double fr = reference.force_N;
  json error{{"force_rel", json_number(std::abs(f - fr) / std::abs(fr))},
             {"force_signed_rel", json_number((f - fr) / std::abs(fr))},
             {"reference_uncertainty_rel", json_number(reference.uncertainty_rel)},
             {"disp_rel_l2", nullptr},
             {"disp_max_m", nullptr},
             {"disp_probes", 0},
             {"reference_disp_uncertainty_rel", json_number(reference.disp_uncertainty_rel)}};
  json by_method = json::object();
  const json& methods = json_at_path(qoi, {"forces_by_method_N"});
  if (methods.is_object())
    for (const auto& [name, value] : methods.items()) {
      const double fm = value.is_number() ? value.get<double>() : axial(value, d);
      by_method[name] = json_number((fm - fr) / std::abs(fr));
    }
  error["by_method_signed_rel"] = by_method;
  if (qoi.contains("probes") && qoi.at("probes").is_array() && !qoi.at("probes").empty()) {
    const ProbeComparison p = compare_probes(qoi.at("probes"), reference.probes);
    if (p.count > 0) {
      error["disp_rel_l2"] = json_number(p.rel_l2);
      error["disp_max_m"] = json_number(p.max_abs_m);
      error["disp_probes"] = p.count;
    }
  }
  error["field_rel_l2"] = c.value("error", json::object()).value("field_rel_l2", json(nullptr));
  c["error"] = error;
  c["reference"] = reference.id;
  // B1 and B2: the closed form the FEM reference itself is checked against, next to it.
  const double fh = reference.half_space_force_N;
  if (std::isfinite(fh))
    c["error_half_space"] = {{"force_rel", json_number(std::abs(f - fh) / std::abs(fh))},
                             {"force_signed_rel", json_number((f - fh) / std::abs(fh))},
                             {"reference", reference.half_space_id},
                             {"formula", reference.half_space_formula}};
  if (full != nullptr) {
    c["error_full_domain"] = {{"force_rel", json_number(std::abs(f - full->force_N) / std::abs(full->force_N))},
                              {"force_signed_rel", json_number((f - full->force_N) / std::abs(full->force_N))},
                              {"reference", full->id},
                              {"reference_uncertainty_rel", json_number(full->uncertainty_rel)}};
  }
  Eigen::Matrix3d kt = Eigen::Matrix3d::Constant(nan_value);
  const json& m = json_at_path(qoi, {"tool_stiffness_matrix_N_per_m"});
  if (m.is_array() && m.size() == 3)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) kt(i, j) = value_or_nan(m.at(i).at(j));
  json ramp = json::array();
  for (const double v : mfs_force_ramp_N(kt, d, r.problem().depths_m)) ramp.push_back(json_number(v));
  c["depths_m"] = r.problem().depths_m;
  c["force_depth_N"] = ramp;
  // What the engine says about its own accuracy, next to the status (a case can end "ok"
  // far from the reference; these flags need no reference).
  c["accuracy"] = to_json(accuracy_indicator(c, d, previous));
}

}  // namespace touchstone::studies::comparison
