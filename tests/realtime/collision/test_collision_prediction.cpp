// Collision prediction (paper §3.1–3.2): eqs. 1–2 by hand, the ring buffer, the
// settings, the certified corridor, and — against full detection run every cycle — that no
// contact is ever missed over thousands of randomized approaches with tremor, on a convex and a
// non-convex surface, at the full and at reduced prediction rates; that a cycle after a
// prediction costs one distance and one comparison and no surface query; and that misses are
// counted when the certificate is wrong (a lying surface). One file, as one source file makes
// the prediction: the randomized approaches and their surfaces serve every case.
//
// Built twice: test_collision_prediction (label fast) and, with TOUCHSTONE_LARGE_TESTS,
// test_collision_prediction_large (label large: five times the trajectories, finer meshes).
#include "brute_force_queries.hpp"

#include "touchstone/realtime/hand_motion/approach_trajectory.hpp"
#include "touchstone/realtime/collision/collision_prediction.hpp"
#include "touchstone/geometry/icosphere.hpp"
#include "touchstone/geometry/triangle_surface.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace touchstone::realtime::collision {
namespace {

using Eigen::Vector3d;
using geometry::TriangleMeshData;
using geometry::TriangleSurface;
using namespace touchstone::realtime::hand_motion;  // the approach paths and tremor fed to the predictor
using testing::BruteForceQueries;
using testing::CountingQueries;

constexpr double pi = 3.14159265358979323846;
constexpr double radius_m = 0.05;

#ifdef TOUCHSTONE_LARGE_TESTS
constexpr int scale = 5;
constexpr int sphere_level = 3;
constexpr int fused_level = 4;
#else
constexpr int scale = 1;
constexpr int sphere_level = 2;
constexpr int fused_level = 3;
#endif

/// Two overlapping spheres (centres ±20 mm on x, radius 30 mm: a concave waist of radius
/// 22 mm) with two Gaussian dimples pressed into one lobe: the icosphere's directions scaled
/// to the star-shaped union, so the mesh stays closed and consistently oriented.
TriangleMeshData fused_spheres_with_dimples(int level) {
  TriangleMeshData mesh = geometry::icosphere(level, 1.0);
  const double offset = 0.020, lobe = 0.030;
  const std::vector<std::pair<Vector3d, double>> dimples = {{Vector3d(0.5, 0.8, 0.3).normalized(), 0.25},
                                                            {Vector3d(0.7, -0.2, 0.7).normalized(), 0.2}};
  for (Vector3d& u : mesh.vertices) {
    double r = 0;
    for (const double side : {-1.0, 1.0}) {
      const double along = side * offset * u.x();
      r = std::max(r, along + std::sqrt(along * along - offset * offset + lobe * lobe));
    }
    for (const auto& [axis, depth] : dimples) {
      const double angle = std::acos(std::clamp(u.dot(axis), -1.0, 1.0));
      r *= 1 - depth * std::exp(-angle * angle / (0.25 * 0.25));
    }
    u *= r;
  }
  return mesh;
}

struct Scene {
  std::string name;
  std::unique_ptr<TriangleSurface> surface;
  std::unique_ptr<BruteForceQueries> queries;
};

Scene make_scene(const std::string& name, const TriangleMeshData& mesh) {
  Scene scene;
  scene.name = name;
  scene.surface = std::make_unique<TriangleSurface>(mesh.vertices, mesh.triangles, name);
  scene.queries = std::make_unique<BruteForceQueries>(*scene.surface);
  return scene;
}

const Scene& icosphere_scene() {
  static const Scene scene = make_scene("icosphere", geometry::icosphere(sphere_level, radius_m));
  return scene;
}

const Scene& fused_scene() {
  static const Scene scene = make_scene("fused spheres with dimples", fused_spheres_with_dimples(fused_level));
  return scene;
}

/// Full detection every cycle, written independently of the library's reference.
class Oracle {
 public:
  explicit Oracle(const SurfaceQueries& queries) : queries_(queries) {}
  bool step(const Vector3d& p, SurfaceHit& hit) {
    bool began = false;
    if (!started_) {
      started_ = true;
      inside_ = queries_.contains(p);
      began = inside_;
    } else if (!inside_) {
      hit = queries_.first_hit_segment(previous_, p);
      if (hit.hit) inside_ = began = true;
    } else if (!queries_.contains(p)) {
      inside_ = false;
    }
    previous_ = p;
    return began;
  }

