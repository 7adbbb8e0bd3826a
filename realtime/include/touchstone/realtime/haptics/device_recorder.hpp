#pragma once
/// @file
/// A recorder that wraps any device: every tick's pose (as read) and force (as written) go into
/// a buffer reserved before the run — the haptic tick does no I/O and no allocation — and are
/// written as CSV when the run ends. `replay_device.hpp` plays such a file back.
///
/// CSV columns (SI): time_s, x_m, y_m, z_m, qw, qx, qy, qz, connected, fx_N, fy_N, fz_N, with a
/// header line; one line per tick, in order.

#include "touchstone/realtime/haptics/haptic_device.hpp"

#include <string>
#include <vector>

namespace touchstone::realtime::haptics {

struct RecordedSample {
  double time_s = 0;
  Eigen::Vector3d tip_position_m = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  bool connected = true;
  Eigen::Vector3d force_N = Eigen::Vector3d::Zero();
};

class RecordingDevice final : public HapticDevice {
 public:
  /// Records `inner` (which must outlive the recorder); room for `capacity_samples` ticks
  /// (further ticks are counted as dropped, not recorded).
  RecordingDevice(HapticDevice& inner, std::size_t capacity_samples);

  std::string name() const override { return inner_.name(); }
  void start() override { inner_.start(); }
  DeviceSample read(double time_s) noexcept override;
  void write_force(const Eigen::Vector3d& force_N, double time_s) noexcept override;
  void stop() noexcept override { inner_.stop(); }
  double max_force_N() const noexcept override { return inner_.max_force_N(); }

  const std::vector<RecordedSample>& samples() const noexcept { return samples_; }
  long long dropped() const noexcept { return dropped_; }
  /// Writes the CSV (atomically: a temporary file renamed). Throws std::runtime_error naming the file.
  void write_csv(const std::string& path) const;

 private:
  HapticDevice& inner_;
  std::vector<RecordedSample> samples_;
  std::size_t capacity_;
  long long dropped_ = 0;
  bool pending_force_ = false;  ///< the last sample read still waits for its force
};

/// Reads a recording. Throws std::runtime_error naming the file and line for malformed rows,
/// non-finite values or times that do not increase.
std::vector<RecordedSample> read_recording_csv(const std::string& path);

}  // namespace touchstone::realtime::haptics
