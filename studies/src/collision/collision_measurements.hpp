#pragma once
// The measurements of `touchstone collision` that its three parts share: the organs and their
// trajectories, full detection every cycle (the Table 1 count), the predictor on the same tip
// positions, the first-contact query time, and distributions of the results.

#include "touchstone/geometry/triangle_surface.hpp"
#include "touchstone/meshes/organ_geometry.hpp"
#include "touchstone/realtime/collision/collision_prediction.hpp"
#include "touchstone/realtime/collision/surface_queries.hpp"
#include "touchstone/realtime/hand_motion/approach_trajectory.hpp"

#include <nlohmann/json.hpp>

#include <chrono>
#include <climits>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace touchstone::studies::collision {

/// "stomach-2500": an organ's id in results.json, the CSV tables and the report.
std::string organ_id(const meshes::OrganParameters& organ);

/// Nearest-rank percentile: the value at round(q (n − 1)) of the sorted list; +∞ entries sort
/// last; NaN when empty.
double percentile_sorted(const std::vector<double>& sorted, double q);

/// {count, mean, trimmed_mean, median, p90, p99, max} of `values` (mean over the finite ones);
/// null entries when empty.
nlohmann::json distribution(std::vector<double> values);

/// {mean, max} of `values`; nulls when empty.
nlohmann::json mean_max(const std::vector<double>& values);

double elapsed_ns(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b);

// ---------------------------------------------------------------------------------------------
// Per-cycle cost, accumulated per phase of the run.

enum Phase { approach_phase, contact_phase, release_phase, phase_count };

struct PhaseCost {
  long long cycles = 0;
  long long distances = 0;        ///< point–point distances (the predictor's ball checks)
  long long surface_queries = 0;  ///< segment, ray, closest-point and inside queries
  long long box_tests = 0;
  long long triangle_tests = 0;
  long long max_box_tests = 0;    ///< in one cycle
  long long max_triangle_tests = 0;
  std::vector<double> cycle_ns;

  void add(long long distances_in_cycle, long long queries, long long boxes, long long triangles, double ns);
  void merge(const PhaseCost& other);
  nlohmann::json to_json() const;
};

/// Each phase's cost and "all" of them.
nlohmann::json phases_json(const PhaseCost (&phases)[phase_count]);

// ---------------------------------------------------------------------------------------------
// One organ: the surface and its trajectories.

struct Organ {
  meshes::OrganParameters parameters;
  std::unique_ptr<geometry::TriangleSurface> surface;
  nlohmann::json info;  ///< id, shape, counts, mesh size and time, area, volume
};

Organ make_organ(const meshes::OrganParameters& parameters);

/// `count` trajectories with seeds seed, seed + 1, …
std::vector<realtime::hand_motion::ApproachTrajectory> make_trajectories(
    const geometry::TriangleSurface& surface, const realtime::hand_motion::ApproachSettings& settings, int count,
    std::uint64_t seed);

// ---------------------------------------------------------------------------------------------
// One (organ, tree) case: full detection every cycle (the Table 1 count at first contact and
// the reference's contacts), then the predictor on the same tip positions, then the time of
// the first-contact query alone.

struct ReferenceRun {
  /// Per trajectory and cycle: the phase, and whether contact began (full detection's answer).
  std::vector<std::vector<std::uint8_t>> phase, began;
  std::vector<double> first_box, first_triangle;  ///< per trajectory with a contact
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> first_segments;
  PhaseCost cost[phase_count];
  long long contacts = 0;
  int without_contact = 0;
};

ReferenceRun run_full_detection(const realtime::collision::SurfaceQueries& tree,
                                const std::vector<realtime::hand_motion::ApproachTrajectory>& trajectories);

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
  realtime::collision::PredictionCounters counters;
};

PredictionRun run_prediction(const realtime::collision::SurfaceQueries& tree,
                             const realtime::collision::PredictionSettings& settings,
                             const std::vector<realtime::hand_motion::ApproachTrajectory>& trajectories,
                             const ReferenceRun& reference);

/// Time of one first-contact query [ns]: after a warm-up pass, the least of three means over
/// repeated passes lasting ≥ min_s / 3 each (the least disturbed on a shared machine).
double first_contact_query_ns(const realtime::collision::SurfaceQueries& tree,
                              const std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>>& segments, double min_s);

}  // namespace touchstone::studies::collision
