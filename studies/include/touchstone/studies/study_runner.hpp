#pragma once
/// @file
/// `touchstone study`: the comparison runner. One study file names the problem (benchmark,
/// material, tool, the tool-tip depth ramp), the converged FEM reference on that problem (a
/// `touchstone fem` study file, cached), the MFS series (each a `touchstone mfs` section swept
/// over the node count) and the Table 2 rows. Both models receive the same tool displacement δ d
/// at the same contact point; errors are measured at the same probe points and every error
/// against the reference is written next to the reference's own estimated discretisation error.
///
/// Output: results.json (the study contract plus "table2", "targets", "reference_summary"), CSV
/// tables, report.md with PNG plots (the reports package, matplotlib), one folder per case.
/// Finished MFS cases are reused when the same case (same resolved config and code version) is
/// already in the output folder; FEM solves are reused through the reference study's cache.

#include "touchstone/studies/mfs_study.hpp"
#include "touchstone/studies/fem_reference/reference_study.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace touchstone::studies {

/// The problem both models solve; imposed on every FEM and MFS sub-study of the study.
struct ComparisonProblem {
  meshes::Benchmark benchmark = meshes::Benchmark::B3;  ///< B1, B2, B3 or B5 (B4: B2 and point_tool)
  /// B4 (`benchmark = "B4"` in a study): the paper's point tool on B2. Every MFS series must be
  /// in paper mode (one tool-tip node); the FEM reference of each MFS case is a flat punch of
  /// radius equal to that case's tip-node spacing s (a point displacement has no finite force),
  /// so there is one converged reference per distinct s, its mesh sizes those of [reference]
  /// scaled by s/a.
  bool point_tool = false;
  double body_radius_m = 0.05;    ///< R (B2, B3, B5) or W (B1: cylinder radius = height)
  double tool_radius_m = 0.0025;  ///< a
  /// L [m]: B3's domain and the MFS local ball (organ ∩ ball(contact, L)) on every benchmark.
  /// On B1 the contact point is the centre of the flat top face, the origin.
  double local_radius_m = 0.0125;
  /// B5: polar angle θ [rad] of the tool patch centre on the hemisphere (0: the pole). The
  /// contact point is R (sin θ, 0, cos θ); the base z = 0 is clamped in the FEM only.
  double contact_polar_angle_rad = 0.0;
  geometry::Material material;
  geometry::ContactCondition contact = geometry::ContactCondition::frictionless;
  Eigen::Vector3d direction{0.0, 0.0, -1.0};  ///< d, normalised when used
  /// The tool-tip depth ramp δ_i [m] (ascending, > 0, δ_max ≤ L/2). Both models are linear
  /// (small strain): each case is solved once at max δ and the ramp is K_t δ_i d (MFS) or
  /// F_ref δ_i / δ_max (FEM), so depths beyond a/2 test numerical stability, not physics.
  std::vector<double> depths_m{0.05e-3, 0.10e-3, 0.15e-3, 0.20e-3, 0.25e-3};
  double max_depth_m() const { return depths_m.back(); }
  /// Outward surface normal at the contact point (e_z on B1, B2, B3).
  Eigen::Vector3d outward_normal() const;
  /// Angle between d and the inward normal −n [rad]: 0 pushes straight in, near π/2 grazes.
  double angle_to_normal_rad() const;
  /// δ_max > a/2: beyond where the linear small-strain model means anything physically.
  bool beyond_small_strain() const { return max_depth_m() > 0.5 * tool_radius_m; }
  /// The MFS ball(contact, L) reaches the clamped base: B5 near the base (R cos θ < L), or B1
  /// with W < L (the base is z = −W). The MFS holds it only where its engine supports a
  /// clamped surface (Galerkin); see problem notes in the report.
  bool ball_reaches_base() const;
  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// One MFS series: an `touchstone mfs` study (its own knobs) swept over node counts.
struct MfsSeries {
  std::string name;          ///< the key of [mfs.<name>]
  MfsStudy study;            ///< geometry, material and tool already set from the problem
  std::string config_text;   ///< the series as the TOML it was read from (for its hash)
  /// Its resolved engine settings equal the engine defaults (realtime::mfs::LocalModelSettings{}
  /// with the MFS study reader's defaults), compared by value whatever the series is named.
  bool engine_default = false;
};

/// One problem of a study with its own FEM reference and its MFS series. A study without
/// [problems.<name>] tables has one, named "base", whose case ids carry no prefix; with them,
/// each [problems.<name>] is [problem] with the table's keys replaced, and its case ids start
/// with "<name>/".
struct StudyProblem {
  std::string name = "base";
  std::string id_prefix;  ///< "" or "<name>/"
  ComparisonProblem problem;
  /// The converged reference on the problem's own domain (≥ 2 levels; ≥ 3 for an estimate).
  ReferenceStudy reference;
  std::vector<MfsSeries> series;
  /// The keys the variant replaced ("poisson_ratio", "reference.config", ...), for the report.
  std::vector<std::string> overridden_keys;
};

/// Allowed drift against the baseline, in physical terms.
struct RegressionTolerances {
  double force_error_points = 0.5;         ///< |force_rel − baseline| ≤ 0.5 percentage points
  double displacement_error_points = 0.5;  ///< same for disp_rel_l2
  double reference_force_rel = 1e-3;       ///< the FEM reference force itself within 0.1 %
  void validate() const;
};

/// One study file of `touchstone study`.
struct ComparisonStudy {
  std::string name = "study";
  std::string config_path;  ///< the file it was read from
  std::string config_text;  ///< its text, as read (the run's provenance records it)
  /// The problems in file order (at least one). The first one's cases give Table 2 and the
  /// summary fields of results.json ("problem", "reference_summary").
  std::vector<StudyProblem> problems;
  const StudyProblem& first() const { return problems.front(); }
  /// Table 2: the FE model at the paper's size (one level) and the converged reference of its
  /// domain (B2); both optional, on the first problem's material and tool.
  std::optional<ReferenceStudy> table2_fem;
  std::optional<ReferenceStudy> table2_reference;
  /// The MFS series giving the Table 2 MFS row (its first node count; the paper: 34).
  std::string table2_mfs_series;
  /// CI: the baseline file ([ci] baseline, relative to the study file) and its tolerances.
  /// `touchstone study` checks a run against it when it exists; `touchstone study accept`
  /// rewrites it. Empty: no baseline.
  std::string baseline_path;
  RegressionTolerances tolerances;
  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// Reads a study file. `[reference] config`, `[table2] fem|reference` name `touchstone fem`
/// files and `[mfs.<name>]` tables are `touchstone mfs` sections without [geometry],
/// [material] and [tool] (the problem gives those). `[problems.<name>]` tables are variants of
/// [problem]: any [problem] key, plus `series` (the [mfs.<name>] series to run on it; default
/// all) and a `[problems.<name>.reference]` table replacing [reference] keys (e.g. another
/// `config`). Errors name the file and the key.
ComparisonStudy read_comparison_study(const std::string& path);

struct StudyRunOptions {
  std::string output_directory;                  ///< empty: output/<study name>
  std::string cache_directory = ".cache/touchstone";
  /// Run only cases whose id contains one of these substrings (a problem's FEM reference runs
  /// when any of its MFS cases is selected, and always in a one-problem study). Empty: all.
  std::vector<std::string> only;
  bool quiet = false;
  bool write_report = true;
  /// MFS cases run this many at a time (they are independent). Above 1 their run times are
  /// measured while other cases run, and results.json says so (`mfs_jobs`); Table 2 and the
  /// run-time plots then compare times taken under load — keep 1 for timing studies.
  int jobs = 1;
  std::string python = "/usr/bin/python3";       ///< with matplotlib, for the reports package
};

/// Runs the study and writes <out>/results.json, the CSV tables and (unless disabled) the
/// report. Throws std::runtime_error when the report cannot be made (results.json is written
/// first). Needs a live fem::MpiSession; under mpirun every rank takes part in the FEM solves and
/// rank 0 alone runs the MFS cases and writes (the other ranks return the FEM cases only).
nlohmann::json run_comparison_study(const ComparisonStudy& study, const StudyRunOptions& options);

/// The per-depth tool force along d [N] of a case: K_t (δ d) · d for the MFS.
std::vector<double> mfs_force_ramp_N(const Eigen::Matrix3d& tool_stiffness_N_per_m, const Eigen::Vector3d& direction,
                                     const std::vector<double>& depths_m);

/// Accuracy indicator of an MFS case that ended "ok" (reference-free: what the engine itself
/// reports). Thresholds are named constants, documented with their reasons.
struct AccuracyIndicator {
  /// (max − min) / max |F| over the independent force estimators along d: reaction and
  /// energy (the weak form's pair, equal for a self-consistent discrete equilibrium) when both
  /// are finite, else traction integral and the paper's partition. NaN: fewer than two.
  double force_method_spread = std::numeric_limits<double>::quiet_NaN();
  std::vector<std::string> force_methods;  ///< the estimators compared
  double support_scale_max = std::numeric_limits<double>::quiet_NaN();  ///< NaN: not reported
  double rcond_min = std::numeric_limits<double>::quiet_NaN();          ///< NaN: not reported
  /// k / k_hs: the tool stiffness along d, F·d / δ, over the half-space flat-punch stiffness
  /// k_hs = 2 E a / (1 − ν²) (Sneddon). NaN: no force.
  double stiffness_ratio = std::numeric_limits<double>::quiet_NaN();
  /// |F_N − F_prev| / |F_N| along d against the same series' case at the next smaller node count
  /// (which ended ok): the series' own convergence in N. NaN: no such case.
  double force_change_from_previous_n = std::numeric_limits<double>::quiet_NaN();
  int previous_node_count = 0;  ///< its requested N (0: none)
  /// The enriched model only (NaN / empty otherwise): the share of the strain energy its MLS
  /// part carries, the normal punch field's amplitude per metre of depth (1 on a half-space;
  /// the clamped cut at 5a raises it to about 1.4), and the exterior it used.
  double mls_energy_share = std::numeric_limits<double>::quiet_NaN();
  double normal_amplitude = std::numeric_limits<double>::quiet_NaN();
  std::string exterior_used;
  /// With corrected gradients: the part of the integration-constraint residuals the correction
  /// could not remove (the volume and boundary rules disagree on the divergence theorem); NaN:
  /// no correction.
  double gradient_correction_left = std::numeric_limits<double>::quiet_NaN();
  /// "force_methods_disagree", "supports_grew", "ill_conditioned", "stiffness_implausible",
  /// "unconverged_in_n"; enriched: "mls_dominated" (the singular fields carry too little: the
  /// contact is unlike a punch on a smooth body), "amplitude_implausible", "exterior_fallback"
  /// (body_aware was asked, the half-space was used: no organ atlas sample near the contact),
  /// "rules_disagree" (with corrected gradients: the boundary rules do not close the local
  /// domain, so the correction aims at a wrong target)
  std::vector<std::string> flags;
};
/// Flag "rules_disagree" above this share of the constraint residuals left uncorrected: about
/// 1e-3 on the hemisphere's local domain, 0.1 and more when a boundary piece is missing.
constexpr double gradient_correction_left_limit = 1e-2;
/// Flag "mls_dominated" above this MLS share of the energy: about 0.08 on B3 at 5a.
constexpr double mls_energy_share_limit = 0.35;
/// Flag "amplitude_implausible" outside these bounds of the normal amplitude per metre of depth.
constexpr double normal_amplitude_min = 0.5, normal_amplitude_max = 2.5;
/// Flag "force_methods_disagree" above this spread: healthy default Galerkin cases at N ≥ 100 on
/// B3 stay well below it, broken ones (tiny supports that grew) far above.
constexpr double force_method_spread_limit = 0.15;
/// Flag "unconverged_in_n" when the force moved by more than this from the series' previous N
/// (a series doubling N between cases): a force still moving by more than the coarsest force
/// target (5 %) is not yet that accurate, reference or not. On the default Galerkin series on B3
/// the change under-estimated the error against the FEM, never over-estimated it, so the flag
/// errs on the side of silence.
constexpr double force_change_limit = 0.05;
/// Flag "supports_grew" when the largest adaptive support growth exceeds 1 by more than this
/// (the engine grows supports where the moment matrix is singular: the layout was too sparse).
constexpr double support_growth_tolerance = 1e-9;
/// Flag "ill_conditioned" when the smallest moment-matrix rcond is within this factor of the
/// engine's own failure threshold ([mls] min_rcond): shape functions on the edge of failing.
constexpr double rcond_margin = 100.0;

/// Flag "stiffness_implausible" outside [min, max] × k_hs. A rigid flat punch on a body whose
/// clamped boundary is at least 2a away (L > 2a) is within a small factor of the half-space:
/// B2 (R = 20a) 1.16×, B1 (W = 20a) 1.05× (FEM), B3 at L = 5a 1.6× (the Galerkin MFS's local ball
/// on B1's flat top somewhat more), bonded ≈ frictionless as ν → 0.5, a free base near the patch
/// softer. Tiny Galerkin supports that grew can be an order of magnitude too stiff while the force
/// estimators agree (a spread under force_method_spread_limit): this bound is what catches them.
constexpr double stiffness_ratio_min = realtime::mfs::plausible_stiffness_ratio_min;
constexpr double stiffness_ratio_max = realtime::mfs::plausible_stiffness_ratio_max;

/// The indicator of an MFS case's JSON (qoi.force_N, qoi.forces_by_method_N, qoi.min_rcond,
/// diagnostics, params: min_rcond_threshold, youngs_modulus_Pa, poisson_ratio, tool_radius_m,
/// depth_m, node_count_requested) for the tool direction d. `previous`: the same series' case at
/// the next smaller node count, or null. A case whose status is not "ok" gets no flags.
AccuracyIndicator accuracy_indicator(const nlohmann::json& mfs_case, const Eigen::Vector3d& direction,
                                     const nlohmann::json* previous = nullptr);
nlohmann::json to_json(const AccuracyIndicator& indicator);

/// How fast a series' error falls with its node count: a least-squares line through
/// (log N, log error) over its largest node counts, and where that line reaches a target.
struct ConvergenceInN {
  double order = std::numeric_limits<double>::quiet_NaN();  ///< slope p of error ∝ N^p (< 0: falling)
  /// N at which the fitted line reaches the target; NaN when p ≥ 0 (no rate to extrapolate).
  double n_at_target = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> node_counts;  ///< the N fitted
};
/// Fits the last `max_points` (at least 3) of `n_and_error` (actual N, relative error > 0),
/// sorted by N. Fewer than 3 usable points: order NaN.
ConvergenceInN convergence_in_n(std::vector<std::pair<double, double>> n_and_error, double target, std::size_t max_points = 4);

/// Relative L2 and max-abs difference [m] of probe displacements matched by name (a probe
/// missing or not found in either list is skipped); `count` is the number compared.
struct ProbeComparison {
  double rel_l2 = 0, max_abs_m = 0;
  int count = 0;
};
ProbeComparison compare_probes(const nlohmann::json& probes, const nlohmann::json& reference_probes);

// ---------------------------------------------------------------------------------------------
// CI accuracy regression: a baseline of a small study's errors, with provenance.

/// One comparison of a current value with its baseline.
struct RegressionFinding {
  std::string case_id, quantity;
  double baseline = 0, current = 0, allowed = 0;
  bool passed = true;
  std::string message;  ///< "MFS-galerkin-N34 force_rel: 12.31 % → 12.40 % (allowed ± 0.50 points)"
};

/// The baseline document of a study result: every MFS case's force_rel and disp_rel_l2, the
/// reference force, the tolerances, provenance of the run.
nlohmann::json make_baseline(const nlohmann::json& results, const RegressionTolerances& tolerances);

/// Compares a result with a baseline (tolerances from the baseline). A case of the baseline
/// missing from the results, or not "ok", fails.
std::vector<RegressionFinding> check_against_baseline(const nlohmann::json& results, const nlohmann::json& baseline);

/// Human-readable differences between two baselines (one line per changed number, "unchanged"
/// when none), for `touchstone study accept`.
std::string describe_baseline_change(const nlohmann::json& old_baseline, const nlohmann::json& new_baseline);

}  // namespace touchstone::studies
