#include "touchstone/realtime/haptics/safety_filter.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace touchstone::realtime::haptics {

namespace {
void require_positive(double value, const char* field) {
  if (!std::isfinite(value) || value <= 0)
    throw std::invalid_argument(std::string("SafetySettings.") + field + " = " + std::to_string(value) +
                                " must be finite and > 0");
}
}  // namespace

void SafetySettings::validate() const {
  require_positive(max_force_N, "max_force_N");
  require_positive(max_rate_N_per_s, "max_rate_N_per_s");
  require_positive(stale_after_s, "stale_after_s");
}

SafetyFilter::SafetyFilter(const SafetySettings& settings) : settings_(settings) { settings_.validate(); }

Eigen::Vector3d SafetyFilter::filter(const Eigen::Vector3d& requested_N, const SafetyInput& input) noexcept {
  ++counters_.ticks;
  // The first tick has no previous output to limit against: it starts from zero with dt = 0,
  // so it can only output zero.
  double dt = started_ && std::isfinite(input.time_s) ? input.time_s - last_time_s_ : 0.0;
  if (!(dt >= 0)) dt = 0;  // a clock that ran backwards gives no allowance
  if (std::isfinite(input.time_s)) last_time_s_ = input.time_s;
  started_ = true;

  if (!input.connected || input.shutting_down) {
    if (!output_.isZero(0)) ++counters_.disconnect_zero;
    output_.setZero();
    return output_;
  }

  Eigen::Vector3d target = requested_N;
  if (!target.allFinite()) {
    ++counters_.non_finite;
    target.setZero();
  }
  if (!(input.model_age_s <= settings_.stale_after_s)) {  // also catches a NaN age
    ++counters_.stale;
    target.setZero();
  }
  const double magnitude = target.norm();
  if (magnitude > settings_.max_force_N) {
    ++counters_.clamped;
    target *= settings_.max_force_N / magnitude;
  }
  const Eigen::Vector3d step = target - output_;
  const double max_step = settings_.max_rate_N_per_s * dt;
  const double step_norm = step.norm();
  if (step_norm > max_step) {
    ++counters_.rate_limited;
    output_ += step * (max_step / step_norm);
  } else {
    output_ = target;
  }
  return output_;
}

}  // namespace touchstone::realtime::haptics
