#include "touchstone/realtime/haptics/palpation_device.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace touchstone::realtime::haptics {

PalpationDevice::PalpationDevice(PalpationScript script, double max_force_N)
    : script_(std::move(script)), max_force_N_(max_force_N) {
  if (script_.moves.empty() || script_.sample_count <= 0)
    throw std::invalid_argument("PalpationDevice: the script has no samples");
  if (!std::isfinite(script_.sample_period_s) || script_.sample_period_s <= 0)
    throw std::invalid_argument("PalpationDevice: sample_period_s = " + std::to_string(script_.sample_period_s) +
                                " must be > 0");
  if (!std::isfinite(max_force_N_) || max_force_N_ <= 0)
    throw std::invalid_argument("PalpationDevice: max_force_N = " + std::to_string(max_force_N_) + " must be > 0");
  long long next = 0;
  for (std::size_t m = 0; m < script_.moves.size(); ++m) {
    const PalpationMove& move = script_.moves[m];
    if (move.begin != next || move.samples < 1)
      throw std::invalid_argument("PalpationDevice: move " + std::to_string(m) + " does not continue the previous one");
    if (!move.from_m.allFinite() || !move.to_m.allFinite())
      throw std::invalid_argument("PalpationDevice: move " + std::to_string(m) + " has a non-finite position");
    if (!move.tool_axis.allFinite() || move.tool_axis.norm() < 1e-12)
      throw std::invalid_argument("PalpationDevice: move " + std::to_string(m) + "'s tool axis is not a direction");
    // As ScriptedDevice computes it for each of the move's samples.
    orientation_.push_back(Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), move.tool_axis.normalized()));
    next += move.samples;
  }
  if (next != script_.sample_count)
    throw std::invalid_argument("PalpationDevice: the moves hold " + std::to_string(next) + " samples, the script says " +
                                std::to_string(script_.sample_count));
  if (script_.tremor.rms_per_axis_m > 0) tremor_.emplace(script_.tremor);
}

DeviceSample PalpationDevice::read(double time_s) noexcept {
  DeviceSample sample;
  // The same sample index as ScriptedDevice::read.
  const double position = std::isfinite(time_s) && time_s > 0 ? time_s / script_.sample_period_s : 0.0;
  const double index = std::floor(position + 1e-9);
  const auto last = static_cast<double>(script_.sample_count - 1);
  sample.finished = index > last;
  const auto k = static_cast<long long>(std::min(index, last));

  if (k < script_.moves[move_].begin) move_ = 0;
  while (k >= script_.moves[move_].begin + script_.moves[move_].samples) ++move_;
  const PalpationMove& move = script_.moves[move_];
  sample.tip_position_m = palpation_sample(move, k);
  sample.orientation = orientation_[move_];

  if (tremor_) {
    // Sample k carries the (k + 1)-th tremor draw.
    if (k + 1 < tremor_samples_) {
      tremor_->reset();
      tremor_samples_ = 0;
    }
    while (tremor_samples_ < k + 1) {
      tremor_now_ = tremor_->next();
      ++tremor_samples_;
    }
    sample.tip_position_m += tremor_now_;
  }
  return sample;
}

void PalpationDevice::write_force(const Eigen::Vector3d& force_N, double) noexcept { last_force_N_ = force_N; }

}  // namespace touchstone::realtime::haptics
