// The haptic tick (target: prediction check + force from K_t + safety filter ≤ 1 µs p99, headroom
// for 10 kHz).
// The real tick of the runtime is timed through its probe while a virtual-clock run plays a
// scripted palpation on a 20,480-triangle sphere: every tick's duration goes into a list, and
// the benchmark reports the median and p99 of free ticks (prediction: one distance, one
// comparison) and of contact ticks (F = K_t U, cross-fades, release test), each including the
// cost of the two clock reads that bracket it. Model builds (collocation, N = 40) happen
// in the model steps, outside the timed ticks — but in the same thread on a virtual clock, so
// a tick after a model step starts with colder caches than on the threaded runtime. A few free
// ticks make a (re-)prediction or full detection near the surface (hierarchy queries).
// Page faults dominated the p99 when the first tick to write each page of the reserved force
// history paid for it, so the buffers are touched before the run (figures: see README, Measured).
#include "touchstone/geometry/icosphere.hpp"
#include "touchstone/realtime/haptics/palpation_trajectory.hpp"
#include "touchstone/realtime/haptics/scripted_device.hpp"
#include "touchstone/realtime/runtime/simulation.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <vector>

namespace {

using namespace touchstone::realtime;
namespace geometry = touchstone::geometry;

struct TickTimer {
  std::chrono::steady_clock::time_point start;
  std::vector<double> durations_ns;
};

void tick_begin(void* context) { static_cast<TickTimer*>(context)->start = std::chrono::steady_clock::now(); }
void tick_end(void* context) {
  auto* timer = static_cast<TickTimer*>(context);
  timer->durations_ns.push_back(std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - timer->start).count());
}

double quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  return values[static_cast<std::size_t>(q * static_cast<double>(values.size() - 1))];
}

void BM_HapticTick(benchmark::State& state) {
  const runtime::ForceMode mode = state.range(0) == 0 ? runtime::ForceMode::stiffness : runtime::ForceMode::extrapolation;
  const auto mesh = geometry::icosphere(5, 0.05);
  const geometry::TriangleSurface organ(mesh.vertices, mesh.triangles, "icosphere");
  haptics::PalpationSettings palpation;
  palpation.generated_sites = 3;
  palpation.duration_s = 20;
  const auto path = haptics::make_palpation_trajectory(organ, palpation);
  runtime::SceneSettings scene;
  scene.model.formulation = mfs::Formulation::collocation;
  scene.model.sprinkling.node_count = 40;
  scene.model.force.haptic_method = mfs::default_haptic_method(mfs::Formulation::collocation, false);
  scene.model.force.energy = false;
  scene.model.force.reaction = false;
  scene.force_mode = mode;
  scene.record_force_history = true;  // to split the ticks into free and contact
  std::vector<double> free_ns, contact_ns;
  for (auto _ : state) {
    haptics::ScriptedDevice device(path.tip, path.tool_axis, path.sample_period_s);
    runtime::Simulation simulation(organ, scene, &device, {});
    TickTimer timer;
    timer.durations_ns.resize(path.tip.size() + 16);  // pages touched before the run
    timer.durations_ns.clear();
    simulation.set_haptic_tick_probe({tick_begin, tick_end, &timer});
    const runtime::RunSummary run = simulation.run_virtual();
    for (std::size_t k = 0; k < run.force_history.size() && k < timer.durations_ns.size(); ++k)
      (run.force_history[k].in_contact ? contact_ns : free_ns).push_back(timer.durations_ns[k]);
  }
  for (const auto& [name, ticks] : {std::pair{"free", &free_ns}, std::pair{"contact", &contact_ns}}) {
    state.counters[std::string(name) + "_p50_ns"] = quantile(*ticks, 0.5);
    state.counters[std::string(name) + "_p90_ns"] = quantile(*ticks, 0.9);
    state.counters[std::string(name) + "_p99_ns"] = quantile(*ticks, 0.99);
  }
  state.counters["ticks"] = static_cast<double>(free_ns.size() + contact_ns.size());
}
BENCHMARK(BM_HapticTick)->Arg(0)->Arg(1)->ArgNames({"extrapolation"})->Iterations(3)->Unit(benchmark::kMillisecond);

}  // namespace
