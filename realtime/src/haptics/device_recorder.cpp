#include "touchstone/realtime/haptics/device_recorder.hpp"
#include "touchstone/geometry/regular_file.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace touchstone::realtime::haptics {

RecordingDevice::RecordingDevice(HapticDevice& inner, std::size_t capacity_samples)
    : inner_(inner), capacity_(capacity_samples) {
  // Touched now (filled, then emptied): the ticks that record never take a page fault.
  samples_.resize(capacity_samples);
  samples_.clear();
}

DeviceSample RecordingDevice::read(double time_s) noexcept {
  const DeviceSample sample = inner_.read(time_s);
  if (samples_.size() < capacity_) {
    RecordedSample& recorded = samples_.emplace_back();  // within the reserved capacity: no allocation
    recorded.time_s = time_s;
    recorded.tip_position_m = sample.tip_position_m;
    recorded.orientation = sample.orientation;
    recorded.connected = sample.connected;
    pending_force_ = true;
  } else {
    ++dropped_;
    pending_force_ = false;
  }
  return sample;
}

void RecordingDevice::write_force(const Eigen::Vector3d& force_N, double time_s) noexcept {
  if (pending_force_) samples_.back().force_N = force_N;
  pending_force_ = false;
  inner_.write_force(force_N, time_s);
}

void RecordingDevice::write_csv(const std::string& path) const {
  const std::string temporary = path + ".partial";
  {
    std::ofstream out(temporary);
    if (!out) throw std::runtime_error("recording: cannot write " + temporary);
    out << "time_s,x_m,y_m,z_m,qw,qx,qy,qz,connected,fx_N,fy_N,fz_N\n";
    char line[512];
    for (const auto& s : samples_) {
      std::snprintf(line, sizeof line, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%d,%.17g,%.17g,%.17g\n", s.time_s,
                    s.tip_position_m.x(), s.tip_position_m.y(), s.tip_position_m.z(), s.orientation.w(),
                    s.orientation.x(), s.orientation.y(), s.orientation.z(), s.connected ? 1 : 0, s.force_N.x(),
                    s.force_N.y(), s.force_N.z());
      out << line;
    }
    if (!out) throw std::runtime_error("recording: error writing " + temporary);
  }
  if (std::rename(temporary.c_str(), path.c_str()) != 0)
    throw std::runtime_error("recording: cannot rename " + temporary + " to " + path);
}

std::vector<RecordedSample> read_recording_csv(const std::string& path) {
  if (const std::string reason = geometry::non_regular_file_reason(path); !reason.empty())
    throw std::runtime_error("recording " + path + ": cannot open (" + reason + ")");
  std::ifstream in(path);
  if (!in) throw std::runtime_error("recording " + path + ": cannot open");
  std::string line;
  if (!std::getline(in, line) || line.rfind("time_s,", 0) != 0)
    throw std::runtime_error("recording " + path + ": line 1: expected the header 'time_s,x_m,...'");
  std::vector<RecordedSample> samples;
  int number = 1;
  while (std::getline(in, line)) {
    ++number;
    if (line.empty()) continue;
    std::istringstream fields(line);
    std::string field;
    double values[12];
    std::string texts[12];
    int count = 0;
    while (count < 12 && std::getline(fields, field, ',')) {
      char* end = nullptr;
      values[count] = std::strtod(field.c_str(), &end);
      if (end == field.c_str() || *end != '\0')
        throw std::runtime_error("recording " + path + ": line " + std::to_string(number) + ": field " +
                                 std::to_string(count + 1) + " '" + field + "' is not a number");
      if (!std::isfinite(values[count]))
        throw std::runtime_error("recording " + path + ": line " + std::to_string(number) + ": field " +
                                 std::to_string(count + 1) + " is not finite");
      texts[count] = field;
      ++count;
    }
    if (count != 12 || std::getline(fields, field, ','))
      throw std::runtime_error("recording " + path + ": line " + std::to_string(number) + ": expected 12 fields");
    RecordedSample s;
    s.time_s = values[0];
    s.tip_position_m = {values[1], values[2], values[3]};
    s.orientation = Eigen::Quaterniond(values[4], values[5], values[6], values[7]);
    if (std::abs(s.orientation.norm() - 1) > 1e-6)
      throw std::runtime_error("recording " + path + ": line " + std::to_string(number) +
                               ": the orientation is not a unit quaternion");
    // A flag, not a quantity: 0.5 or 2 means a corrupted or hand-edited file, not "connected".
    if (values[8] != 0 && values[8] != 1)
      throw std::runtime_error("recording " + path + ": line " + std::to_string(number) + ": connected = " + texts[8] +
                               " must be 0 or 1");
    s.connected = values[8] == 1;
    s.force_N = {values[9], values[10], values[11]};
    if (!samples.empty() && !(s.time_s > samples.back().time_s))
      throw std::runtime_error("recording " + path + ": line " + std::to_string(number) + ": time " +
                               std::to_string(s.time_s) + " does not increase");
    samples.push_back(s);
  }
  if (samples.empty()) throw std::runtime_error("recording " + path + ": no samples");
  return samples;
}

}  // namespace touchstone::realtime::haptics
