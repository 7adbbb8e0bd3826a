#pragma once
/// @file
/// A device that plays a precomputed tool-tip trajectory (the palpation script, an approach
/// trajectory, a test's path): the input of headless runs, tests and study mode. Sample k is
/// the pose at time k × period; read(t) returns the nearest earlier-or-equal sample, and the
/// trajectory's end is reported as `finished`.

#include "touchstone/realtime/haptics/haptic_device.hpp"

#include <vector>

namespace touchstone::realtime::haptics {

class ScriptedDevice final : public HapticDevice {
 public:
  /// `tool_axis` may be empty (the shaft then points along +z) or one unit vector per sample.
  /// Throws std::invalid_argument on an empty or non-finite path, a non-positive period or a
  /// size mismatch.
  ScriptedDevice(std::vector<Eigen::Vector3d> tip_path_m, std::vector<Eigen::Vector3d> tool_axis, double period_s,
                 double max_force_N = 10.0);

  std::string name() const override { return "scripted"; }
  void start() override {}
  DeviceSample read(double time_s) noexcept override;
  void write_force(const Eigen::Vector3d& force_N, double time_s) noexcept override;
  void stop() noexcept override { last_force_N_.setZero(); }
  double max_force_N() const noexcept override { return max_force_N_; }

  /// The force last written [N] (what a real device would render).
  const Eigen::Vector3d& last_force_N() const noexcept { return last_force_N_; }
  double duration_s() const noexcept { return period_s_ * static_cast<double>(tip_path_m_.size()); }

 private:
  std::vector<Eigen::Vector3d> tip_path_m_;
  std::vector<Eigen::Quaterniond> orientation_;
  double period_s_;
  double max_force_N_;
  Eigen::Vector3d last_force_N_ = Eigen::Vector3d::Zero();
};

}  // namespace touchstone::realtime::haptics
