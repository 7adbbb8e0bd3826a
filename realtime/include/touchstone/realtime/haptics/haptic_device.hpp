#pragma once
/// @file
/// What the runtime asks of a haptic device: the tool pose in, the force out.
/// Every backend — scripted trajectories, replay of a recording, an OpenIGTLink peer, an
/// OpenHaptics device — sits behind this interface, and the haptic loop does not know which.
///
/// read() and write_force() are called from the haptic thread once per tick: they are noexcept,
/// allocation-free and never block on I/O (a network backend exchanges data with its own thread
/// through lock-free structures). start() and stop() run outside the loop and may throw.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <string>

namespace touchstone::realtime::haptics {

/// The device's state at one tick, in the scene's world frame (SI units).
struct DeviceSample {
  Eigen::Vector3d tip_position_m = Eigen::Vector3d::Zero();
  /// Orientation of the tool: the shaft runs from the tip along orientation · (0, 0, 1).
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  /// False once the device or peer is gone: the runtime outputs zero force from this tick on.
  bool connected = true;
  /// True when a scripted or replayed trajectory has ended (the run stops).
  bool finished = false;
  /// True when the pose is new since the previous read (network devices); scripted devices
  /// produce a pose every tick.
  bool fresh = true;
};

/// The last guard where a force leaves for hardware or a network peer: finite, and no larger
/// than `max_force_N` [N] (non-finite → zero, larger → scaled down along its direction). The
/// runtime's SafetyFilter has already done both; a backend applies this again because it
/// cannot know who called it.
inline Eigen::Vector3d bounded_force_N(const Eigen::Vector3d& force_N, double max_force_N) noexcept {
  if (!force_N.allFinite()) return Eigen::Vector3d::Zero();
  const double magnitude = force_N.norm();
  return magnitude > max_force_N ? Eigen::Vector3d(force_N * (max_force_N / magnitude)) : force_N;
}

class HapticDevice {
 public:
  virtual ~HapticDevice() = default;
  /// "scripted", "replay", "openigtlink", "openhaptics".
  virtual std::string name() const = 0;
  /// Opens the device (ports, files, drivers). Throws std::runtime_error naming what failed.
  virtual void start() = 0;
  /// The pose at `time_s` since the run began. Haptic thread: noexcept, no allocation or I/O.
  virtual DeviceSample read(double time_s) noexcept = 0;
  /// The force on the user's hand [N], already through the safety filter. Haptic thread.
  virtual void write_force(const Eigen::Vector3d& force_N, double time_s) noexcept = 0;
  /// Zero force, then close. Idempotent.
  virtual void stop() noexcept = 0;
  /// The largest force the device renders [N]; the safety clamp never exceeds it.
  virtual double max_force_N() const noexcept = 0;
};

}  // namespace touchstone::realtime::haptics
