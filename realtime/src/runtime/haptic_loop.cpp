#include "haptic_loop.hpp"

#include <algorithm>
#include <cmath>

namespace touchstone::realtime::runtime {

HapticLoop::HapticLoop(RuntimeState& sim_)
    : sim(sim_), predictor(sim_.hierarchy, sim_.settings.prediction), safety(clamped_safety(sim_)) {
  latencies_s.resize(1 << 16);  // touched now, kept as capacity
  latencies_s.clear();
}

haptics::SafetySettings HapticLoop::clamped_safety(const RuntimeState& sim) {
  haptics::SafetySettings safety = sim.settings.safety;
  if (sim.device) safety.max_force_N = std::min(safety.max_force_N, sim.device->max_force_N());
  return safety;
}

bool HapticLoop::usable(const ModelSnapshot& snapshot, const Eigen::Vector3d& tip) const noexcept {
  return snapshot.valid && eigen(snapshot.direction).dot(-contact_normal) > 0.5 &&
         tangential_offset_m(snapshot, tip) <= sim.settings.contact.usable_fraction * snapshot.local_radius_m;
}

bool HapticLoop::finish(const char* reason, double time_s, bool disconnected) noexcept {
  haptics::SafetyInput input;
  input.time_s = time_s;
  input.connected = !disconnected;
  input.shutting_down = true;
  const Eigen::Vector3d out = safety.filter(Eigen::Vector3d::Zero(), input);
  sim.device->write_force(out, time_s);
  sim.end_reason = reason;
  return false;
}

bool HapticLoop::tick(double time_s) noexcept {
  ++work.haptic_ticks;
  const haptics::DeviceSample sample = sim.device->read(time_s);
  if (!sample.connected) {
    if (connected_once) return finish("device disconnected", time_s, true);
    if (time_s > sim.settings.connect_timeout_s) return finish("no device connection", time_s, true);
    haptics::SafetyInput input;
    input.time_s = time_s;
    input.connected = false;
    sim.device->write_force(safety.filter(Eigen::Vector3d::Zero(), input), time_s);
    return true;
  }
  connected_once = true;
  if (sample.finished) return finish("trajectory finished", time_s, false);
  const Eigen::Vector3d tip = sample.tip_position_m;

  // The model loop's latest: a new model starts a cross-fade from the old one.
  ModelSnapshot latest;
  if (sim.model_snapshot.try_load(latest)) {
    if (latest.force_sequence != model.force_sequence && model.force_time_s >= 0 && latest.force_time_s >= 0 &&
        latest.model_id == model.model_id) {
      const double step = (extrapolated_force_N(latest, time_s, sim.settings.contact.extrapolation_horizon_s) -
                           extrapolated_force_N(model, time_s, sim.settings.contact.extrapolation_horizon_s))
                              .norm();
      ++forces.extrapolation_updates;
      extrapolation_step_sum += step;
      forces.extrapolation_update_step_max_N = std::max(forces.extrapolation_update_step_max_N, step);
    }
    if (latest.model_id != model.model_id && in_contact && usable(latest, tip)) {
      // A new model while pressing fades in: from the old model's force after a
      // re-sprinkle, from zero when the model arrives after the contact began.
      fading_from = model;
      switch_time_s = time_s;
      if (usable(model, tip)) {
        const double jump = (stiffness_force_N(latest, tip) - stiffness_force_N(model, tip)).norm();
        ++forces.model_switches;
        switch_jump_sum += jump;
        forces.switch_jump_max_N = std::max(forces.switch_jump_max_N, jump);
      } else {
        ++forces.late_model_fade_ins;
      }
    }
    model = latest;
  }

  // Contact: prediction and detection while free; the model's frame while pressed.
  if (!in_contact) {
    ++work.free_ticks;
    const collision::PredictionStep step = predictor.step(tip);
    if (step.status == collision::PredictionStatus::contact) {
      in_contact = true;
      ++work.contacts;
      contact_point = step.hit.point;
      contact_normal = step.hit.normal;
      contact_start_s = time_s;
      waiting_for_model = true;
    }
  } else {
    ++work.contact_ticks;
    const bool have_model = usable(model, tip);
    const double depth = have_model ? penetration_depth_m(model, tip) : (tip - contact_point).dot(-contact_normal);
    if (depth <= 0) {
      in_contact = false;
      waiting_for_model = false;
      switch_time_s = -1;
      predictor.reset();
    }
  }

  // The force on the tissue: exact K_t U (cross-faded after a switch), and the paper's
  // extrapolation, both computed so that the run can compare them.
  Eigen::Vector3d request = Eigen::Vector3d::Zero(), exact = Eigen::Vector3d::Zero();
  double model_age_s = 0;
  bool in_fade = false;
  if (in_contact && usable(model, tip)) {
    if (waiting_for_model) {
      if (latencies_s.size() < latencies_s.capacity()) latencies_s.push_back(time_s - contact_start_s);
      if (time_s == contact_start_s) ++work.contacts_with_model_ready;
      waiting_for_model = false;
    }
    exact = stiffness_force_N(model, tip);
    Eigen::Vector3d smooth = exact;
    if (switch_time_s >= 0 && sim.settings.contact.crossfade_s > 0 &&
        time_s - switch_time_s < sim.settings.contact.crossfade_s) {
      const double w = (time_s - switch_time_s) / sim.settings.contact.crossfade_s;
      const Eigen::Vector3d old_force = usable(fading_from, tip) ? stiffness_force_N(fading_from, tip) : Eigen::Vector3d::Zero();
      smooth = (1 - w) * old_force + w * exact;
      in_fade = true;
    }
    const Eigen::Vector3d extrapolated =
        extrapolated_force_N(model, time_s, sim.settings.contact.extrapolation_horizon_s);
    if (model.force_time_s >= 0) {
      const double error = (extrapolated - exact).norm();
      ++forces.compared_ticks;
      extrapolation_error_sq += error * error;
      forces.extrapolation_error_max_N = std::max(forces.extrapolation_error_max_N, error);
    }
    request = sim.settings.force_mode == ForceMode::stiffness ? smooth : extrapolated;
    model_age_s = time_s - model.heartbeat_s;
  }
  if (in_fade || last_request_in_fade)
    forces.crossfade_step_max_N = std::max(forces.crossfade_step_max_N, (request - last_request).norm());
  last_request_in_fade = in_fade;
  last_request = request;

  // The tool feels the opposite of the force on the tissue.
  haptics::SafetyInput input;
  input.time_s = time_s;
  input.model_age_s = model_age_s;
  const Eigen::Vector3d out = safety.filter(-request, input);
  sim.device->write_force(out, time_s);
  forces.output_step_max_N = std::max(forces.output_step_max_N, (out - last_output).norm());
  forces.max_force_N = std::max(forces.max_force_N, out.norm());
  last_output = out;

  // Publish for the model and graphics loops.
  HapticState state;
  state.time_s = time_s;
  state.tip_m = plain(tip);
  state.tool_axis = plain(sample.orientation * Eigen::Vector3d::UnitZ());
  state.force_on_hand_N = plain(out);
  state.in_contact = in_contact;
  state.contact_point_m = plain(contact_point);
  state.contact_normal = plain(contact_normal);
  const collision::CollisionPrediction& prediction = predictor.prediction();
  // Any predicted point will do for building ahead, in range or not: a build can take longer
  // than the tool needs from the straight-line range to contact.
  state.prediction_valid = !in_contact && prediction.valid;
  state.predicted_point_m = plain(prediction.point);
  state.predicted_normal = plain(prediction.normal);
  state.time_to_contact_s = prediction.time_to_contact_s;
  state.model_in_use = in_contact && usable(model, tip) ? model.model_id : 0;
  sim.haptic_state.store(state);

  if (history) {
    if (history->size() < history->capacity()) {
      ForceSample& s = history->emplace_back();
      s.time_s = time_s;
      s.tip_m = tip;
      s.force_on_hand_N = out;
      s.exact_N = exact;
      s.in_contact = in_contact;
      s.model_id = state.model_in_use;
    } else {
      ++history_dropped;
    }
  }
  return true;
}

}  // namespace touchstone::realtime::runtime