 private:
  const SurfaceQueries& queries_;
  Vector3d previous_ = Vector3d::Zero();
  bool started_ = false;
  bool inside_ = false;
};

const char* name(PredictionStatus status) {
  switch (status) {
    case PredictionStatus::free: return "free";
    case PredictionStatus::corridor_advance: return "corridor_advance";
    case PredictionStatus::deferral_start: return "deferral_start";
    case PredictionStatus::deferred: return "deferred";
    case PredictionStatus::predicted: return "predicted";
    case PredictionStatus::repredicted: return "repredicted";
    case PredictionStatus::handover: return "handover";
    case PredictionStatus::full_detection: return "full_detection";
    case PredictionStatus::contact: return "contact";
    case PredictionStatus::in_contact: return "in_contact";
    case PredictionStatus::released: return "released";
    case PredictionStatus::invalid_input: return "invalid_input";
  }
  return "?";
}

/// What a sweep of trajectories did, summed.
struct Tally {
  long long trajectories = 0;
  long long cycles = 0;
  long long contacts = 0;          ///< oracle
  long long misses = 0;            ///< oracle contact began, predictor did not report it
  long long spurious = 0;          ///< predictor reported a contact the oracle did not
  long long hit_mismatches = 0;    ///< same cycle, different first hit
  long long approach_cycles = 0;   ///< cycles before each trajectory's first contact
  long long approach_cheap = 0;    ///< … decided by one distance + one comparison
  long long off_schedule_prediction_queries = 0;  ///< closest/ray calls on non-detection cycles
  long long forced_cycles = 0;
  std::map<std::string, long long> statuses;
  std::map<std::string, long long> miss_statuses;
  PredictionCounters counters;     ///< summed
};

void add(PredictionCounters& total, const PredictionCounters& c) {
  total.cycles += c.cycles;
  total.cheap_checks += c.cheap_checks;
  total.cheap_distances += c.cheap_distances;
  total.corridor_advances += c.corridor_advances;
  total.predictions += c.predictions;
  total.repredictions_direction += c.repredictions_direction;
  total.repredictions_retreat += c.repredictions_retreat;
  total.repredictions_range += c.repredictions_range;
  total.repredictions_ball_exit += c.repredictions_ball_exit;
  total.handovers += c.handovers;
  total.deferrals += c.deferrals;
  total.forced_predictions += c.forced_predictions;
  total.full_detections += c.full_detections;
  total.certified_steps += c.certified_steps;
  total.contact_checks += c.contact_checks;
  total.closest_point_queries += c.closest_point_queries;
  total.ray_casts += c.ray_casts;
  total.contacts += c.contacts;
  total.releases += c.releases;
  total.audited_contacts += c.audited_contacts;
  total.misses_cheap_check += c.misses_cheap_check;
  total.misses_deferred += c.misses_deferred;
  total.misses_other += c.misses_other;
  total.spurious_contacts += c.spurious_contacts;
}

/// Runs the predictor and the oracle side by side over one trajectory.
void run(const SurfaceQueries& queries, const PredictionSettings& settings, const std::vector<Vector3d>& tip,
         Tally& tally) {
  CountingQueries counting(queries);
  auto predictor = std::make_unique<CollisionPredictor>(counting, settings);
  Oracle oracle(queries);
  bool touched = false;
  for (std::size_t k = 0; k < tip.size(); ++k) {
    const long long before = counting.closest_calls + counting.ray_calls;
    const PredictionStep out = predictor->step(tip[k]);
    SurfaceHit hit;
    const bool began = oracle.step(tip[k], hit);
    const bool reported = out.status == PredictionStatus::contact;
    ++tally.statuses[name(out.status)];
    if (began) ++tally.contacts;
    if (began && !reported) {
      ++tally.misses;
      ++tally.miss_statuses[name(out.status)];
    }
    if (!began && reported) ++tally.spurious;
    if (began && reported && (hit.triangle != out.hit.triangle || hit.distance_m != out.hit.distance_m))
      ++tally.hit_mismatches;
    if (out.forced) ++tally.forced_cycles;
    if (static_cast<long long>(k) % settings.detection_period_cycles != 0 && !out.forced)
      tally.off_schedule_prediction_queries += counting.closest_calls + counting.ray_calls - before;
    if (began) touched = true;
    if (!touched) {
      ++tally.approach_cycles;
      if (out.status == PredictionStatus::free || out.status == PredictionStatus::deferred) ++tally.approach_cheap;
    }
  }
  ++tally.trajectories;
  tally.cycles += static_cast<long long>(tip.size());
  add(tally.counters, predictor->counters());
}

void print(const std::string& title, const Tally& t) {
  const double n = static_cast<double>(std::max(1LL, t.trajectories));
  const PredictionCounters& c = t.counters;
  std::printf("%s: %lld trajectories, %lld cycles, %lld contacts, %lld misses, %lld spurious\n", title.c_str(),
              t.trajectories, t.cycles, t.contacts, t.misses, t.spurious);
  std::printf("  before first contact: %.1f%% of cycles one distance + one comparison\n",
              100.0 * t.approach_cheap / std::max(1LL, t.approach_cycles));
  std::printf("  per trajectory: predictions %.2f, re-predictions %.2f (direction %.2f, retreat %.2f, range %.2f, "
              "ball exit %.2f), handovers %.2f\n",
              c.predictions / n, c.repredictions() / n, c.repredictions_direction / n, c.repredictions_retreat / n,
              c.repredictions_range / n, c.repredictions_ball_exit / n, c.handovers / n);
  std::printf("  per trajectory: closest-point queries %.1f, ray casts %.2f, segment queries %.1f, contains %.1f, "
              "corridor advances %.2f, deferrals %.2f, forced %.2f\n",
              c.closest_point_queries / n, c.ray_casts / n, c.full_detections / n, c.contact_checks / n,
              c.corridor_advances / n, c.deferrals / n, c.forced_predictions / n);
  std::printf("  statuses:");
  for (const auto& [status, count] : t.statuses) std::printf(" %s %.1f%%", status.c_str(), 100.0 * count / t.cycles);
  std::printf("\n");
}

ApproachSettings tremor_approach(double tremor_rms_m) {
  ApproachSettings settings;
  settings.tremor.rms_per_axis_m = tremor_rms_m;
  return settings;
}

Tally sweep(const Scene& scene, const PredictionSettings& settings, const ApproachSettings& approach, int count,
            std::uint64_t first_seed) {
  const ApproachTrajectoryGenerator generator(*scene.surface, approach);
  Tally tally;
  for (int i = 0; i < count; ++i) run(*scene.queries, settings, generator.generate(first_seed + i).tip, tally);
  return tally;
}

void expect_no_miss(const Tally& t) {
  EXPECT_GT(t.contacts, 0);
  EXPECT_EQ(t.misses, 0);
  for (const auto& [status, count] : t.miss_statuses) ADD_FAILURE() << count << " misses in " << status << " cycles";
  EXPECT_EQ(t.spurious, 0);
  EXPECT_EQ(t.hit_mismatches, 0);
  EXPECT_EQ(t.counters.contacts, t.contacts);
}

/// A straight minimum-jerk path from `from` to `to` over `seconds` after `rest` cycles at rest.
[[maybe_unused]] std::vector<Vector3d> straight_path(const Vector3d& from, const Vector3d& to, double seconds, int rest = 300) {
  std::vector<Vector3d> path(rest, from);
  const int n = static_cast<int>(seconds * 1000);
  for (int k = 1; k <= n; ++k) path.push_back(from + minimum_jerk(static_cast<double>(k) / n) * (to - from));
  return path;
}

#ifndef TOUCHSTONE_LARGE_TESTS

// ---------------------------------------------------------------------------------------------
// Eqs. 1–2 and the ring buffer

TEST(ToolPathHistory, EquationsOneAndTwoByHand) {
  ToolPathHistory history(3);
  EXPECT_EQ(history.mean_tool_path(Vector3d(1, 2, 3)), Vector3d::Zero());
  history.push({0, 0, 0});
  history.push({1, 0, 0});
  const Vector3d current(4, 1, 1);
  // Two held: ((4,1,1) − (1,0,0) + (4,1,1) − (0,0,0)) / 2.
  EXPECT_TRUE(history.mean_tool_path(current).isApprox(Vector3d(3.5, 1, 1)));
  history.push({2, 1, 0});
  ASSERT_EQ(history.size(), 3);
  EXPECT_EQ(history.previous(1), Vector3d(2, 1, 0));
  EXPECT_EQ(history.previous(3), Vector3d(0, 0, 0));
  // Eq. 1: P_current − P_previous.
  EXPECT_EQ(tool_path_vector(current, history.previous(1)), Vector3d(2, 0, 1));
  // Eq. 2: ((2,0,1) + (3,1,1) + (4,1,1)) / 3 = (3, 2/3, 1).
  const Vector3d mean = history.mean_tool_path(current);
  EXPECT_NEAR(mean.x(), 3.0, 1e-15);
  EXPECT_NEAR(mean.y(), 2.0 / 3.0, 1e-15);
  EXPECT_NEAR(mean.z(), 1.0, 1e-15);
}

TEST(ToolPathHistory, RingWrapsAround) {
  ToolPathHistory history(4);
  for (int k = 1; k <= 11; ++k) history.push({static_cast<double>(k), 0, 0});
  EXPECT_EQ(history.size(), 4);
  for (int i = 1; i <= 4; ++i) EXPECT_EQ(history.previous(i).x(), 11 - (i - 1));
  // (1 + 2 + 3 + 4) / 4 from the current x = 12.
  EXPECT_DOUBLE_EQ(history.mean_tool_path({12, 0, 0}).x(), 2.5);

  ToolPathHistory longest(max_window_samples);
  for (int k = 1; k <= 1000; ++k) longest.push({static_cast<double>(k), 0, 0});
  EXPECT_EQ(longest.size(), max_window_samples);
  EXPECT_EQ(longest.previous(1).x(), 1000);
  EXPECT_EQ(longest.previous(max_window_samples).x(), 1000 - max_window_samples + 1);

  history.clear();
  EXPECT_EQ(history.size(), 0);
  history.push({5, 0, 0});
  EXPECT_EQ(history.previous(1).x(), 5);
}

TEST(ToolPathHistory, WindowOfOneIsTheToolPathVectorAndConstantVelocityScalesByHalfTheWindow) {
  ToolPathHistory one(1);
  one.push({1, 2, 3});
  one.push({2, 2, 3});
  EXPECT_EQ(one.mean_tool_path({4, 4, 4}), tool_path_vector({4, 4, 4}, {2, 2, 3}));

  // Constant velocity v sampled every Δt, newest sample one Δt old: P̄ = v Δt (m + 1) / 2.
  const int m = 7;
  ToolPathHistory history(m);
  const Vector3d velocity_step(0.001, -0.002, 0.0005);
  for (int k = 0; k < 20; ++k) history.push(k * velocity_step);
  EXPECT_TRUE(history.mean_tool_path(20 * velocity_step).isApprox(velocity_step * (m + 1) / 2.0, 1e-12));
}

TEST(PredictionSettings, ValidateNamesTheField) {
  EXPECT_NO_THROW(PredictionSettings{}.validate());
  const std::vector<std::pair<std::string, std::function<void(PredictionSettings&)>>> cases = {
      {"window_samples", [](PredictionSettings& s) { s.window_samples = 0; }},
      {"window_samples", [](PredictionSettings& s) { s.window_samples = max_window_samples + 1; }},
      {"sample_period_cycles", [](PredictionSettings& s) { s.sample_period_cycles = 0; }},
      {"straight_line_range_m", [](PredictionSettings& s) { s.straight_line_range_m = -1; }},
      {"direction_threshold_rad", [](PredictionSettings& s) { s.direction_threshold_rad = 4; }},
      {"margin_m", [](PredictionSettings& s) { s.margin_m = std::numeric_limits<double>::quiet_NaN(); }},
      {"handover_distance_m", [](PredictionSettings& s) { s.handover_distance_m = 0; }},
      {"near_exit_distance_m", [](PredictionSettings& s) { s.near_exit_distance_m = 0; }},
      {"corridor_step_fraction", [](PredictionSettings& s) { s.corridor_step_fraction = 1.5; }},
      {"corridor_balls", [](PredictionSettings& s) { s.corridor_balls = max_corridor_balls + 1; }},
      {"ray_max_distance_m", [](PredictionSettings& s) { s.ray_max_distance_m = 0.001; }},
      {"min_path_length_m", [](PredictionSettings& s) { s.min_path_length_m = -1; }},
      {"detection_period_cycles", [](PredictionSettings& s) { s.detection_period_cycles = 0; }},
      {"max_tip_speed_m_per_s", [](PredictionSettings& s) { s.max_tip_speed_m_per_s = 0; }},
      {"cycle_period_s", [](PredictionSettings& s) { s.cycle_period_s = std::numeric_limits<double>::infinity(); }},
      {"direction_check_period_cycles", [](PredictionSettings& s) {
         s.detection_period_cycles = 4;
         s.direction_check_period_cycles = 10;
       }},
  };
  for (const auto& [field, mutate] : cases) {
    PredictionSettings settings;
    mutate(settings);
    try {
      settings.validate();
      ADD_FAILURE() << field << ": no exception";
    } catch (const std::invalid_argument& error) {
      EXPECT_NE(std::string(error.what()).find("PredictionSettings." + field), std::string::npos) << error.what();
    }
  }
  PredictionSettings bad;
  bad.window_samples = 0;
  EXPECT_THROW(CollisionPredictor(*icosphere_scene().queries, bad), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// The brute-force reference itself

TEST(BruteForceQueries, AgreeWithTheSurfaceAndTheSphere) {
  const Scene& scene = icosphere_scene();
  double inscribed = radius_m;
  for (const Eigen::Vector3i& t : scene.surface->triangles()) {
    const Vector3d& a = scene.surface->vertices()[t[0]];
    const Vector3d normal = (scene.surface->vertices()[t[1]] - a).cross(scene.surface->vertices()[t[2]] - a).normalized();
    inscribed = std::min(inscribed, normal.dot(a));
  }
  RandomStream random(7);
  QueryCounters counters;
  for (int i = 0; i < 200; ++i) {
    const Vector3d direction = Vector3d(random.gaussian(), random.gaussian(), random.gaussian()).normalized();
    // A ray from 2R toward the centre meets the polyhedron between the inscribed and the
    // circumscribed sphere; its first hit is outward-facing and on the surface.
    const SurfaceHit hit = scene.queries->first_hit_ray(2 * radius_m * direction, -direction, 2 * radius_m, &counters);
    ASSERT_TRUE(hit.hit);
    EXPECT_LE(hit.point.norm(), radius_m * (1 + 1e-12));
    EXPECT_GE(hit.point.norm(), inscribed * (1 - 1e-12));
    EXPECT_GT(hit.normal.dot(direction), 0);
    EXPECT_NEAR(scene.surface->project(hit.point).distance_m, 0, 1e-12);
    // The same as a segment, and the closest point as the surface's own (AABB tree) projection.
    const SurfaceHit segment = scene.queries->first_hit_segment(2 * radius_m * direction, Vector3d::Zero());
    EXPECT_EQ(segment.triangle, hit.triangle);
    EXPECT_NEAR(segment.distance_m, hit.distance_m, 1e-12);
    const Vector3d x = 1.5 * radius_m * Vector3d(random.uniform() - 0.5, random.uniform() - 0.5, random.uniform() - 0.5);
    EXPECT_NEAR(scene.queries->closest_point(x, &counters).distance_m, scene.surface->project(x).distance_m, 1e-15);
  }
  EXPECT_EQ(counters.queries, 400);
  EXPECT_GT(counters.triangle_tests, 0);
  EXPECT_GT(counters.box_tests, counters.triangle_tests);
  EXPECT_FALSE(scene.queries->first_hit_segment({0, 0, 2 * radius_m}, {0, radius_m, 2 * radius_m}).hit);
}

// ---------------------------------------------------------------------------------------------
// One approach, step by step

TEST(CollisionPrediction, HeadOnApproachPredictsThePointAndHandsOverJustBeforeContact) {
  const Scene& scene = icosphere_scene();
  // Toward a point that is no vertex or edge of the mesh, along its normal.
  const Vector3d towards = Vector3d(0.13, 0.21, 1).normalized();
  const SurfaceHit surface_point = scene.queries->first_hit_ray(2 * radius_m * towards, -towards, 2 * radius_m);
  ASSERT_TRUE(surface_point.hit);
  const Vector3d normal = surface_point.normal;
  const Vector3d target = surface_point.point;
  const std::vector<Vector3d> path = straight_path(target + 0.02 * normal, target - 0.003 * normal, 1.0);

  CountingQueries counting(*scene.queries);
  PredictionSettings settings;
  settings.audit = true;
  CollisionPredictor predictor(counting, settings);
  Oracle oracle(*scene.queries);
  std::map<std::string, int> statuses;
  int contact_cycle = -1, oracle_cycle = -1, in_range_cycle = -1;
  for (int k = 0; k < static_cast<int>(path.size()); ++k) {
    const PredictionStep out = predictor.step(path[k]);
    SurfaceHit hit;
    if (oracle.step(path[k], hit) && oracle_cycle < 0) oracle_cycle = k;
    if (contact_cycle < 0) ++statuses[name(out.status)];
    if (k == 0) {
      EXPECT_EQ(out.status, PredictionStatus::predicted);
    }
    if (out.status == PredictionStatus::repredicted && predictor.prediction().in_range && in_range_cycle < 0) {
      in_range_cycle = k;
      EXPECT_EQ(out.cause, RepredictionCause::out_of_range);
      // Straight motion: the predicted point is where the path meets the surface.
      EXPECT_LT((predictor.prediction().point - target).norm(), 1e-9);
      EXPECT_LT(predictor.prediction().path_distance_m, settings.straight_line_range_m);
      EXPECT_GT(predictor.prediction().time_to_contact_s, 0.01);
    }
    if (out.status == PredictionStatus::contact && contact_cycle < 0) {
      contact_cycle = k;
      EXPECT_LT((out.hit.point - target).norm(), 1e-9);
    }
  }
  EXPECT_EQ(contact_cycle, oracle_cycle);
  EXPECT_GT(in_range_cycle, 0);
  EXPECT_EQ(predictor.counters().misses(), 0);
  EXPECT_EQ(predictor.counters().audited_contacts, 1);
  for (const auto& [status, count] : statuses) std::printf("  %s: %d cycles\n", status.c_str(), count);
  // Before contact: one prediction at the start, one entering the straight-line range, a
  // hand-over near the surface, the rest one distance + one comparison.
  EXPECT_EQ(statuses["predicted"], 1);
  EXPECT_EQ(statuses["repredicted"], 1);
  EXPECT_EQ(statuses["handover"], 1);
  EXPECT_GT(statuses["free"], 0.97 * contact_cycle);
  EXPECT_LT(statuses["full_detection"], 0.03 * contact_cycle);
}

TEST(CollisionPrediction, FreeCyclesCostOneDistanceOneComparisonAndNoSurfaceQuery) {
  const Scene& scene = icosphere_scene();
  const ApproachTrajectoryGenerator generator(*scene.surface, tremor_approach(2e-4));
  for (const int period : {1, 5}) {
    PredictionSettings settings;
    settings.detection_period_cycles = period;
    long long free = 0, deferred = 0, approach = 0, cheap_approach = 0;
    for (std::uint64_t seed = 1; seed <= 20; ++seed) {
      const ApproachTrajectory trajectory = generator.generate(seed);
      CountingQueries counting(*scene.queries);
      CollisionPredictor predictor(counting, settings);
      bool touched = false;
      for (const Vector3d& p : trajectory.tip) {
        const long long calls = counting.calls();
        const QueryCounters work = counting.work;
        const PredictionCounters before = predictor.counters();
        const PredictionStep out = predictor.step(p);
        const PredictionCounters& after = predictor.counters();
        touched = touched || out.status == PredictionStatus::contact;
        if (!touched) {
          ++approach;
          if (out.status == PredictionStatus::free || out.status == PredictionStatus::deferred) ++cheap_approach;
        }
        if (out.status == PredictionStatus::corridor_advance || out.status == PredictionStatus::deferral_start) {
          // Passing between balls: more distances, still no query.
          ASSERT_EQ(counting.calls(), calls) << name(out.status);
          ASSERT_GE(after.cheap_distances - before.cheap_distances, 2);
          continue;
        }
        if (out.status != PredictionStatus::free && out.status != PredictionStatus::deferred) continue;
        (out.status == PredictionStatus::free ? free : deferred) += 1;
        ASSERT_EQ(counting.calls(), calls) << name(out.status);
        ASSERT_EQ(counting.work.box_tests, work.box_tests);
        ASSERT_EQ(counting.work.triangle_tests, work.triangle_tests);
        ASSERT_EQ(after.cheap_distances - before.cheap_distances, 1);
        ASSERT_EQ(after.cheap_checks - before.cheap_checks, 1);
      }
    }
    std::printf("N = %d: %lld free and %lld deferred cycles, each 1 distance + 1 comparison and no query; "
                "%.1f%% of the approach cycles\n",
                period, free, deferred, 100.0 * cheap_approach / approach);
    EXPECT_GT(cheap_approach, (period == 1 ? 0.9 : 0.8) * approach);
    if (period > 1) {
      EXPECT_GT(deferred, 0);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Never a miss

#endif  // !TOUCHSTONE_LARGE_TESTS

#ifdef TOUCHSTONE_LARGE_TESTS
#define PREDICTION_SWEEP CollisionPredictionLarge
#else
#define PREDICTION_SWEEP CollisionPrediction
#endif

TEST(PREDICTION_SWEEP, NeverMissesOnAnIcosphereWithTremor) {
  PredictionSettings settings;
  settings.audit = true;
  const Tally tally = sweep(icosphere_scene(), settings, tremor_approach(2e-4), 1000 * scale, 1000);
  print("icosphere (level " + std::to_string(sphere_level) + "), tremor 0.2 mm per axis", tally);
  expect_no_miss(tally);
  EXPECT_EQ(tally.counters.misses(), 0);
  EXPECT_EQ(tally.counters.spurious_contacts, 0);
  EXPECT_EQ(tally.counters.audited_contacts, tally.contacts);
  EXPECT_GT(tally.approach_cheap, 0.9 * tally.approach_cycles);
}

TEST(PREDICTION_SWEEP, NeverMissesOnFusedSpheresWithDimples) {
  PredictionSettings settings;
  ApproachSettings approach = tremor_approach(3e-4);
  approach.max_approach_angle_rad = 1.3;  // grazing approaches too
  const Tally tally = sweep(fused_scene(), settings, approach, 500 * scale, 5000);
  print(fused_scene().name + ", tremor 0.3 mm per axis", tally);
  expect_no_miss(tally);
  EXPECT_GT(tally.approach_cheap, 0.8 * tally.approach_cycles);
}

TEST(PREDICTION_SWEEP, ReducedPredictionRateNeverMissesAndQueriesOnlyOnDetectionCycles) {
  // The paper's "another advantage": prediction's queries at a lower rate than the haptic loop.
  // Cost: check radii shrink by N·v_max·Δt, so the full-detection zone widens; saving: every
  // prediction query lands on a detection cycle (schedulable in a slower thread).
  ApproachSettings approach = tremor_approach(2e-4);
  approach.max_approach_angle_rad = 1.2;
  std::printf("%-4s %10s %10s %12s %12s %10s %8s\n", "N", "cheap %", "closest/tr", "ray/tr", "segment/tr",
              "deferred/tr", "forced");
  for (const int period : {1, 2, 5, 10}) {
    PredictionSettings settings;
    settings.detection_period_cycles = period;
    for (const Scene* scene : {&icosphere_scene(), &fused_scene()}) {
      const Tally tally = sweep(*scene, settings, approach, 80 * scale, 9000);
      const double n = static_cast<double>(tally.trajectories);
      std::printf("%-4d %10.1f %10.1f %12.2f %12.1f %10.2f %8lld  (%s)\n", period,
                  100.0 * tally.approach_cheap / tally.approach_cycles, tally.counters.closest_point_queries / n,
                  tally.counters.ray_casts / n, tally.counters.full_detections / n, tally.counters.deferrals / n,
                  tally.counters.forced_predictions, scene->name.c_str());
      expect_no_miss(tally);
      // Hand speeds stay below the 0.25 m/s bound: nothing forced, nothing off-schedule.
      EXPECT_EQ(tally.counters.forced_predictions, 0);
      EXPECT_EQ(tally.off_schedule_prediction_queries, 0);
    }
  }
}

TEST(PREDICTION_SWEEP, NeverMissesWithLargeStepsAndSharpTurns) {
  // Random walks of 0.05–1.5 mm steps (up to 1.5 m/s), drifting toward the non-convex surface
  // and turning at random: tip steps far beyond the margin, between corridor balls, across the
  // straight-line range, in and out of contact.
  const Scene& scene = fused_scene();
  for (const int period : {1, 5}) {
    PredictionSettings settings;
    settings.detection_period_cycles = period;
    settings.audit = true;
    Tally tally;
    RandomStream random(17 + period);
    for (int walk = 0; walk < 150 * scale; ++walk) {
      const Vector3d towards = Vector3d(random.gaussian(), random.gaussian(), random.gaussian()).normalized();
      std::vector<Vector3d> path = {0.065 * towards};
      Vector3d heading = -towards;
      for (int k = 0; k < 400; ++k) {
        const Vector3d turn(random.gaussian(), random.gaussian(), random.gaussian());
        heading = (heading + 0.3 * turn - 0.05 * path.back().normalized()).normalized();
        const double step = random.uniform() < 0.1 ? 1.5e-3 * random.uniform() : 5e-5 + 3e-4 * random.uniform();
        path.push_back(path.back() + step * heading);
      }
      run(*scene.queries, settings, path, tally);
    }
    print("random walks with large steps, N = " + std::to_string(period), tally);
    expect_no_miss(tally);
    EXPECT_EQ(tally.counters.misses(), 0);
    EXPECT_GT(tally.counters.corridor_advances, 0);
  }
}

#ifndef TOUCHSTONE_LARGE_TESTS

TEST(CollisionPrediction, ViolatedSpeedBoundForcesAPredictionAndStillNeverMisses) {
  // 1 m/s (1 mm per cycle) against a 0.25 m/s bound at N = 10: the tip leaves certified radii
  // between detection cycles; predictions are forced there and counted.
  const Scene& scene = icosphere_scene();
  PredictionSettings settings;
  settings.detection_period_cycles = 10;
  Tally tally;
  RandomStream random(3);
  for (int i = 0; i < 50; ++i) {
    const Vector3d towards = Vector3d(random.gaussian(), random.gaussian(), random.gaussian()).normalized();
    const Vector3d sideways = towards.unitOrthogonal() * 0.01 * (random.uniform() - 0.5);
    std::vector<Vector3d> path(50, towards * (radius_m + 0.03));
    for (int k = 1; k <= 40; ++k) path.push_back(towards * (radius_m + 0.03 - 0.001 * k) + sideways * k / 40.0);
    run(*scene.queries, settings, path, tally);
  }
  print("1 m/s approaches, N = 10", tally);
  expect_no_miss(tally);
  EXPECT_EQ(tally.contacts, 50);
  EXPECT_GT(tally.counters.forced_predictions, 0);
  EXPECT_EQ(tally.forced_cycles, tally.counters.forced_predictions);
}

/// The half-space z < 0 plus a small ball (an obstacle that can be switched on), answered
/// analytically; logs the points of its closest-point queries.
class FloorWithObstacle final : public SurfaceQueries {
 public:
  Vector3d obstacle = Vector3d::Zero();
  double obstacle_radius = 0;  ///< 0: no obstacle
  mutable std::vector<Vector3d> closest_queries;

  SurfaceHit first_hit_segment(const Vector3d& a, const Vector3d& b, QueryCounters* = nullptr) const noexcept override {
    SurfaceHit hit = first_hit_ray(a, (b - a).normalized(), (b - a).norm());
    return hit;
  }
  SurfaceHit first_hit_ray(const Vector3d& o, const Vector3d& d, double max, QueryCounters* = nullptr) const noexcept override {
    SurfaceHit hit;
    const auto take = [&](double t, const Vector3d& normal) {
      if (t >= 0 && t <= max && (!hit.hit || t < hit.distance_m)) hit = {true, t, o + t * d, normal, 0};
    };
    if (o.z() >= 0 && d.z() < 0) take(-o.z() / d.z(), Vector3d::UnitZ());
    if (obstacle_radius > 0) {
      const Vector3d m = o - obstacle;
      const double b = m.dot(d), c = m.squaredNorm() - obstacle_radius * obstacle_radius;
      if (c > 0 && b < 0 && b * b >= c) {
        const double t = -b - std::sqrt(b * b - c);
        take(t, (o + t * d - obstacle).normalized());
      }
    }
    return hit;
  }
  ClosestSurfacePoint closest_point(const Vector3d& x, QueryCounters* = nullptr) const noexcept override {
    closest_queries.push_back(x);
    ClosestSurfacePoint closest{Vector3d(x.x(), x.y(), 0), std::abs(x.z()), 0};
    if (obstacle_radius > 0 && (x - obstacle).norm() - obstacle_radius < closest.distance_m) {
      closest.distance_m = (x - obstacle).norm() - obstacle_radius;
      closest.point = obstacle + obstacle_radius * (x - obstacle).normalized();
    }
    return closest;
  }
  bool contains(const Vector3d& x, QueryCounters* = nullptr) const noexcept override {
    return x.z() < 0 || (obstacle_radius > 0 && (x - obstacle).norm() < obstacle_radius);
  }
};

TEST(CollisionPrediction, AStepBetweenCorridorBallsIsCheckedAsAWhole) {
  // Two overlapping certified balls leave a notch outside both along their crease. A fast step
  // from the first ball into the second can cross that notch; an obstacle placed there (no
  // nearer to any point the predictor queried than the floor, so the corridor is the same)
  // must be detected. Both ends of a step must lie in the ball the tip advances into.
  FloorWithObstacle floor;
  const PredictionSettings settings;
  const Vector3d u = Vector3d(std::sin(1.05), 0, -std::cos(1.05));  // 60° from the normal
  const Vector3d start(0, 0, 0.02);
  std::vector<Vector3d> approach;
  for (int k = 0; k < 2000 && (start + 5e-5 * k * u).z() > 0.002; ++k) approach.push_back(start + 5e-5 * k * u);

  // Without the obstacle: where the corridor is built.
  const auto run_until_corridor = [&](CollisionPredictor& predictor) {
    for (std::size_t k = 0; k < approach.size(); ++k) {
      predictor.step(approach[k]);
      if (predictor.phase() == PredictorPhase::corridor && predictor.prediction().in_range &&
          predictor.corridor().size >= 2)
        return static_cast<int>(k);
    }
    return -1;
  };
  CollisionPredictor first(floor, settings);
  const int built = run_until_corridor(first);
  ASSERT_GT(built, 0);
  const CertifiedBall b0 = first.corridor().balls[0], b1 = first.corridor().balls[1];
  const double r0 = std::sqrt(b0.check_radius2_m2), r1 = std::sqrt(b1.check_radius2_m2);

  // The lowest point K of the crease, the tangents there away from the other ball, and a
  // step q → p across the notch whose middle is the obstacle.
  const Vector3d w = u.cross(Vector3d::UnitY()).normalized().dot(Vector3d::UnitZ()) > 0
                         ? Vector3d(u.cross(Vector3d::UnitY()).normalized())
                         : Vector3d(-u.cross(Vector3d::UnitY()).normalized());  // ⟂ u, upward
  const double s1 = (b1.centre - b0.centre).norm();
  const double x = (r0 * r0 - r1 * r1 + s1 * s1) / (2 * s1);
  const Vector3d crease = b0.centre + x * u - std::sqrt(r0 * r0 - x * x) * w;
  const auto tangent_away = [&](const Vector3d& centre, const Vector3d& other) {
    const Vector3d radial = (crease - centre).normalized();
    Vector3d t = (other - centre).cross(radial).cross(radial).normalized();  // in the plane, ⟂ radial
    if (t.dot(other - crease) > 0) t = -t;
    return t;
  };
  const double reach = 6e-4;
  const auto on_sphere = [&](const Vector3d& centre, double radius, const Vector3d& towards) {
    return Vector3d(centre + (radius - 1e-5) * (towards - centre).normalized());
  };
  const Vector3d q = on_sphere(b0.centre, r0, crease + reach * tangent_away(b0.centre, b1.centre));
  const Vector3d p = on_sphere(b1.centre, r1, crease + reach * tangent_away(b1.centre, b0.centre));
  ASSERT_LT((q - b0.centre).norm(), r0);
  ASSERT_GT((q - b1.centre).norm(), r1);
  ASSERT_LT((p - b1.centre).norm(), r1);
  ASSERT_GT((p - b0.centre).norm(), r0);
  floor.obstacle = 0.5 * (q + p);
  floor.obstacle_radius = 2e-5;
  ASSERT_GT(floor.obstacle.z(), floor.obstacle_radius);
  // The obstacle is farther than the floor from every point the predictor queried.
  for (const Vector3d& queried : floor.closest_queries)
    ASSERT_GT((queried - floor.obstacle).norm() - floor.obstacle_radius, queried.z());
  floor.closest_queries.clear();

  // With the obstacle: the same corridor; walk to q inside ball 0, then jump to p.
  CollisionPredictor predictor(floor, settings);
  ASSERT_EQ(run_until_corridor(predictor), built);
  ASSERT_EQ(predictor.corridor().size, first.corridor().size);
  const Vector3d from = approach[built];
  for (int k = 1; k <= 20; ++k) {
    const PredictionStep out = predictor.step(from + (q - from) * k / 20.0);
    ASSERT_EQ(out.status, PredictionStatus::free) << k;
  }
  Oracle oracle(floor);
  SurfaceHit hit;
  oracle.step(q, hit);
  ASSERT_TRUE(oracle.step(p, hit));  // the step crosses the obstacle
  const PredictionStep jump = predictor.step(p);
  EXPECT_EQ(jump.status, PredictionStatus::contact);
  EXPECT_LT((jump.hit.point - floor.obstacle).norm(), 1.01 * floor.obstacle_radius);
}

TEST(CollisionPrediction, AuditCountsTheMissesOfAWrongCertificate) {
  // A surface whose closest-point distance is three times too large certifies balls that
  // contain surface: the predictor then misses contacts, and its audit counts them — as the
  // independent oracle does.
  class Lying final : public SurfaceQueries {
   public:
    explicit Lying(const SurfaceQueries& inner) : inner_(inner) {}
    SurfaceHit first_hit_segment(const Vector3d& a, const Vector3d& b, QueryCounters* c) const noexcept override {
      return inner_.first_hit_segment(a, b, c);
    }
    SurfaceHit first_hit_ray(const Vector3d& o, const Vector3d& d, double t, QueryCounters* c) const noexcept override {
      return inner_.first_hit_ray(o, d, t, c);
    }
    ClosestSurfacePoint closest_point(const Vector3d& x, QueryCounters* c) const noexcept override {
      ClosestSurfacePoint closest = inner_.closest_point(x, c);
      closest.distance_m *= 3;
      return closest;
    }
    bool contains(const Vector3d& x, QueryCounters* c) const noexcept override { return inner_.contains(x, c); }

   private:
    const SurfaceQueries& inner_;
  };
  const Scene& scene = icosphere_scene();
  const Lying lying(*scene.queries);
  PredictionSettings settings;
  settings.audit = true;
  const ApproachTrajectoryGenerator generator(*scene.surface, tremor_approach(1e-4));
  Tally tally;
  for (std::uint64_t seed = 1; seed <= 30; ++seed) run(lying, settings, generator.generate(seed).tip, tally);
  std::printf("lying surface: %lld contacts, %lld misses (audit: %lld cheap-check, %lld other)\n", tally.contacts,
              tally.misses, tally.counters.misses_cheap_check, tally.counters.misses_other);
  EXPECT_GT(tally.misses, 0);
  EXPECT_EQ(tally.counters.misses(), tally.misses);
  EXPECT_GT(tally.counters.misses_cheap_check, 0);
}

// ---------------------------------------------------------------------------------------------
// Re-prediction causes, the certified corridor, odd inputs

TEST(CollisionPrediction, RepredictionCauses) {
  const Scene& scene = icosphere_scene();
  const Vector3d towards = Vector3d(0.3, -0.2, 1).normalized();
  const Vector3d target = scene.queries->first_hit_ray(2 * radius_m * towards, -towards, 2 * radius_m).point;
  const Vector3d sideways = towards.unitOrthogonal();
  const Vector3d start = target + 0.03 * towards;
  const Vector3d close = target + 0.004 * towards;

  const auto count = [&](const std::vector<Vector3d>& path, int direction_checks) {
    PredictionSettings settings;
    settings.direction_check_period_cycles = direction_checks;
    settings.audit = true;
    CollisionPredictor predictor(*scene.queries, settings);
    for (const Vector3d& p : path) predictor.step(p);
    EXPECT_EQ(predictor.counters().misses(), 0);
    return predictor.counters();
  };

  // In and back out: a retreat (seen by the direction check, or when the tip leaves the
  // corridor backward).
  std::vector<Vector3d> back = straight_path(start, close, 0.8);
  for (const Vector3d& p : straight_path(close, start, 0.8, 0)) back.push_back(p);
  EXPECT_GE(count(back, 10).repredictions_retreat, 1);

  // In, then turning to move along the surface: a change of direction.
  std::vector<Vector3d> turn = straight_path(start, close, 0.8);
  for (const Vector3d& p : straight_path(close, close + 0.01 * sideways, 0.5, 0)) turn.push_back(p);
  EXPECT_GE(count(turn, 10).repredictions_direction, 1);

  // From 30 mm: out of the straight-line range, then into it.
  EXPECT_GE(count(straight_path(start, close, 0.8), 0).repredictions_range, 1);

  // Direction checks re-predict while the tip is still certified; without them the same turn
  // is seen only when the tip leaves the corridor.
  EXPECT_GE(count(turn, 10).direction_checks, 1);
  EXPECT_EQ(count(turn, 0).direction_checks, 0);
}

TEST(PredictCollision, CorridorBallsAreSurfaceFreeAndReachTowardThePredictedPoint) {
  const Scene& scene = fused_scene();
  PredictionSettings settings;
  RandomStream random(11);
  int oblique = 0;
  double covered_length = 0;
  for (int i = 0; i < 300; ++i) {
    // A surface point, an anchor 3–7 mm out along a direction within 70° of its normal.
    const Vector3d towards = Vector3d(random.gaussian(), random.gaussian(), random.gaussian()).normalized();
    const SurfaceHit on = scene.queries->first_hit_ray(0.2 * towards, -towards, 0.2);
    ASSERT_TRUE(on.hit);
    const Vector3d tilt = on.normal.unitOrthogonal();
    const double angle = 1.2 * random.uniform();
    const Vector3d outward = std::cos(angle) * on.normal + std::sin(angle) * tilt;
    const Vector3d anchor = on.point + (0.003 + 0.004 * random.uniform()) * outward;
    if (scene.surface->signed_distance(anchor) <= 0) continue;
    Corridor corridor;
    const ClosestSurfacePoint closest = scene.queries->closest_point(anchor);
    const CollisionPrediction prediction = predict_collision(*scene.queries, settings, anchor, closest, -outward,
                                                             0.1, 0.0, corridor, nullptr, nullptr, nullptr);
    if (prediction.near_surface) continue;
    ASSERT_GE(corridor.size, 1);
    for (int b = 0; b < corridor.size; ++b) {
      const CertifiedBall& ball = corridor.balls[b];
      const double distance = scene.queries->closest_point(ball.centre).distance_m;
      EXPECT_LE(std::sqrt(ball.safe_radius2_m2), distance - settings.margin_m + 1e-15);
      EXPECT_LE(ball.check_radius2_m2, ball.safe_radius2_m2);
    }
    if (!prediction.in_range) continue;
    // The straight path is covered from the anchor up to its first point within 3 (h + margin)
    // of the surface (the corridor's cursor steps 3/4 of its ball, whose radius shrinks at most
    // as fast as the distance: a sample below h + margin ends it only beyond that point).
    const double stop = 3 * (settings.handover_distance_m + settings.margin_m) + 1e-4;
    for (double s = 0; s < prediction.path_distance_m; s += 1e-4) {
      const Vector3d x = anchor + s * prediction.direction;
      if (scene.queries->closest_point(x).distance_m <= stop) break;
      bool covered = false;
      for (int b = 0; b < corridor.size && !covered; ++b)
        covered = (x - corridor.balls[b].centre).squaredNorm() < corridor.balls[b].check_radius2_m2;
      if (!covered && corridor.size == max_corridor_balls) break;  // capacity, not a gap
      ASSERT_TRUE(covered) << "s = " << s << " of " << prediction.path_distance_m << ", angle " << angle;
      covered_length = std::max(covered_length, s);
    }
    if (angle > 0.8) ++oblique;
  }
  EXPECT_GT(oblique, 20);
  EXPECT_GT(covered_length, 0.004);
}

TEST(CollisionPrediction, OddInputs) {
  const Scene& scene = icosphere_scene();
  PredictionSettings settings;
  settings.audit = true;
  CollisionPredictor predictor(*scene.queries, settings);
  // A NaN sample is ignored; the next one carries on from the last valid position.
  EXPECT_EQ(predictor.step({0, 0, 0.08}).status, PredictionStatus::predicted);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(predictor.step({nan, 0, 0.08}).status, PredictionStatus::invalid_input);
  EXPECT_EQ(predictor.counters().cycles, 1);
  EXPECT_EQ(predictor.counters().invalid_inputs, 1);
  EXPECT_EQ(predictor.cycle(), 1);
  EXPECT_EQ(predictor.step({0, 0, 0.0799}).status, PredictionStatus::free);
  // A jump straight through the sphere in one cycle: contact at the near side.
  const PredictionStep through = predictor.step({0.001, 0.002, -0.08});
  EXPECT_EQ(through.status, PredictionStatus::contact);
  EXPECT_NEAR(through.hit.point.norm(), radius_m, 0.002);
  EXPECT_GT(through.hit.point.z(), 0);
  // Out on the far side: released next cycle.
  EXPECT_EQ(predictor.step({0.001, 0.002, -0.0801}).status, PredictionStatus::released);
  EXPECT_EQ(predictor.counters().misses(), 0);

  // Starting inside is a contact at once.
  predictor.reset();
  EXPECT_EQ(predictor.step({0, 0, 0}).status, PredictionStatus::contact);
  EXPECT_EQ(predictor.step({0, 0, 0.001}).status, PredictionStatus::in_contact);
  EXPECT_EQ(predictor.phase(), PredictorPhase::in_contact);
}

#endif  // !TOUCHSTONE_LARGE_TESTS

}  // namespace
}  // namespace touchstone::realtime::collision
