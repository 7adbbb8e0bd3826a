// The runtime (realtime/runtime/simulation): the three loops on a virtual clock (study mode) and
// on real threads, driven by the scripted palpation on a sphere — contact, force, safety, work
// skipped, determinism.
#include "touchstone/realtime/runtime/simulation.hpp"

#include "support/expect_invalid_argument.hpp"
#include "touchstone/geometry/icosphere.hpp"
#include "touchstone/realtime/haptics/palpation_trajectory.hpp"
#include "touchstone/realtime/haptics/palpation_device.hpp"
#include "touchstone/realtime/haptics/scripted_device.hpp"

#include <gtest/gtest.h>

#include <cstring>

namespace touchstone::realtime::runtime {
namespace {

const geometry::TriangleSurface& sphere_organ() {
  static const geometry::TriangleSurface organ = [] {
    auto mesh = geometry::icosphere(4, 0.04);  // 5120 triangles, radius 40 mm
    return geometry::TriangleSurface(mesh.vertices, mesh.triangles, "icosphere");
  }();
  return organ;
}

haptics::PalpationSettings palpation(double duration_s) {
  haptics::PalpationSettings p;
  p.generated_sites = 2;
  p.site_spread_m = 0.01;
  p.duration_s = duration_s;
  // A brisk palpation (2.4 s, transfers 1.8 s) so that short runs see several.
  p.approach_s = 0.5;
  p.hold_s = 0.3;
  p.slide_s = 0.6;
  p.release_s = 0.5;
  p.rest_s = 0.2;
  p.transfer_s = 0.6;
  p.tremor.rms_per_axis_m = 5e-5;
  p.seed = 7;
  return p;
}

/// The fast model: collocation (builds in milliseconds), no study-only force extractions.
SceneSettings fast_scene() {
  SceneSettings scene;
  scene.model.formulation = mfs::Formulation::collocation;
  scene.model.sprinkling.node_count = 60;
  scene.model.force.haptic_method = mfs::default_haptic_method(mfs::Formulation::collocation, false);
  scene.model.force.energy = false;
  scene.model.force.reaction = false;
  scene.timing.request_fifo = false;
  scene.record_force_history = true;
  return scene;
}

std::unique_ptr<haptics::ScriptedDevice> scripted(const haptics::PalpationTrajectory& path) {
  return std::make_unique<haptics::ScriptedDevice>(path.tip, path.tool_axis, path.sample_period_s);
}

TEST(Simulation, VirtualPalpationTouchesPressesAndReleases) {
  const auto path = haptics::make_palpation_trajectory(sphere_organ(), palpation(9.0));
  ASSERT_GE(path.palpations, 2);
  auto device = scripted(path);
  const SceneSettings scene = fast_scene();
  Simulation simulation(sphere_organ(), scene, device.get(), {});
  const RunSummary run = simulation.run_virtual();

  EXPECT_EQ(run.end_reason, "trajectory finished");
  EXPECT_EQ(run.work.contacts, path.palpations);
  EXPECT_EQ(run.prediction.releases, 0) << "releases are the runtime's, not the predictor's";
  EXPECT_GT(run.work.contact_ticks, 1000);
  // Every contact found its model ready: built at the predicted point before contact.
  EXPECT_EQ(run.work.contacts_with_model_ready, run.work.contacts);
  EXPECT_GE(run.work.model_prebuilds, path.palpations);
  EXPECT_EQ(run.forces.model_latency_max_s, 0.0);
  // Benign trajectory: no safety intervention, and a force of the right size: pressing 3 mm
  // into 10 kPa tissue with a 2.5 mm punch: a half-space gives F = 2 a δ E/(1 − ν²) ≈ 0.19 N.
  EXPECT_EQ(run.safety.interventions(), 0) << "clamped " << run.safety.clamped << " rate " << run.safety.rate_limited
                                           << " stale " << run.safety.stale << " nan " << run.safety.non_finite;
  EXPECT_GT(run.forces.max_force_N, 0.01);
  EXPECT_LT(run.forces.max_force_N, scene.safety.max_force_N);
  // The force pushes the tool out of the organ while pressed, and is zero while free.
  int pressed = 0;
  for (const ForceSample& s : run.force_history) {
    if (!s.in_contact) {
      ASSERT_EQ(s.force_on_hand_N.norm(), 0.0) << "t = " << s.time_s;
      continue;
    }
    const Eigen::Vector3d outward = s.tip_m.normalized();
    if (s.force_on_hand_N.norm() > 1e-3) {
      EXPECT_GT(s.force_on_hand_N.normalized().dot(outward), 0.9) << "t = " << s.time_s;
      ++pressed;
    }
  }
  EXPECT_GT(pressed, 1000);
}

TEST(Simulation, StiffnessForceIsKtTimesTheToolDisplacement) {
  const auto path = haptics::make_palpation_trajectory(sphere_organ(), palpation(5.0));
  auto device = scripted(path);
  SceneSettings scene = fast_scene();
  scene.contact.crossfade_s = 0;
  Simulation simulation(sphere_organ(), scene, device.get(), {});
  const RunSummary run = simulation.run_virtual();
  // In stiffness mode the device gets −(K_t U) exactly (no safety intervention, no fade).
  ASSERT_EQ(run.safety.interventions(), 0);
  int compared = 0;
  for (const ForceSample& s : run.force_history) {
    if (!s.in_contact) continue;
    EXPECT_EQ(s.force_on_hand_N, -s.exact_N) << "t = " << s.time_s;
    ++compared;
  }
  EXPECT_GT(compared, 500);
}

// Every model made current is recorded (c, d, K_t, why), and every tick with a force names its
// model: exact_N is that record's K_t (tip − c), push-only — what a replay through the reference
// FEM needs to pair each tick with the reference at the same contact.
TEST(Simulation, EveryTickNamesTheModelRecordItsForceCameFrom) {
  const auto path = haptics::make_palpation_trajectory(sphere_organ(), palpation(9.0));
  auto device = scripted(path);
  Simulation simulation(sphere_organ(), fast_scene(), device.get(), {});
  const RunSummary run = simulation.run_virtual();
  ASSERT_GE(run.models.size(), 2u);
  EXPECT_EQ(run.models_not_recorded, 0);
  EXPECT_EQ(static_cast<long long>(run.models.size()), run.work.model_builds - run.work.model_build_failures);
  for (std::size_t i = 0; i < run.models.size(); ++i) {
    const ModelRecord& m = run.models[i];
    EXPECT_EQ(m.model_id, i + 1);
    EXPECT_TRUE(m.reason == "contact" || m.reason == "prebuild" || m.reason == "resprinkle") << m.reason;
    EXPECT_NEAR(m.direction.norm(), 1.0, 1e-12);
    EXPECT_NEAR(m.contact_point_m.norm(), 0.04, 1e-3) << "on the sphere organ";
    EXPECT_GT(m.direction.dot(m.tool_stiffness_N_per_m * m.direction), 0.0);
    EXPECT_GT(m.node_count, 0u);
    if (i > 0) {
      EXPECT_GE(m.adopted_s, run.models[i - 1].adopted_s);
    }
  }
  int named = 0;
  for (const ForceSample& s : run.force_history) {
    if (s.model_id == 0) {
      EXPECT_EQ(s.exact_N.norm(), 0.0) << "t = " << s.time_s;
      continue;
    }
    ASSERT_LE(s.model_id, run.models.size());
    const ModelRecord& m = run.models[s.model_id - 1];
    EXPECT_LE(m.adopted_s, s.time_s);
    const Eigen::Vector3d expected =
        push_only(m.tool_stiffness_N_per_m * (s.tip_m - m.contact_point_m) + m.load_force_N, m.direction);
    EXPECT_LE((s.exact_N - expected).norm(), 1e-12 * (1 + expected.norm())) << "t = " << s.time_s;
    ++named;
  }
  EXPECT_GT(named, 1000);
}

TEST(Simulation, StudyModeIsBitReproducible) {
  const auto path = haptics::make_palpation_trajectory(sphere_organ(), palpation(6.0));
  SceneSettings scene = fast_scene();
  std::vector<ForceSample> first, second;
  for (auto* history : {&first, &second}) {
    auto device = scripted(path);
    Simulation simulation(sphere_organ(), scene, device.get(), {});
    *history = simulation.run_virtual().force_history;
  }
  ASSERT_EQ(first.size(), second.size());
  ASSERT_GT(first.size(), 5000U);
  for (std::size_t k = 0; k < first.size(); ++k) {
    ASSERT_EQ(std::memcmp(first[k].force_on_hand_N.data(), second[k].force_on_hand_N.data(), 3 * sizeof(double)), 0)
        << "tick " << k;
  }
}

TEST(Simulation, StreamedHistoryIsTheKeptHistoryInChunks) {
  // The same run kept in memory, then streamed in chunks of 1,000 ticks from a PalpationDevice
  // (poses computed as read): the same ticks, bit for bit, and no history left in the summary.
  haptics::PalpationSettings settings = palpation(6.0);
  const haptics::PalpationScript script = haptics::make_palpation_script(sphere_organ(), settings);
  const SceneSettings scene = fast_scene();
  auto device = scripted(haptics::sample_palpation_script(script));
  Simulation kept(sphere_organ(), scene, device.get(), {});
  const std::vector<ForceSample> whole = kept.run_virtual().force_history;
  ASSERT_GT(whole.size(), 5000U);

  haptics::PalpationDevice computed(script);
  Simulation streamed(sphere_organ(), scene, &computed, {});
  std::vector<ForceSample> chunks;
  std::size_t largest_chunk = 0, calls = 0;
  streamed.stream_force_history(
      [&](const std::vector<ForceSample>& chunk) {
        largest_chunk = std::max(largest_chunk, chunk.size());
        ++calls;
        chunks.insert(chunks.end(), chunk.begin(), chunk.end());
      },
      1000);
  const RunSummary run = streamed.run_virtual();
  EXPECT_TRUE(run.force_history.empty());
  EXPECT_EQ(largest_chunk, 1000U);
  EXPECT_EQ(calls, (whole.size() + 999) / 1000);
  ASSERT_EQ(chunks.size(), whole.size());
  for (std::size_t k = 0; k < whole.size(); ++k) {
    ASSERT_EQ(chunks[k].time_s, whole[k].time_s) << "tick " << k;
    ASSERT_EQ(chunks[k].tip_m, whole[k].tip_m) << "tick " << k;
    ASSERT_EQ(std::memcmp(chunks[k].force_on_hand_N.data(), whole[k].force_on_hand_N.data(), 3 * sizeof(double)), 0)
        << "tick " << k;
  }
  EXPECT_THROW(streamed.stream_force_history([](const std::vector<ForceSample>&) {}, 0), std::invalid_argument);
}

TEST(Simulation, ExtrapolationModeIsComparedWithTheExactForce) {
  const auto path = haptics::make_palpation_trajectory(sphere_organ(), palpation(5.0));
  auto device = scripted(path);
  SceneSettings scene = fast_scene();
  scene.force_mode = ForceMode::extrapolation;
  Simulation simulation(sphere_organ(), scene, device.get(), {});
  const RunSummary run = simulation.run_virtual();
  EXPECT_EQ(run.force_mode, ForceMode::extrapolation);
  EXPECT_GT(run.forces.compared_ticks, 500);
  EXPECT_GT(run.forces.extrapolation_updates, 100);
  // The paper's scheme lags the exact force; with tremor on a slow press it is off by a small
  // fraction of the force, not by nothing.
  EXPECT_GT(run.forces.extrapolation_error_rms_N, 0.0);
  EXPECT_LT(run.forces.extrapolation_error_rms_N, 0.1 * run.forces.max_force_N);
  EXPECT_GT(run.work.model_forces, 100);
}

TEST(Simulation, SkipsWhatTheSceneDoesNotNeed) {
  // No device: nothing runs — no haptic ticks, no model steps.
  {
    Simulation simulation(sphere_organ(), fast_scene(), nullptr, {});
    const RunSummary run = simulation.run_virtual();
    EXPECT_EQ(run.work.haptic_ticks, 0);
    EXPECT_EQ(run.work.model_steps, 0);
    EXPECT_EQ(run.work.graphics_frames, 0);
  }
  // A device and no outputs: no surface update. Free flight: the model loop idles, and the
  // haptic loop spends almost every free tick on one distance and one comparison.
  const auto path = haptics::make_palpation_trajectory(sphere_organ(), palpation(9.0));
  auto device = scripted(path);
  Simulation simulation(sphere_organ(), fast_scene(), device.get(), {});
  const RunSummary run = simulation.run_virtual();
  EXPECT_EQ(run.work.surface_updates, 0);
  EXPECT_EQ(run.work.vertices_written, 0);
  EXPECT_GT(run.work.model_idle_steps, run.work.model_steps / 3);
  EXPECT_LT(run.work.model_builds, 12);
  EXPECT_GT(run.prediction.cheap_checks, run.work.free_ticks * 8 / 10);
  EXPECT_LT(run.work.hierarchy_queries, run.work.free_ticks / 5);
}

TEST(Simulation, SlidingResprinklesWithoutAForceJump) {
  haptics::PalpationSettings p = palpation(8.0);
  p.slide_m = 0.008;  // beyond keep_fraction × L = 3.1 mm: at least two re-sprinkles per slide
  const auto path = haptics::make_palpation_trajectory(sphere_organ(), p);
  auto device = scripted(path);
  SceneSettings scene = fast_scene();
  Simulation simulation(sphere_organ(), scene, device.get(), {});
  const RunSummary run = simulation.run_virtual();
  EXPECT_GE(run.work.model_resprinkles, 2 * path.palpations);
  EXPECT_GE(run.forces.model_switches, 2);
  // The cross-fade spreads each switch's jump over crossfade_s: the per-tick step of the
  // request stays below jump × dt / crossfade_s plus the motion's own change (0.1 of it here).
  const double bound = run.forces.switch_jump_max_N * 1e-3 / scene.contact.crossfade_s * 1.1 + 1e-3;
  EXPECT_LE(run.forces.crossfade_step_max_N, bound);
  EXPECT_EQ(run.safety.interventions(), 0);
}

TEST(Simulation, ThreadedRunKeepsTheLoopsAtTheirRates) {
  haptics::PalpationSettings p = palpation(3.0);
#if defined(__SANITIZE_THREAD__) || defined(__SANITIZE_ADDRESS__)
  // Builds take seconds under a sanitizer: hold the press until the model has arrived.
  p.hold_s = 8.0;
  p.duration_s = 20.0;
#endif
  const auto path = haptics::make_palpation_trajectory(sphere_organ(), p);
  auto device = scripted(path);
  SceneSettings scene = fast_scene();
  Simulation simulation(sphere_organ(), scene, device.get(), {});
  const RunSummary run = simulation.run_threaded();
  EXPECT_EQ(run.end_reason, "trajectory finished");
  // Counts, not speed: about 1000 haptic ticks per second of trajectory (skipped deadlines
  // account for the rest), ~200 model steps per second.
  const double seconds = p.duration_s;
  EXPECT_NEAR(run.work.haptic_ticks + run.haptic.skipped_deadlines, 1000 * seconds, 60);
  EXPECT_NEAR(run.work.model_steps + run.model.skipped_deadlines, 200 * seconds, 30);
  EXPECT_GE(run.work.contacts, 1);
  EXPECT_GT(run.forces.max_force_N, 0.01);
  EXPECT_FALSE(run.haptic_thread.note.empty());
  for (const ForceSample& s : run.force_history) ASSERT_TRUE(s.force_on_hand_N.allFinite());
}

TEST(Simulation, InvalidSceneSettingsNameTheField) {
  SceneSettings scene = fast_scene();
  scene.rates.model_hz = 5000;
  testing::expect_invalid_argument([&] { Simulation s(sphere_organ(), scene, nullptr, {}); }, {"rates.model_hz"});
  scene = fast_scene();
  scene.contact.keep_fraction = 0.9;
  testing::expect_invalid_argument([&] { Simulation s(sphere_organ(), scene, nullptr, {}); }, {"contact.usable_fraction"});
  scene = fast_scene();
  scene.model.paper_mode = true;
  testing::expect_invalid_argument([&] { Simulation s(sphere_organ(), scene, nullptr, {}); }, {"paper_mode"});
  scene = fast_scene();
  scene.prediction.cycle_period_s = 0.01;
  testing::expect_invalid_argument([&] { Simulation s(sphere_organ(), scene, nullptr, {}); }, {"cycle_period_s"});
}

}  // namespace
}  // namespace touchstone::realtime::runtime
