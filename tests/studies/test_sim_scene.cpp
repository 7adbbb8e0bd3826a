// `touchstone sim` (studies/sim_scene): the scene file, a study-mode run with its outputs, and
// a recording replayed through the same scene.
#include "touchstone/studies/sim_scene.hpp"

#include "support/temporary_directory.hpp"
#include "touchstone/meshes/surface_mesh_io.hpp"
#include "touchstone/geometry/icosphere.hpp"
#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/provenance.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>

namespace touchstone::studies {
namespace {

const std::string source_dir = TOUCHSTONE_SOURCE_DIR;

TEST(SimScene, ReadsTheShippedPalpationScene) {
  const SimScene scene = read_sim_scene(source_dir + "/studies/configs/scenes/palpation.toml");
  EXPECT_EQ(scene.name, "palpation");
  EXPECT_EQ(scene.settings.duration_s, 60.0);
  EXPECT_EQ(scene.generated_organ.shape, meshes::OrganShape::stomach);
  EXPECT_EQ(scene.generated_organ.target_triangles, 20000);
  EXPECT_EQ(scene.settings.material.youngs_modulus_Pa, 10e3);
  EXPECT_EQ(scene.settings.model.formulation, realtime::mfs::Formulation::enriched);
  EXPECT_EQ(scene.settings.model.sprinkling.node_count, 35);
  EXPECT_DOUBLE_EQ(scene.settings.tool.tip_radius_m, 2.5e-3);
  EXPECT_EQ(scene.device, DeviceKind::scripted);
  EXPECT_DOUBLE_EQ(scene.palpation.press_depth_m, 3e-3);
  EXPECT_EQ(scene.settings.rates.haptic_hz, 1000.0);
  EXPECT_EQ(scene.settings.force_mode, realtime::runtime::ForceMode::stiffness);
  EXPECT_FALSE(scene.settings.model.force.energy) << "the energy quadrature is a study quantity";
}

void expect_scene_error(const std::string& text, const std::string& fragment) {
  touchstone::testing::TemporaryDirectory directory("scene");
  const std::string file = directory.file("bad.toml", text);
  try {
    read_sim_scene(file);
    ADD_FAILURE() << "accepted; expected an error mentioning " << fragment;
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("bad.toml"), std::string::npos) << e.what();
  }
}

TEST(SimScene, BadScenesNameTheFileAndKey) {
  expect_scene_error("dration = \"60 s\"\n", "dration");
  expect_scene_error("force_mode = \"magic\"\n", "force_mode");
  expect_scene_error("[device]\nkind = \"phantom\"\n", "kind");
  expect_scene_error("[organ]\nsurface = \"nowhere.vtp\"\n", "organ.surface");
  expect_scene_error("[safety]\nmax_force = \"-1 N\"\n", "max_force");
  expect_scene_error("[rates]\nmodel_hz = 5000\n", "rates.model_hz");
  expect_scene_error("[material]\npoisson_ratio = 0.5\n", "poisson_ratio");
  expect_scene_error("[device]\nkind = \"replay\"\n", "replay");
  expect_scene_error("[model.sprinkling]\nnode_count = \"many\"\n", "node_count");
  // Absurd run lengths and rates are refused before anything is reserved for them.
  expect_scene_error("duration = \"1e9 s\"\n", "duration");
  expect_scene_error("[rates]\nhaptic_hz = 1e9\n", "rates.haptic_hz");
  // A tip that does not fit in the local ball: every build would fail and the device feel nothing.
  expect_scene_error("[tool]\ntip_radius = \"2.5 mm\"\n[model.sprinkling]\nlocal_radius = \"4 mm\"\n",
                     "tool.tip_radius");
}

/// A small scene on a sphere written to a file: collocation (fast builds), 6 s of palpation.
std::string small_scene(const touchstone::testing::TemporaryDirectory& directory) {
  const auto mesh = geometry::icosphere(4, 0.04);
  meshes::write_surface_mesh(directory.path("sphere.vtp"), mesh.vertices, mesh.triangles);
  return directory.file("small.toml", R"(
scene = "small"
duration = "6 s"
[organ]
surface = "sphere.vtp"
[model]
formulation = "collocation"
[model.sprinkling]
node_count = 40
[model.force]
reaction = false
[device.scripted]
generated_sites = 2
site_spread = "8 mm"
approach = "0.5 s"
hold = "0.3 s"
slide_time = "0.6 s"
release = "0.5 s"
rest = "0.2 s"
transfer = "0.6 s"
[output]
frame_stride = 10
)");
}

TEST(SimRun, StudyModeWritesSummaryForcesAndATimeSeries) {
  touchstone::testing::TemporaryDirectory directory("sim");
  const SimScene scene = read_sim_scene(small_scene(directory));
  SimOptions options;
  options.virtual_clock = true;
  options.output_directory = directory.path("out");
  options.print = false;
  const nlohmann::json summary = run_sim(scene, options);
  EXPECT_EQ(summary["clock"], "virtual");
  EXPECT_EQ(summary["end_reason"], "duration");
  EXPECT_EQ(summary["loops"]["haptic"]["ticks"], 6000);
  EXPECT_GE(summary["work"]["contacts"].get<int>(), 1);
  EXPECT_EQ(summary["safety"]["interventions"], 0);
  EXPECT_TRUE(summary.contains("provenance"));
  // The files: summary.json (the same document), forces.csv (a line per tick), the PVDs.
  const auto written = nlohmann::json::parse(read_file(directory.path("out/summary.json")));
  EXPECT_EQ(written["work"], summary["work"]);
  std::ifstream csv(directory.path("out/forces.csv"));
  int lines = 0;
  for (std::string line; std::getline(csv, line);) ++lines;
  EXPECT_EQ(lines, 6001);
  ASSERT_TRUE(summary.contains("time_series"));
  EXPECT_TRUE(std::filesystem::exists(summary["time_series"]["organ_pvd"].get<std::string>()));
  EXPECT_EQ(summary["time_series"]["frames_written"], 18);  // 180 frames at 30 Hz, every 10th
  // ParaView's readers open the series (python3-vtk9).
  const std::string check = "/usr/bin/python3 " + source_dir + "/tests/realtime/graphics/check_vtp_series.py " +
                            directory.path("out") + " small 18";
  EXPECT_EQ(std::system(check.c_str()), 0) << check;
}

TEST(SimRun, ARecordingReplaysToTheSameForces) {
  touchstone::testing::TemporaryDirectory directory("sim");
  const SimScene scene = read_sim_scene(small_scene(directory));
  SimOptions options;
  options.virtual_clock = true;
  options.print = false;
  options.output_directory = directory.path("recorded");
  options.record_path = directory.path("recording.csv");
  const nlohmann::json recorded = run_sim(scene, options);
  EXPECT_EQ(recorded["recording"]["samples"], 6000);
  options.record_path.clear();
  options.replay_path = directory.path("recording.csv");
  options.output_directory = directory.path("replayed");
  const nlohmann::json replayed = run_sim(scene, options);
  EXPECT_EQ(replayed["device"], "replay");
  EXPECT_EQ(read_file(directory.path("recorded/forces.csv")), read_file(directory.path("replayed/forces.csv")));
}


// A generated organ is cached under a name that changes with every parameter: a changed
// parameter never reuses the old organ.
TEST(SimScene, GeneratedOrganCacheNameCoversEveryParameter) {
  meshes::OrganParameters base;
  const std::string name = generated_organ_cache_name(base);
  EXPECT_EQ(name, generated_organ_cache_name(base));
  std::set<std::string> names{name};
  auto changed = [&](auto change) {
    meshes::OrganParameters p = base;
    change(p);
    return names.insert(generated_organ_cache_name(p)).second;
  };
  EXPECT_TRUE(changed([](auto& p) { p.shape = meshes::OrganShape::hemisphere; }));
  EXPECT_TRUE(changed([](auto& p) { p.target_triangles += 1; }));
  EXPECT_TRUE(changed([](auto& p) { p.relative_tolerance = 0.04; }));
  EXPECT_TRUE(changed([](auto& p) { p.stomach_scale = 1.1; }));
  EXPECT_TRUE(changed([](auto& p) { p.stomach_flattening = 0.8; }));
  EXPECT_TRUE(changed([](auto& p) { p.hemisphere_radius_m = 0.06; }));
  EXPECT_TRUE(changed([](auto& p) { p.max_passes = 5; }));
}

// A truncated cached organ (a run killed while writing it) is generated again, and the run
// goes on with the regenerated organ.
TEST(SimRun, ATruncatedCachedOrganIsGeneratedAgain) {
  touchstone::testing::TemporaryDirectory directory("sim");
  const std::string scene_path = directory.file("generated.toml", R"(
scene = "generated"
duration = "3 s"
[organ]
shape = "hemisphere"
triangles = 600
hemisphere_radius = "40 mm"
[model]
formulation = "collocation"
[model.sprinkling]
node_count = 40
[model.force]
reaction = false
[device.scripted]
generated_sites = 1
approach = "0.5 s"
hold = "0.3 s"
slide_time = "0.6 s"
release = "0.5 s"
rest = "0.2 s"
transfer = "0.6 s"
[output]
frame_stride = 10
)");
  const SimScene scene = read_sim_scene(scene_path);
  SimOptions options;
  options.virtual_clock = true;
  options.print = false;
  options.output_directory = directory.path("out");
  const nlohmann::json first = run_sim(scene, options);
  const std::string cached = directory.path("out/" + generated_organ_cache_name(scene.generated_organ));
  ASSERT_TRUE(std::filesystem::exists(cached)) << cached;
  const std::string text = read_file(cached);
  write_file_atomically(cached, text.substr(0, text.size() / 3));
  const nlohmann::json second = run_sim(scene, options);
  EXPECT_EQ(second["organ_triangles"], first["organ_triangles"]);
  EXPECT_EQ(read_file(cached), text);  // regenerated: gmsh is deterministic for the parameters
}

}  // namespace
}  // namespace touchstone::studies
