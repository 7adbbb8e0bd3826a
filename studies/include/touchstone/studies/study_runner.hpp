#pragma once
/// @file
/// `touchstone study`: the comparison runner (DESIGN.md §8, issue 4). One study file names the
/// problem (benchmark, material, tool, the tool-tip depth ramp), the converged FEM reference on
/// that problem (a `touchstone fem` study file, cached), the MFS series (each a `touchstone mfs`
/// section swept over the node count) and the Table 2 rows. Both models receive the same tool
/// displacement δ d at the same contact point; errors are measured at the same probe points and
/// every error against the reference is written next to the reference's own estimated
/// discretisation error.
///
/// Output: results.json (the §8 contract plus "table2", "targets", "reference_summary"), CSV
/// tables, report.md with PNG plots (reports/make_report.py, matplotlib), one folder per case.
/// Finished MFS cases are reused when the same case (same resolved config and code version) is
/// already in the output folder; FEM solves are reused through the reference study's cache.

#include "touchstone/studies/mfs_study.hpp"
#include "touchstone/studies/reference_study.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace touchstone::studies {

/// The problem both models solve; imposed on every FEM and MFS sub-study of the study.
struct ComparisonProblem {
  meshes::Benchmark benchmark = meshes::Benchmark::B3;
  double body_radius_m = 0.05;    ///< R
  double tool_radius_m = 0.0025;  ///< a
  double local_radius_m = 0.0125; ///< L (B3: the domain; the MFS local ball)
  fem::Material material;
  fem::Contact contact = fem::Contact::frictionless;
  Eigen::Vector3d direction{0.0, 0.0, -1.0};  ///< d, normalised when used
  /// The tool-tip depth ramp δ_i [m] (ascending, > 0). Both models are linear: each case is
  /// solved once at max δ and the ramp is K_t δ_i d (MFS) or F_ref δ_i / δ_max (FEM).
  std::vector<double> depths_m{0.05e-3, 0.10e-3, 0.15e-3, 0.20e-3, 0.25e-3};
  double max_depth_m() const { return depths_m.back(); }
  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// One MFS series: an `touchstone mfs` study (its own knobs) swept over node counts.
struct MfsSeries {
  std::string name;          ///< the key of [mfs.<name>]
  MfsStudy study;            ///< geometry, material and tool already set from the problem
  std::string config_text;   ///< the series as the TOML it was read from (for its hash)
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
  ComparisonProblem problem;
  /// The converged reference on the problem's own domain (≥ 3 levels).
  ReferenceStudy reference;
  /// Table 2: the FE model at the paper's size (one level) and the converged reference of its
  /// domain (B2); both optional.
  std::optional<ReferenceStudy> table2_fem;
  std::optional<ReferenceStudy> table2_reference;
  /// The MFS series giving the Table 2 MFS row (its first node count; the paper: 34).
  std::string table2_mfs_series;
  std::vector<MfsSeries> series;
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
/// [material] and [tool] (the problem gives those). Errors name the file and the key.
ComparisonStudy read_comparison_study(const std::string& path);

struct StudyRunOptions {
  std::string output_directory;                  ///< empty: output/<study name>
  std::string cache_directory = ".cache/touchstone";
  /// Run only cases whose id contains one of these substrings (FEM references always run:
  /// every error needs them). Empty: all.
  std::vector<std::string> only;
  bool quiet = false;
  bool write_report = true;
  /// MFS cases run this many at a time (they are independent). Above 1 their run times are
  /// measured while other cases run, and results.json says so (`mfs_jobs`); Table 2 and the
  /// run-time plots then compare times taken under load — keep 1 for timing studies.
  int jobs = 1;
  std::string python = "/usr/bin/python3";       ///< with matplotlib
  std::string report_script;                     ///< empty: <source>/reports/make_report.py
};

/// Runs the study and writes <out>/results.json, the CSV tables and (unless disabled) the
/// report. Throws std::runtime_error when the report cannot be made (results.json is written
/// first). Needs a live fem::MpiSession; under mpirun every rank takes part in the FEM solves and
/// rank 0 alone runs the MFS cases and writes (the other ranks return the FEM cases only).
nlohmann::json run_comparison_study(const ComparisonStudy& study, const StudyRunOptions& options);

/// The per-depth tool force along d [N] of a case: K_t (δ d) · d for the MFS.
std::vector<double> mfs_force_ramp_N(const Eigen::Matrix3d& tool_stiffness_N_per_m, const Eigen::Vector3d& direction,
                                     const std::vector<double>& depths_m);

/// Relative L2 and max-abs difference [m] of probe displacements matched by name (a probe
/// missing or not found in either list is skipped); `count` is the number compared.
struct ProbeComparison {
  double rel_l2 = 0, max_abs_m = 0;
  int count = 0;
};
ProbeComparison compare_probes(const nlohmann::json& probes, const nlohmann::json& reference_probes);

// ---------------------------------------------------------------------------------------------
// CI accuracy regression (DESIGN.md §8): a baseline of a small study's errors, with provenance.

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
