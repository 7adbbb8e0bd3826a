// The shared measurements of `touchstone collision` (see the header).
#include "collision_measurements.hpp"

#include "touchstone/studies/collision_study.hpp"
#include "touchstone/studies/output_files.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace touchstone::studies {
namespace rc = realtime::collision;
namespace hm = realtime::hand_motion;
using Eigen::Vector3d;
using nlohmann::json;

namespace {
constexpr double infinity = std::numeric_limits<double>::infinity();
}  // namespace

namespace collision {
namespace {
const char* const phase_names[phase_count] = {"approach", "contact", "release"};
}  // namespace

std::string organ_id(const meshes::OrganParameters& organ) {
  return meshes::to_string(organ.shape) + "-" + std::to_string(organ.target_triangles);
}

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


void PhaseCost::add(long long d, long long q, long long b, long long t, double ns) {
  ++cycles;
  distances += d;
  surface_queries += q;
  box_tests += b;
  triangle_tests += t;
  max_box_tests = std::max(max_box_tests, b);
  max_triangle_tests = std::max(max_triangle_tests, t);
  cycle_ns.push_back(ns);
}

void PhaseCost::merge(const PhaseCost& other) {
  cycles += other.cycles;
  distances += other.distances;
  surface_queries += other.surface_queries;
  box_tests += other.box_tests;
  triangle_tests += other.triangle_tests;
  max_box_tests = std::max(max_box_tests, other.max_box_tests);
  max_triangle_tests = std::max(max_triangle_tests, other.max_triangle_tests);
  cycle_ns.insert(cycle_ns.end(), other.cycle_ns.begin(), other.cycle_ns.end());
}

json PhaseCost::to_json() const {
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

}  // namespace collision

// ---------------------------------------------------------------------------------------------
// The public measurements.

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

}  // namespace touchstone::studies
