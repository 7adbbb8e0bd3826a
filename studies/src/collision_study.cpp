// `touchstone collision`: TOML → CollisionStudy, the three measurements (Table 1 replica,
// tremor, per-cycle cost), results.json (the study contract) and CSV tables; report.md and the
// plots are the reports package's (report_launcher.hpp). One file for now: the three measurements
// share the organs, the trees and the approach trajectories; splitting them is the next step.
#include "touchstone/studies/collision_study.hpp"

#include "touchstone/geometry/triangle_surface.hpp"
#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/provenance.hpp"
#include "touchstone/studies/report_launcher.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <climits>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace touchstone::studies {
namespace fs = std::filesystem;
namespace rc = realtime::collision;
namespace hm = realtime::hand_motion;
using Eigen::Vector3d;
using nlohmann::json;

namespace {

constexpr double infinity = std::numeric_limits<double>::infinity();

// ---------------------------------------------------------------------------------------------
// Names as spelled in configs, results.json and the report.

std::string volume_name(rc::BoundingVolume v) { return v == rc::BoundingVolume::obb ? "obb" : "aabb"; }
rc::BoundingVolume volume_from(const std::string& name) {
  return name == "aabb" ? rc::BoundingVolume::aabb : rc::BoundingVolume::obb;
}
std::string split_name(rc::SplitRule s) { return s == rc::SplitRule::mean ? "mean" : "median"; }
std::string spectrum_name(hm::TremorSpectrum s) { return s == hm::TremorSpectrum::sinusoids ? "sinusoids" : "band_noise"; }

std::string organ_id(const meshes::OrganParameters& organ) {
  return meshes::to_string(organ.shape) + "-" + std::to_string(organ.target_triangles);
}

std::string printf_string(const char* format, double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, format, value);
  return buffer;
}

// ---------------------------------------------------------------------------------------------
// Distributions.

