#pragma once
/// @file
/// `touchstone collision`: the paper's collision-detection results measured.
///
/// Three parts, all over randomized approach–press–release trajectories with hand tremor
/// (approach_trajectory.hpp) on generated organ surfaces (organ_geometry.hpp):
/// - Table 1 replica: overlap tests of the query that finds the first contact (the tip's motion
///   segment in the contact cycle), per organ size and tree (OBB/AABB; the binary tree the
///   paper counts and the default tree), mean and max over the trajectories, next to the
///   paper's numbers and the prediction's "1 distance + 1 comparison"; the query's time.
///   Embree is not linked here: the speed comparison with it is benchmarks/collision_benchmark.
/// - Tremor: the predicted-point error of the mean tool path (eq. 2) against the window m, the
///   sampling period and the tremor amplitude, as a distribution (median, p90, max).
/// - Per-cycle cost over whole runs: full detection every cycle against the predictor, split
///   into approach, contact and release cycles (distances, box tests, triangle tests, time).
///
/// Output: results.json (the study contract, plus the sections "settings", "organs", "table1",
/// "tremor", "cycle_cost"; schema reports/schema/collision_results.schema.json),
/// config.resolved.toml, table1.csv, tremor.csv, cycle_cost.csv; report.md and the plots are
/// written by the reports package (`python3 -m touchstone_reports collision`).

#include "touchstone/meshes/organ_geometry.hpp"
#include "touchstone/realtime/hand_motion/approach_trajectory.hpp"
#include "touchstone/realtime/collision/bounding_volume_hierarchy.hpp"
#include "touchstone/realtime/collision/collision_prediction.hpp"
#include "touchstone/realtime/collision/surface_queries.hpp"
#include "touchstone/studies/fem_reference/config_reader.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace touchstone::studies {

/// One tree of the Table 1 sweep: a name ("binary", "default") and its settings; the bounding
/// volume is swept separately (BvhSettings::bounding_volume is overwritten per case).
struct CollisionTree {
  std::string name;
  realtime::collision::BvhSettings settings;
};

/// The tremor part: how well the mean tool path predicts the contact point.
struct TremorStudySettings {
  /// RMS tremor per axis [m], one set of trajectories each.
  std::vector<double> amplitudes_m{1e-4, 2e-4, 5e-4};
  /// m of eq. 2 (1 = the last tool path vector, eq. 1).
  std::vector<int> windows{1, 10, 30};
  /// The history takes a sample every this many haptic cycles (10 at 1 kHz: 100 Hz).
  std::vector<int> sample_period_cycles{1, 10};
  /// The prediction is made when the smooth hand is this far from the point it will touch
  /// (the straight-line range) [m].
  double evaluate_at_m = 0.0075;
  int trajectories = 200;
  /// Approaches start at least this far from the target [m] (so that the longest window lies
  /// within the approach).
  double start_distance_min_m = 0.020;
  /// The organ (generated like the others; reused when it is in the list).
  meshes::OrganShape shape = meshes::OrganShape::stomach;
  int target_triangles = 2500;
  std::uint64_t seed = 1000;
  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// One study file of `touchstone collision`.
struct CollisionStudy {
  std::string name = "collision";
  /// The organs, one Table 1 row each (shape, target triangle count and shape parameters).
  std::vector<meshes::OrganParameters> organs;
  /// Swept bounding volumes.
  std::vector<realtime::collision::BoundingVolume> bounding_volumes{realtime::collision::BoundingVolume::obb,
                                                                    realtime::collision::BoundingVolume::aabb};
  /// Swept trees. Default: "binary" (2 children, 1-triangle leaves, no entry grid: the paper's
  /// structure and count) and "default" (BvhSettings{}).
  std::vector<CollisionTree> trees;
  /// The approaches of Table 1 and the per-cycle cost (tremor included).
  realtime::hand_motion::ApproachSettings approach;
  int trajectories = 200;
  std::uint64_t seed = 1;
  /// The predictor of the per-cycle cost; cycle_period_s is 1 / approach.sample_rate_hz.
  realtime::collision::PredictionSettings prediction;
  TremorStudySettings tremor;
  /// Each query time is measured over repeated passes lasting at least this long [s].
  double min_timing_s = 0.05;

  /// Throws std::invalid_argument naming the field (including the engine structs' validate()).
  void validate() const;
};

/// The default study (organs: stomach at 500, 2,500, 17,000, 35,000 triangles and the B2
/// hemisphere at 2,500; trees "binary" and "default").
CollisionStudy default_collision_study();

/// The names of the sweeps' enums in study files, results.json and the report.
std::string to_string(realtime::collision::BoundingVolume volume);
std::string to_string(realtime::collision::SplitRule split);

/// Reads a [prediction] table into `settings` (its values are the defaults); shared by
/// `touchstone collision` studies and `touchstone sim` scenes. The cycle period is the caller's.
void read_prediction_settings(ConfigTable& prediction, realtime::collision::PredictionSettings& settings);

/// Reads a study; unknown keys are errors naming the file and key, invalid values end in a
/// ConfigError naming the file and the field.
CollisionStudy read_collision_study(ConfigTable& config);

/// The study with every default filled in, quantities in SI, as TOML that
/// read_collision_study reads back to the same study.
std::string resolved_config_toml(const CollisionStudy& study);

/// results.json params: every scalar setting of the study under one key each (the same table as
/// the reader and config.resolved.toml), plus the organs' shared shape parameters.
nlohmann::json collision_params(const CollisionStudy& study);

struct CollisionRunOptions {
  std::string output_directory = "output/collision";
  std::string config_text;  ///< for provenance (config_sha256)
  bool quiet = false;
  /// Write report.md with the reports package (report_launcher.hpp); false: data only.
  bool report = true;
  /// PNG plots linked from report.md (matplotlib); when they cannot be made, report.md says so
  /// and everything else is still written.
  bool plots = true;
  /// The interpreter of the reports package.
  std::string python = "/usr/bin/python3";
};

/// Runs the three parts and writes results.json, config.resolved.toml and the CSV tables into the
/// output folder, then (options.report) runs the reports package for report.md and the plots.
/// Returns the results document; throws std::runtime_error when the report was asked for and
/// could not be written (the data files are written by then).
nlohmann::json run_collision_study(const CollisionStudy& study, const CollisionRunOptions& options);

/// The tremor study's measurement on one trajectory (shared with test_tremor_model's method):
/// at the first sample k of the approach where the smooth hand is within `evaluate_at_m` of
/// the target, the mean tool path (eq. 2) over m previous tip samples taken every
/// `sample_period_cycles` (the newest one cycle old) is ray-cast from the tip; the error is the
/// distance from the hit to the target. +∞ when the ray misses (within 0.5 m), NaN when the
/// window reaches before the first sample.
double predicted_point_error_m(const realtime::collision::SurfaceQueries& surface,
                               const realtime::hand_motion::ApproachTrajectory& trajectory, int window_samples,
                               int sample_period_cycles, double evaluate_at_m) noexcept;

/// The paper's Table 1 overlap counts (9, 12, 14, 16 at 500, 2.5K, 17K, 35K triangles), by
/// nearest size; 0 for other sizes (more than 25 % away from all four).
int paper_table1_overlap_tests(int triangles) noexcept;

}  // namespace touchstone::studies
