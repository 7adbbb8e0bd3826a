// `touchstone fem` end to end on a tiny B2 problem: the results.json contract (the fields other
// tools read), the cache, and config errors that name the file and key.
#include "touchstone/fem/elasticity_problem.hpp"
#include "touchstone/studies/fem_reference/config_reader.hpp"
#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/provenance.hpp"
#include "touchstone/studies/fem_reference/reference_study.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

namespace touchstone::studies {
namespace {

namespace fs = std::filesystem;

const char* tiny_b2 = R"(
study = "tiny_b2"
[geometry]
benchmark = "B2"
body_radius = "50 mm"
tool_radius = "5 mm"
[mesh]
edge_size = "2.5 mm"
size_growth = 0.8
max_size = "25 mm"
refinements = [0, 1, 2]
[material]
youngs_modulus = "10 kPa"
poisson_ratio = 0.45
[tool]
depth = "0.5 mm"
[solver]
degree = 1
)";

ReferenceStudy tiny_study() {
  ConfigTable config = ConfigTable::from_string(tiny_b2, "tiny_b2.toml");
  return read_reference_study(config);
}

TEST(ReferenceStudy, ResultsJsonCarriesTheContract) {
  RunOptions options;
  options.output_directory = "reference_study_contract";
  options.cache_directory = "";
  options.config_text = tiny_b2;
  options.quiet = true;
  fs::remove_all(options.output_directory);
  const nlohmann::json written = run_reference_study(tiny_study(), options);
  const nlohmann::json document = nlohmann::json::parse(read_file(options.output_directory + "/results.json"));
  EXPECT_EQ(document, written);

  EXPECT_EQ(document.at("study"), "tiny_b2");
  for (const char* key : {"git", "build_type", "compiler", "machine", "config_sha256"})
    EXPECT_TRUE(document.at("provenance").contains(key)) << key;
  EXPECT_EQ(document.at("provenance").at("config_sha256"), sha256_hex(tiny_b2));

  // Three levels, the Richardson case and the half-space case.
  const auto& cases = document.at("cases");
  ASSERT_EQ(cases.size(), 5u);
  for (const auto& c : cases) {
    for (const char* key : {"id", "model", "params", "qoi", "error", "reference", "time_s", "status"})
      EXPECT_TRUE(c.contains(key)) << c.value("id", "?") << " lacks " << key;
    for (const char* key : {"force_N", "stiffness_N_per_m", "energy_J"}) EXPECT_TRUE(c.at("qoi").contains(key)) << key;
    EXPECT_EQ(c.at("qoi").at("force_N").size(), 3u);
    for (const char* key : {"force_rel", "disp_rel_l2", "disp_max_m"}) EXPECT_TRUE(c.at("error").contains(key)) << key;
    for (const char* key : {"build", "solve", "total"}) EXPECT_TRUE(c.at("time_s").contains(key)) << key;
  }
  EXPECT_EQ(cases[0].at("model"), "fem");
  EXPECT_EQ(cases[0].at("reference"), "B2-frictionless-nu0.45-R0.05-richardson");
  EXPECT_EQ(cases[4].at("model"), "analytic");
  // The stiffness is the force over the depth, and the energy check F·δ = 2U holds per level.
  for (int level = 0; level < 3; ++level) {
    const auto& qoi = cases[level].at("qoi");
    EXPECT_NEAR(qoi.at("stiffness_N_per_m").get<double>() * 0.5e-3, qoi.at("axial_force_N").get<double>(), 1e-15);
    EXPECT_NEAR(qoi.at("energy_force_N").get<double>(), qoi.at("axial_force_N").get<double>(),
                1e-7 * qoi.at("axial_force_N").get<double>());
    EXPECT_GT(qoi.at("probes").size(), 10u);
  }
  // Per-problem convergence summary with the observed order and the error estimates.
  const auto& convergence = document.at("convergence").at(0);
  for (const char* key : {"observed_order", "extrapolated_force_N", "finest_relative_error", "gci_finest",
                          "extrapolated_relative_uncertainty", "ratio_to_half_space"})
    EXPECT_TRUE(convergence.contains(key)) << key;
  EXPECT_TRUE(fs::exists(options.output_directory + "/B2-frictionless-nu0.45-R0.05.pvd"));
  EXPECT_TRUE(fs::exists(options.output_directory + "/" + cases[2].at("vtu").get<std::string>()));
}

TEST(ReferenceStudy, SecondRunComesFromTheCache) {
  RunOptions options;
  options.output_directory = "reference_study_cache_out";
  options.cache_directory = "reference_study_cache";
  options.config_text = tiny_b2;
  options.quiet = true;
  fs::remove_all(options.cache_directory);
  const nlohmann::json first = run_reference_study(tiny_study(), options);
  const nlohmann::json second = run_reference_study(tiny_study(), options);
  for (int level = 0; level < 3; ++level) {
    EXPECT_FALSE(first.at("cases")[level].at("cached").get<bool>());
    EXPECT_TRUE(second.at("cases")[level].at("cached").get<bool>());
    EXPECT_EQ(first.at("cases")[level].at("qoi"), second.at("cases")[level].at("qoi"));
  }
}

// The tiny study at another Poisson ratio and two levels: the same geometry, another FEM problem.
ReferenceStudy tiny_study_at_poisson_ratio(const std::string& nu, std::string& text) {
  text = tiny_b2;
  text.replace(text.find("poisson_ratio = 0.45"), std::string("poisson_ratio = 0.45").size(), "poisson_ratio = " + nu);
  text.replace(text.find("refinements = [0, 1, 2]"), std::string("refinements = [0, 1, 2]").size(), "refinements = [0, 1]");
  ConfigTable config = ConfigTable::from_string(text, "tiny_b2_nu.toml");
  return read_reference_study(config);
}

std::vector<fs::path> cached_meshes(const std::string& cache_directory) {
  std::vector<fs::path> found;
  for (const auto& entry : fs::directory_iterator(cache_directory + "/meshes")) found.push_back(entry.path());
  std::sort(found.begin(), found.end());
  return found;
}

// The mesh cache's scenario: the tiny study at ν = 0.45 run into a fresh cache (`first`), then
// the same geometry at ν = 0.3 to run on it (`second_study`), and that study run afresh without
// a cache (`fresh`) to compare with.
struct MeshCacheScenario {
  RunOptions options;
  nlohmann::json first, fresh;
  ReferenceStudy second_study;
  std::string second_text;
};

MeshCacheScenario first_run_into_a_fresh_cache(const std::string& name) {
  MeshCacheScenario scenario;
  RunOptions& options = scenario.options;
  options.output_directory = name + "_out";
  options.cache_directory = name + "_cache";
  options.quiet = true;
  fs::remove_all(options.cache_directory);
  std::string first_text;
  const ReferenceStudy first_study = tiny_study_at_poisson_ratio("0.45", first_text);
  scenario.second_study = tiny_study_at_poisson_ratio("0.3", scenario.second_text);
  options.config_text = first_text;
  scenario.first = run_reference_study(first_study, options);
  RunOptions fresh_options = options;
  fresh_options.output_directory = name + "_fresh";
  fresh_options.cache_directory = "";
  fresh_options.config_text = scenario.second_text;
  scenario.fresh = run_reference_study(scenario.second_study, fresh_options);
  options.config_text = scenario.second_text;
  return scenario;
}

// Levels that differ only in material share the mesh of the first: the second study meshes
// nothing, its solves equal those of a run that meshed afresh, and its level times still count
// gmsh's time (a level's cost must not depend on the cache).
TEST(ReferenceStudy, LevelsThatDifferOnlyInMaterialShareOneMesh) {
  const MeshCacheScenario scenario = first_run_into_a_fresh_cache("reference_study_mesh_cache");
  ASSERT_EQ(cached_meshes(scenario.options.cache_directory).size(), 2u);
  const nlohmann::json second = run_reference_study(scenario.second_study, scenario.options);
  EXPECT_EQ(cached_meshes(scenario.options.cache_directory).size(), 2u);
  for (int level = 0; level < 2; ++level) {
    const nlohmann::json& made = scenario.first.at("cases")[level];
    const nlohmann::json& reused = second.at("cases")[level];
    const nlohmann::json& fresh = scenario.fresh.at("cases")[level];
    EXPECT_FALSE(made.at("time_s").at("mesh_reused").get<bool>());
    EXPECT_TRUE(reused.at("time_s").at("mesh_reused").get<bool>());
    EXPECT_FALSE(reused.at("cached").get<bool>());  // solved, on the kept mesh
    EXPECT_EQ(reused.at("time_s").at("mesh"), made.at("time_s").at("mesh"));
    EXPECT_GT(reused.at("time_s").at("total").get<double>(), reused.at("time_s").at("mesh").get<double>());
    EXPECT_EQ(reused.at("mesh").at("vertices"), fresh.at("mesh").at("vertices"));
    EXPECT_EQ(reused.at("mesh").at("tetrahedra"), fresh.at("mesh").at("tetrahedra"));
    EXPECT_EQ(reused.at("qoi"), fresh.at("qoi"));
  }
}

// A mesh cache entry left damaged (a truncated mesh, a lost record) is made again, not used.
TEST(ReferenceStudy, ADamagedMeshCacheEntryIsMadeAgain) {
  const MeshCacheScenario scenario = first_run_into_a_fresh_cache("reference_study_damaged_mesh");
  const std::vector<fs::path> entries = cached_meshes(scenario.options.cache_directory);
  ASSERT_EQ(entries.size(), 2u);
  const std::uintmax_t bytes = fs::file_size(entries[0] / "mesh.msh");
  fs::resize_file(entries[0] / "mesh.msh", bytes / 2);
  fs::remove(entries[1] / "mesh.json");

  const nlohmann::json second = run_reference_study(scenario.second_study, scenario.options);
  for (int level = 0; level < 2; ++level) {
    EXPECT_FALSE(second.at("cases")[level].at("time_s").at("mesh_reused").get<bool>()) << level;
    EXPECT_EQ(second.at("cases")[level].at("qoi"), scenario.fresh.at("cases")[level].at("qoi")) << level;
  }
  EXPECT_EQ(fs::file_size(entries[0] / "mesh.msh"), bytes);
  EXPECT_TRUE(fs::exists(entries[1] / "mesh.json"));
}

// A level record left damaged in the FEM cache is solved again, with a warning, not used and
// not the end of the run: a truncated record, one with a null force (what a NaN becomes in
// JSON), and one whose parameters are another problem's.
TEST(ReferenceStudy, ADamagedLevelRecordIsSolvedAgain) {
  RunOptions options;
  options.output_directory = "reference_study_damaged_record_out";
  options.cache_directory = "reference_study_damaged_record_cache";
  options.quiet = true;
  fs::remove_all(options.cache_directory);
  std::string text;
  const ReferenceStudy study = tiny_study_at_poisson_ratio("0.45", text);
  options.config_text = text;
  const nlohmann::json first = run_reference_study(study, options);

  std::vector<fs::path> records;
  for (const auto& entry : fs::directory_iterator(options.cache_directory + "/fem")) {
    records.push_back(entry.path() / "case.json");
  }
  ASSERT_EQ(records.size(), 2u);
  const std::string whole = read_file(records[0].string());
  write_file_atomically(records[0].string(), whole.substr(0, whole.size() / 2));
  nlohmann::json null_force = nlohmann::json::parse(read_file(records[1].string()));
  null_force["qoi"]["axial_force_N"] = nullptr;
  write_file_atomically(records[1].string(), null_force.dump(2));

  const nlohmann::json second = run_reference_study(study, options);
  for (int level = 0; level < 2; ++level) {
    EXPECT_FALSE(second.at("cases")[level].at("cached").get<bool>()) << level;
    EXPECT_EQ(second.at("cases")[level].at("qoi"), first.at("cases")[level].at("qoi")) << level;
  }

  // Another problem's record under this level's key (a hash collision, a copied file).
  nlohmann::json other = nlohmann::json::parse(read_file(records[0].string()));
  other["params"]["poisson_ratio"] = 0.3;
  write_file_atomically(records[0].string(), other.dump(2));
  const nlohmann::json third = run_reference_study(study, options);
  int solved_again = 0;
  for (int level = 0; level < 2; ++level) {
    solved_again += third.at("cases")[level].at("cached").get<bool>() ? 0 : 1;
    EXPECT_EQ(third.at("cases")[level].at("qoi"), first.at("cases")[level].at("qoi")) << level;
  }
  EXPECT_EQ(solved_again, 1);
}

TEST(ReferenceStudy, UnknownKeyIsNamed) {
  ConfigTable misspelled = ConfigTable::from_string(
      "study = \"x\"\n[geometry]\nbenchmark = \"B2\"\ntool_radus = \"2 mm\"\n", "misspelled.toml");
  try {
    read_reference_study(misspelled);
    FAIL() << "expected an error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("misspelled.toml"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("geometry.tool_radus"), std::string::npos) << e.what();
  }
}

// A tool pushed through the body is refused, named, with the thickness it was held to: R on
// B2 and B5, W on B1, the smaller of R and L on B3; a depth just inside passes.
TEST(ReferenceStudy, ADepthBeyondTheBodyIsRefused) {
  struct Case {
    meshes::Benchmark benchmark;
    double thickness_m;
  };
  for (const Case c : {Case{meshes::Benchmark::B1, 0.05}, Case{meshes::Benchmark::B2, 0.05}, Case{meshes::Benchmark::B5, 0.05},
                       Case{meshes::Benchmark::B3, 0.0125}}) {
    ReferenceStudy study = tiny_study();
    study.geometry.benchmark = c.benchmark;
    study.geometry.contact_polar_angle_rad = c.benchmark == meshes::Benchmark::B5 ? 0.3 : 0.0;
    study.geometry.local_radius_m = 0.0125;
    study.punch.depth_m = 0.99 * c.thickness_m;
    EXPECT_NO_THROW(study.validate()) << meshes::to_string(c.benchmark);
    study.punch.depth_m = c.thickness_m;
    try {
      study.validate();
      ADD_FAILURE() << meshes::to_string(c.benchmark) << ": a depth equal to the body's thickness was accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("tool.depth_m"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("thickness under the tool"), std::string::npos) << e.what();
    }
  }
  ReferenceStudy swept = tiny_study();  // every body radius of a sweep is held to it
  swept.body_radii_m = {0.05, 0.02};
  swept.punch.depth_m = 0.03;
  EXPECT_THROW(swept.validate(), std::invalid_argument);
}

TEST(ReferenceStudy, HalfSpaceClosedForms) {
  const geometry::Material material{10.0e3, 0.45};
  // Sneddon: 2Eaδ/(1−ν²); Mossakovskii: 4Gaδ ln(3−4ν)/(1−2ν), G = E/(2(1+ν)).
  EXPECT_NEAR(half_space_punch_force_N(material, 2.5e-3, 1e-4, geometry::ContactCondition::frictionless),
              2 * 10.0e3 * 2.5e-3 * 1e-4 / (1 - 0.45 * 0.45), 1e-15);
  const double g = 10.0e3 / 2.9;
  EXPECT_NEAR(half_space_punch_force_N(material, 2.5e-3, 1e-4, geometry::ContactCondition::bonded),
              4 * g * 2.5e-3 * 1e-4 * std::log(1.2) / 0.1, 1e-15);
  // Bonded is stiffer than frictionless, and both agree at ν = 0.5 in the limit.
  EXPECT_GT(half_space_punch_force_N(material, 2.5e-3, 1e-4, geometry::ContactCondition::bonded),
            half_space_punch_force_N(material, 2.5e-3, 1e-4, geometry::ContactCondition::frictionless));
}

}  // namespace
}  // namespace touchstone::studies
