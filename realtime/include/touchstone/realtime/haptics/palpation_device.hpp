#pragma once
/// @file
/// The scripted hand as a device that computes each pose when it is read: the palpation
/// script's moves and a tremor generator, instead of every sample in memory. A run of any length
/// holds the same few hundred kilobytes (a ScriptedDevice of a sampled trajectory holds 56 bytes
/// per haptic tick: 200 MB for an hour at 1 kHz). Its poses equal, bit for bit, those of a
/// ScriptedDevice playing sample_palpation_script() of the same script.
///
/// Reads are expected in time order (the haptic loop's); a read earlier than the previous one
/// restarts the tremor sequence from its first sample, which costs time proportional to the
/// sample index but gives the same pose.

#include "touchstone/realtime/hand_motion/tremor_model.hpp"
#include "touchstone/realtime/haptics/haptic_device.hpp"
#include "touchstone/realtime/haptics/palpation_trajectory.hpp"

#include <Eigen/Geometry>

#include <optional>
#include <vector>

namespace touchstone::realtime::haptics {

class PalpationDevice final : public HapticDevice {
 public:
  /// Throws std::invalid_argument on a script without samples, with gaps between its moves,
  /// non-finite positions or axes, or a non-positive period or force limit.
  explicit PalpationDevice(PalpationScript script, double max_force_N = 10.0);

  std::string name() const override { return "scripted"; }
  void start() override {}
  DeviceSample read(double time_s) noexcept override;
  void write_force(const Eigen::Vector3d& force_N, double time_s) noexcept override;
  void stop() noexcept override { last_force_N_.setZero(); }
  double max_force_N() const noexcept override { return max_force_N_; }

  const Eigen::Vector3d& last_force_N() const noexcept { return last_force_N_; }
  double duration_s() const noexcept { return script_.sample_period_s * static_cast<double>(script_.sample_count); }
  const PalpationScript& script() const noexcept { return script_; }

 private:
  PalpationScript script_;
  std::vector<Eigen::Quaterniond> orientation_;  ///< per move
  double max_force_N_;
  std::optional<hand_motion::TremorGenerator> tremor_;
  long long tremor_samples_ = 0;  ///< tremor samples drawn so far; the last one is tremor_now_
  Eigen::Vector3d tremor_now_ = Eigen::Vector3d::Zero();
  std::size_t move_ = 0;          ///< the move of the previous read
  Eigen::Vector3d last_force_N_ = Eigen::Vector3d::Zero();
};

}  // namespace touchstone::realtime::haptics
