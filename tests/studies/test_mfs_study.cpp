// `touchstone mfs` end to end on a tiny sweep (N = 34, 60 on the B2 hemisphere): the
// results.json contract (the fields other tools read), the resolved config, the VTU files, and
// config errors that name the file and the key or field.
#include "touchstone/studies/fem_reference/config_reader.hpp"
#include "touchstone/studies/mfs_study.hpp"
#include "touchstone/meshes/surface_mesh_io.hpp"
#include "touchstone/studies/fem_reference/probes.hpp"
#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/provenance.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <string>

namespace touchstone::studies {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// A coarse organ surface keeps gmsh quick; the local ball is still a few hundred triangles.
const std::string tiny_config = R"(
study = "tiny_mfs"
formulation = "galerkin"
[geometry]
benchmark = "B2"
body_radius = "50 mm"
tool_radius = "2.5 mm"
[organ]
edge_size = "0.5 mm"
size_growth = 0.3
max_size = "8 mm"
[material]
youngs_modulus = "10 kPa"
poisson_ratio = 0.45
[tool]
depth = "0.25 mm"
contact = "frictionless"
[sprinkling]
node_count = [34, 60]
local_radius = "12.5 mm"
[force]
cut_polar_points = 12
cut_azimuth_points = 24
volume_radial_points = 8
volume_polar_points = 12
volume_azimuth_points = 16
[mls]
max_support_scale = 2.0   # 34 nodes with the quadratic basis need the supports to grow near the cut
)";

// The pid keeps parallel test processes (ctest -j runs each test in its own) apart.
fs::path temp_directory() {
  static const fs::path path = fs::temp_directory_path() / ("touchstone_test_mfs_study_" + std::to_string(getpid()));
  return path;
}

class RemoveTemporaries : public ::testing::Environment {
 public:
  void TearDown() override { fs::remove_all(temp_directory()); }
};
const auto* const remove_temporaries = ::testing::AddGlobalTestEnvironment(new RemoveTemporaries);

/// Reads `text` as a config named `name`; the ConfigError message, or "" when it is valid.
// What every MFS study file must set (the problem: a default would be a guess), for the
// snippets below that test something else; the body's size comes with the organ or separately.
const std::string problem_keys =
    "[geometry]\ntool_radius = \"2.5 mm\"\n[material]\nyoungs_modulus = \"10 kPa\"\npoisson_ratio = 0.45\n[tool]\ndepth = \"0.25 mm\"\n";
const std::string problem_keys_with_body =
    "[geometry]\nbody_radius = \"50 mm\"\ntool_radius = \"2.5 mm\"\n[material]\nyoungs_modulus = \"10 kPa\"\npoisson_ratio = 0.45\n[tool]\ndepth = \"0.25 mm\"\n";

