#include "model_loop.hpp"

#include <algorithm>

namespace touchstone::realtime::runtime {

BuildResult RuntimeState::build(const BuildRequest& request) const {
  BuildResult result;
  result.request = request;
  const auto start = std::chrono::steady_clock::now();
  try {
    mfs::ToolContact contact;
    contact.point = request.point;
    contact.direction = request.direction;
    contact.radius_m = settings.tool.tip_radius_m;
    contact.condition = settings.tool.condition;
    auto model = std::make_shared<mfs::LocalModel>(mfs::build_local_model(organ, contact, settings.material, settings.model, {}, mfs::exterior_from_atlas(settings.organ_atlas)));
    if (model->ok() && graphics_enabled())
      result.deformation = std::make_shared<DeformationMap>(make_deformation_map(*model, organ, 0));
    result.model = std::move(model);
  } catch (const std::exception& error) {
    result.error = error.what();
  }
  result.build_s = seconds_since(start);
  return result;
}

void RuntimeState::build_worker() {
  std::unique_lock lock(build_mutex);
  while (true) {
    build_signal.wait(lock, [&] { return build_pending || build_stop; });
    if (build_stop) return;
    const BuildRequest request = pending_request;
    build_pending = false;
    lock.unlock();
    auto result = std::make_unique<BuildResult>(build(request));
    lock.lock();
    finished_build = std::move(result);
  }
}

void ModelLoop::request(const BuildRequest& request) {
  build_in_flight = true;
  in_flight = request;
  if (synchronous) {
    adopt(sim.build(request));
    return;
  }
  std::lock_guard lock(sim.build_mutex);
  sim.pending_request = request;
  sim.build_pending = true;
  sim.build_signal.notify_one();
}

void ModelLoop::collect() {
  if (synchronous) return;
  std::unique_ptr<BuildResult> result;
  {
    std::lock_guard lock(sim.build_mutex);
    result = std::move(sim.finished_build);
  }
  if (result) adopt(std::move(*result));
}

void ModelLoop::adopt(BuildResult result) {
  build_in_flight = false;
  build_times_s.push_back(result.build_s);
  ++work.model_builds;
  if (result.request.reason == BuildReason::prebuild) ++work.model_prebuilds;
  if (result.request.reason == BuildReason::resprinkle) ++work.model_resprinkles;
  if (!result.model || !result.model->ok()) {
    ++work.model_build_failures;
    if (first_build_error.empty())
      first_build_error = !result.error.empty() ? result.error : result.model ? result.model->status : "no model";
    return;  // keep the previous model; the contact will ask again
  }
  model = result.model;
  ++exterior_used[model->exterior_used.empty() ? "none" : model->exterior_used];
  if (first_exterior_note.empty() && !model->exterior_note.empty()) first_exterior_note = model->exterior_note;
  // Adopted all the same (the safety filter bounds what the device renders), but counted: the
  // run's summary says that its forces came from a model that is wrong.
  const double stiffness_ratio = mfs::stiffness_ratio_to_half_space(*model);
  if (!(stiffness_ratio >= mfs::plausible_stiffness_ratio_min && stiffness_ratio <= mfs::plausible_stiffness_ratio_max)) {
    if (implausible_stiffness_models == 0) first_implausible_stiffness_ratio = stiffness_ratio;
    ++implausible_stiffness_models;
  }
  snapshot.model_id += 1;
  snapshot.valid = true;
  snapshot.tool_stiffness_N_per_m = plain(model->tool_stiffness_N_per_m);
  snapshot.load_force_N = plain(model->load_force_N);
  snapshot.contact_point_m = plain(model->contact.point);
  snapshot.direction = plain(model->contact.direction);
  snapshot.local_radius_m = sim.local_radius_m();
  snapshot.force_time_s = snapshot.previous_force_time_s = -1;
  if (records.size() < max_model_records) {
    static const char* const reasons[] = {"contact", "prebuild", "resprinkle"};
    ModelRecord& r = records.emplace_back();
    r.model_id = snapshot.model_id;
    r.adopted_s = now_s;
    r.reason = reasons[static_cast<int>(result.request.reason)];
    r.contact_point_m = model->contact.point;
    r.direction = model->contact.direction;
    r.tool_stiffness_N_per_m = model->tool_stiffness_N_per_m;
    r.load_force_N = model->load_force_N;
    r.exterior_used = model->exterior_used.empty() ? "none" : model->exterior_used;
    r.node_count = model->cloud.positions.size();
    r.build_s = result.build_s;
    r.stiffness_ratio_to_half_space = stiffness_ratio;
  } else {
    ++records_dropped;
  }
  if (result.deformation) {
    auto map = std::make_shared<DeformationMap>(*result.deformation);
    map->model_id = snapshot.model_id;
    std::lock_guard lock(sim.deformation_mutex);
    sim.deformation = std::move(map);
  }
}

bool ModelLoop::near_model(const Eigen::Vector3d& point, const Eigen::Vector3d& outward_normal) const {
  if (!snapshot.valid) return false;
  const double keep = sim.settings.contact.keep_fraction * sim.local_radius_m();
  return (point - eigen(snapshot.contact_point_m)).norm() <= keep &&
         eigen(snapshot.direction).dot(-outward_normal) > 0.5;
}

bool ModelLoop::near_in_flight(const Eigen::Vector3d& point) const {
  return build_in_flight &&
         (point - in_flight.point).norm() <= sim.settings.contact.keep_fraction * sim.local_radius_m();
}

void ModelLoop::step(double time_s) {
  now_s = time_s;
  ++work.model_steps;
  collect();
  const HapticState state = sim.haptic_state.load();
  const Eigen::Vector3d tip = eigen(state.tip_m);
  bool worked = false;
  if (state.in_contact) {
    const Eigen::Vector3d contact_point = eigen(state.contact_point_m);
    const Eigen::Vector3d normal = eigen(state.contact_normal);
    const bool model_for_contact = snapshot.valid && eigen(snapshot.direction).dot(-normal) > 0.5 &&
                                   tangential_offset_m(snapshot, tip) <= sim.settings.contact.usable_fraction * sim.local_radius_m();
    if (!model_for_contact && !near_model(contact_point, normal)) {
      if (!near_in_flight(contact_point)) request({contact_point, -normal, BuildReason::contact});
      worked = true;
    } else if (tangential_offset_m(snapshot, tip) > sim.settings.contact.keep_fraction * sim.local_radius_m() &&
               !build_in_flight) {
      // Slid beyond the kept region: a new local domain at the tip's closest surface point.
      const auto closest = sim.hierarchy.closest_point(tip);
      if (closest.triangle >= 0) {
        const auto& t = sim.organ.triangles()[closest.triangle];
        const auto& v = sim.organ.vertices();
        const Eigen::Vector3d face_normal = (v[t[1]] - v[t[0]]).cross(v[t[2]] - v[t[0]]).normalized();
        request({closest.point, -face_normal, BuildReason::resprinkle});
      }
      worked = true;
    }
    // The model loop's own force (the paper's 200 Hz force; extrapolated by the haptic loop).
    if (model) {
      const auto solution = mfs::solve_local_model(*model, tip - model->contact.point);
      const Eigen::Vector3d force = push_only(solution.forces.haptic_N, model->contact.direction);
      snapshot.previous_force_N = snapshot.force_N;
      snapshot.previous_force_time_s = snapshot.force_time_s;
      snapshot.force_N = plain(force);
      snapshot.force_time_s = time_s;
      ++snapshot.force_sequence;
      ++work.model_forces;
      worked = true;
    }
  } else {
    snapshot.force_time_s = snapshot.previous_force_time_s = -1;
    if (state.prediction_valid && sim.settings.contact.prebuild_on_prediction &&
        state.time_to_contact_s <= sim.settings.contact.prebuild_horizon_s) {
      const Eigen::Vector3d point = eigen(state.predicted_point_m);
      const Eigen::Vector3d normal = eigen(state.predicted_normal);
      if (!near_model(point, normal) && !near_in_flight(point) && !build_in_flight) {
        request({point, -normal, BuildReason::prebuild});
        worked = true;
      }
    }
  }
  if (!worked) ++work.model_idle_steps;
  snapshot.heartbeat_s = time_s;
  sim.model_snapshot.store(snapshot);
}

}  // namespace touchstone::realtime::runtime
