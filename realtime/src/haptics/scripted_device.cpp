#include "touchstone/realtime/haptics/scripted_device.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace touchstone::realtime::haptics {

ScriptedDevice::ScriptedDevice(std::vector<Eigen::Vector3d> tip_path_m, std::vector<Eigen::Vector3d> tool_axis,
                               double period_s, double max_force_N)
    : tip_path_m_(std::move(tip_path_m)), period_s_(period_s), max_force_N_(max_force_N) {
  if (tip_path_m_.empty()) throw std::invalid_argument("ScriptedDevice: the tip path is empty");
  if (!std::isfinite(period_s_) || period_s_ <= 0)
    throw std::invalid_argument("ScriptedDevice: period_s = " + std::to_string(period_s_) + " must be > 0");
  if (!std::isfinite(max_force_N_) || max_force_N_ <= 0)
    throw std::invalid_argument("ScriptedDevice: max_force_N = " + std::to_string(max_force_N_) + " must be > 0");
  if (!tool_axis.empty() && tool_axis.size() != tip_path_m_.size())
    throw std::invalid_argument("ScriptedDevice: " + std::to_string(tool_axis.size()) + " tool axes for " +
                                std::to_string(tip_path_m_.size()) + " tip positions");
  for (std::size_t k = 0; k < tip_path_m_.size(); ++k)
    if (!tip_path_m_[k].allFinite())
      throw std::invalid_argument("ScriptedDevice: tip position " + std::to_string(k) + " is not finite");
  orientation_.reserve(tool_axis.size());
  for (std::size_t k = 0; k < tool_axis.size(); ++k) {
    if (!tool_axis[k].allFinite() || tool_axis[k].norm() < 1e-12)
      throw std::invalid_argument("ScriptedDevice: tool axis " + std::to_string(k) + " is not a direction");
    orientation_.push_back(Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), tool_axis[k].normalized()));
  }
}

DeviceSample ScriptedDevice::read(double time_s) noexcept {
  DeviceSample sample;
  const double position = std::isfinite(time_s) && time_s > 0 ? time_s / period_s_ : 0.0;
  // A small tolerance so that t = k × period lands on sample k despite rounding.
  const double index = std::floor(position + 1e-9);
  const auto last = static_cast<double>(tip_path_m_.size() - 1);
  sample.finished = index > last;
  const auto k = static_cast<std::size_t>(std::min(index, last));
  sample.tip_position_m = tip_path_m_[k];
  if (!orientation_.empty()) sample.orientation = orientation_[k];
  return sample;
}

void ScriptedDevice::write_force(const Eigen::Vector3d& force_N, double) noexcept { last_force_N_ = force_N; }

}  // namespace touchstone::realtime::haptics
