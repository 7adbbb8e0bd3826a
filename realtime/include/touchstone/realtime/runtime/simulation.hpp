#pragma once
/// @file
/// The running system (paper §5–6, Fig. 7): a haptic loop at 1 kHz, a model loop
/// at ~200 Hz and a graphics loop at 30 Hz share one organ.
///
///   haptic (1 kHz)   device pose → contact (prediction: one distance + one comparison per tick
///                    while free) → force (F = K_t U, or the paper's extrapolation) → safety
///                    filter → device. No mutex, allocation or I/O.
///   model (~200 Hz)  on a predicted or actual contact: sprinkle, assemble, factorise, condense
///                    to K_t (a build worker does the heavy part, so the loop's heartbeat and
///                    forces continue meanwhile); re-sprinkle when the tool slides beyond a
///                    fraction of L; publish K_t and the contact frame.
///   graphics (30 Hz) the local field applied to the surface vertices in the local domain; the
///                    outputs (ParaView series, window, OpenIGTLink POLYDATA).
///
/// Threads exchange data through Seqlocks (haptic ↔ model, haptic → graphics); the model loop
/// hands the deformation map to graphics and build requests to its worker through small
/// mutex-guarded slots, which the haptic thread never touches.
///
/// Study mode runs the same three loops on a virtual clock, lock-step in one thread: tick k at
/// t = k/f_haptic, a model step every f_haptic/f_model ticks (builds complete within the step),
/// a graphics frame when due. Same seed, same force history, bit for bit.
///
/// Skip what a scene doesn't need: no device → no haptic or model thread; no graphics sink → no
/// graphics thread and no surface update; no contact or prediction → no model work; a valid
/// prediction → no hierarchy traversal; only vertices inside the local domain are moved. The
/// work counters of the run summary show each of these.

