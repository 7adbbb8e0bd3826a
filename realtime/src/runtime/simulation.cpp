#include "touchstone/realtime/runtime/simulation.hpp"

#include "touchstone/realtime/runtime/seqlock.hpp"
#include "touchstone/realtime/runtime/surface_deformation.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <exception>
#include <future>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <thread>

namespace touchstone::realtime::runtime {

namespace {

void require_positive(double value, const std::string& field) {
  if (!std::isfinite(value) || value <= 0)
    throw std::invalid_argument(field + " = " + std::to_string(value) + " must be finite and > 0");
}
void require_non_negative(double value, const std::string& field) {
  if (!std::isfinite(value) || value < 0)
    throw std::invalid_argument(field + " = " + std::to_string(value) + " must be finite and >= 0");
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

double median_of(std::vector<double> values) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

/// What the haptic loop publishes for the model and graphics loops (a Seqlock payload).
struct HapticState {
  double time_s = 0;
  PlainVector3 tip_m{}, tool_axis{0, 0, 1};
  PlainVector3 force_on_hand_N{};
  bool in_contact = false;
  std::uint64_t contact_epoch = 0;
  PlainVector3 contact_point_m{}, contact_normal{};  ///< outward, at the first hit
  bool prediction_valid = false;                    ///< a predicted collision point ahead
  PlainVector3 predicted_point_m{}, predicted_normal{};
  double time_to_contact_s = 0;
  std::uint64_t model_in_use = 0;  ///< id of the model the force came from (0: none)
};

/// A build request: where, which way, and why.
enum class BuildReason : std::uint8_t { contact, prebuild, resprinkle };

struct BuildRequest {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = -Eigen::Vector3d::UnitZ();
  BuildReason reason = BuildReason::contact;
};

struct BuildResult {
  BuildRequest request;
  std::shared_ptr<const mfs::LocalModel> model;
  std::shared_ptr<const DeformationMap> deformation;  ///< null when no graphics
  double build_s = 0;
  std::string error;  ///< an exception from the build (a contact off the surface, …)
};

}  // namespace

void RateSettings::validate() const {
  require_positive(haptic_hz, "rates.haptic_hz");
  require_positive(model_hz, "rates.model_hz");
  require_positive(graphics_hz, "rates.graphics_hz");
  if (model_hz > haptic_hz)
    throw std::invalid_argument("rates.model_hz = " + std::to_string(model_hz) + " must not exceed rates.haptic_hz = " +
                                std::to_string(haptic_hz));
}

void ToolSettings::validate() const {
  require_positive(tip_radius_m, "tool.tip_radius_m");
  require_non_negative(shaft_length_m, "tool.shaft_length_m");
  require_non_negative(shaft_radius_m, "tool.shaft_radius_m");
}

void ContactSettings::validate() const {
  require_positive(keep_fraction, "contact.keep_fraction");
  require_positive(usable_fraction, "contact.usable_fraction");
  if (usable_fraction < keep_fraction)
    throw std::invalid_argument("contact.usable_fraction = " + std::to_string(usable_fraction) +
                                " must be >= contact.keep_fraction = " + std::to_string(keep_fraction));
  if (usable_fraction > 1)
    throw std::invalid_argument("contact.usable_fraction = " + std::to_string(usable_fraction) + " must be <= 1");
  require_non_negative(crossfade_s, "contact.crossfade_s");
  require_non_negative(prebuild_horizon_s, "contact.prebuild_horizon_s");
  require_non_negative(extrapolation_horizon_s, "contact.extrapolation_horizon_s");
}

void TimingSettings::validate() const {
  require_non_negative(spin_tail_s, "timing.spin_tail_s");
  require_positive(late_threshold_s, "timing.late_threshold_s");
  if (fifo_priority < 1 || fifo_priority > 99)
    throw std::invalid_argument("timing.fifo_priority = " + std::to_string(fifo_priority) + " must be in [1, 99]");
}

void SceneSettings::validate() const {
  material.validate();
  model.validate();
  tool.validate();
  rates.validate();
  contact.validate();
  safety.validate();
  prediction.validate();
  timing.validate();
  require_non_negative(duration_s, "duration_s");
  require_non_negative(connect_timeout_s, "connect_timeout_s");
  if (model.paper_mode)
    throw std::invalid_argument("model.paper_mode: the paper's point tool gives no usable force (DESIGN.md §1); "
                                "the runtime needs a tool of finite radius");
  if (std::abs(prediction.cycle_period_s * rates.haptic_hz - 1) > 1e-9)
    throw std::invalid_argument("prediction.cycle_period_s = " + std::to_string(prediction.cycle_period_s) +
                                " must be 1 / rates.haptic_hz = " + std::to_string(1 / rates.haptic_hz));
}

// ---------------------------------------------------------------------------------------------
struct Simulation::Impl {
  const geometry::TriangleSurface& organ;
  SceneSettings settings;
  haptics::HapticDevice* device;
  std::vector<graphics::GraphicsSink*> sinks;
  collision::BoundingVolumeHierarchy hierarchy;

