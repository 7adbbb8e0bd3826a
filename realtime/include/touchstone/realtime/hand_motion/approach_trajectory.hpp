#pragma once
/// @file
/// Tool-tip trajectories for prediction studies (paper §3): smooth hand motion —
/// rest, a minimum-jerk approach along a straight line to a point on the surface and a few mm
/// beyond it (contact and press), hold, a minimum-jerk release back to the start — with hand
/// tremor (tremor_model.hpp) on top, sampled at the haptic rate. Start points and targets are
/// random and deterministic for a seed.
///
/// The smooth motion stays below 10 Hz: minimum-jerk segments last at least `min_segment_s`
/// (0.4 s: the velocity spectrum of such a segment has under 10⁻⁴ of its power above 10 Hz,
/// asserted in test_tremor_model) and join with zero velocity and acceleration.

#include "touchstone/realtime/hand_motion/tremor_model.hpp"
#include "touchstone/geometry/triangle_surface.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace touchstone::realtime::hand_motion {

/// Minimum-jerk profile s(τ) = 10τ³ − 15τ⁴ + 6τ⁵ for τ clamped to [0, 1] (Flash & Hogan 1985):
/// zero velocity and acceleration at both ends.
double minimum_jerk(double tau) noexcept;

struct ApproachSettings {
  double start_distance_min_m = 0.010;  ///< start this far from the target along the approach
  double start_distance_max_m = 0.040;
  /// The approach direction makes at most this angle with the outward normal at the target.
  double max_approach_angle_rad = 1.0;
  double speed_min_m_per_s = 0.02;      ///< mean speed of the approach and of the release
  double speed_max_m_per_s = 0.05;
  double press_depth_min_m = 0.002;     ///< how far beyond the target (into the organ) it goes
  double press_depth_max_m = 0.004;
  double rest_s = 0.3;                  ///< at rest (tremor only) before the approach
  double hold_s = 0.2;                  ///< pressed
  double final_rest_s = 0.1;            ///< after the release
  double min_segment_s = 0.4;           ///< shortest approach or release (keeps motion < 10 Hz)
  double sample_rate_hz = 1000.0;
  /// Tremor added to the smooth motion (its seed is derived from the trajectory's seed;
  /// rms_per_axis_m = 0 for none). Its sample rate is set to sample_rate_hz.
  TremorSettings tremor;
  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// One trajectory: sample k is at time k / sample_rate_hz.
struct ApproachTrajectory {
  std::vector<Eigen::Vector3d> smooth;  ///< hand motion [m]
  std::vector<Eigen::Vector3d> tip;     ///< smooth + tremor: what the device reports [m]
  Eigen::Vector3d start = Eigen::Vector3d::Zero();
  Eigen::Vector3d target = Eigen::Vector3d::Zero();         ///< on the surface
  Eigen::Vector3d target_normal = Eigen::Vector3d::Zero();  ///< outward face normal there
  Eigen::Vector3d direction = Eigen::Vector3d::Zero();      ///< unit, start → target
  Eigen::Vector3d press_point = Eigen::Vector3d::Zero();    ///< target + press depth · direction
  int approach_begin = 0;  ///< first sample of the approach
  int approach_end = 0;    ///< reaches press_point
  int release_begin = 0;
  int release_end = 0;     ///< back at start
  double sample_period_s = 1e-3;
};

/// Draws approach trajectories to a closed surface. Targets are uniform over the area;
/// the approach direction is uniform in the cone about the target's normal; a start is kept
/// only when it is outside and the straight segment to the target does not enter the surface
/// before it (sphere tracing with the exact signed distance), so the smooth path's first
/// contact is the target.
class ApproachTrajectoryGenerator {
 public:
  /// Keeps a reference to `surface`. Throws std::invalid_argument on invalid settings.
  ApproachTrajectoryGenerator(const geometry::TriangleSurface& surface, const ApproachSettings& settings);

  /// Deterministic for a seed. Throws std::runtime_error when no valid start is found.
  ApproachTrajectory generate(std::uint64_t seed) const;

  const ApproachSettings& settings() const noexcept { return settings_; }

 private:
  bool clear_path(const Eigen::Vector3d& start, const Eigen::Vector3d& target) const;

  const geometry::TriangleSurface& surface_;
  ApproachSettings settings_;
  std::vector<double> cumulative_area_;
};

}  // namespace touchstone::realtime::hand_motion