std::string config_error(const std::string& text, const std::string& name = "bad.toml") {
  try {
    ConfigTable config = ConfigTable::from_string(text, name);
    read_mfs_study(config, temp_directory().string());
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

/// tiny_config with `from` replaced by `to` (which must occur).
std::string edited(const std::string& from, const std::string& to) {
  std::string text = tiny_config;
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

class MfsStudyRun : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    fs::remove_all(temp_directory());
    fs::create_directories(temp_directory());
    const fs::path config_path = temp_directory() / "tiny_mfs.toml";
    write_file_atomically(config_path.string(), tiny_config);
    ConfigTable config = ConfigTable::from_file(config_path.string());
    const MfsStudy study = read_mfs_study(config, temp_directory().string());
    MfsRunOptions options;
    options.output_directory = output().string();
    options.config_text = tiny_config;
    options.quiet = true;
    *returned = run_mfs_study(study, options);
  }
  static fs::path output() { return temp_directory() / "out"; }
  static inline json* returned = new json;
};

TEST_F(MfsStudyRun, ResultsJsonCarriesTheContract) {
  const json document = json::parse(read_file((output() / "results.json").string()));
  EXPECT_EQ(document, *returned);
  EXPECT_EQ(document.at("study"), "tiny_mfs");
  for (const char* key : {"git", "build_type", "compiler", "machine", "config_sha256"})
    EXPECT_TRUE(document.at("provenance").contains(key)) << key;
  EXPECT_EQ(document.at("provenance").at("config_sha256"), sha256_hex(tiny_config));
  EXPECT_GT(document.at("organ").at("triangles").get<int>(), 500);

  const json& cases = document.at("cases");
  ASSERT_EQ(cases.size(), 2u);
  const int requested[] = {34, 60};
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const json& c = cases[i];
    SCOPED_TRACE(c.dump().substr(0, 400));
    EXPECT_EQ(c.at("id"), "MFS-frictionless-N" + std::to_string(requested[i]));
    EXPECT_EQ(c.at("model"), "mfs");
    EXPECT_EQ(c.at("status"), "ok");
    EXPECT_TRUE(c.at("reference").is_null());
    for (const char* key : {"force_rel", "disp_rel_l2", "disp_max_m"}) EXPECT_TRUE(c.at("error").contains(key)) << key;
    for (const char* key : {"build", "solve", "total", "sprinkle", "assembly", "factorize", "condense", "force"}) {
      ASSERT_TRUE(c.at("time_s").at(key).is_number()) << key;
      EXPECT_GE(c.at("time_s").at(key).get<double>(), 0.0) << key;
    }
    // The build time is the median of up to five builds, repeated while they have taken less
    // than 0.25 s: a second build exactly when the first took less than that.
    const json& time = c.at("time_s");
    const int samples = time.at("build_samples").get<int>();
    EXPECT_GE(samples, 1);
    EXPECT_LE(samples, 5);
    EXPECT_EQ(samples >= 2, time.at("build_first").get<double>() < 0.25);
    EXPECT_NEAR(time.at("total").get<double>(),
                time.at("build").get<double>() + time.at("solve").get<double>() + time.at("force").get<double>(), 1e-12);

    const json& params = c.at("params");
    EXPECT_EQ(params.at("node_count_requested"), requested[i]);
    // The sprinkler lands within a few per cent of the target N.
    EXPECT_NEAR(params.at("node_count").get<double>(), requested[i], 0.25 * requested[i]);
    for (const char* key : {"extra_points", "basis", "oversampling", "radius_factor", "local_radius_m"})
      EXPECT_TRUE(params.contains(key)) << key;
    EXPECT_DOUBLE_EQ(params.at("local_radius_m").get<double>(), 0.0125);

    const json& qoi = c.at("qoi");
    ASSERT_EQ(qoi.at("force_N").size(), 3u);
    for (const auto& component : qoi.at("force_N")) EXPECT_TRUE(component.is_number());
    // The force's accuracy is the engine's business (and the study runner's, against the FEM);
    // here: it is a number, and the stiffness is |F·d|/δ with d = −z.
    const double f_z = qoi.at("force_N").at(2).get<double>();
    EXPECT_GT(std::abs(f_z), 0.0);
    EXPECT_NEAR(qoi.at("stiffness_N_per_m").get<double>(), std::abs(f_z) / 0.00025, 1e-9 * std::abs(f_z) / 0.00025);
    EXPECT_GT(qoi.at("energy_J").get<double>(), 0.0);
    EXPECT_NEAR(qoi.at("k_star").get<double>(), -f_z / (10e3 * 0.0025 * 0.00025), 1e-9 * std::abs(qoi.at("k_star").get<double>()));
    const json& by_method = qoi.at("forces_by_method_N");
    for (const char* method : {"traction_integral", "reaction", "paper_partition"}) {
      ASSERT_EQ(by_method.at(method).size(), 3u) << method;
      for (const auto& component : by_method.at(method)) EXPECT_TRUE(component.is_number()) << method;
    }
    EXPECT_TRUE(by_method.at("energy_along_tool").is_number());
    // The haptic force is K_t U_tool by the reaction (the default method).
    EXPECT_NEAR(by_method.at("reaction").at(2).get<double>(), f_z, 1e-9 * std::abs(f_z));
    ASSERT_EQ(qoi.at("tool_stiffness_matrix_N_per_m").size(), 3u);
    EXPECT_GT(qoi.at("min_rcond").get<double>(), 0.0);

    // Probes inside the local ball only (0.9 L = 11.25 mm from the contact point).
    const json& probes = qoi.at("probes");
    ASSERT_FALSE(probes.empty());
    for (const auto& probe : probes) {
      const json& p = probe.at("position_m");
      const double distance = std::hypot(p.at(0).get<double>(), p.at(1).get<double>(), p.at(2).get<double>() - 0.05);
      EXPECT_LT(distance, 0.9 * 0.0125) << probe.at("name");
      ASSERT_TRUE(probe.at("displacement_m").is_array()) << probe.at("name");
    }
    EXPECT_EQ(probes.front().at("name"), "axis_0.25a");
    // Just under the tool the tissue moves down by about δ.
    EXPECT_NEAR(probes.front().at("displacement_m").at(2).get<double>(), -0.00025, 0.5 * 0.00025);

    EXPECT_EQ(c.at("vtu"), c.at("id").get<std::string>() + ".vtu");
    EXPECT_TRUE(fs::is_regular_file(output() / c.at("vtu").get<std::string>()));
  }
  EXPECT_EQ(document.dump().find("NaN"), std::string::npos);
  // Each case says what it can about its own accuracy without a reference (as `study` does).
  for (const json& c : cases) {
    ASSERT_TRUE(c.contains("accuracy")) << c.at("id");
    EXPECT_TRUE(c.at("accuracy").at("flags").is_array()) << c.at("id");
    EXPECT_GT(c.at("accuracy").at("stiffness_ratio").get<double>(), 0.1) << c.at("id");
  }
  EXPECT_TRUE(cases[0].at("accuracy").at("force_change_from_previous_n").is_null());
  EXPECT_EQ(cases[1].at("accuracy").at("previous_node_count"), 34);
  EXPECT_GT(cases[1].at("accuracy").at("force_change_from_previous_n").get<double>(), 0.0);
}

