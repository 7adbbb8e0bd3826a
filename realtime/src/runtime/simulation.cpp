#include "touchstone/realtime/runtime/simulation.hpp"

#include "graphics_loop.hpp"
#include "haptic_loop.hpp"
#include "model_loop.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
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


double median_of(std::vector<double> values) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

}  // namespace

void RateSettings::validate() const {
  require_positive(haptic_hz, "rates.haptic_hz");
  require_positive(model_hz, "rates.model_hz");
  require_positive(graphics_hz, "rates.graphics_hz");
  if (model_hz > haptic_hz)
    throw std::invalid_argument("rates.model_hz = " + std::to_string(model_hz) + " must not exceed rates.haptic_hz = " +
                                std::to_string(haptic_hz));
  if (haptic_hz > max_haptic_hz)
    throw std::invalid_argument("rates.haptic_hz = " + std::to_string(haptic_hz) + " must be <= " +
                                std::to_string(max_haptic_hz) + " (haptic devices run at 1-10 kHz)");
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
  if (duration_s > max_duration_s)
    throw std::invalid_argument("duration_s = " + std::to_string(duration_s) + " must be <= " + std::to_string(max_duration_s) +
                                " (30 days)");
  require_non_negative(connect_timeout_s, "connect_timeout_s");
  if (model.paper_mode)
    throw std::invalid_argument("model.paper_mode: the paper's point tool gives no usable force (it tends to zero as the node cloud is refined); "
                                "the runtime needs a tool of finite radius");
  if (std::abs(prediction.cycle_period_s * rates.haptic_hz - 1) > 1e-9)
    throw std::invalid_argument("prediction.cycle_period_s = " + std::to_string(prediction.cycle_period_s) +
                                " must be 1 / rates.haptic_hz = " + std::to_string(1 / rates.haptic_hz));
}

// ---------------------------------------------------------------------------------------------
struct Simulation::Impl : RuntimeState {
  using RuntimeState::RuntimeState;

  Simulation::TickProbe probe;
  Simulation::ForceHistorySink history_sink;
  std::size_t history_chunk_samples = std::size_t(1) << 16;

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
      summary.exterior_used = model->exterior_used;
      summary.first_build_error = model->first_build_error;
      summary.first_exterior_note = model->first_exterior_note;
      summary.implausible_stiffness_models = model->implausible_stiffness_models;
      summary.first_implausible_stiffness_ratio = model->first_implausible_stiffness_ratio;
      summary.models = model->records;
      summary.models_not_recorded = model->records_dropped;
      if (model->records_dropped > 0)
        notes.push_back("model records: " + std::to_string(model->records_dropped) + " models beyond the first " +
                        std::to_string(max_model_records) + " were not recorded");
      if (work.model_build_failures > 0)
        notes.push_back(std::to_string(work.model_build_failures) + " of " + std::to_string(work.model_builds) +
                        " model builds failed (the force stayed on the previous model, or zero); the first: " +
                        model->first_build_error);
      if (model->implausible_stiffness_models > 0) {
        char text[256];
        std::snprintf(text, sizeof text,
                      " models had a normal stiffness outside [%g, %g] times the half-space punch's 2Ea/(1 - nu^2) "
                      "(the first: %.3g times): the local model is wrong there, not the tissue stiff",
                      mfs::plausible_stiffness_ratio_min, mfs::plausible_stiffness_ratio_max,
                      model->first_implausible_stiffness_ratio);
        notes.push_back(std::to_string(model->implausible_stiffness_models) + text);
      }
      if (!model->first_exterior_note.empty()) {
        const auto fallback = model->exterior_used.find("half_space");
        notes.push_back(std::to_string(fallback == model->exterior_used.end() ? 0 : fallback->second) +
                        " model builds used the half-space exterior in place of the body-aware one; the first because: " +
                        model->first_exterior_note);
      }
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

  /// The loops a run needs: haptic and model only with a device, graphics only with outputs.
  struct Loops {
    std::unique_ptr<HapticLoop> haptic;
    std::unique_ptr<ModelLoop> model;
    std::unique_ptr<GraphicsLoop> graphics;
    std::vector<ForceSample> history;
  };

  /// The force history's last chunk to the sink, or all of it into the summary.
  void hand_over_history(std::vector<ForceSample>& history, RunSummary& summary) {
    if (!history_sink) {
      summary.force_history = std::move(history);
      return;
    }
    if (!history.empty()) history_sink(history);
    history.clear();
  }

  /// Resets the shared state, starts the device and makes the loops (`synchronous`: builds
  /// complete within the model step, for the virtual clock).
  void prepare(bool synchronous, Loops& loops) {
    end_reason = "";
    notes.clear();
    deformation.reset();
    if (device) {
      device->start();
      loops.haptic = std::make_unique<HapticLoop>(*this);
      loops.model = std::make_unique<ModelLoop>(*this, synchronous);
      if (settings.record_force_history) {
        const double seconds = settings.duration_s > 0 ? settings.duration_s : 600.0;
        // Filled then emptied: the pages are touched now, not by the first tick to reach each
        // one (a page fault costs microseconds).
        const double ticks = seconds * settings.rates.haptic_hz + 16;
        std::size_t capacity = static_cast<std::size_t>(std::min(ticks, double(max_force_history_samples)));
        if (history_sink && synchronous) capacity = std::min(capacity, history_chunk_samples);
        loops.history.resize(capacity);
        loops.history.clear();
        loops.haptic->history = &loops.history;
      }
    }
    if (graphics_enabled()) loops.graphics = std::make_unique<GraphicsLoop>(*this);
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

void Simulation::set_haptic_tick_probe(const TickProbe& probe) noexcept { impl_->probe = probe; }

void Simulation::stream_force_history(ForceHistorySink sink, std::size_t chunk_samples) {
  if (chunk_samples < 1) throw std::invalid_argument("Simulation::stream_force_history: chunk_samples must be >= 1");
  impl_->history_sink = std::move(sink);
  impl_->history_chunk_samples = chunk_samples;
}

RunSummary Simulation::run_virtual(const std::atomic<bool>* stop) {
  Impl& sim = *impl_;
  const auto& rates = sim.settings.rates;
  const double period = 1.0 / rates.haptic_hz;
  const long long model_every = std::max(1LL, std::llround(rates.haptic_hz / rates.model_hz));
  Impl::Loops loops;
  sim.prepare(true, loops);
  auto& haptic = loops.haptic;
  auto& model = loops.model;
  auto& graphics = loops.graphics;
  auto& history = loops.history;
  for (auto* sink : sim.sinks) sink->begin(sim.organ);
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
      if (sim.history_sink && haptic->history && history.size() == history.capacity()) {
        sim.history_sink(history);
        history.clear();  // keeps the capacity: no allocation
      }
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
  sim.hand_over_history(history, summary);
  return summary;
}

RunSummary Simulation::run_threaded(const std::atomic<bool>* stop) {
  Impl& sim = *impl_;
  const auto& rates = sim.settings.rates;
  Impl::Loops loops;
  sim.prepare(false, loops);
  auto& haptic = loops.haptic;
  auto& model = loops.model;
  auto& graphics = loops.graphics;
  auto& history = loops.history;
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
  sim.hand_over_history(history, summary);
  return summary;
}

}  // namespace touchstone::realtime::runtime