/// Nearest-rank percentile (as test_tremor_model): the value at round(q (n − 1)) of the sorted
/// list; +∞ entries sort last.
double percentile_sorted(const std::vector<double>& sorted, double q) {
  if (sorted.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto index = static_cast<std::size_t>(std::lround(q * static_cast<double>(sorted.size() - 1)));
  return sorted[std::min(index, sorted.size() - 1)];
}

/// {mean, median, p90, p99, max} of `values` (mean over the finite ones); null entries when empty.
json distribution(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  double sum = 0;
  std::size_t finite = 0;
  for (const double v : values)
    if (std::isfinite(v)) {
      sum += v;
      ++finite;
    }
  // Mean of the values up to the 99.9th percentile: timings without the rare preemptions of a
  // shared machine, which would otherwise dominate the mean.
  const double cut = percentile_sorted(values, 0.999);
  double trimmed_sum = 0;
  std::size_t trimmed = 0;
  for (const double v : values)
    if (std::isfinite(v) && v <= cut) {
      trimmed_sum += v;
      ++trimmed;
    }
  return {{"count", values.size()},
          {"mean", finite ? json_number(sum / static_cast<double>(finite)) : json(nullptr)},
          {"trimmed_mean", trimmed ? json_number(trimmed_sum / static_cast<double>(trimmed)) : json(nullptr)},
          {"median", json_number(percentile_sorted(values, 0.5))},
          {"p90", json_number(percentile_sorted(values, 0.9))},
          {"p99", json_number(percentile_sorted(values, 0.99))},
          {"max", values.empty() ? json(nullptr) : json_number(values.back())}};
}

// ---------------------------------------------------------------------------------------------
// Per-cycle cost, accumulated per phase of the run.

enum Phase { approach_phase, contact_phase, release_phase, phase_count };
const char* const phase_names[phase_count] = {"approach", "contact", "release"};

struct PhaseCost {
  long long cycles = 0;
  long long distances = 0;        ///< point–point distances (the predictor's ball checks)
  long long surface_queries = 0;  ///< segment, ray, closest-point and inside queries
  long long box_tests = 0;
  long long triangle_tests = 0;
  long long max_box_tests = 0;    ///< in one cycle
  long long max_triangle_tests = 0;
  std::vector<double> cycle_ns;

  void add(long long d, long long q, long long b, long long t, double ns) {
    ++cycles;
    distances += d;
    surface_queries += q;
    box_tests += b;
    triangle_tests += t;
    max_box_tests = std::max(max_box_tests, b);
    max_triangle_tests = std::max(max_triangle_tests, t);
    cycle_ns.push_back(ns);
  }
  void merge(const PhaseCost& other) {
    cycles += other.cycles;
    distances += other.distances;
    surface_queries += other.surface_queries;
    box_tests += other.box_tests;
    triangle_tests += other.triangle_tests;
    max_box_tests = std::max(max_box_tests, other.max_box_tests);
    max_triangle_tests = std::max(max_triangle_tests, other.max_triangle_tests);
    cycle_ns.insert(cycle_ns.end(), other.cycle_ns.begin(), other.cycle_ns.end());
  }
  json to_json() const {
    const double n = cycles > 0 ? static_cast<double>(cycles) : std::numeric_limits<double>::quiet_NaN();
    json time = distribution(cycle_ns);
    return {{"cycles", cycles},
            {"distances_per_cycle", json_number(static_cast<double>(distances) / n)},
            {"surface_queries_per_cycle", json_number(static_cast<double>(surface_queries) / n)},
            {"box_tests_per_cycle", json_number(static_cast<double>(box_tests) / n)},
            {"triangle_tests_per_cycle", json_number(static_cast<double>(triangle_tests) / n)},
            {"max_box_tests_in_a_cycle", max_box_tests},
            {"max_triangle_tests_in_a_cycle", max_triangle_tests},
            {"time_ns",
             {{"mean", time["mean"]},
              {"median", time["median"]},
              {"trimmed_mean", time["trimmed_mean"]},
              {"p99", time["p99"]},
              {"max", time["max"]}}}};
  }
};

json phases_json(const PhaseCost (&phases)[phase_count]) {
  json j;
  PhaseCost all;
  for (int p = 0; p < phase_count; ++p) {
    j[phase_names[p]] = phases[p].to_json();
    all.merge(phases[p]);
  }
  j["all"] = all.to_json();
  return j;
}

double elapsed_ns(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double, std::nano>(b - a).count();
}

// ---------------------------------------------------------------------------------------------
// One organ: the surface and its trajectories.

struct Organ {
  meshes::OrganParameters parameters;
  std::unique_ptr<geometry::TriangleSurface> surface;
  json info;
};

Organ make_organ(const meshes::OrganParameters& parameters) {
  meshes::OrganMesh mesh = meshes::generate_organ_mesh(parameters);
  Organ organ;
  organ.parameters = parameters;
  organ.info = {{"id", organ_id(parameters)},
                {"shape", meshes::to_string(parameters.shape)},
                {"target_triangles", parameters.target_triangles},
                {"triangles", mesh.triangles.size()},
                {"vertices", mesh.vertices.size()},
                {"mesh_size_m", mesh.mesh_size_m},
                {"mesh_s", mesh.seconds}};
  organ.surface = std::make_unique<geometry::TriangleSurface>(std::move(mesh.vertices), std::move(mesh.triangles),
                                                                        organ_id(parameters));
  organ.info["area_m2"] = json_number(organ.surface->area_m2());
  organ.info["volume_m3"] = json_number(organ.surface->volume_m3());
  return organ;
}

std::vector<hm::ApproachTrajectory> make_trajectories(const geometry::TriangleSurface& surface,
                                                      const hm::ApproachSettings& settings, int count,
                                                      std::uint64_t seed) {
  const hm::ApproachTrajectoryGenerator generator(surface, settings);
  std::vector<hm::ApproachTrajectory> trajectories;
  trajectories.reserve(static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i) trajectories.push_back(generator.generate(seed + static_cast<std::uint64_t>(i)));
  return trajectories;
}

// ---------------------------------------------------------------------------------------------
// One (organ, tree) case: full detection every cycle (the Table 1 count at first contact and
// the reference's contacts), then the predictor on the same tip positions, then the time of
// the first-contact query alone.

struct ReferenceRun {
  /// Per trajectory and cycle: the phase, and whether contact began (full detection's answer).
  std::vector<std::vector<std::uint8_t>> phase, began;
  std::vector<double> first_box, first_triangle;  ///< per trajectory with a contact
  std::vector<std::pair<Vector3d, Vector3d>> first_segments;
  PhaseCost cost[phase_count];
  long long contacts = 0;
  int without_contact = 0;
};

ReferenceRun run_full_detection(const rc::SurfaceQueries& tree, const std::vector<hm::ApproachTrajectory>& trajectories) {
  ReferenceRun run;
  for (const hm::ApproachTrajectory& t : trajectories) {
    rc::FullDetectionReference reference(tree);
    std::vector<std::uint8_t> phase(t.tip.size()), began(t.tip.size());
    bool contacted = false;
    for (std::size_t k = 0; k < t.tip.size(); ++k) {
      rc::QueryCounters counters;
      rc::SurfaceHit hit;
      const auto start = std::chrono::steady_clock::now();
      const bool begins = reference.step(t.tip[k], &hit, &counters);
      const auto end = std::chrono::steady_clock::now();
      if (begins && !contacted && k > 0) {
        // The query of the contact cycle: the Table 1 count.
        run.first_box.push_back(static_cast<double>(counters.box_tests));
        run.first_triangle.push_back(static_cast<double>(counters.triangle_tests));
        run.first_segments.emplace_back(t.tip[k - 1], t.tip[k]);
      }
      contacted = contacted || begins;
      run.contacts += begins;
      const Phase p = !contacted ? approach_phase : (begins || reference.in_contact()) ? contact_phase : release_phase;
      phase[k] = static_cast<std::uint8_t>(p);
      began[k] = begins;
      run.cost[p].add(0, counters.queries, counters.box_tests, counters.triangle_tests, elapsed_ns(start, end));
    }
    run.without_contact += !contacted;
    run.phase.push_back(std::move(phase));
    run.began.push_back(std::move(began));
  }
  return run;
}

struct PredictionRun {
  PhaseCost cost[phase_count];
  long long free_cycles = 0;
  long long free_cycle_distances_max = 0;
  long long free_cycle_distances_min = LLONG_MAX;
  long long free_cycle_surface_tests = 0;  ///< box + triangle tests in free cycles (must be 0)
  long long cheap_before_contact = 0;      ///< approach cycles decided by the cheap check
  long long approach_cycles = 0;
  long long misses = 0;    ///< full detection saw contact begin, the predictor did not
  long long spurious = 0;  ///< the predictor reported a contact that full detection did not
  rc::PredictionCounters counters;
};

PredictionRun run_prediction(const rc::SurfaceQueries& tree, const rc::PredictionSettings& settings,
                             const std::vector<hm::ApproachTrajectory>& trajectories, const ReferenceRun& reference) {
  PredictionRun run;
  rc::CollisionPredictor predictor(tree, settings);
  for (std::size_t i = 0; i < trajectories.size(); ++i) {
    const hm::ApproachTrajectory& t = trajectories[i];
    predictor.reset();
    for (std::size_t k = 0; k < t.tip.size(); ++k) {
      const rc::PredictionCounters before = predictor.counters();
      const auto start = std::chrono::steady_clock::now();
      const rc::PredictionStep step = predictor.step(t.tip[k]);
      const auto end = std::chrono::steady_clock::now();
      const rc::PredictionCounters& after = predictor.counters();
      const long long distances = after.cheap_distances - before.cheap_distances;
      const long long queries = (after.closest_point_queries - before.closest_point_queries) +
                                (after.ray_casts - before.ray_casts) + (after.full_detections - before.full_detections) +
                                (after.contact_checks - before.contact_checks);
      const long long boxes = after.queries.box_tests - before.queries.box_tests;
      const long long triangles = after.queries.triangle_tests - before.queries.triangle_tests;
      const Phase p = static_cast<Phase>(reference.phase[i][k]);
      run.cost[p].add(distances, queries, boxes, triangles, elapsed_ns(start, end));
      if (step.status == rc::PredictionStatus::free) {
        ++run.free_cycles;
        run.free_cycle_distances_max = std::max(run.free_cycle_distances_max, distances);
        run.free_cycle_distances_min = std::min(run.free_cycle_distances_min, distances);
        run.free_cycle_surface_tests += boxes + triangles + queries;
      }
      if (p == approach_phase) {
        ++run.approach_cycles;
        run.cheap_before_contact += step.status == rc::PredictionStatus::free ||
                                    step.status == rc::PredictionStatus::deferred;
      }
      const bool contact = step.status == rc::PredictionStatus::contact;
      run.misses += reference.began[i][k] && !contact;
      run.spurious += contact && !reference.began[i][k];
    }
  }
  run.counters = predictor.counters();
  if (run.free_cycles == 0) run.free_cycle_distances_min = 0;
  return run;
}

/// Time of one first-contact query [ns]: after a warm-up pass, the least of three means over
/// repeated passes lasting ≥ min_s / 3 each (the least disturbed on a shared machine).
double first_contact_query_ns(const rc::SurfaceQueries& tree, const std::vector<std::pair<Vector3d, Vector3d>>& segments,
                              double min_s) {
  if (segments.empty()) return std::numeric_limits<double>::quiet_NaN();
  int sink = 0;
  for (const auto& [from, to] : segments) sink += tree.first_hit_segment(from, to).triangle;
  double best = infinity;
  for (int repetition = 0; repetition < 3; ++repetition) {
    long long queries = 0;
    const auto start = std::chrono::steady_clock::now();
    double elapsed = 0;
    do {
      for (const auto& [from, to] : segments) sink += tree.first_hit_segment(from, to).triangle;
      queries += static_cast<long long>(segments.size());
      elapsed = seconds_since(start);
    } while (elapsed < min_s / 3);
    best = std::min(best, 1e9 * elapsed / static_cast<double>(queries));
  }
  // Keeps the loops from being optimized away.
  if (sink == INT_MIN) std::printf(" ");
  return best;
}

json mean_max(const std::vector<double>& values) {
  if (values.empty()) return {{"mean", nullptr}, {"max", nullptr}};
  double sum = 0, max = 0;
  for (const double v : values) {
    sum += v;
    max = std::max(max, v);
  }
  return {{"mean", sum / static_cast<double>(values.size())}, {"max", max}};
}

/// Null fields of the results.json contract that a collision case has no value for.
json contract_qoi() { return {{"force_N", nullptr}, {"stiffness_N_per_m", nullptr}, {"energy_J", nullptr}}; }
json contract_error() { return {{"force_rel", nullptr}, {"disp_rel_l2", nullptr}, {"disp_max_m", nullptr}}; }

// ---------------------------------------------------------------------------------------------
// CSV tables.

std::string write_csv(const std::vector<std::string>& header, const std::vector<std::vector<std::string>>& rows) {
  std::ostringstream out;
  for (std::size_t i = 0; i < header.size(); ++i) out << (i ? "," : "") << header[i];
  out << "\n";
  for (const auto& row : rows) {
    for (std::size_t i = 0; i < row.size(); ++i) out << (i ? "," : "") << row[i];
    out << "\n";
  }
  return out.str();
}

/// report.md and the plots by the reports package. Plots asked for but not made (no matplotlib):
/// the report is written again without them and says why. Throws when no report is written.
void write_report(const CollisionRunOptions& options) {
  ReportLaunchOptions launch;
  launch.python = options.python;
  if (options.quiet) launch.arguments.push_back("--quiet");
  if (!options.plots) launch.arguments.push_back("--no-plots");
  ReportStatus status = run_report("collision", options.output_directory, launch);
  if (status.exit_status > 0 && options.plots) {  // the package ran and failed: retry without plots
    std::fprintf(stderr, "collision report: %s; writing it without plots\n", status.message.c_str());
    launch.arguments.insert(launch.arguments.end(), {"--no-plots", "--plot-note", "the plot step failed: " + status.message});
    status = run_report("collision", options.output_directory, launch);
  }
  if (!status.ok())
    throw std::runtime_error("the collision report failed: " + status.message +
                             "; results.json and the CSV tables are written");
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Shared measurements.

double predicted_point_error_m(const rc::SurfaceQueries& surface, const hm::ApproachTrajectory& t, int window_samples,
                               int sample_period_cycles, double evaluate_at_m) noexcept {
  int k = t.approach_begin;
  while (k < t.approach_end && (t.smooth[static_cast<std::size_t>(k)] - t.target).norm() > evaluate_at_m) ++k;
  const long oldest = static_cast<long>(k) - 1 - static_cast<long>(window_samples - 1) * sample_period_cycles;
  if (oldest < 0 || window_samples < 1 || window_samples > rc::max_window_samples)
    return std::numeric_limits<double>::quiet_NaN();
  rc::ToolPathHistory history(window_samples);
  for (int j = window_samples; j >= 1; --j)
    history.push(t.tip[static_cast<std::size_t>(k - 1 - (j - 1) * sample_period_cycles)]);
  const Vector3d& tip = t.tip[static_cast<std::size_t>(k)];
  const Vector3d path = history.mean_tool_path(tip);
  if (!(path.norm() > 0)) return infinity;
  const rc::SurfaceHit hit = surface.first_hit_ray(tip, path.normalized(), 0.5);
  return hit.hit ? (hit.point - t.target).norm() : infinity;
}

int paper_table1_overlap_tests(int triangles) noexcept {
  static constexpr int sizes[4] = {500, 2500, 17000, 35000};
  static constexpr int counts[4] = {9, 12, 14, 16};
  for (int i = 0; i < 4; ++i)
    if (std::abs(triangles - sizes[i]) <= sizes[i] / 4) return counts[i];
  return 0;
}

// ---------------------------------------------------------------------------------------------
// Settings.

void TremorStudySettings::validate() const {
  if (amplitudes_m.empty()) throw std::invalid_argument("tremor_study.amplitudes is an empty list");
  for (const double a : amplitudes_m)
    if (!std::isfinite(a) || a < 0)
      throw std::invalid_argument("tremor_study.amplitudes: " + format_number(a) + " must be finite and >= 0");
  if (windows.empty()) throw std::invalid_argument("tremor_study.windows is an empty list");
  for (const int m : windows)
    if (m < 1 || m > rc::max_window_samples)
      throw std::invalid_argument("tremor_study.windows: " + std::to_string(m) + " must be in [1, " +
                                  std::to_string(rc::max_window_samples) + "]");
  if (sample_period_cycles.empty()) throw std::invalid_argument("tremor_study.sample_period_cycles is an empty list");
  for (const int s : sample_period_cycles)
    if (s < 1) throw std::invalid_argument("tremor_study.sample_period_cycles: " + std::to_string(s) + " must be >= 1");
  if (!(evaluate_at_m > 0) || !std::isfinite(evaluate_at_m))
    throw std::invalid_argument("tremor_study.evaluate_at = " + format_number(evaluate_at_m) + " must be > 0");
  if (trajectories < 1) throw std::invalid_argument("tremor_study.trajectories = " + std::to_string(trajectories) + " must be >= 1");
  if (!(start_distance_min_m > evaluate_at_m))
    throw std::invalid_argument("tremor_study.start_distance_min = " + format_number(start_distance_min_m) +
                                " must be > tremor_study.evaluate_at");
  meshes::OrganParameters organ;
  organ.shape = shape;
  organ.target_triangles = target_triangles;
  try {
    organ.validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("tremor_study.organ: ") + e.what());
  }
}

void CollisionStudy::validate() const {
  if (name.empty()) throw std::invalid_argument("study name is empty");
  if (organs.empty()) throw std::invalid_argument("organ: no organ (stomach_triangles and hemisphere_triangles are empty)");
  for (const auto& organ : organs) organ.validate();
  if (bounding_volumes.empty()) throw std::invalid_argument("bvh.bounding_volume is an empty list");
  if (trees.empty()) throw std::invalid_argument("bvh.trees is an empty list");
  for (const auto& tree : trees) {
    try {
      tree.settings.validate();
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("bvh." + tree.name + ": " + e.what());
    }
  }
  approach.validate();
  if (trajectories < 1) throw std::invalid_argument("approach.trajectories = " + std::to_string(trajectories) + " must be >= 1");
  prediction.validate();
  if (std::abs(prediction.cycle_period_s * approach.sample_rate_hz - 1) > 1e-9)
    throw std::invalid_argument("prediction.cycle_period_s must be 1 / approach.sample_rate_hz");
  tremor.validate();
  if (!(tremor.start_distance_min_m <= approach.start_distance_max_m))
    throw std::invalid_argument("tremor_study.start_distance_min = " + format_number(tremor.start_distance_min_m) +
                                " must be <= approach.start_distance_max = " + format_number(approach.start_distance_max_m));
  if (!(min_timing_s >= 0) || !std::isfinite(min_timing_s))
    throw std::invalid_argument("timing.min_time = " + format_number(min_timing_s) + " must be finite and >= 0");
}

CollisionStudy default_collision_study() {
  CollisionStudy study;
  for (const int n : {500, 2500, 17000, 35000}) {
    meshes::OrganParameters organ;
    organ.target_triangles = n;
    study.organs.push_back(organ);
  }
  meshes::OrganParameters hemisphere;
  hemisphere.shape = meshes::OrganShape::hemisphere;
  hemisphere.target_triangles = 2500;
  study.organs.push_back(hemisphere);
  rc::BvhSettings binary;
  binary.children_per_node = 2;
  binary.max_leaf_triangles = 1;
  binary.entry_grid_cell = 0;
  study.trees = {{"binary", binary}, {"default", rc::BvhSettings{}}};
  study.prediction.cycle_period_s = 1 / study.approach.sample_rate_hz;
  return study;
}

void read_prediction_settings(ConfigTable& prediction, realtime::collision::PredictionSettings& p) {
  p.window_samples = read_int(prediction, "window_samples", p.window_samples);
  p.sample_period_cycles = read_int(prediction, "sample_period_cycles", p.sample_period_cycles);
  p.straight_line_range_m = prediction.quantity("straight_line_range", Dimension::length, p.straight_line_range_m);
  p.direction_threshold_rad = prediction.quantity("direction_threshold", Dimension::angle, p.direction_threshold_rad);
  p.margin_m = prediction.quantity("margin", Dimension::length, p.margin_m);
  p.handover_distance_m = prediction.quantity("handover_distance", Dimension::length, p.handover_distance_m);
  p.near_exit_distance_m = prediction.quantity("near_exit_distance", Dimension::length, p.near_exit_distance_m);
  p.corridor_step_fraction = prediction.number("corridor_step_fraction", p.corridor_step_fraction);
  p.corridor_balls = read_int(prediction, "corridor_balls", p.corridor_balls);
  p.ray_max_distance_m = prediction.quantity("ray_max_distance", Dimension::length, p.ray_max_distance_m);
  p.min_path_length_m = prediction.quantity("min_path_length", Dimension::length, p.min_path_length_m);
  p.detection_period_cycles = read_int(prediction, "detection_period_cycles", p.detection_period_cycles);
  p.max_tip_speed_m_per_s = prediction.number("max_tip_speed_m_per_s", p.max_tip_speed_m_per_s);
  p.direction_check_period_cycles = read_int(prediction, "direction_check_period_cycles", p.direction_check_period_cycles);
  p.audit = prediction.boolean("audit", p.audit);
}

CollisionStudy read_collision_study(ConfigTable& config) {
  CollisionStudy study = default_collision_study();
  study.name = config.string("study", study.name);

  // The organs: every listed count of each shape.
  ConfigTable organ = config.table("organ");
  meshes::OrganParameters base;
  base.relative_tolerance = organ.number("relative_tolerance", base.relative_tolerance);
  base.stomach_scale = organ.number("stomach_scale", base.stomach_scale);
  base.stomach_flattening = organ.number("stomach_flattening", base.stomach_flattening);
  base.hemisphere_radius_m = organ.quantity("hemisphere_radius", Dimension::length, base.hemisphere_radius_m);
  base.max_passes = read_int(organ, "max_passes", base.max_passes);
  const std::vector<int> stomach = read_int_list(organ, "stomach_triangles", {500, 2500, 17000, 35000});
  const std::vector<int> hemisphere = read_int_list(organ, "hemisphere_triangles", {2500});
  study.organs.clear();
  for (const auto& [shape, counts] : {std::pair{meshes::OrganShape::stomach, stomach},
                                      std::pair{meshes::OrganShape::hemisphere, hemisphere}})
    for (const int n : counts) {
      meshes::OrganParameters p = base;
      p.shape = shape;
      p.target_triangles = n;
      try {
        p.validate();
      } catch (const std::invalid_argument& e) {
        throw ConfigError(organ.where(shape == meshes::OrganShape::stomach ? "stomach_triangles" : "hemisphere_triangles") +
                          ": " + e.what());
      }
      study.organs.push_back(p);
    }

  // The trees: each named tree's settings in [bvh.<name>]; the bounding volume is swept.
  ConfigTable bvh = config.table("bvh");
  study.bounding_volumes.clear();
  for (const auto& name : bvh.choice_list("bounding_volume", {"obb", "aabb"}, {"obb", "aabb"}))
    study.bounding_volumes.push_back(volume_from(name));
  const std::vector<std::string> tree_names = bvh.choice_list("trees", {"binary", "default"}, {"binary", "default"});
  std::vector<CollisionTree> defaults = study.trees;
  study.trees.clear();
  for (const std::string& name : tree_names) {
    ConfigTable t = bvh.table(name);
    CollisionTree tree = name == "binary" ? defaults[0] : defaults[1];
    rc::BvhSettings& s = tree.settings;
    s.split = t.choice("split", {"median", "mean"}, split_name(s.split)) == "mean" ? rc::SplitRule::mean : rc::SplitRule::median;
    s.max_leaf_triangles = read_int(t, "max_leaf_triangles", s.max_leaf_triangles);
    s.children_per_node = read_int(t, "children_per_node", s.children_per_node);
    s.entry_grid_cell = t.number("entry_grid_cell", s.entry_grid_cell);
    try {
      s.validate();
    } catch (const std::invalid_argument& e) {
      throw ConfigError(t.where("") + e.what());
    }
    study.trees.push_back(tree);
  }

  ConfigTable approach = config.table("approach");
  hm::ApproachSettings& a = study.approach;
  study.trajectories = read_int(approach, "trajectories", study.trajectories);
  study.seed = read_seed(approach, "seed", study.seed);
  a.start_distance_min_m = approach.quantity("start_distance_min", Dimension::length, a.start_distance_min_m);
  a.start_distance_max_m = approach.quantity("start_distance_max", Dimension::length, a.start_distance_max_m);
  a.max_approach_angle_rad = approach.quantity("max_approach_angle", Dimension::angle, a.max_approach_angle_rad);
  a.speed_min_m_per_s = approach.number("speed_min_m_per_s", a.speed_min_m_per_s);
  a.speed_max_m_per_s = approach.number("speed_max_m_per_s", a.speed_max_m_per_s);
  a.press_depth_min_m = approach.quantity("press_depth_min", Dimension::length, a.press_depth_min_m);
  a.press_depth_max_m = approach.quantity("press_depth_max", Dimension::length, a.press_depth_max_m);
  a.rest_s = approach.quantity("rest", Dimension::time, a.rest_s);
  a.hold_s = approach.quantity("hold", Dimension::time, a.hold_s);
  a.final_rest_s = approach.quantity("final_rest", Dimension::time, a.final_rest_s);
  a.min_segment_s = approach.quantity("min_segment", Dimension::time, a.min_segment_s);
  a.sample_rate_hz = approach.number("sample_rate_hz", a.sample_rate_hz);
  ConfigTable tremor = approach.table("tremor");
  hm::TremorSettings& ts = a.tremor;
  ts.rms_per_axis_m = tremor.quantity("rms_per_axis", Dimension::length, ts.rms_per_axis_m);
  ts.band_low_hz = tremor.number("band_low_hz", ts.band_low_hz);
  ts.band_high_hz = tremor.number("band_high_hz", ts.band_high_hz);
  ts.spectrum = tremor.choice("spectrum", {"band_noise", "sinusoids"}, spectrum_name(ts.spectrum)) == "sinusoids"
                    ? hm::TremorSpectrum::sinusoids
                    : hm::TremorSpectrum::band_noise;
  ts.filter_order = read_int(tremor, "filter_order", ts.filter_order);
  ts.sinusoid_count = read_int(tremor, "sinusoid_count", ts.sinusoid_count);
  ts.sample_rate_hz = a.sample_rate_hz;

  ConfigTable prediction = config.table("prediction");
  rc::PredictionSettings& p = study.prediction;
  read_prediction_settings(prediction, p);
  p.cycle_period_s = a.sample_rate_hz > 0 ? 1 / a.sample_rate_hz : p.cycle_period_s;

  ConfigTable tremor_study = config.table("tremor_study");
  TremorStudySettings& t = study.tremor;
  t.amplitudes_m = tremor_study.quantity_list("amplitudes", Dimension::length, t.amplitudes_m);
  t.windows = read_int_list(tremor_study, "windows", t.windows);
  t.sample_period_cycles = read_int_list(tremor_study, "sample_period_cycles", t.sample_period_cycles);
  t.evaluate_at_m = tremor_study.quantity("evaluate_at", Dimension::length, t.evaluate_at_m);
  t.trajectories = read_int(tremor_study, "trajectories", t.trajectories);
  t.start_distance_min_m = tremor_study.quantity("start_distance_min", Dimension::length, t.start_distance_min_m);
  t.shape = meshes::organ_shape_from_string(
      tremor_study.choice("organ", {"stomach", "hemisphere"}, meshes::to_string(t.shape)));
  t.target_triangles = read_int(tremor_study, "organ_triangles", t.target_triangles);
  t.seed = read_seed(tremor_study, "seed", t.seed);

  ConfigTable timing = config.table("timing");
  study.min_timing_s = timing.quantity("min_time", Dimension::time, study.min_timing_s);

  config.finish();
  // Value errors name the field; the section-qualified field names map onto the config's keys.
  try {
    study.validate();
  } catch (const std::invalid_argument& e) {
    throw ConfigError(config.where("") + e.what());
  }
  return study;
}

std::string resolved_config_toml(const CollisionStudy& study) {
  toml::array stomach, hemisphere;
  for (const auto& o : study.organs) (o.shape == meshes::OrganShape::stomach ? stomach : hemisphere).push_back(o.target_triangles);
  const meshes::OrganParameters& o0 = study.organs.front();
  toml::array volumes, tree_names;
  for (const auto v : study.bounding_volumes) volumes.push_back(volume_name(v));
  toml::table bvh;
  for (const auto& tree : study.trees) {
    tree_names.push_back(tree.name);
    bvh.insert(tree.name, toml::table{{"split", split_name(tree.settings.split)},
                                      {"max_leaf_triangles", tree.settings.max_leaf_triangles},
                                      {"children_per_node", tree.settings.children_per_node},
                                      {"entry_grid_cell", tree.settings.entry_grid_cell}});
  }
  bvh.insert("bounding_volume", volumes);
  bvh.insert("trees", tree_names);
  const hm::ApproachSettings& a = study.approach;
  const rc::PredictionSettings& p = study.prediction;
  const TremorStudySettings& t = study.tremor;
  toml::array amplitudes, windows, periods;
  for (const double v : t.amplitudes_m) amplitudes.push_back(v);
  for (const int v : t.windows) windows.push_back(v);
  for (const int v : t.sample_period_cycles) periods.push_back(v);
  toml::table document{
      {"study", study.name},
      {"organ", toml::table{{"stomach_triangles", stomach},
                            {"hemisphere_triangles", hemisphere},
                            {"relative_tolerance", o0.relative_tolerance},
                            {"stomach_scale", o0.stomach_scale},
                            {"stomach_flattening", o0.stomach_flattening},
                            {"hemisphere_radius", o0.hemisphere_radius_m},
                            {"max_passes", o0.max_passes}}},
      {"bvh", bvh},
      {"approach",
       toml::table{{"trajectories", study.trajectories},
                   {"seed", static_cast<std::int64_t>(study.seed)},
                   {"start_distance_min", a.start_distance_min_m},
                   {"start_distance_max", a.start_distance_max_m},
                   {"max_approach_angle", a.max_approach_angle_rad},
                   {"speed_min_m_per_s", a.speed_min_m_per_s},
                   {"speed_max_m_per_s", a.speed_max_m_per_s},
                   {"press_depth_min", a.press_depth_min_m},
                   {"press_depth_max", a.press_depth_max_m},
                   {"rest", a.rest_s},
                   {"hold", a.hold_s},
                   {"final_rest", a.final_rest_s},
                   {"min_segment", a.min_segment_s},
                   {"sample_rate_hz", a.sample_rate_hz},
                   {"tremor", toml::table{{"rms_per_axis", a.tremor.rms_per_axis_m},
                                          {"band_low_hz", a.tremor.band_low_hz},
                                          {"band_high_hz", a.tremor.band_high_hz},
                                          {"spectrum", spectrum_name(a.tremor.spectrum)},
                                          {"filter_order", a.tremor.filter_order},
                                          {"sinusoid_count", a.tremor.sinusoid_count}}}}},
      {"prediction", toml::table{{"window_samples", p.window_samples},
                                 {"sample_period_cycles", p.sample_period_cycles},
                                 {"straight_line_range", p.straight_line_range_m},
                                 {"direction_threshold", p.direction_threshold_rad},
                                 {"margin", p.margin_m},
                                 {"handover_distance", p.handover_distance_m},
                                 {"near_exit_distance", p.near_exit_distance_m},
                                 {"corridor_step_fraction", p.corridor_step_fraction},
                                 {"corridor_balls", p.corridor_balls},
                                 {"ray_max_distance", p.ray_max_distance_m},
                                 {"min_path_length", p.min_path_length_m},
                                 {"detection_period_cycles", p.detection_period_cycles},
                                 {"max_tip_speed_m_per_s", p.max_tip_speed_m_per_s},
                                 {"direction_check_period_cycles", p.direction_check_period_cycles},
                                 {"audit", p.audit}}},
      {"tremor_study", toml::table{{"amplitudes", amplitudes},
                                   {"windows", windows},
                                   {"sample_period_cycles", periods},
                                   {"evaluate_at", t.evaluate_at_m},
                                   {"trajectories", t.trajectories},
                                   {"start_distance_min", t.start_distance_min_m},
                                   {"organ", meshes::to_string(t.shape)},
                                   {"organ_triangles", t.target_triangles},
                                   {"seed", static_cast<std::int64_t>(t.seed)}}},
      {"timing", toml::table{{"min_time", study.min_timing_s}}}};
  std::ostringstream text;
  text << "# " << study.name
       << ", resolved by `touchstone collision`: every default filled in, quantities in SI (m, s, rad).\n"
       << document << "\n";
  return text.str();
}

// ---------------------------------------------------------------------------------------------
// The run.

nlohmann::json run_collision_study(const CollisionStudy& study, const CollisionRunOptions& options) {
  study.validate();
  const auto start = std::chrono::steady_clock::now();
  fs::create_directories(options.output_directory);
  write_file_atomically(options.output_directory + "/config.resolved.toml", resolved_config_toml(study));
  const auto say = [&](const char* format, auto... values) {
    if (options.quiet) return;
    std::printf(format, values...);
    std::fflush(stdout);
  };

  json document{{"study", study.name},
                {"provenance", provenance(options.config_text)},
                {"config_resolved", "config.resolved.toml"},
                {"output_directory", options.output_directory},
                {"embree_comparison", "benchmarks/collision_benchmark (first_contact vs first_contact_embree); "
                                      "Embree is not linked into the touchstone program"},
                {"organs", json::array()},
                {"table1", json::array()},
                {"tremor", json::array()},
                {"cycle_cost", json::array()},
                {"cases", json::array()}};
  {
    // What reading the clock around a cycle costs: the median of empty timed regions.
    std::vector<double> empty(10000);
    for (double& ns : empty) {
      const auto a = std::chrono::steady_clock::now();
      const auto b = std::chrono::steady_clock::now();
      ns = elapsed_ns(a, b);
    }
    document["timer_overhead_ns"] = distribution(empty)["median"];
  }
  // The settings the report quotes (the full study is config.resolved.toml). The detailed tree
  // of the per-cycle cost tables is the second tree when there are several (the first is the
  // paper's binary tree), with the first bounding volume.
  document["settings"] = {
      {"trajectories", study.trajectories},
      {"approach_tremor_rms_per_axis_m", study.approach.tremor.rms_per_axis_m},
      {"tremor", {{"trajectories", study.tremor.trajectories},
                  {"start_distance_min_m", study.tremor.start_distance_min_m},
                  {"evaluate_at_m", study.tremor.evaluate_at_m}}},
      {"prediction", {{"window_samples", study.prediction.window_samples},
                      {"sample_period_cycles", study.prediction.sample_period_cycles},
                      {"straight_line_range_m", study.prediction.straight_line_range_m}}},
      {"detailed_tree", study.trees.size() > 1 ? study.trees[1].name : study.trees[0].name},
      {"detailed_bounding_volume", volume_name(study.bounding_volumes.front())}};
  json seeds{{"approach", study.seed}, {"tremor_study", study.tremor.seed}};
  document["provenance"]["seeds"] = seeds;

  const std::size_t total_cases = study.organs.size() * study.trees.size() * study.bounding_volumes.size();
  std::size_t done = 0;
  std::map<std::pair<meshes::OrganShape, int>, std::size_t> organ_index;
  std::vector<Organ> organs;

  // Table 1 and the per-cycle cost: per organ, one set of trajectories for every tree.
  for (const meshes::OrganParameters& parameters : study.organs) {
    organs.push_back(make_organ(parameters));
    Organ& organ = organs.back();
    organ_index[{parameters.shape, parameters.target_triangles}] = organs.size() - 1;
    const auto trajectories_start = std::chrono::steady_clock::now();
    const std::vector<hm::ApproachTrajectory> trajectories =
        make_trajectories(*organ.surface, study.approach, study.trajectories, study.seed);
    long long cycles = 0;
    for (const auto& t : trajectories) cycles += static_cast<long long>(t.tip.size());
    organ.info["trajectories"] = study.trajectories;
    organ.info["cycles"] = cycles;
    organ.info["trajectories_s"] = seconds_since(trajectories_start);
    document["organs"].push_back(organ.info);
    say("organ %s: %zu triangles (meshing %.2f s), %d trajectories, %lld cycles (%.2f s)\n",
        organ.info["id"].get<std::string>().c_str(), organ.surface->triangles().size(),
        organ.info["mesh_s"].get<double>(), study.trajectories, cycles, organ.info["trajectories_s"].get<double>());

    for (const CollisionTree& tree : study.trees)
      for (const rc::BoundingVolume volume : study.bounding_volumes) {
        const auto case_start = std::chrono::steady_clock::now();
        rc::BvhSettings settings = tree.settings;
        settings.bounding_volume = volume;
        const auto build_start = std::chrono::steady_clock::now();
        const rc::BoundingVolumeHierarchy bvh(*organ.surface, settings);
        const double build_s = seconds_since(build_start);
        const rc::BvhStats stats = bvh.stats();

        const ReferenceRun reference = run_full_detection(bvh, trajectories);
        const PredictionRun prediction = run_prediction(bvh, study.prediction, trajectories, reference);
        const double query_ns = first_contact_query_ns(bvh, reference.first_segments, study.min_timing_s);

        // Table 1 row.
        const std::string id = organ.info["id"].get<std::string>() + "-" + tree.name + "-" + volume_name(volume);
        const bool binary_no_grid = settings.children_per_node == 2 && settings.entry_grid_cell == 0;
        std::vector<double> overlap(reference.first_box.size()), entered(reference.first_box.size());
        for (std::size_t i = 0; i < overlap.size(); ++i) {
          overlap[i] = reference.first_box[i] + reference.first_triangle[i];
          entered[i] = (reference.first_box[i] - 1) / 2;
        }
        const int triangles = static_cast<int>(organ.surface->triangles().size());
        const int paper = paper_table1_overlap_tests(triangles);
        json row{{"id", id},
                 {"organ", organ.info["id"]},
                 {"triangles", triangles},
                 {"tree", tree.name},
                 {"bounding_volume", volume_name(volume)},
                 {"children_per_node", settings.children_per_node},
                 {"max_leaf_triangles", settings.max_leaf_triangles},
                 {"entry_grid_cell", settings.entry_grid_cell},
                 {"depth", stats.depth},
                 {"binary_depth", stats.binary_depth},
                 {"node_count", stats.node_count},
                 {"memory_bytes", stats.memory_bytes},
                 {"build_ms", 1e3 * build_s},
                 {"first_contacts", reference.first_box.size()},
                 {"trajectories_without_contact", reference.without_contact},
                 {"paper_overlap_tests", paper > 0 ? json(paper) : json(nullptr)},
                 {"box_tests", mean_max(reference.first_box)},
                 {"triangle_tests", mean_max(reference.first_triangle)},
                 {"overlap_tests", mean_max(overlap)},
                 {"nodes_entered", binary_no_grid ? mean_max(entered) : json{{"mean", nullptr}, {"max", nullptr}}},
                 {"query_time_ns", json_number(query_ns)},
                 {"prediction_free_cycle", {{"distances", 1}, {"comparisons", 1}, {"box_tests", 0}}}};
        document["table1"].push_back(row);

        // Per-cycle cost rows.
        const rc::PredictionCounters& c = prediction.counters;
        json full{{"organ", organ.info["id"]}, {"tree", tree.name}, {"bounding_volume", volume_name(volume)},
                  {"mode", "full_detection"}, {"phases", phases_json(reference.cost)}};
        json predicted{{"organ", organ.info["id"]}, {"tree", tree.name}, {"bounding_volume", volume_name(volume)},
                       {"mode", "prediction"}, {"phases", phases_json(prediction.cost)}};
        predicted["prediction"] = {
            {"free_cycles", prediction.free_cycles},
            {"free_cycle_distances_min", prediction.free_cycle_distances_min},
            {"free_cycle_distances_max", prediction.free_cycle_distances_max},
            {"free_cycle_surface_tests", prediction.free_cycle_surface_tests},
            {"cheap_fraction_before_contact",
             prediction.approach_cycles > 0
                 ? static_cast<double>(prediction.cheap_before_contact) / static_cast<double>(prediction.approach_cycles)
                 : 0.0},
            {"predictions", c.predictions},
            {"repredictions", c.repredictions()},
            {"repredictions_by_cause", {{"direction_change", c.repredictions_direction},
                                        {"retreat", c.repredictions_retreat},
                                        {"out_of_range", c.repredictions_range},
                                        {"ball_exit", c.repredictions_ball_exit}}},
            {"handovers", c.handovers},
            {"corridor_advances", c.corridor_advances},
            {"closest_point_queries", c.closest_point_queries},
            {"ray_casts", c.ray_casts},
            {"full_detections", c.full_detections},
            {"contact_checks", c.contact_checks},
            {"contacts", c.contacts},
            {"reference_contacts", reference.contacts},
            {"misses", prediction.misses},
            {"spurious_contacts", prediction.spurious},
            {"audit_misses", c.misses()}};
        document["cycle_cost"].push_back(full);
        document["cycle_cost"].push_back(predicted);

        // The contract's case: parameters, the QoIs above, times.
        const double total_s = seconds_since(case_start);
        json qoi = contract_qoi();
        qoi["first_contact"] = {{"box_tests", row["box_tests"]},
                                {"triangle_tests", row["triangle_tests"]},
                                {"overlap_tests", row["overlap_tests"]},
                                {"nodes_entered", row["nodes_entered"]},
                                {"query_time_ns", row["query_time_ns"]}};
        qoi["cycle_cost"] = {{"full_detection", full["phases"]}, {"prediction", predicted["phases"]}};
        qoi["prediction_events"] = predicted["prediction"];
        const bool ok = reference.without_contact == 0 && prediction.misses == 0 && prediction.spurious == 0;
        document["cases"].push_back(
            {{"id", id},
             {"model", "collision"},
             {"params", {{"organ", organ.info["id"]}, {"triangles", triangles}, {"tree", tree.name},
                         {"bounding_volume", volume_name(volume)}, {"children_per_node", settings.children_per_node},
                         {"max_leaf_triangles", settings.max_leaf_triangles}, {"entry_grid_cell", settings.entry_grid_cell},
                         {"split", split_name(settings.split)}, {"trajectories", study.trajectories}}},
             {"qoi", qoi},
             {"error", contract_error()},
             {"reference", "full detection every cycle (exact queries)"},
             {"time_s", {{"build", build_s}, {"solve", total_s - build_s}, {"total", total_s}}},
             {"status", ok ? "ok" : (prediction.misses > 0 ? "prediction missed a contact"
                                     : prediction.spurious > 0 ? "prediction reported a spurious contact"
                                                               : "a trajectory without contact")}});
        ++done;
        const double elapsed = seconds_since(start);
        const json& full_approach = full["phases"]["approach"];
        const json& predicted_approach = predicted["phases"]["approach"];
        say("[%zu/%zu] %-30s first contact: box %.1f (max %.0f), triangle %.1f, query %.0f ns; approach per cycle: "
            "box tests %.2f with prediction vs %.2f; misses %lld  (elapsed %.1f s)\n",
            done, total_cases, id.c_str(), row["box_tests"]["mean"].is_null() ? 0.0 : row["box_tests"]["mean"].get<double>(),
            row["box_tests"]["max"].is_null() ? 0.0 : row["box_tests"]["max"].get<double>(),
            row["triangle_tests"]["mean"].is_null() ? 0.0 : row["triangle_tests"]["mean"].get<double>(), query_ns,
            predicted_approach["box_tests_per_cycle"].is_null() ? 0.0 : predicted_approach["box_tests_per_cycle"].get<double>(),
            full_approach["box_tests_per_cycle"].is_null() ? 0.0 : full_approach["box_tests_per_cycle"].get<double>(),
            prediction.misses, elapsed);
      }
  }

  // Tremor: the predicted-point error distribution per amplitude, window and sampling period.
  {
    const TremorStudySettings& t = study.tremor;
    const auto found = organ_index.find({t.shape, t.target_triangles});
    std::size_t index = 0;
    if (found != organ_index.end()) {
      index = found->second;
    } else {
      meshes::OrganParameters parameters = study.organs.front();
      parameters.shape = t.shape;
      parameters.target_triangles = t.target_triangles;
      organs.push_back(make_organ(parameters));
      index = organs.size() - 1;
    }
    const Organ& organ = organs[index];
    document["tremor_organ"] = organ.info["id"];
    rc::BvhSettings settings;  // the default tree: the predictor's
    const rc::BoundingVolumeHierarchy bvh(*organ.surface, settings);
    for (const double amplitude : t.amplitudes_m) {
      const auto amplitude_start = std::chrono::steady_clock::now();
      hm::ApproachSettings approach = study.approach;
      approach.start_distance_min_m = t.start_distance_min_m;
      approach.tremor.rms_per_axis_m = amplitude;
      const std::vector<hm::ApproachTrajectory> trajectories =
          make_trajectories(*organ.surface, approach, t.trajectories, t.seed);
      for (const int period : t.sample_period_cycles)
        for (const int m : t.windows) {
          if (m == 1 && period != t.sample_period_cycles.front()) continue;  // eq. 1: the same at any period
          std::vector<double> errors;
          int skipped = 0, no_hit = 0;
          for (const auto& trajectory : trajectories) {
            const double e = predicted_point_error_m(bvh, trajectory, m, period, t.evaluate_at_m);
            if (std::isnan(e)) {
              ++skipped;
              continue;
            }
            no_hit += std::isinf(e);
            errors.push_back(e);
          }
          const json error = distribution(errors);
          const double rate = approach.sample_rate_hz / period;
          const std::string id = "tremor-" + printf_string("%.3gmm", 1e3 * amplitude) + "-m" + std::to_string(m) + "-s" +
                                 std::to_string(period);
          json row{{"id", id},
                   {"organ", organ.info["id"]},
                   {"amplitude_m", amplitude},
                   {"window_samples", m},
                   {"sample_period_cycles", period},
                   {"sample_rate_hz", rate},
                   {"window_s", m / rate},
                   {"filter", m == 1 ? "eq. 1 (last tool path vector)" : "eq. 2 (mean tool path)"},
                   {"trajectories", t.trajectories},
                   {"skipped", skipped},
                   {"no_hit", no_hit},
                   {"error_m", error}};
          document["tremor"].push_back(row);
          json qoi = contract_qoi();
          qoi["predicted_point_error_m"] = error;
          qoi["no_hit"] = no_hit;
          document["cases"].push_back({{"id", id},
                                       {"model", "prediction"},
                                       {"params", {{"organ", organ.info["id"]}, {"amplitude_m", amplitude},
                                                   {"window_samples", m}, {"sample_period_cycles", period},
                                                   {"evaluate_at_m", t.evaluate_at_m}, {"trajectories", t.trajectories}}},
                                       {"qoi", qoi},
                                       {"error", contract_error()},
                                       {"reference", "contact point of the smooth hand motion"},
                                       {"time_s", {{"build", 0.0}, {"solve", 0.0}, {"total", 0.0}}},
                                       {"status", skipped == 0 ? "ok" : "window reaches before the trajectory"}});
        }
      say("tremor %.2f mm: %d trajectories (%.2f s)\n", 1e3 * amplitude, t.trajectories, seconds_since(amplitude_start));
    }
  }

  document["time_s"] = {{"total", seconds_since(start)}};

  // CSV tables.
  {
    std::vector<std::vector<std::string>> rows;
    for (const json& r : document["table1"])
      rows.push_back({r["organ"].get<std::string>(), csv_value(r["triangles"]), r["tree"].get<std::string>(),
                      r["bounding_volume"].get<std::string>(), csv_value(r["depth"]), csv_value(r["binary_depth"]),
                      csv_value(r["paper_overlap_tests"]), csv_value(r["first_contacts"]),
                      csv_value(r["nodes_entered"]["mean"]), csv_value(r["nodes_entered"]["max"]),
                      csv_value(r["box_tests"]["mean"]), csv_value(r["box_tests"]["max"]),
                      csv_value(r["triangle_tests"]["mean"]), csv_value(r["triangle_tests"]["max"]),
                      csv_value(r["query_time_ns"]), csv_value(r["build_ms"])});
    write_file_atomically(options.output_directory + "/table1.csv",
                          write_csv({"organ", "triangles", "tree", "bounding_volume", "depth", "binary_depth", "paper",
                                     "first_contacts", "nodes_entered_mean", "nodes_entered_max", "box_tests_mean",
                                     "box_tests_max", "triangle_tests_mean", "triangle_tests_max", "query_time_ns",
                                     "build_ms"},
                                    rows));
  }
  {
    std::vector<std::vector<std::string>> rows;
    for (const json& r : document["tremor"])
      rows.push_back({r["organ"].get<std::string>(), csv_value(r["amplitude_m"]), csv_value(r["window_samples"]),
                      csv_value(r["sample_period_cycles"]), csv_value(r["window_s"]), csv_value(r["trajectories"]),
                      csv_value(r["no_hit"]), csv_value(r["error_m"]["median"]), csv_value(r["error_m"]["p90"]),
                      csv_value(r["error_m"]["max"]), csv_value(r["error_m"]["mean"])});
    write_file_atomically(options.output_directory + "/tremor.csv",
                          write_csv({"organ", "amplitude_m", "window_samples", "sample_period_cycles", "window_s",
                                     "trajectories", "no_hit", "error_median_m", "error_p90_m", "error_max_m",
                                     "error_mean_hit_m"},
                                    rows));
  }
  {
    std::vector<std::vector<std::string>> rows;
    for (const json& r : document["cycle_cost"])
      for (const char* phase : {"approach", "contact", "release", "all"}) {
        const json& p = r["phases"][phase];
        rows.push_back({r["organ"].get<std::string>(), r["tree"].get<std::string>(), r["bounding_volume"].get<std::string>(),
                        r["mode"].get<std::string>(), phase, csv_value(p["cycles"]), csv_value(p["distances_per_cycle"]),
                        csv_value(p["surface_queries_per_cycle"]), csv_value(p["box_tests_per_cycle"]),
                        csv_value(p["triangle_tests_per_cycle"]), csv_value(p["max_box_tests_in_a_cycle"]),
                        csv_value(p["time_ns"]["mean"]), csv_value(p["time_ns"]["median"]),
                        csv_value(p["time_ns"]["trimmed_mean"]), csv_value(p["time_ns"]["p99"]),
                        csv_value(p["time_ns"]["max"])});
      }
    write_file_atomically(options.output_directory + "/cycle_cost.csv",
                          write_csv({"organ", "tree", "bounding_volume", "mode", "phase", "cycles", "distances_per_cycle",
                                     "surface_queries_per_cycle", "box_tests_per_cycle", "triangle_tests_per_cycle",
                                     "max_box_tests_in_a_cycle", "time_mean_ns", "time_median_ns", "time_trimmed_mean_ns",
                                     "time_p99_ns", "time_max_ns"},
                                    rows));
  }
  write_file_atomically(options.output_directory + "/results.json", document.dump(2) + "\n");
  if (options.report) write_report(options);
  say("done in %.1f s\n", seconds_since(start));
  return document;
}

}  // namespace touchstone::studies