TEST_F(MfsStudyRun, ResolvedConfigReadsBackToTheSameStudy) {
  const std::string resolved = read_file((output() / "config.resolved.toml").string());
  ConfigTable config = ConfigTable::from_string(resolved, "config.resolved.toml");
  const MfsStudy study = read_mfs_study(config);
  EXPECT_EQ(resolved_config_toml(study), resolved);
  EXPECT_EQ(study.node_counts, (std::vector<int>{34, 60}));
  EXPECT_DOUBLE_EQ(study.material.youngs_modulus_Pa, 10e3);
  EXPECT_EQ(study.model.force.cut_polar_points, 12);
}

// A case that cannot be built (here: the tool point is off the organ) is recorded, not fatal,
// and its numbers are null, never NaN.
// An organ given as a surface file is read in any format the readers know: the run's own organ
// surface (.msh) written as .obj and .stl gives the same forces (STL stores 32-bit floats: the
// vertices move by ~1e-7 relative, the force by as little). A clamped group is a gmsh name:
// asked of an .stl it is refused, naming the key.
TEST_F(MfsStudyRun, OrganSurfaceInEveryFormatGivesTheSameForce) {
  const meshes::SurfaceMesh organ = meshes::read_surface_mesh((output() / "organ_surface.msh").string());
  std::map<std::string, double> force_N;
  for (const std::string name : {"organ.msh", "organ.obj", "organ.stl"}) {
    SCOPED_TRACE(name);
    const fs::path file = temp_directory() / name;
    if (name == "organ.msh") fs::copy_file(output() / "organ_surface.msh", file, fs::copy_options::overwrite_existing);
    else meshes::write_surface_mesh(file.string(), organ.vertices, organ.triangles);
    std::string text = edited("edge_size = \"0.5 mm\"\nsize_growth = 0.3\nmax_size = \"8 mm\"", "surface = \"" + name + "\"");
    text.replace(text.find("node_count = [34, 60]"), std::string("node_count = [34, 60]").size(), "node_count = 34");
    ConfigTable from_file = ConfigTable::from_string(text, name + ".toml");
    const MfsStudy study = read_mfs_study(from_file, temp_directory().string());
    MfsRunOptions options;
    options.output_directory = (temp_directory() / ("out_" + name)).string();
    options.quiet = true;
    const json document = run_mfs_study(study, options);
    ASSERT_EQ(document.at("cases").size(), 1u);
    ASSERT_EQ(document.at("cases")[0].at("status"), "ok") << document.at("cases")[0].dump();
    EXPECT_EQ(document.at("organ").at("triangles"), organ.triangles.size());
    force_N[name] = document.at("cases")[0].at("qoi").at("force_N")[2].get<double>();
  }
  EXPECT_NEAR(force_N["organ.obj"], force_N["organ.msh"], 1e-9 * std::abs(force_N["organ.msh"]));
  EXPECT_NEAR(force_N["organ.stl"], force_N["organ.msh"], 1e-5 * std::abs(force_N["organ.msh"]));

  const std::string message = config_error("[organ]\nsurface = \"organ.stl\"\nclamped_group = \"base\"\n" + problem_keys);
  EXPECT_NE(message.find("organ.clamped_group"), std::string::npos) << message;
  EXPECT_NE(message.find(".msh"), std::string::npos) << message;
}

