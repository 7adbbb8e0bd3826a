#pragma once
/// @file
/// The safety layer on every force sent to a device. Whatever the model, the
/// network or a bug produces, the device sees a finite force no larger than the clamp, changing
/// no faster than the rate limit — with one exception: a disconnect or shutdown drops the force
/// to zero at once, because removing the force is what a device does when its controller goes.
///
/// Order of the guards in one tick, each counted when it acts:
///   1. disconnect / shutdown → zero now (skips the rest);
///   2. NaN/Inf in the requested force → the request is replaced by zero (the output then ramps
///      down at the rate limit: a sudden drop of a large force is itself a jolt);
///   3. watchdog: model data older than `stale_after_s` → the request is replaced by zero;
///   4. magnitude clamp to `max_force_N`;
///   5. rate limit: the output moves toward the request by at most `max_rate_N_per_s` × dt.
/// The output therefore never exceeds the clamp, and consecutive outputs never differ by more
/// than max_rate × dt except at a disconnect/shutdown zero (tests/realtime/haptics).

#include <Eigen/Core>

#include <cstdint>

namespace touchstone::realtime::haptics {

struct SafetySettings {
  /// Magnitude clamp [N]; the runtime lowers it to the device's own maximum.
  double max_force_N = 3.0;
  /// Largest |dF/dt| of the output [N/s] (3 N in 30 ms at the default).
  double max_rate_N_per_s = 100.0;
  /// Model data older than this makes the watchdog ramp the force to zero [s].
  double stale_after_s = 0.1;
  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// How often each guard acted (ticks), since construction.
struct SafetyCounters {
  long long ticks = 0;
  long long non_finite = 0;      ///< requested force had NaN/Inf
  long long stale = 0;           ///< watchdog active (model data too old)
  long long clamped = 0;         ///< |request| above the clamp
  long long rate_limited = 0;    ///< output held back by the rate limit
  long long disconnect_zero = 0; ///< zeroed for a disconnect or shutdown
  /// Ticks any guard other than a disconnect changed the requested force.
  long long interventions() const noexcept { return non_finite + stale + clamped + rate_limited; }
};

/// What the filter knows about the tick besides the requested force.
struct SafetyInput {
  double time_s = 0;
  /// Age of the model data the request was computed from [s]; 0 when no model is needed (no
  /// contact: the request is zero anyway).
  double model_age_s = 0;
  bool connected = true;
  bool shutting_down = false;
};

class SafetyFilter {
 public:
  /// Validates the settings (throws std::invalid_argument naming the field).
  explicit SafetyFilter(const SafetySettings& settings);
  /// The force to send [N]. noexcept, allocation-free.
  Eigen::Vector3d filter(const Eigen::Vector3d& requested_N, const SafetyInput& input) noexcept;
  /// Last output [N].
  const Eigen::Vector3d& output() const noexcept { return output_; }
  const SafetyCounters& counters() const noexcept { return counters_; }
  const SafetySettings& settings() const noexcept { return settings_; }

 private:
  SafetySettings settings_;
  SafetyCounters counters_;
  Eigen::Vector3d output_ = Eigen::Vector3d::Zero();
  double last_time_s_ = 0;
  bool started_ = false;
};

}  // namespace touchstone::realtime::haptics