  Impl(const geometry::TriangleSurface& organ_, const SceneSettings& settings_, haptics::HapticDevice* device_,
       std::vector<graphics::GraphicsSink*> sinks_)
      : organ(organ_), settings(settings_), device(device_), sinks(std::move(sinks_)),
        hierarchy(organ_, settings_.hierarchy) {}

  double local_radius_m() const { return settings.model.sprinkling.local_radius_m; }
  bool graphics_enabled() const { return !sinks.empty(); }

  // -- shared state ----------------------------------------------------------------------------
  Seqlock<HapticState> haptic_state;
  Seqlock<ModelSnapshot> model_snapshot;
  std::atomic<bool> running{false};
  // Written by the haptic loop (or the driver) before running = false; a literal, so that the
  // tick that ends the run allocates nothing either.
  std::atomic<const char*> end_reason{""};

  std::mutex deformation_mutex;  // model ↔ graphics only
  std::shared_ptr<const DeformationMap> deformation;

  // -- build worker (model loop only) ----------------------------------------------------------
  std::mutex build_mutex;
  std::condition_variable build_signal;
  bool build_pending = false, build_stop = false;
  BuildRequest pending_request;
  std::unique_ptr<BuildResult> finished_build;
  std::thread build_thread;

  BuildResult build(const BuildRequest& request) const {
    BuildResult result;
    result.request = request;
    const auto start = std::chrono::steady_clock::now();
    try {
      mfs::ToolContact contact;
      contact.point = request.point;
      contact.direction = request.direction;
      contact.radius_m = settings.tool.tip_radius_m;
      contact.condition = settings.tool.condition;
      auto model = std::make_shared<mfs::LocalModel>(mfs::build_local_model(organ, contact, settings.material, settings.model));
      if (model->ok() && graphics_enabled())
        result.deformation = std::make_shared<DeformationMap>(make_deformation_map(*model, organ, 0));
      result.model = std::move(model);
    } catch (const std::exception& error) {
      result.error = error.what();
    }
    result.build_s = seconds_since(start);
    return result;
  }

