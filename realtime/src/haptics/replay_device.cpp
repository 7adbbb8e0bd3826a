#include "touchstone/realtime/haptics/replay_device.hpp"

#include <cmath>
#include <stdexcept>

namespace touchstone::realtime::haptics {

ReplayDevice::ReplayDevice(std::vector<RecordedSample> samples, double max_force_N)
    : samples_(std::move(samples)), max_force_N_(max_force_N) {
  if (samples_.empty()) throw std::invalid_argument("ReplayDevice: the recording has no samples");
}

ReplayDevice ReplayDevice::from_csv(const std::string& path, double max_force_N) {
  return ReplayDevice(read_recording_csv(path), max_force_N);
}

DeviceSample ReplayDevice::read(double time_s) noexcept {
  DeviceSample sample;
  if (!std::isfinite(time_s)) time_s = samples_[cursor_].time_s;
  // Reads move forward in time: advance the cursor (a read earlier than the cursor restarts).
  if (time_s < samples_[cursor_].time_s) cursor_ = 0;
  while (cursor_ + 1 < samples_.size() && samples_[cursor_ + 1].time_s <= time_s) ++cursor_;
  const RecordedSample& a = samples_[cursor_];
  sample.connected = a.connected;
  if (cursor_ + 1 == samples_.size() || time_s <= a.time_s) {
    sample.tip_position_m = a.tip_position_m;
    sample.orientation = a.orientation;
    sample.finished = time_s > samples_.back().time_s;
    return sample;
  }
  const RecordedSample& b = samples_[cursor_ + 1];
  const double w = (time_s - a.time_s) / (b.time_s - a.time_s);
  sample.tip_position_m = (1 - w) * a.tip_position_m + w * b.tip_position_m;
  sample.orientation = a.orientation.slerp(w, b.orientation);
  return sample;
}

}  // namespace touchstone::realtime::haptics