TEST(MfsStudyFailure, FailedCaseHasAStatusAndNoNumbers) {
  ConfigTable config = ConfigTable::from_string(
      edited("contact = \"frictionless\"", "contact = \"bonded\"\npoint = [\"0 mm\", \"0 mm\", \"60 mm\"]"),
      "off_surface.toml");
  MfsStudy study = read_mfs_study(config);
  study.node_counts = {34};
  MfsRunOptions options;
  options.output_directory = (temp_directory() / "failure").string();
  options.quiet = true;
  const json document = run_mfs_study(study, options);
  ASSERT_EQ(document.at("cases").size(), 1u);
  const json& c = document.at("cases").at(0);
  EXPECT_EQ(c.at("id"), "MFS-bonded-N34");
  const std::string status = c.at("status");
  EXPECT_NE(status, "ok");
  EXPECT_NE(status.find("ToolContact.point"), std::string::npos) << status;
  EXPECT_TRUE(c.at("qoi").at("force_N").is_null());
  EXPECT_TRUE(c.at("qoi").at("stiffness_N_per_m").is_null());
  EXPECT_TRUE(c.at("vtu").is_null());
  const std::string text = read_file(options.output_directory + "/results.json");
  EXPECT_EQ(text.find("NaN"), std::string::npos);
  EXPECT_EQ(json::parse(text), document);
}

TEST(MfsStudyConfig, UnknownKeyNamesFileAndKey) {
  const std::string message = config_error(edited("local_radius =", "local_radus ="), "tiny_mfs.toml");
  EXPECT_NE(message.find("tiny_mfs.toml"), std::string::npos) << message;
  EXPECT_NE(message.find("sprinkling.local_radus"), std::string::npos) << message;
  EXPECT_NE(message.find("did you mean 'sprinkling.local_radius'"), std::string::npos) << message;
}

// The keys that define the problem are required, named when missing (with a misspelt key that
// may be the one meant); every other key the file leaves out is a default that is reported.
TEST(MfsStudyConfig, TheProblemIsRequiredAndDefaultsAreReported) {
  for (const char* key : {"tool_radius", "body_radius", "youngs_modulus", "poisson_ratio", "depth"}) {
    std::string text = problem_keys_with_body;
    const std::size_t at = text.find(std::string(key) + " =");
    ASSERT_NE(at, std::string::npos) << key;
    text.erase(at, text.find('\n', at) + 1 - at);
    const std::string message = config_error(text);
    EXPECT_NE(message.find(key), std::string::npos) << message;
    EXPECT_NE(message.find("missing"), std::string::npos) << message;
  }
  std::string misspelt = problem_keys_with_body;
  misspelt.replace(misspelt.find("tool_radius"), 11, "tool_radus");
  EXPECT_NE(config_error(misspelt).find("is 'geometry.tool_radus' a misspelling of it?"), std::string::npos) << config_error(misspelt);

  ConfigTable config = ConfigTable::from_string(problem_keys_with_body, "minimal.toml");
  read_mfs_study(config);
  const std::vector<std::string> filled = config.defaults_filled();
  const auto has = [&](const std::string& setting) { return std::find(filled.begin(), filled.end(), setting) != filled.end(); };
  EXPECT_TRUE(has("geometry.local_radius = 0.0125 m")) << ::testing::PrintToString(filled);  // 5 a
  EXPECT_TRUE(has("geometry.benchmark = \"B2\"")) << ::testing::PrintToString(filled);
  for (const std::string& setting : filled) EXPECT_EQ(setting.find("youngs_modulus"), std::string::npos) << setting;
}