  void build_worker() {
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

  // -- model loop ------------------------------------------------------------------------------
  struct ModelLoop {
    Impl& sim;
    bool synchronous;  ///< virtual clock: builds complete within the step
    std::shared_ptr<const mfs::LocalModel> model;
    ModelSnapshot snapshot;
    bool build_in_flight = false;
    BuildRequest in_flight;
    std::vector<double> build_times_s;
    WorkCounters work;  // model fields only

    ModelLoop(Impl& sim_, bool synchronous_) : sim(sim_), synchronous(synchronous_) {}

    void request(const BuildRequest& request) {
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

    void collect() {
      if (synchronous) return;
      std::unique_ptr<BuildResult> result;
      {
        std::lock_guard lock(sim.build_mutex);
        result = std::move(sim.finished_build);
      }
      if (result) adopt(std::move(*result));
    }

    void adopt(BuildResult result) {
      build_in_flight = false;
      build_times_s.push_back(result.build_s);
      ++work.model_builds;
      if (result.request.reason == BuildReason::prebuild) ++work.model_prebuilds;
      if (result.request.reason == BuildReason::resprinkle) ++work.model_resprinkles;
      if (!result.model || !result.model->ok()) {
        ++work.model_build_failures;
        return;  // keep the previous model; the contact will ask again
      }
      model = result.model;
      snapshot.model_id += 1;
      snapshot.valid = true;
      snapshot.tool_stiffness_N_per_m = plain(model->tool_stiffness_N_per_m);
      snapshot.load_force_N = plain(model->load_force_N);
      snapshot.contact_point_m = plain(model->contact.point);
      snapshot.direction = plain(model->contact.direction);
      snapshot.local_radius_m = sim.local_radius_m();
      snapshot.force_time_s = snapshot.previous_force_time_s = -1;
      if (result.deformation) {
        auto map = std::make_shared<DeformationMap>(*result.deformation);
        map->model_id = snapshot.model_id;
        std::lock_guard lock(sim.deformation_mutex);
        sim.deformation = std::move(map);
      }
    }

    bool near_model(const Eigen::Vector3d& point, const Eigen::Vector3d& outward_normal) const {
      if (!snapshot.valid) return false;
      const double keep = sim.settings.contact.keep_fraction * sim.local_radius_m();
      return (point - eigen(snapshot.contact_point_m)).norm() <= keep &&
             eigen(snapshot.direction).dot(-outward_normal) > 0.5;
    }
    bool near_in_flight(const Eigen::Vector3d& point) const {
      return build_in_flight &&
             (point - in_flight.point).norm() <= sim.settings.contact.keep_fraction * sim.local_radius_m();
    }

    void step(double time_s) {
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
  };

  // -- haptic loop -----------------------------------------------------------------------------
  struct HapticLoop {
    Impl& sim;
    collision::CollisionPredictor predictor;
    haptics::SafetyFilter safety;
    double period_s;
    bool connected_once = false;
    bool in_contact = false;
    std::uint64_t contact_epoch = 0;
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

    HapticLoop(Impl& sim_)
        : sim(sim_), predictor(sim_.hierarchy, sim_.settings.prediction), safety(clamped_safety(sim_)),
          period_s(1.0 / sim_.settings.rates.haptic_hz) {
      latencies_s.resize(1 << 16);  // touched now, kept as capacity
      latencies_s.clear();
    }

    static haptics::SafetySettings clamped_safety(const Impl& sim) {
      haptics::SafetySettings safety = sim.settings.safety;
      if (sim.device) safety.max_force_N = std::min(safety.max_force_N, sim.device->max_force_N());
      return safety;
    }

    bool usable(const ModelSnapshot& snapshot, const Eigen::Vector3d& tip) const noexcept {
      return snapshot.valid && eigen(snapshot.direction).dot(-contact_normal) > 0.5 &&
             tangential_offset_m(snapshot, tip) <= sim.settings.contact.usable_fraction * snapshot.local_radius_m;
    }

    /// Finishes with zero force on the device; returns false (the loop ends).
    bool finish(const char* reason, double time_s, bool disconnected) noexcept {
      haptics::SafetyInput input;
      input.time_s = time_s;
      input.connected = !disconnected;
      input.shutting_down = true;
      const Eigen::Vector3d out = safety.filter(Eigen::Vector3d::Zero(), input);
      sim.device->write_force(out, time_s);
      sim.end_reason = reason;
      return false;
    }

    /// One haptic tick at `time_s`; false when the run is over. noexcept, no allocation.
    bool tick(double time_s) noexcept {
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
          ++contact_epoch;
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
      state.contact_epoch = contact_epoch;
      state.contact_point_m = plain(contact_point);
      state.contact_normal = plain(contact_normal);
      const collision::CollisionPrediction& prediction = predictor.prediction();
      // Any predicted point will do for building ahead, in range or not: the build takes a few
      // hundred milliseconds, and the straight-line range is reached later than that.
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
        } else {
          ++history_dropped;
        }
      }
      return true;
    }
  };

  // -- graphics loop ---------------------------------------------------------------------------
  struct GraphicsLoop {
    Impl& sim;
    DeformedSurface surface;
    std::vector<bool> sink_alive;
    WorkCounters work;  // graphics fields only
    int frame_index = 0;

    explicit GraphicsLoop(Impl& sim_) : sim(sim_), surface(sim_.organ), sink_alive(sim_.sinks.size(), true) {}

    void frame(double time_s) {
      ++work.graphics_frames;
      const HapticState state = sim.haptic_state.load();
      std::shared_ptr<const DeformationMap> map;
      {
        std::lock_guard lock(sim.deformation_mutex);
        map = sim.deformation;
      }
      const bool apply = state.in_contact && map && map->model_id == state.model_in_use;
      const Eigen::Vector3d tip = eigen(state.tip_m);
      Eigen::Vector3d displacement = Eigen::Vector3d::Zero();
      if (apply) {
        displacement = tip - map->contact_point_m;
        if (displacement.dot(map->direction) <= 0) displacement.setZero();
      }
      if (apply || surface.moved_vertices() > 0) {
        ++work.surface_updates;
        work.vertices_written += surface.update(map.get(), displacement, apply);
      }
      graphics::GraphicsFrame frame;
      frame.time_s = time_s;
      frame.index = frame_index++;
      frame.organ_vertices_m = &surface.vertices_m();
      frame.organ_displacement_m = &surface.displacement_m();
      frame.tool_tip_m = tip;
      frame.tool_axis = eigen(state.tool_axis).normalized();
      frame.tool_tip_radius_m = sim.settings.tool.tip_radius_m;
      frame.tool_shaft_length_m = sim.settings.tool.shaft_length_m;
      frame.tool_shaft_radius_m = sim.settings.tool.shaft_radius_m;
      frame.force_on_hand_N = eigen(state.force_on_hand_N);
      frame.in_contact = state.in_contact;
      for (std::size_t i = 0; i < sim.sinks.size(); ++i) {
        if (!sink_alive[i]) continue;
        try {
          sim.sinks[i]->frame(frame);
        } catch (const std::exception& error) {
          ++work.sink_errors;
          sink_alive[i] = false;
          std::lock_guard lock(sim.notes_mutex);
          sim.notes.push_back("graphics output '" + sim.sinks[i]->name() + "' failed and was disabled: " + error.what());
        }
      }
    }
  };

  std::mutex notes_mutex;
  std::vector<std::string> notes;
  Simulation::TickProbe probe;

  bool probed_tick(HapticLoop& haptic, double time_s) noexcept {
    if (probe.before) probe.before(probe.context);
    const bool go_on = haptic.tick(time_s);
    if (probe.after) probe.after(probe.context);
    return go_on;
  }

  RunSummary summarize(const HapticLoop* haptic, const ModelLoop* model, const GraphicsLoop* graphics,
                       bool virtual_clock, double duration_s) {
    RunSummary summary;
    summary.device = device ? device->name() : "none";
    summary.virtual_clock = virtual_clock;
    summary.duration_s = duration_s;
    summary.end_reason = end_reason.load();
    summary.force_mode = settings.force_mode;
    WorkCounters& work = summary.work;
    work.organ_vertices = static_cast<long long>(organ.vertices().size());
    if (haptic) {
      work.haptic_ticks = haptic->work.haptic_ticks;
      work.free_ticks = haptic->work.free_ticks;
      work.contact_ticks = haptic->work.contact_ticks;
      work.contacts = haptic->work.contacts;
      work.contacts_with_model_ready = haptic->work.contacts_with_model_ready;
      summary.safety = haptic->safety.counters();
      summary.prediction = haptic->predictor.counters();
      const auto& p = summary.prediction;
      work.hierarchy_queries = p.full_detections + p.closest_point_queries + p.ray_casts + p.contact_checks;
      summary.forces = haptic->forces;
      auto& f = summary.forces;
      if (f.compared_ticks > 0) f.extrapolation_error_rms_N = std::sqrt(haptic->extrapolation_error_sq / f.compared_ticks);
      if (f.model_switches > 0) f.switch_jump_mean_N = haptic->switch_jump_sum / f.model_switches;
      if (f.extrapolation_updates > 0) f.extrapolation_update_step_mean_N = haptic->extrapolation_step_sum / f.extrapolation_updates;
      f.model_latency_samples = static_cast<long long>(haptic->latencies_s.size());
      f.model_latency_p50_s = median_of(haptic->latencies_s);
      f.model_latency_max_s = haptic->latencies_s.empty() ? 0 : *std::max_element(haptic->latencies_s.begin(), haptic->latencies_s.end());
      if (haptic->history_dropped > 0)
        notes.push_back("force history: " + std::to_string(haptic->history_dropped) + " ticks beyond its capacity were not kept");
    }
    if (model) {
      work.model_steps = model->work.model_steps;
      work.model_idle_steps = model->work.model_idle_steps;
      work.model_builds = model->work.model_builds;
      work.model_prebuilds = model->work.model_prebuilds;
      work.model_resprinkles = model->work.model_resprinkles;
      work.model_build_failures = model->work.model_build_failures;
      work.model_forces = model->work.model_forces;
      summary.forces.build_p50_s = median_of(model->build_times_s);
      summary.forces.build_max_s = model->build_times_s.empty() ? 0 : *std::max_element(model->build_times_s.begin(), model->build_times_s.end());
    }
    if (graphics) {
      work.graphics_frames = graphics->work.graphics_frames;
      work.surface_updates = graphics->work.surface_updates;
      work.vertices_written = graphics->work.vertices_written;
      work.sink_errors = graphics->work.sink_errors;
    }
    summary.notes = notes;
    return summary;
  }

  static void fill_loop(LoopStatistics& loop, const char* name, double period_s, const LatenessHistogram& lateness,
                        const LatenessHistogram& work, double late_threshold_s, long long skipped) {
    loop.name = name;
    loop.period_s = period_s;
    loop.ticks = work.count();
    loop.lateness_p50_s = lateness.quantile(0.5);
    loop.lateness_p99_s = lateness.quantile(0.99);
    loop.lateness_max_s = lateness.max_s();
    loop.late_threshold_s = late_threshold_s;
    loop.late_ticks = lateness.count_above(late_threshold_s);
    loop.skipped_deadlines = skipped;
    loop.work_p50_s = work.quantile(0.5);
    loop.work_p99_s = work.quantile(0.99);
    loop.work_max_s = work.max_s();
  }

  void reserve_history(HapticLoop& haptic, std::vector<ForceSample>& history) const {
    if (!settings.record_force_history) return;
    const double seconds = settings.duration_s > 0 ? settings.duration_s : 600.0;
    // Filled then emptied: the pages are touched now, not by the first tick to reach each one
    // (a page fault costs microseconds).
    history.resize(static_cast<std::size_t>(seconds * settings.rates.haptic_hz) + 16);
    history.clear();
    haptic.history = &history;
  }
};

// ---------------------------------------------------------------------------------------------
Simulation::Simulation(const geometry::TriangleSurface& organ, const SceneSettings& settings,
                       haptics::HapticDevice* device, std::vector<graphics::GraphicsSink*> sinks) {
  settings.validate();
  for (auto* sink : sinks)
    if (sink == nullptr) throw std::invalid_argument("Simulation: a graphics sink is null");
  impl_ = new Impl(organ, settings, device, std::move(sinks));
}

Simulation::~Simulation() { delete impl_; }

const collision::BoundingVolumeHierarchy& Simulation::hierarchy() const noexcept { return impl_->hierarchy; }

void Simulation::set_haptic_tick_probe(const TickProbe& probe) noexcept { impl_->probe = probe; }

RunSummary Simulation::run_virtual(const std::atomic<bool>* stop) {
  Impl& sim = *impl_;
  sim.end_reason = "";
  sim.notes.clear();
  sim.deformation.reset();
  const auto& rates = sim.settings.rates;
  const double period = 1.0 / rates.haptic_hz;
  const long long model_every = std::max(1LL, std::llround(rates.haptic_hz / rates.model_hz));
  std::unique_ptr<Impl::HapticLoop> haptic;
  std::unique_ptr<Impl::ModelLoop> model;
  std::unique_ptr<Impl::GraphicsLoop> graphics;
  std::vector<ForceSample> history;
  if (sim.device) {
    sim.device->start();
    haptic = std::make_unique<Impl::HapticLoop>(sim);
    model = std::make_unique<Impl::ModelLoop>(sim, true);
    sim.reserve_history(*haptic, history);
  }
  if (sim.graphics_enabled()) {
    for (auto* sink : sim.sinks) sink->begin(sim.organ);
    graphics = std::make_unique<Impl::GraphicsLoop>(sim);
  }
  LatenessHistogram zero, haptic_work, model_work, graphics_work;
  double next_graphics = 0, time_s = 0;
  for (long long k = 0;; ++k) {
    time_s = static_cast<double>(k) * period;
    if (sim.settings.duration_s > 0 && time_s >= sim.settings.duration_s) {
      if (haptic) haptic->finish("duration", time_s, false);
      else sim.end_reason = "duration";
      break;
    }
    if (stop && stop->load()) {
      if (haptic) haptic->finish("stopped", time_s, false);
      else sim.end_reason = "stopped";
      break;
    }
    if (!haptic && !graphics) {
      sim.end_reason = "nothing to run (no device, no outputs)";
      break;
    }
    if (!haptic && sim.settings.duration_s <= 0) {
      graphics->frame(time_s);  // a static scene: one frame of the organ at rest
      sim.end_reason = "no device: one frame";
      break;
    }
    if (haptic) {
      const auto start = std::chrono::steady_clock::now();
      const bool go_on = sim.probed_tick(*haptic, time_s);
      haptic_work.add(seconds_since(start));
      if (!go_on) break;
      if (k % model_every == 0) {
        const auto model_start = std::chrono::steady_clock::now();
        model->step(time_s);
        model_work.add(seconds_since(model_start));
      }
    }
    if (graphics && time_s + 1e-12 >= next_graphics) {
      const auto graphics_start = std::chrono::steady_clock::now();
      graphics->frame(time_s);
      graphics_work.add(seconds_since(graphics_start));
      next_graphics += 1.0 / rates.graphics_hz;
    }
  }
  if (sim.device) sim.device->stop();
  for (auto* sink : sim.sinks) sink->end();
  RunSummary summary = sim.summarize(haptic.get(), model.get(), graphics.get(), true, time_s);
  Impl::fill_loop(summary.haptic, "haptic", period, zero, haptic_work, sim.settings.timing.late_threshold_s, 0);
  Impl::fill_loop(summary.model, "model", model_every * period, zero, model_work, 1.0 / rates.model_hz, 0);
  Impl::fill_loop(summary.graphics, "graphics", 1.0 / rates.graphics_hz, zero, graphics_work, 1.0 / rates.graphics_hz, 0);
  summary.haptic_thread.note = "virtual clock: no real-time thread";
  summary.force_history = std::move(history);
  return summary;
}

RunSummary Simulation::run_threaded(const std::atomic<bool>* stop) {
  Impl& sim = *impl_;
  sim.end_reason = "";
  sim.notes.clear();
  sim.deformation.reset();
  const auto& rates = sim.settings.rates;
  std::unique_ptr<Impl::HapticLoop> haptic;
  std::unique_ptr<Impl::ModelLoop> model;
  std::unique_ptr<Impl::GraphicsLoop> graphics;
  std::vector<ForceSample> history;
  if (sim.device) {
    sim.device->start();
    haptic = std::make_unique<Impl::HapticLoop>(sim);
    model = std::make_unique<Impl::ModelLoop>(sim, false);
    sim.reserve_history(*haptic, history);
  }
  if (sim.graphics_enabled()) graphics = std::make_unique<Impl::GraphicsLoop>(sim);
  auto haptic_lateness = std::make_unique<LatenessHistogram>(), haptic_work = std::make_unique<LatenessHistogram>();
  auto model_lateness = std::make_unique<LatenessHistogram>(), model_work = std::make_unique<LatenessHistogram>();
  auto graphics_lateness = std::make_unique<LatenessHistogram>(), graphics_work = std::make_unique<LatenessHistogram>();
  long long haptic_skipped = 0, model_skipped = 0, graphics_skipped = 0;
  RealtimeThreadReport haptic_report;
  auto start = std::chrono::steady_clock::now();  // set again when every thread is ready
  const double duration = sim.settings.duration_s;
  sim.running = true;
  std::atomic<double> end_time{0};

  // Runs `body` every `period` until the run ends; records lateness and work.
  auto periodic = [&](double period_s, double spin_tail_s, LatenessHistogram& lateness, LatenessHistogram& work,
                      long long& skipped, auto&& body) {
    DeadlineScheduler scheduler(period_s, spin_tail_s, start);
    while (sim.running.load(std::memory_order_acquire)) {
      lateness.add(scheduler.wait());
      const auto tick_start = std::chrono::steady_clock::now();
      const double now = std::chrono::duration<double>(scheduler.deadline() - start).count();
      if (!body(now)) break;
      work.add(seconds_since(tick_start));
    }
    skipped = scheduler.skipped();
  };

  std::thread model_thread, graphics_thread, haptic_thread;
  // The graphics thread owns its outputs from begin() to end() (a VTK window must be used
  // from the thread that created it). It starts first; the loops start when it is ready.
  std::promise<std::exception_ptr> graphics_ready;
  std::promise<void> go;
  std::shared_future<void> go_signal = go.get_future().share();
  if (graphics) {
    graphics_thread = std::thread([&] {
      try {
        for (auto* sink : sim.sinks) sink->begin(sim.organ);
      } catch (...) {
        graphics_ready.set_value(std::current_exception());
        for (auto* sink : sim.sinks) sink->end();
        return;
      }
      graphics_ready.set_value(nullptr);
      go_signal.wait();
      periodic(1.0 / rates.graphics_hz, 0.0, *graphics_lateness, *graphics_work, graphics_skipped, [&](double now) {
        graphics->frame(now);
        return haptic != nullptr || duration > 0 || graphics->work.graphics_frames < 1;
      });
      if (!haptic && duration <= 0) {
        sim.end_reason = "no device: one frame";
        sim.running = false;
      }
      for (auto* sink : sim.sinks) sink->end();
    });
    if (std::exception_ptr error = graphics_ready.get_future().get()) {
      graphics_thread.join();
      sim.running = false;
      if (sim.device) sim.device->stop();
      std::rethrow_exception(error);
    }
  }
  start = std::chrono::steady_clock::now();
  go.set_value();
  if (model) {
    sim.build_stop = false;
    sim.build_pending = false;
    sim.finished_build.reset();
    sim.build_thread = std::thread([&] { sim.build_worker(); });
    model_thread = std::thread([&] {
      periodic(1.0 / rates.model_hz, 0.0, *model_lateness, *model_work, model_skipped, [&](double now) {
        model->step(now);
        return true;
      });
    });
  }
  if (haptic) {
    haptic_thread = std::thread([&] {
      haptic_report = configure_realtime_thread(sim.settings.timing.request_fifo, sim.settings.timing.fifo_priority);
      periodic(1.0 / rates.haptic_hz, sim.settings.timing.spin_tail_s, *haptic_lateness, *haptic_work, haptic_skipped,
               [&](double now) {
                 if (duration > 0 && now >= duration) return haptic->finish("duration", now, false);
                 if (stop && stop->load(std::memory_order_relaxed)) return haptic->finish("stopped", now, false);
                 end_time.store(now, std::memory_order_relaxed);
                 return sim.probed_tick(*haptic, now);
               });
      sim.running.store(false, std::memory_order_release);
    });
  }
  if (!haptic && !graphics) {
    sim.end_reason = "nothing to run (no device, no outputs)";
    sim.running = false;
  }
  // Without a device the driver waits for the duration or a stop.
  if (!haptic && graphics) {
    while (sim.running.load()) {
      const double now = seconds_since(start);
      if ((duration > 0 && now >= duration) || (stop && stop->load())) {
        sim.end_reason = duration > 0 && now >= duration ? "duration" : "stopped";
        sim.running = false;
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  }
  if (haptic_thread.joinable()) haptic_thread.join();
  if (model_thread.joinable()) model_thread.join();
  if (graphics_thread.joinable()) graphics_thread.join();
  if (sim.build_thread.joinable()) {
    {
      std::lock_guard lock(sim.build_mutex);
      sim.build_stop = true;
    }
    sim.build_signal.notify_one();
    sim.build_thread.join();
  }
  if (sim.device) sim.device->stop();
  const double elapsed = haptic ? end_time.load() : seconds_since(start);
  RunSummary summary = sim.summarize(haptic.get(), model.get(), graphics.get(), false, elapsed);
  Impl::fill_loop(summary.haptic, "haptic", 1.0 / rates.haptic_hz, *haptic_lateness, *haptic_work,
                  sim.settings.timing.late_threshold_s, haptic_skipped);
  Impl::fill_loop(summary.model, "model", 1.0 / rates.model_hz, *model_lateness, *model_work, 1.0 / rates.model_hz,
                  model_skipped);
  Impl::fill_loop(summary.graphics, "graphics", 1.0 / rates.graphics_hz, *graphics_lateness, *graphics_work,
                  1.0 / rates.graphics_hz, graphics_skipped);
  summary.haptic_thread = haptic_report;
  summary.force_history = std::move(history);
  return summary;
}

}  // namespace touchstone::realtime::runtime
