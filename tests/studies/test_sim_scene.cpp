// `touchstone sim` (studies/sim_scene): the scene file, a study-mode run with its outputs, and
// a recording replayed through the same scene.
#include "touchstone/studies/sim_scene.hpp"

#include "support/temporary_directory.hpp"
#include "touchstone/meshes/surface_mesh_io.hpp"
#include "touchstone/geometry/icosphere.hpp"
#include "touchstone/realtime/mfs/organ_atlas.hpp"
#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/provenance.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
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

// One settings table reads the scene, writes config.resolved.toml and summary.json params: the
// shipped scene, and a scene changed away from its defaults in every section, read back from
// their resolved configs (written in another folder) with every param and path equal.
TEST(SimScene, ResolvedSceneReadsBackEverySetting) {
  touchstone::testing::TemporaryDirectory directory("scene_resolved");
  const std::string changed = directory.file("changed.toml", R"(
scene = "changed"
duration = "2.5 s"
force_mode = "extrapolation"
[organ]
shape = "hemisphere"
triangles = 800
hemisphere_radius = "40 mm"
[material]
youngs_modulus = "12 kPa"
poisson_ratio = 0.4
[tool]
tip_radius = "2 mm"
contact = "bonded"
[model]
formulation = "galerkin"
[model.sprinkling]
node_count = 40
layout = "lattice"
[model.solver]
kind = "sparse_lu"
[device]
kind = "none"
max_force = "2.5 N"
[device.scripted]
site0 = ["1 mm", "2 mm", "30 mm"]
press_depth = "2 mm"
seed = 9
[device.openigtlink]
port = 18000
[rates]
model_hz = 100
[contact]
crossfade = "30 ms"
prebuild_on_prediction = false
[safety]
max_rate_N_per_s = 50
[prediction]
window_samples = 12
margin = "0.2 mm"
[timing]
fifo = false
[output]
frame_stride = 3
force_history = true
)");
  std::filesystem::create_directories(directory.path("elsewhere"));
  for (const std::string& path : {source_dir + "/studies/configs/scenes/palpation.toml", changed}) {
    SCOPED_TRACE(path);
    const SimScene scene = read_sim_scene(path);
    const std::string resolved = directory.file("elsewhere/" + scene.name + ".resolved.toml", resolved_scene_toml(scene));
    const SimScene back = read_sim_scene(resolved);
    EXPECT_EQ(sim_scene_params(back), sim_scene_params(scene));
    EXPECT_EQ(back.surface_path, scene.surface_path);
    EXPECT_EQ(back.palpation.sites, scene.palpation.sites);
  }
  const nlohmann::json params = sim_scene_params(read_sim_scene(changed));
  EXPECT_EQ(params.at("force_mode"), "extrapolation");
  EXPECT_EQ(params.at("model_formulation"), "galerkin");
  EXPECT_EQ(params.at("model_layout"), "lattice");
  EXPECT_EQ(params.at("node_count"), 40);
  EXPECT_DOUBLE_EQ(params.at("local_radius").get<double>(), 0.010) << "default 5 tip radii";
  EXPECT_DOUBLE_EQ(params.at("prediction_margin").get<double>(), 2e-4);
  EXPECT_EQ(params.at("contact"), "bonded");
  EXPECT_EQ(params.at("device_max_force"), 2.5);
  EXPECT_EQ(params.at("directory"), "output/changed");
}

/// `text` with what every scene must set (the material and the tool tip: a default would be a
/// guess) added where it lacks them, so that a snippet tests only its own error.
std::string with_required_keys(std::string text) {
  const auto ensure = [&text](const std::string& table, const std::string& line) {
    const std::string key = line.substr(0, line.find(' '));
    if (text.find("[" + table + "]\n") == std::string::npos)
      text += "[" + table + "]\n" + line + "\n";
    else if (text.find(key + " =") == std::string::npos)
      text.insert(text.find("[" + table + "]\n") + table.size() + 3, line + "\n");
  };
  ensure("material", "youngs_modulus = \"10 kPa\"");
  ensure("material", "poisson_ratio = 0.45");
  ensure("tool", "tip_radius = \"2.5 mm\"");
  return text;
}

