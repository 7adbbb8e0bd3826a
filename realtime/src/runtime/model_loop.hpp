#pragma once
// Private to realtime/src/runtime: the model loop (~200 Hz). It builds local models at
// predicted and actual contacts and when the tool slides, publishes K_t and the contact frame,
// and computes the model-rate force the paper extrapolated. The builds run on a worker thread
// (RuntimeState::build_worker), so the loop's heartbeat never stops for one.

#include "runtime_state.hpp"

#include <limits>
#include <map>
#include <string>

namespace touchstone::realtime::runtime {

struct ModelLoop {
  RuntimeState& sim;
  bool synchronous;  ///< virtual clock: builds complete within the step
  std::shared_ptr<const mfs::LocalModel> model;
  ModelSnapshot snapshot;
  bool build_in_flight = false;
  BuildRequest in_flight;
  std::vector<double> build_times_s;
  WorkCounters work;  // model fields only
  /// Builds that succeeded, by the exterior the model used (enriched: "clamped", "half_space",
  /// "body_aware", or "half_space" after a body-aware fallback); other formulations: "none".
  std::map<std::string, long long> exterior_used;
  std::string first_build_error;  ///< why the first failed build failed ("" when none did)
  std::string first_exterior_note;  ///< why the first build without its body-aware exterior fell back ("" when none did)
  /// Models made current with an implausible normal stiffness, and the first one's multiple of
  /// the half-space punch's (NaN: none).
  long long implausible_stiffness_models = 0;
  double first_implausible_stiffness_ratio = std::numeric_limits<double>::quiet_NaN();
  std::vector<ModelRecord> records;  ///< every model made current (at most max_model_records)
  long long records_dropped = 0;
  double now_s = 0;                  ///< the current step's time [s]

  ModelLoop(RuntimeState& sim_, bool synchronous_) : sim(sim_), synchronous(synchronous_) {}

  /// Hands a build to the worker (virtual clock: builds it now).
  void request(const BuildRequest& request);
  /// Takes a finished build from the worker, if any.
  void collect();
  /// Makes a built model current: a new model id, K_t and the contact frame for the haptic
  /// loop, the deformation map for graphics. A failed build keeps the previous model.
  void adopt(BuildResult result);
  /// A current model whose contact point is within keep_fraction × L of `point`, facing it.
  bool near_model(const Eigen::Vector3d& point, const Eigen::Vector3d& outward_normal) const;
  /// A build in flight within keep_fraction × L of `point`.
  bool near_in_flight(const Eigen::Vector3d& point) const;
  /// One step at `time_s`: decide what to build, compute the model-rate force, publish.
  void step(double time_s);
};

}  // namespace touchstone::realtime::runtime