#include "touchstone/realtime/collision/bounding_volume_hierarchy.hpp"
#include "touchstone/realtime/collision/collision_prediction.hpp"
#include "touchstone/geometry/triangle_surface.hpp"
#include "touchstone/realtime/graphics/graphics_sink.hpp"
#include "touchstone/realtime/haptics/haptic_device.hpp"
#include "touchstone/realtime/haptics/safety_filter.hpp"
#include "touchstone/realtime/mfs/local_model.hpp"
#include "touchstone/geometry/material.hpp"
#include "touchstone/realtime/runtime/contact_model.hpp"
#include "touchstone/realtime/runtime/loop_timing.hpp"

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace touchstone::realtime::runtime {

/// Limits that keep a run's memory bounded and refuse absurd settings with a named error.
inline constexpr double max_haptic_hz = 100e3;           ///< [Hz]
inline constexpr double max_duration_s = 30 * 86400.0;   ///< [s]: 30 days
/// The force history keeps at most this many ticks (about 100 MB; 17 min at 1 kHz); ticks
/// beyond are counted and a note says so.
inline constexpr std::size_t max_force_history_samples = std::size_t(1) << 20;

struct RateSettings {
  double haptic_hz = 1000.0;
  double model_hz = 200.0;
  double graphics_hz = 30.0;
  void validate() const;
};

/// The rigid tool: a flat tip of radius a on a cylindrical shaft (graphics only).
struct ToolSettings {
  double tip_radius_m = 0.0025;
  double shaft_length_m = 0.08;
  double shaft_radius_m = 0.0015;
  geometry::ContactCondition condition = geometry::ContactCondition::frictionless;
  void validate() const;
};

/// How contacts are followed while the tool presses and slides.
struct ContactSettings {
  /// The contact point and local domain are kept while the tip stays within this fraction of L
  /// of the model's contact point (across the push direction); beyond, the model loop
  /// re-sprinkles at the tip's closest surface point.
  double keep_fraction = 0.25;
  /// A model is not used at all once the tip is farther than this fraction of L across d
  /// (the watchdog then ramps the force down until the new model arrives).
  double usable_fraction = 0.6;
  /// A new model replaces the old one by a linear cross-fade of their forces over this time
  /// (a model that arrives after its contact began fades in from zero): the per-tick step of
  /// the requested force at a switch is |F_new − F_old| × dt / crossfade_s plus the motion's own
  /// change.
  double crossfade_s = 0.02;
  /// Build the local model at the predicted collision point before contact (paper §3.1: the
  /// prediction leaves time to prepare), when the predicted contact is this close in time [s].
  bool prebuild_on_prediction = true;
  double prebuild_horizon_s = 1.0;
  /// Extrapolation mode: the longest extrapolation beyond the model loop's last force [s].
  double extrapolation_horizon_s = 0.01;
  void validate() const;
};

/// Haptic-thread scheduling.
struct TimingSettings {
  double spin_tail_s = 1e-4;   ///< busy-wait before each deadline
  bool request_fifo = true;    ///< ask for SCHED_FIFO (a refusal is reported, not fatal)
  int fifo_priority = 80;
  /// A haptic tick starting later than this after its deadline counts as late (the timing
  /// target: at most 0.2 % of the haptic ticks more than 0.5 ms late).
  double late_threshold_s = 5e-4;
  void validate() const;
};

struct SceneSettings {
  geometry::Material material;
  mfs::LocalModelSettings model;   ///< contact, direction and tool radius are set per contact
  /// The organ atlas of the enriched model's body-aware exterior; null: every build falls back to
  /// the half-space exterior and the run reports it.
  std::shared_ptr<const mfs::OrganAtlas> organ_atlas;
  ToolSettings tool;
  RateSettings rates;
  ForceMode force_mode = ForceMode::stiffness;
  ContactSettings contact;
  haptics::SafetySettings safety;
  collision::PredictionSettings prediction;
  collision::BvhSettings hierarchy;
  TimingSettings timing;
  /// Run length [s]; 0: until the device's trajectory ends or it disconnects (or Ctrl-C).
  double duration_s = 0;
  /// Waiting for a network device's first connection ends the run after this [s].
  double connect_timeout_s = 30.0;
  /// Keep the history of every tick's force (study mode; reserved before the run, at most
  /// max_force_history_samples).
  bool record_force_history = false;
  void validate() const;
};

/// One tick of the force history (study mode and tests).
struct ForceSample {
  double time_s = 0;
  Eigen::Vector3d tip_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d force_on_hand_N = Eigen::Vector3d::Zero();  ///< after the safety filter
  Eigen::Vector3d exact_N = Eigen::Vector3d::Zero();          ///< K_t U of the current model (on the tissue)
  bool in_contact = false;
  std::uint64_t model_id = 0;  ///< the model (ModelRecord::model_id) whose K_t gave exact_N; 0: none
};

/// The run keeps at most this many model records; later models are counted, not recorded.
inline constexpr std::size_t max_model_records = std::size_t(1) << 16;

/// One local model the model loop made current: where it was built, what it gives and how. A
/// replay of the run through the reference FEM solves the same contacts (c, d) and compares
/// its tool stiffness with K_t, tick by tick through ForceSample::model_id.
struct ModelRecord {
  std::uint64_t model_id = 0;     ///< 1, 2, …: ModelSnapshot::model_id
  double adopted_s = 0;           ///< run time at which the model became current [s]
  std::string reason;             ///< "contact", "prebuild" (at the predicted point), "resprinkle"
  Eigen::Vector3d contact_point_m = Eigen::Vector3d::Zero();  ///< c
  Eigen::Vector3d direction = -Eigen::Vector3d::UnitZ();      ///< d, unit, into the organ
  Eigen::Matrix3d tool_stiffness_N_per_m = Eigen::Matrix3d::Zero();  ///< K_t
  Eigen::Vector3d load_force_N = Eigen::Vector3d::Zero();     ///< F_loads
  std::string exterior_used;      ///< enriched: "clamped", "half_space", "body_aware"; else "none"
  std::size_t node_count = 0;
  double build_s = 0;             ///< wall time of the build [s]
  /// d·K_t·d over the half-space punch's 2Ea/(1 − ν²) (mfs::stiffness_ratio_to_half_space)
  double stiffness_ratio_to_half_space = 0;
};

/// Work done and skipped: a scene skips the work it doesn't need, and these counters show it.
struct WorkCounters {
  long long haptic_ticks = 0;
  long long free_ticks = 0;              ///< no contact
  long long contact_ticks = 0;
  long long hierarchy_queries = 0;       ///< BVH queries made by the haptic loop (prediction + detection)
  long long model_steps = 0;
  long long model_idle_steps = 0;        ///< no contact, no prediction: nothing done
  long long model_builds = 0;            ///< local models built
  long long model_prebuilds = 0;         ///< … of them at a predicted point before contact
  long long model_resprinkles = 0;       ///< … of them because the tool slid beyond keep_fraction × L
  long long model_build_failures = 0;
  long long model_forces = 0;            ///< forces computed by the model loop (extrapolation mode)
  long long contacts = 0;
  long long contacts_with_model_ready = 0;  ///< a usable model existed at the first contact tick
  long long graphics_frames = 0;
  long long surface_updates = 0;         ///< frames that recomputed vertex positions
  long long vertices_written = 0;        ///< vertex positions written (moved or restored)
  long long organ_vertices = 0;          ///< vertices of the organ, for comparison
  long long sink_errors = 0;
};

/// Force quality at haptic rate.
struct ForceStatistics {
  double max_force_N = 0;
  /// Extrapolated against exact F = K_t U over the contact ticks (both computed every tick,
  /// whichever mode drives the device) [N].
  double extrapolation_error_rms_N = 0, extrapolation_error_max_N = 0;
  long long compared_ticks = 0;
  /// Model switches: |F_new − F_old| at the switch (before the cross-fade) [N], and the largest
  /// per-tick change of the requested force during a cross-fade [N].
  long long model_switches = 0;
  double switch_jump_max_N = 0, switch_jump_mean_N = 0;
  double crossfade_step_max_N = 0;
  /// Models that arrived after their contact began (built too late): faded in from zero.
  long long late_model_fade_ins = 0;
  /// Extrapolation mode: the change of the requested force when a new model force arrives [N].
  long long extrapolation_updates = 0;
  double extrapolation_update_step_max_N = 0, extrapolation_update_step_mean_N = 0;
  /// Largest per-tick change of the output force [N].
  double output_step_max_N = 0;
  /// From the first contact tick to the first tick with a usable model [s] (p50, max).
  double model_latency_p50_s = 0, model_latency_max_s = 0;
  long long model_latency_samples = 0;
  /// Build times of the local models [s].
  double build_p50_s = 0, build_max_s = 0;
};

struct RunSummary {
  std::string device;
  bool virtual_clock = false;
  double duration_s = 0;
  std::string end_reason;  ///< "duration", "trajectory finished", "device disconnected", "stopped", …
  ForceMode force_mode = ForceMode::stiffness;
  LoopStatistics haptic, model, graphics;
  RealtimeThreadReport haptic_thread;
  haptics::SafetyCounters safety;
  collision::PredictionCounters prediction;
  WorkCounters work;
  ForceStatistics forces;
  std::vector<ForceSample> force_history;  ///< when SceneSettings::record_force_history
  /// Every model made current, in order (at most max_model_records; the rest are counted).
  std::vector<ModelRecord> models;
  long long models_not_recorded = 0;
  /// Successful model builds by the exterior the model used ("none" outside the enriched model).
  std::map<std::string, long long> exterior_used;
  std::string first_build_error;  ///< why the first failed model build failed ("" when none did)
  /// Why the first build that wanted the body-aware exterior fell back to the half-space (e.g. no
  /// organ atlas, or no atlas sample near the contact); "" when none did.
  std::string first_exterior_note;
  /// Models made current whose normal stiffness lies outside the plausible multiples of the
  /// half-space punch's (mfs::plausible_stiffness_ratio_min … max), and the first one's multiple
  /// (NaN when none did): a local model that is wrong, not stiff tissue.
  long long implausible_stiffness_models = 0;
  double first_implausible_stiffness_ratio = std::numeric_limits<double>::quiet_NaN();
  std::vector<std::string> notes;
};

class Simulation {
 public:
  /// Validates the settings and builds the collision hierarchy. `organ` must outlive the
  /// simulation. `device` may be null (a scene without a device); sinks may be empty.
  Simulation(const geometry::TriangleSurface& organ, const SceneSettings& settings, haptics::HapticDevice* device,
             std::vector<graphics::GraphicsSink*> sinks);
  ~Simulation();
  Simulation(const Simulation&) = delete;
  Simulation& operator=(const Simulation&) = delete;

  /// Runs on real threads until the duration, the trajectory's end, a disconnect or `stop`
  /// becomes true (may be null). Calls device start()/stop() and the sinks' begin()/end().
  RunSummary run_threaded(const std::atomic<bool>* stop = nullptr);
  /// Runs lock-step on a virtual clock (study mode): deterministic, as fast as the work allows.
  RunSummary run_virtual(const std::atomic<bool>* stop = nullptr);

  /// Hands the force history (SceneSettings::record_force_history) to `sink` in time order, in
  /// chunks of at most `chunk_samples` ticks, instead of RunSummary::force_history: on the virtual
  /// clock a chunk goes out whenever it fills, so a run's memory does not grow with its
  /// duration and no tick is dropped; a threaded run (whose haptic thread must not do I/O)
  /// keeps its bounded history and hands it over at the end. Call before running.
  using ForceHistorySink = std::function<void(const std::vector<ForceSample>&)>;
  void stream_force_history(ForceHistorySink sink, std::size_t chunk_samples = std::size_t(1) << 16);

  /// Instrumentation for tests: called right before and after every haptic tick, in the
  /// haptic thread (e.g. to count heap allocations inside the tick). Null: none.
  struct TickProbe {
    void (*before)(void* context) = nullptr;
    void (*after)(void* context) = nullptr;
    void* context = nullptr;
  };
  void set_haptic_tick_probe(const TickProbe& probe) noexcept;

 private:
  struct Impl;
  Impl* impl_;
};

}  // namespace touchstone::realtime::runtime