void expect_scene_error(const std::string& text, const std::string& fragment) {
  touchstone::testing::TemporaryDirectory directory("scene");
  const std::string file = directory.file("bad.toml", with_required_keys(text));
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

// An empty scene runs nothing on defaults: the material and the tool tip are required, named;
// what a complete scene leaves out is reported as its defaults.
TEST(SimScene, TheMaterialAndTheTipAreRequiredAndDefaultsAreReported) {
  touchstone::testing::TemporaryDirectory directory("scene");
  for (const auto& [text, key] : std::vector<std::pair<std::string, std::string>>{
           {"scene = \"empty\"\n", "material.youngs_modulus"},
           {"[material]\nyoungs_modulus = \"10 kPa\"\n", "material.poisson_ratio"},
           {"[material]\nyoungs_modulus = \"10 kPa\"\npoisson_ratio = 0.45\n", "tool.tip_radius"}}) {
    try {
      read_sim_scene(directory.file("partial.toml", text));
      ADD_FAILURE() << "accepted without " << key;
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("missing key '" + key + "'"), std::string::npos) << e.what();
    }
  }
  const SimScene scene = read_sim_scene(directory.file("minimal.toml", with_required_keys("scene = \"minimal\"\n")));
  const auto& filled = scene.defaults_filled;
  const auto has = [&](const std::string& prefix) {
    return std::any_of(filled.begin(), filled.end(), [&](const std::string& s) { return s.rfind(prefix, 0) == 0; });
  };
  EXPECT_TRUE(has("duration = 60 s")) << ::testing::PrintToString(filled);
  EXPECT_TRUE(has("rates.haptic_hz = 1000")) << ::testing::PrintToString(filled);
  EXPECT_TRUE(has("model.sprinkling.local_radius = 0.0125 m")) << ::testing::PrintToString(filled);  // 5 tip radii
  EXPECT_FALSE(has("material.")) << ::testing::PrintToString(filled);
  EXPECT_FALSE(has("tool.tip_radius")) << ::testing::PrintToString(filled);
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
[material]
youngs_modulus = "10 kPa"
poisson_ratio = 0.45
[tool]
tip_radius = "2.5 mm"
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

// An organ file in millimetres: with [organ] unit_scale = 0.001 the run is the metre file's (the
// same contacts; forces within 0.1 %: a .vtp holds 32-bit coordinates, rounded differently in
// millimetres, and the largest force is sampled at the haptic ticks); without it the organ is
// 80 m across and the run says so (a note and a warning).
TEST(SimRun, AnOrganFileInMillimetresTakesAUnitScaleAndIsFlaggedWithout) {
  touchstone::testing::TemporaryDirectory directory("sim_units");
  const std::string metres_scene = small_scene(directory);
  auto mesh = geometry::icosphere(4, 0.04);
  for (auto& v : mesh.vertices) v *= 1000.0;
  meshes::write_surface_mesh(directory.path("sphere_mm.vtp"), mesh.vertices, mesh.triangles);
  std::string text = read_file(metres_scene);
  text.replace(text.find("duration = \"6 s\""), 16, "duration = \"3 s\"");
  const std::string metres = directory.file("metres.toml", text);
  text.replace(text.find("surface = \"sphere.vtp\""), 22, "surface = \"sphere_mm.vtp\"\nunit_scale = 0.001");
  const std::string scaled = directory.file("scaled.toml", text);
  text.replace(text.find("unit_scale = 0.001"), 18, "");
  text.replace(text.find("duration = \"3 s\""), 16, "duration = \"0.1 s\"");
  text += "[device]\nkind = \"none\"\n";  // the warning is the organ's; no palpation needed
  const std::string unscaled = directory.file("unscaled.toml", text);

  std::map<std::string, nlohmann::json> summary;
  for (const std::string& scene : {metres, scaled, unscaled}) {
    SimOptions options;
    options.virtual_clock = true;
    options.output_directory = directory.path("out_" + std::filesystem::path(scene).stem().string());
    options.print = false;
    summary[scene] = run_sim(read_sim_scene(scene), options);
  }
  const double force_N = summary[metres]["forces"]["max_force_N"].get<double>();
  EXPECT_GT(force_N, 0.01);
  EXPECT_NEAR(summary[scaled]["forces"]["max_force_N"].get<double>(), force_N, 1e-3 * force_N);
  EXPECT_EQ(summary[scaled]["work"]["contacts"], summary[metres]["work"]["contacts"]);
  const auto has_size_note = [](const nlohmann::json& s) {
    for (const auto& note : s["notes"])
      if (note.get<std::string>().find("unit_scale") != std::string::npos) return true;
    return false;
  };
  EXPECT_FALSE(has_size_note(summary[metres]));
  EXPECT_FALSE(has_size_note(summary[scaled]));
  EXPECT_TRUE(has_size_note(summary[unscaled])) << summary[unscaled]["notes"].dump();
  expect_scene_error("[organ]\nunit_scale = -1\n", "organ.unit_scale");
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

/// A 2.5 s palpation of one site of the organ in sphere.vtp (E = 10 kPa, ν = 0.45, frictionless,
/// 30 nodes at L = 12.5 mm); the strings are added to their tables.
struct SpherePalpation {
  std::string organ_lines, tip_radius = "2.5 mm", model_lines, scripted_lines = "slide = \"1 mm\"";
};

std::string sphere_palpation_scene(const std::string& name, const Eigen::Vector3d& site, const SpherePalpation& p) {
  return "scene = \"" + name + R"("
duration = "2.5 s"
[organ]
surface = "sphere.vtp"
)" + p.organ_lines + R"(
[material]
youngs_modulus = "10 kPa"
poisson_ratio = 0.45
[tool]
tip_radius = ")" + p.tip_radius + R"("
contact = "frictionless"
[model]
)" + p.model_lines + R"(
[model.sprinkling]
node_count = 30
local_radius = "12.5 mm"
[device.scripted]
site0 = [)" + std::to_string(site.x()) + ", " + std::to_string(site.y()) + ", " + std::to_string(site.z()) + R"(]
)" + p.scripted_lines + R"(
approach = "0.5 s"
hold = "0.3 s"
slide_time = "0.3 s"
release = "0.4 s"
rest = "0.2 s"
[output]
time_series = false
)";
}

// [organ] atlas gives the enriched model its body-aware exterior: with an atlas sample at the
// palpation site every build uses it (the summary counts the exterior of each build), and an
// exterior twice the half-space's stiffness makes the largest force larger than the run without
// the atlas, whose builds fall back to the half-space and say so. A missing atlas file is a
// config error naming the key.
TEST(SimRun, AnOrganAtlasGivesTheBuildsTheirBodyAwareExterior) {
  touchstone::testing::TemporaryDirectory directory("sim_atlas");
  const auto mesh = geometry::icosphere(4, 0.04);
  meshes::write_surface_mesh(directory.path("sphere.vtp"), mesh.vertices, mesh.triangles);
  const Eigen::Vector3d top = *std::max_element(mesh.vertices.begin(), mesh.vertices.end(),
                                                [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) { return a.z() < b.z(); });
  const auto scene_with = [&](const std::string& atlas_line, const std::string& name) {
    SpherePalpation palpation;
    palpation.organ_lines = atlas_line;
    return directory.file(name, sphere_palpation_scene("atlas", top, palpation));
  };

  realtime::mfs::OrganAtlas atlas;
  atlas.organ = "icosphere R = 40 mm";
  atlas.mode_count = 3;  // the sim pushes along the face normal, which may be oblique to the patch: all modes
  realtime::mfs::OrganAtlasSample sample;
  sample.label = "top";
  sample.contact_point_m = top;
  sample.direction = -top.normalized();
  sample.frame = realtime::mfs::PunchFrame::along(top, sample.direction);
  sample.tool_radius_m = 0.0025;
  sample.local_radius_m = 0.0125;
  sample.youngs_modulus_Pa = 10e3;
  sample.poisson_ratio = 0.45;
  // Twice the half-space's K_ext (normal 14.4899, tangential 7.32969 N/m: studies/organ_atlas).
  sample.half_space_stiffness_N_per_m.diagonal() << 14.4899, 7.32969, 7.32969;
  sample.stiffness_N_per_m.topLeftCorner<3, 3>() = 2 * sample.half_space_stiffness_N_per_m;
  atlas.samples.push_back(sample);
  realtime::mfs::write_organ_atlas(atlas, directory.path("atlas.json"));

  SimOptions options;
  options.virtual_clock = true;
  options.print = false;
  options.output_directory = directory.path("with");
  const nlohmann::json with = run_sim(read_sim_scene(scene_with("atlas = \"atlas.json\"", "with.toml")), options);
  options.output_directory = directory.path("without");
  const nlohmann::json without = run_sim(read_sim_scene(scene_with("", "without.toml")), options);
  const auto& used_with = with["model_builds"]["exterior_used"];
  const auto& used_without = without["model_builds"]["exterior_used"];
  ASSERT_TRUE(used_with.contains("body_aware")) << with["model_builds"].dump();
  EXPECT_FALSE(used_with.contains("half_space")) << with["model_builds"].dump();
  ASSERT_TRUE(used_without.contains("half_space")) << without["model_builds"].dump();
  EXPECT_FALSE(used_without.contains("body_aware"));
  EXPECT_GT(with["forces"]["max_force_N"].get<double>(), 1.01 * without["forces"]["max_force_N"].get<double>());

  try {
    read_sim_scene(scene_with("atlas = \"no_such_atlas.json\"", "missing.toml"));
    FAIL() << "a missing atlas was accepted";
  } catch (const ConfigError& error) {
    EXPECT_NE(std::string(error.what()).find("organ.atlas"), std::string::npos) << error.what();
  }
}

// A tip far finer than the organ's facets, pressed at a facet's centre (about 30 µm inside the
// sphere the facets approximate, more than a/10): every build succeeds, and the models' normal
// stiffness is the half-space punch's 2Ea/(1 − ν²), as it must be for a ≪ L ≪ R. The contact
// used to be judged against the fitted sphere (every build refused, the device felt nothing),
// and a push a fraction of a degree off the fitted normal locked the model (ten times too stiff).
// A model that is that wrong is counted and noted: the first Galerkin model at 30 nodes shows it.
TEST(SimRun, AFineTipOnACoarseOrganBuildsPlausibleModelsAndImplausibleOnesAreNoted) {
  touchstone::testing::TemporaryDirectory directory("sim_fine_tip");
  const auto mesh = geometry::icosphere(4, 0.04);
  meshes::write_surface_mesh(directory.path("sphere.vtp"), mesh.vertices, mesh.triangles);
  // The centre of the facet nearest the top.
  Eigen::Vector3d site = Eigen::Vector3d::Zero();
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d centre = (mesh.vertices[t[0]] + mesh.vertices[t[1]] + mesh.vertices[t[2]]) / 3;
    if (centre.z() > site.z()) site = centre;
  }
  ASSERT_GT(0.04 - site.norm(), 2e-5) << "the premise: the facet's centre lies well inside the sphere";
  const auto run = [&](const std::string& model_lines, const std::string& tip_radius, const std::string& name) {
    const SpherePalpation palpation{"", tip_radius, model_lines, "press_depth = \"0.5 mm\"\nslide = \"0.2 mm\""};
    const std::string text = sphere_palpation_scene("fine_tip", site, palpation);
    SimOptions options;
    options.virtual_clock = true;
    options.print = false;
    options.output_directory = directory.path(name);
    return run_sim(read_sim_scene(directory.file(name + ".toml", text)), options);
  };

  const nlohmann::json fine = run("", "0.05 mm", "enriched");
  EXPECT_EQ(fine["work"]["model_build_failures"], 0) << fine["model_builds"].dump();
  ASSERT_GE(fine["models"].size(), 1u);
  for (const auto& model : fine["models"]) {
    std::printf("fine tip, enriched: model %d stiffness / half-space's %.5f\n", model["model_id"].get<int>(),
                model["stiffness_ratio_to_half_space"].get<double>());
    EXPECT_NEAR(model["stiffness_ratio_to_half_space"].get<double>(), 1.0, 0.02) << model.dump();
  }
  EXPECT_EQ(fine["model_builds"]["implausible_stiffness_models"], 0);
  EXPECT_GT(fine["forces"]["max_force_N"].get<double>(), 0.0);

  // The first Galerkin model (no singular fields) at 30 nodes, with the usual tip: on the
  // identical domain it is about four times too stiff at this size.
  const nlohmann::json galerkin = run("formulation = \"galerkin\"", "2.5 mm", "galerkin");
  ASSERT_GE(galerkin["models"].size(), 1u) << galerkin["model_builds"].dump();
  EXPECT_EQ(galerkin["model_builds"]["implausible_stiffness_models"].get<long long>(),
            static_cast<long long>(galerkin["models"].size()));
  std::printf("usual tip, first Galerkin model: the first model's stiffness / half-space's %.3f\n",
              galerkin["model_builds"]["first_implausible_stiffness_ratio"].get<double>());
  EXPECT_GT(galerkin["model_builds"]["first_implausible_stiffness_ratio"].get<double>(), 4.0);
  const auto& notes = galerkin["notes"];
  EXPECT_TRUE(std::any_of(notes.begin(), notes.end(), [](const nlohmann::json& note) {
    return note.get<std::string>().find("outside [0.25, 4] times the half-space punch's") != std::string::npos;
  })) << notes.dump();
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

// The provenance hashes the scene file as it was read: the file is read once, so an edit made
// while the scene runs does not change what the run says it ran.
TEST(SimRun, TheProvenanceRecordsTheSceneAsRead) {
  touchstone::testing::TemporaryDirectory directory("sim");
  const std::string path = small_scene(directory);
  const std::string as_read = read_file(path);
  const SimScene scene = read_sim_scene(path);
  std::ofstream(path, std::ios::app) << "# edited after it was read\n";
  ASSERT_NE(read_file(path), as_read);
  SimOptions options;
  options.virtual_clock = true;
  options.print = false;
  options.output_directory = directory.path("run");
  const nlohmann::json results = run_sim(scene, options);
  EXPECT_EQ(results["provenance"]["config_sha256"], sha256_hex(as_read));
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
[material]
youngs_modulus = "10 kPa"
poisson_ratio = 0.45
[tool]
tip_radius = "2.5 mm"
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
