// No heap allocation in a haptic tick: buffers are sized when the model is built. Every heap
// allocation of this process goes through the malloc family, interposed here; a probe around
// each haptic tick counts what happens inside — through first contact, pressing, a re-sprinkle
// cross-fade, extrapolation, release, the end of the trajectory.
#include "touchstone/geometry/icosphere.hpp"
#include "touchstone/realtime/haptics/palpation_trajectory.hpp"
#include "touchstone/realtime/haptics/scripted_device.hpp"
#include "touchstone/realtime/runtime/simulation.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define TOUCHSTONE_INTERPOSE_MALLOC 0  // the sanitizers own malloc
#else
#define TOUCHSTONE_INTERPOSE_MALLOC 1
#endif

namespace {
thread_local bool counting = false;
std::atomic<long long> allocations{0};
}  // namespace

#if TOUCHSTONE_INTERPOSE_MALLOC
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);

void* malloc(std::size_t size) {
  if (counting) ++allocations;
  return __libc_malloc(size);
}
void* calloc(std::size_t count, std::size_t size) {
  if (counting) ++allocations;
  return __libc_calloc(count, size);
}
void* realloc(void* pointer, std::size_t size) {
  if (counting) ++allocations;
  return __libc_realloc(pointer, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) {
  if (counting) ++allocations;
  return __libc_memalign(alignment, size);
}
void* memalign(std::size_t alignment, std::size_t size) {
  if (counting) ++allocations;
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) {
  if (counting) ++allocations;
  *out = __libc_memalign(alignment, size);
  return *out ? 0 : 12;  // ENOMEM
}
}
#endif

namespace touchstone::realtime::runtime {
namespace {

void begin_counting(void*) { counting = true; }
void end_counting(void*) { counting = false; }

TEST(HapticTick, InterposedMallocCountsAllocations) {
#if !TOUCHSTONE_INTERPOSE_MALLOC
  GTEST_SKIP() << "sanitizer build: malloc belongs to the sanitizer";
#endif
  counting = true;
  void* volatile p = std::malloc(64);
  auto* volatile q = new int[8];
  counting = false;
  std::free(p);
  delete[] q;
  EXPECT_GE(allocations.load(), 2) << "the interposer must see malloc and operator new";
  allocations = 0;
}

class HapticTickAllocation : public ::testing::TestWithParam<ForceMode> {};

TEST_P(HapticTickAllocation, NoHeapAllocationInAnyTick) {
#if !TOUCHSTONE_INTERPOSE_MALLOC
  GTEST_SKIP() << "sanitizer build: malloc belongs to the sanitizer";
#endif
  const auto mesh = geometry::icosphere(4, 0.04);
  const geometry::TriangleSurface organ(mesh.vertices, mesh.triangles, "icosphere");
  haptics::PalpationSettings palpation;
  palpation.generated_sites = 2;
  palpation.duration_s = 9.0;
  palpation.slide_m = 0.006;  // a re-sprinkle and its cross-fade
  palpation.approach_s = 0.5;
  palpation.hold_s = 0.3;
  palpation.slide_s = 0.6;
  palpation.release_s = 0.5;
  palpation.rest_s = 0.2;
  palpation.transfer_s = 0.6;
  const auto path = haptics::make_palpation_trajectory(organ, palpation);
  haptics::ScriptedDevice device(path.tip, path.tool_axis, path.sample_period_s);
  SceneSettings scene;
  scene.model.formulation = mfs::Formulation::collocation;
  scene.model.sprinkling.node_count = 40;
  scene.model.force.haptic_method = mfs::default_haptic_method(mfs::Formulation::collocation, false);
  scene.model.force.energy = false;
  scene.model.force.reaction = false;
  scene.force_mode = GetParam();
  scene.record_force_history = true;  // the history is written inside the tick, too
  Simulation simulation(organ, scene, &device, {});
  simulation.set_haptic_tick_probe({begin_counting, end_counting, nullptr});
  allocations = 0;
  const RunSummary run = simulation.run_virtual();
  EXPECT_EQ(allocations.load(), 0) << "heap allocations inside haptic ticks";
  // The run did what the comment above says, so the count covers those paths.
  EXPECT_GE(run.work.contacts, 2);
  EXPECT_GE(run.work.model_resprinkles, 1);
  EXPECT_GE(run.forces.model_switches, 1);
  EXPECT_EQ(run.end_reason, "trajectory finished");
  EXPECT_GT(run.work.haptic_ticks, 8000);
}

INSTANTIATE_TEST_SUITE_P(ForceModes, HapticTickAllocation,
                         ::testing::Values(ForceMode::stiffness, ForceMode::extrapolation),
                         [](const auto& info) { return std::string(to_string(info.param)); });

}  // namespace
}  // namespace touchstone::realtime::runtime