TEST(MfsStudyConfig, BadValuesNameTheField) {
  std::string message = config_error(edited("node_count = [34, 60]", "node_count = 5"));
  EXPECT_NE(message.find("bad.toml"), std::string::npos) << message;
  EXPECT_NE(message.find("node_count"), std::string::npos) << message;

  message = config_error(edited("node_count = [34, 60]", "node_count = [34, 5]"));
  EXPECT_NE(message.find("node_count"), std::string::npos) << message;

  message = config_error(edited("youngs_modulus = \"10 kPa\"", "youngs_modulus = \"-1 kPa\""));
  EXPECT_NE(message.find("bad.toml"), std::string::npos) << message;
  EXPECT_NE(message.find("youngs_modulus"), std::string::npos) << message;

  message = config_error(edited("youngs_modulus = \"10 kPa\"", "youngs_modulus = \"10 kN\""));
  EXPECT_NE(message.find("material.youngs_modulus"), std::string::npos) << message;

  message = config_error(edited("[mls]", "[mls]\nbasis = \"cubic\""));
  EXPECT_NE(message.find("mls.basis"), std::string::npos) << message;

  message = config_error(edited("[force]", "[force]\nhaptic_method = \"energy\""));
  EXPECT_NE(message.find("haptic_method"), std::string::npos) << message;

  message = config_error(edited("local_radius = \"12.5 mm\"", "local_radius = \"4 mm\""));
  EXPECT_NE(message.find("local_radius"), std::string::npos) << message;

  message = config_error("paper_mode = true\n[model]\npaper_mode = true\n" + problem_keys_with_body);
  EXPECT_NE(message.find("paper_mode"), std::string::npos) << message;
}

TEST(MfsStudyConfig, SurfacePathIsRelativeToTheConfigFolder) {
  fs::create_directories(temp_directory() / "organs");
  write_file_atomically((temp_directory() / "organs" / "liver.msh").string(), "not read before the run\n");
  ConfigTable config = ConfigTable::from_string("[organ]\nsurface = \"organs/liver.msh\"\n" + problem_keys, "organ.toml");
  const MfsStudy study = read_mfs_study(config, temp_directory().string());
  EXPECT_EQ(fs::path(study.surface_path), fs::absolute(temp_directory() / "organs" / "liver.msh").lexically_normal());

  const std::string message = config_error("[organ]\nsurface = \"organs/kidney.msh\"\n" + problem_keys);
  EXPECT_NE(message.find("organ.surface"), std::string::npos) << message;
  EXPECT_NE(message.find("kidney.msh"), std::string::npos) << message;
}

TEST(MfsStudyConfig, B1IsTheGeneratedCylinderWithItsClampedBase) {
  ConfigTable config = ConfigTable::from_string(edited("benchmark = \"B2\"", "benchmark = \"B1\""), "b1.toml");
  const MfsStudy study = read_mfs_study(config);
  EXPECT_EQ(study.geometry.benchmark, meshes::Benchmark::B1);
  EXPECT_TRUE(study.surface_path.empty());
  EXPECT_EQ(study.clamped_group, "base");
  EXPECT_NEAR(contact_point(study.geometry).norm(), 0.0, 1e-15);  // the centre of the top face z = 0
  const std::string message = config_error(edited("benchmark = \"B2\"", "benchmark = \"B4\""));
  EXPECT_NE(message.find("geometry.benchmark"), std::string::npos) << message;
  EXPECT_NE(message.find("'B1', 'B2', 'B3', 'B5'"), std::string::npos) << message;
}

TEST(MfsStudyConfig, PaperModeTakesThePapersDefaults) {
  ConfigTable config = ConfigTable::from_string("paper_mode = true\n" + problem_keys_with_body, "paper.toml");
  const MfsStudy study = read_mfs_study(config);
  EXPECT_TRUE(study.model.paper_mode);
  EXPECT_EQ(study.node_counts, (std::vector<int>{34}));
  EXPECT_EQ(study.model.collocation.mls.basis, realtime::mfs::Basis::linear);
  EXPECT_EQ(study.model.force.haptic_method, realtime::mfs::ForceMethod::paper_partition);
}

}  // namespace
}  // namespace touchstone::studies
