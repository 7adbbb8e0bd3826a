#pragma once
/// @file
/// Plays back a recording made by RecordingDevice (`touchstone sim --record`) from any device:
/// the pose at time t is interpolated linearly between the recorded samples (orientation by
/// slerp); a recorded disconnect is replayed as one. Finished after the last sample.

#include "touchstone/realtime/haptics/device_recorder.hpp"

namespace touchstone::realtime::haptics {

class ReplayDevice final : public HapticDevice {
 public:
  /// Throws std::invalid_argument on an empty recording.
  explicit ReplayDevice(std::vector<RecordedSample> samples, double max_force_N = 10.0);
  /// Reads the CSV (read_recording_csv's errors).
  static ReplayDevice from_csv(const std::string& path, double max_force_N = 10.0);

  std::string name() const override { return "replay"; }
  void start() override { cursor_ = 0; }
  DeviceSample read(double time_s) noexcept override;
  void write_force(const Eigen::Vector3d& force_N, double) noexcept override { last_force_N_ = force_N; }
  void stop() noexcept override { last_force_N_.setZero(); }
  double max_force_N() const noexcept override { return max_force_N_; }

  const std::vector<RecordedSample>& samples() const noexcept { return samples_; }
  const Eigen::Vector3d& last_force_N() const noexcept { return last_force_N_; }
  /// Time of the recording's first and last samples [s].
  double begin_s() const noexcept { return samples_.front().time_s; }
  double end_s() const noexcept { return samples_.back().time_s; }

 private:
  std::vector<RecordedSample> samples_;
  std::size_t cursor_ = 0;  ///< last sample at or before the previous read (reads move forward)
  double max_force_N_;
  Eigen::Vector3d last_force_N_ = Eigen::Vector3d::Zero();
};

}  // namespace touchstone::realtime::haptics
