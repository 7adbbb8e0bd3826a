#pragma once
// The parts of `touchstone study` below its public interface (study_runner.hpp), shared by the
// files of this folder: the reference value a run measures against, one problem while it runs,
// and the steps that turn the cases into errors, Table 2, targets and output files. Every
// function here maps data to data except where its name says it writes.

#include "touchstone/studies/study_runner.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace touchstone::studies::comparison {

/// A value not measured (a failed case's force, a missing estimate): results.json writes null.
inline constexpr double nan_value = std::numeric_limits<double>::quiet_NaN();

/// The reference of a `touchstone fem` run: the extrapolated force and its error estimate.
struct ReferenceValue {
  std::string id;    ///< prefixed case id in the study's results
  std::string part;  ///< its FEM run: the folder under <out>/fem/ and the id prefix
  double force_N = nan_value;  ///< axial, at max δ
  double uncertainty_rel = nan_value;
  double disp_uncertainty_rel = nan_value;  ///< probe change, second-finest → finest mesh
  nlohmann::json probes = nlohmann::json::array();
  std::string field_vtu;  ///< the probes' level's solution file, relative to its FEM output folder
  /// The half-space closed form at max δ (Sneddon or Mossakovskii), which the reference study
  /// adds on B1 and B2 as an "analytic" case; NaN on the other benchmarks.
  double half_space_force_N = nan_value;
  std::string half_space_id;
  std::string half_space_formula;
  nlohmann::json summary;
};

/// The reference value of an FEM run's results (`document`), its case ids under `prefix`
/// ("reference/"): the mean over mesh families when there are several, else the one family's
/// Richardson value; forces along the tool direction d.
ReferenceValue pick_reference(const nlohmann::json& document, const std::string& prefix, const Eigen::Vector3d& d);

/// One problem while the study runs: its reference once computed, its selected MFS cases.
struct ProblemRun {
  const StudyProblem* sp = nullptr;
  Eigen::Vector3d d;          ///< the tool direction, normalised
  ReferenceValue reference;   ///< B4: the first case's (every case has its own, below)
  std::string reference_part; ///< "reference" or "<name>/reference": the FEM folder and id prefix
  std::vector<std::pair<const MfsSeries*, int>> mfs_cases;
  /// The problem's reference is solved: always in a one-problem study (every error and the
  /// summary need it), else when one of its MFS cases is selected.
  bool runs_reference = false;
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

/// The id of an MFS case: "<problem prefix>MFS-<series>-N<n>".
std::string mfs_case_id(const ProblemRun& r, const MfsSeries& s, int n);

// --- Errors of each case against its reference (case_errors.cpp) ------------------------------

/// The problem's values as results.json stores them ("problem", and every case's params).
nlohmann::json problem_json(const ComparisonProblem& p);
/// The report's notes on a problem: what its numbers mean beyond the errors.
nlohmann::json problem_notes(const ComparisonProblem& p);
/// Appends the FEM cases of `doc` under `prefix`; level errors are taken against `reference`
/// (the study's reference for this domain), the ramp is F δ_i / δ_max. `problem`: the one
/// solved (r's, or for B4 r's with the punch radius of a tip spacing).
void add_fem_cases(const nlohmann::json& doc, const std::string& prefix, const ReferenceValue& reference,
                   const ComparisonProblem& problem, const ProblemRun& r, nlohmann::json& cases);
/// An MFS case's errors against its reference (force, by method, probes), against the
/// half-space closed form (B1, B2) and the full domain (`full`, when the study has one on
/// another domain), its force ramp and its accuracy indicator (`previous`: the same series'
/// case at the next smaller N, or null).
void add_mfs_errors(nlohmann::json& c, const ProblemRun& r, const ReferenceValue& reference, const ReferenceValue* full,
                    const nlohmann::json* previous);

// --- Table 2 and the targets (targets.cpp) -----------------------------------------------------

/// Table 2: the paper's numbers next to ours (same node counts), with the force error each
/// achieves and the reference's own error estimate. `first`: the study's first problem; a later
/// whole-hemisphere (B2) problem with an engine-default series adds that series' first case as
/// the row `mfs_default_whole_body` (the paper's own comparison: the local model against the
/// whole body).
nlohmann::json table2(const nlohmann::json& cases, const ProblemRun& first, const ReferenceValue& fe_reference,
                      const std::string& table2_mfs_series, const std::vector<ProblemRun>& problems);
/// The speed and accuracy targets: each with the measured value, met or not, and by how much.
nlohmann::json targets(const nlohmann::json& cases, const nlohmann::json& table2, bool have_full_reference,
                       const std::vector<ProblemRun>& problems);

// --- Output files (study_outputs.cpp) ------------------------------------------------------------

/// cases.csv, force_depth.csv, probes.csv and targets.csv in `out`.
void write_csv_tables(const nlohmann::json& document, const std::vector<ProblemRun>& problems, const std::string& out);
/// One PVD per MFS series in `out`, its cases' fields on the reference mesh with the node count
/// as the time step: ParaView steps through N and shows MFS, FEM and their difference.
void write_comparison_pvds(const nlohmann::json& cases, const std::string& out);
/// The references, the MFS cases and the targets on stdout.
void print_summary(const nlohmann::json& document, const std::vector<ProblemRun>& problems);

}  // namespace touchstone::studies::comparison
