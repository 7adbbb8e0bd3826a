#pragma once
/// @file
/// The scripted hand of the palpation demo (paper §6): at each site on the organ
/// the tool approaches along the normal, presses, holds, slides along the surface, holds and
/// releases, then lifts and moves to the next site — minimum-jerk segments (smooth hand motion
/// below 10 Hz, as in hand_motion/approach_trajectory.hpp) with physiological tremor on
/// top (hand_motion/tremor_model.hpp), sampled at the haptic rate. Deterministic for a seed.

#include "touchstone/realtime/hand_motion/tremor_model.hpp"
#include "touchstone/geometry/triangle_surface.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace touchstone::realtime::haptics {

struct PalpationSettings {
  /// Points near the organ; each is projected to the surface to give a site. Empty: the
  /// topmost vertex (largest z) and `generated_sites − 1` random sites within `site_spread_m`
  /// of it, projected.
  std::vector<Eigen::Vector3d> sites;
  int generated_sites = 4;
  double site_spread_m = 0.015;
  /// Total length of the trajectory [s]: palpations repeat over the sites until the next one
  /// would not fit; the remaining time is spent at rest above the last site.
  double duration_s = 60.0;
  double hover_m = 0.008;         ///< start and end of a palpation, above the site along its normal
  double press_depth_m = 0.003;   ///< below the surface at the site, along the normal
  double slide_m = 0.004;         ///< along the surface while pressed (0: no slide)
  double approach_s = 0.8, hold_s = 0.5, slide_s = 1.0, release_s = 0.8, rest_s = 0.4;
  /// Between sites the tool lifts this far above the site, moves over and descends [m, s].
  double lift_m = 0.02;
  double transfer_s = 1.2;
  double sample_rate_hz = 1000.0;
  /// Tremor on top of the smooth motion; its sample rate is set to sample_rate_hz and its seed
  /// derived from `seed`. rms_per_axis_m = 0: none.
  hand_motion::TremorSettings tremor;
  std::uint64_t seed = 1;
  /// Throws std::invalid_argument naming the field; also when duration_s holds no palpation.
  void validate() const;
  /// One palpation at a site: approach, hold, slide, hold, release and rest [s].
  double palpation_s() const noexcept;
  /// The first palpation with the rest before it: the shortest duration_s that holds one [s].
  double first_palpation_s() const noexcept;
};

enum class PalpationPhase : std::uint8_t { rest, approach, hold, slide, release, transfer };
const char* to_string(PalpationPhase phase);

/// A run of samples in one phase (sample k is at time k / sample_rate_hz).
struct PalpationSegment {
  PalpationPhase phase = PalpationPhase::rest;
  int site = 0;
  long long begin = 0, end = 0;  ///< [begin, end)
};

/// One minimum-jerk move of the hand (a rest is a move with from = to): samples
/// begin … begin + samples − 1, sample begin + j − 1 at from + s(j / samples)(to − from), s the
/// minimum-jerk profile.
struct PalpationMove {
  Eigen::Vector3d from_m = Eigen::Vector3d::Zero(), to_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d tool_axis = Eigen::Vector3d::UnitZ();  ///< unit, from the tip along the shaft
  long long begin = 0;
  int samples = 1;
};

/// The palpation as moves plus the tremor that goes on top: what the hand does, in memory that
/// grows with the number of moves (about ten per palpation), not with duration × sample rate.
/// PalpationDevice plays it sample by sample; sample_palpation_script() writes every sample.
struct PalpationScript {
  std::vector<PalpationMove> moves;
  std::vector<PalpationSegment> segments;
  std::vector<Eigen::Vector3d> site_points, site_normals;  ///< on the surface; outward
  hand_motion::TremorSettings tremor;  ///< resolved: the sample rate and seed the trajectory uses
  double sample_period_s = 1e-3;
  long long sample_count = 0;
  int palpations = 0;
};

/// Every sample of a script, for tests and short runs.
struct PalpationTrajectory {
  std::vector<Eigen::Vector3d> smooth;     ///< hand motion [m]
  std::vector<Eigen::Vector3d> tip;        ///< smooth + tremor: what the device reports [m]
  std::vector<Eigen::Vector3d> tool_axis;  ///< unit, from the tip along the shaft
  std::vector<Eigen::Vector3d> site_points, site_normals;  ///< on the surface; outward
  std::vector<PalpationSegment> segments;
  double sample_period_s = 1e-3;
  int palpations = 0;
};

/// Plans the palpation. Throws std::invalid_argument on invalid settings, and
/// std::runtime_error naming the sites when a transfer would pass through the organ (raise
/// lift_m) or when not even one palpation fits in duration_s.
PalpationScript make_palpation_script(const geometry::TriangleSurface& organ, const PalpationSettings& settings);

/// The smooth hand position of sample k (0 ≤ k < sample_count) of move `move`.
Eigen::Vector3d palpation_sample(const PalpationMove& move, long long k) noexcept;

/// Every sample of the script (smooth, then tip = smooth + the tremor sequence).
PalpationTrajectory sample_palpation_script(const PalpationScript& script);

/// make_palpation_script, then every sample.
PalpationTrajectory make_palpation_trajectory(const geometry::TriangleSurface& organ,
                                              const PalpationSettings& settings);

}  // namespace touchstone::realtime::haptics
