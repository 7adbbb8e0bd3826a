#pragma once
// Private to realtime/src/runtime: the haptic loop (1 kHz). Device pose → contact (prediction
// while free, the model's frame while pressed) → force → safety filter → device, with no mutex,
// allocation or I/O in a tick (tests/realtime/runtime/test_haptic_tick_allocation).

#include "runtime_state.hpp"
#include "touchstone/realtime/collision/collision_prediction.hpp"
#include "touchstone/realtime/haptics/safety_filter.hpp"

namespace touchstone::realtime::runtime {

struct HapticLoop {
  RuntimeState& sim;
  collision::CollisionPredictor predictor;
  haptics::SafetyFilter safety;
  bool connected_once = false;
  bool in_contact = false;
  Eigen::Vector3d contact_point = Eigen::Vector3d::Zero(), contact_normal = Eigen::Vector3d::UnitZ();
  double contact_start_s = 0;
  bool waiting_for_model = false;
  ModelSnapshot model, fading_from;
  double switch_time_s = -1;
  Eigen::Vector3d last_request = Eigen::Vector3d::Zero(), last_output = Eigen::Vector3d::Zero();
  bool last_request_in_fade = false;
  WorkCounters work;  // haptic fields only
  ForceStatistics forces;
  double extrapolation_error_sq = 0, switch_jump_sum = 0, extrapolation_step_sum = 0;
  std::vector<double> latencies_s;       // reserved: no allocation in the tick
  std::vector<ForceSample>* history = nullptr;  // reserved
  long long history_dropped = 0;

  explicit HapticLoop(RuntimeState& sim_);

  /// The scene's safety settings with the clamp lowered to the device's maximum.
  static haptics::SafetySettings clamped_safety(const RuntimeState& sim);
  /// A model that can give this contact's force: valid, facing the contact, and the tip within
  /// usable_fraction × L of its contact point across the push direction.
  bool usable(const ModelSnapshot& snapshot, const Eigen::Vector3d& tip) const noexcept;

  /// Finishes with zero force on the device; returns false (the loop ends).
  bool finish(const char* reason, double time_s, bool disconnected) noexcept;

  /// One haptic tick at `time_s`; false when the run is over. noexcept, no allocation.
  bool tick(double time_s) noexcept;
};

}  // namespace touchstone::realtime::runtime
