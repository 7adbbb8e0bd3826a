#pragma once
// Private to realtime/src/runtime: the state the three loops of a Simulation share, and what
// they hand each other. Public types are in include/touchstone/realtime/runtime/simulation.hpp.

#include "touchstone/realtime/concurrency/seqlock.hpp"
#include "touchstone/realtime/runtime/simulation.hpp"
#include "touchstone/realtime/runtime/surface_deformation.hpp"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace touchstone::realtime::runtime {

using concurrency::Seqlock;

inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// What the haptic loop publishes for the model and graphics loops (a Seqlock payload).
struct HapticState {
  double time_s = 0;
  PlainVector3 tip_m{}, tool_axis{0, 0, 1};
  PlainVector3 force_on_hand_N{};
  bool in_contact = false;
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

/// The organ, the settings, the device and outputs, the collision hierarchy, and the hand-offs
/// between the loops. The haptic loop touches only the Seqlocks and `end_reason`.
struct RuntimeState {
  const geometry::TriangleSurface& organ;
  SceneSettings settings;
  haptics::HapticDevice* device;
  std::vector<graphics::GraphicsSink*> sinks;
  collision::BoundingVolumeHierarchy hierarchy;

  RuntimeState(const geometry::TriangleSurface& organ_, const SceneSettings& settings_, haptics::HapticDevice* device_,
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

  /// Builds a local model at the request's point (and its deformation map when graphics runs).
    /// Never throws: an exception ends in BuildResult::error.
    BuildResult build(const BuildRequest& request) const;
    /// The build worker thread's loop: one request at a time, the newest replacing a waiting one.
    void build_worker();

  std::mutex notes_mutex;  // graphics ↔ driver
  std::vector<std::string> notes;
};

}  // namespace touchstone::realtime::runtime
