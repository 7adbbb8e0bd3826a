// `touchstone collision` end to end on a small study (stomach at 500 and 2,500 triangles, 20
// trajectories): every section of results.json and the case fields of its contract, counts
// positive and consistent (the binary tree's first-contact count against its depth, one
// distance per free prediction cycle, no missed contact), report.md (written by the reports
// package through the launcher) showing the numbers of results.json, and config errors that
// name the file and the key.
#include "touchstone/studies/collision_study.hpp"
#include "touchstone/studies/fem_reference/config_reader.hpp"
#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/provenance.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

namespace touchstone::studies {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const std::string small_config = R"(
study = "small_collision"
[organ]
stomach_triangles = [500, 2500]
hemisphere_triangles = []
[approach]
trajectories = 20
seed = 7
[approach.tremor]
rms_per_axis = "0.1 mm"
[tremor_study]
amplitudes = ["0.2 mm"]
windows = [1, 30]
sample_period_cycles = [1, 10]
trajectories = 20
organ_triangles = 500
[timing]
min_time = "1 ms"
)";

fs::path temp_directory() {
  static const fs::path path = fs::temp_directory_path() / ("touchstone_test_collision_study_" + std::to_string(getpid()));
  return path;
}

class RemoveTemporaries : public ::testing::Environment {
 public:
  void TearDown() override { fs::remove_all(temp_directory()); }
};
const auto* const remove_temporaries = ::testing::AddGlobalTestEnvironment(new RemoveTemporaries);

/// The study run once for all tests.
const json& results() {
  static const json document = [] {
    ConfigTable config = ConfigTable::from_string(small_config, "small.toml");
    const CollisionStudy study = read_collision_study(config);
    CollisionRunOptions options;
    options.output_directory = temp_directory().string();
    options.config_text = small_config;
    options.quiet = true;
    options.plots = false;  // no matplotlib needed
    return run_collision_study(study, options);
  }();
  return document;
}

std::string report() {
  results();
  return read_file((temp_directory() / "report.md").string());
}

std::string config_error(const std::string& text) {
  try {
    ConfigTable config = ConfigTable::from_string(text, "bad.toml");
    read_collision_study(config);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

std::string edited(const std::string& from, const std::string& to) {
  std::string text = small_config;
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

std::string format(const char* f, double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, f, value);
  return buffer;
}

/// The first Markdown table row that starts with `prefix` (and has `count` cells, when > 0),
/// split into its cells.
std::vector<std::string> row_cells(const std::string& markdown, const std::string& prefix, std::size_t count = 0) {
  std::istringstream lines(markdown);
  std::string line;
  while (std::getline(lines, line)) {
    if (line.rfind(prefix, 0) != 0) continue;
    std::vector<std::string> cells;
    std::size_t begin = 1;
    for (std::size_t bar = line.find('|', begin); bar != std::string::npos; bar = line.find('|', begin)) {
      std::string c = line.substr(begin, bar - begin);
      c.erase(0, c.find_first_not_of(' '));
      c.erase(c.find_last_not_of(' ') + 1);
      cells.push_back(c);
      begin = bar + 1;
    }
    if (count == 0 || cells.size() == count) return cells;
  }
  return {};
}

void check_sections_and_contract_fields() {
  const json& r = results();
  EXPECT_EQ(r.at("study"), "small_collision");
  for (const char* key : {"git", "build_type", "compiler", "machine", "config_sha256"})
    EXPECT_TRUE(r.at("provenance").contains(key)) << key;
  EXPECT_EQ(r.at("provenance").at("config_sha256"), sha256_hex(small_config));
  ASSERT_EQ(r.at("organs").size(), 2u);
  EXPECT_EQ(r.at("table1").size(), 2u * 2 * 2);      // organs × trees × volumes
  EXPECT_EQ(r.at("cycle_cost").size(), 2u * 2 * 2 * 2);  // × full detection / prediction
  EXPECT_EQ(r.at("tremor").size(), 3u);  // m = 1 (eq. 1, the same at any period), m = 30 at 1 kHz and 100 Hz
  EXPECT_EQ(r.at("cases").size(), r.at("table1").size() + r.at("tremor").size());
  for (const json& c : r.at("cases")) {
    for (const char* key : {"id", "model", "params", "qoi", "error", "reference", "time_s", "status"})
      EXPECT_TRUE(c.contains(key)) << key;
    for (const char* key : {"force_N", "stiffness_N_per_m", "energy_J"}) EXPECT_TRUE(c.at("qoi").contains(key)) << key;
    for (const char* key : {"build", "solve", "total"}) EXPECT_TRUE(c.at("time_s").contains(key)) << key;
    EXPECT_EQ(c.at("status"), "ok") << c.at("id");
  }
  for (const char* file : {"results.json", "config.resolved.toml", "table1.csv", "tremor.csv", "cycle_cost.csv", "report.md"})
    EXPECT_TRUE(fs::is_regular_file(temp_directory() / file)) << file;
  EXPECT_EQ(json::parse(read_file((temp_directory() / "results.json").string())), r);

  // The resolved config reads back to the same study.
  ConfigTable resolved = ConfigTable::from_file((temp_directory() / "config.resolved.toml").string());
  const CollisionStudy again = read_collision_study(resolved);
  EXPECT_EQ(again.organs.size(), 2u);
  EXPECT_EQ(again.trajectories, 20);
  EXPECT_EQ(again.tremor.windows, (std::vector<int>{1, 30}));
}

void check_first_contact_counts() {
  for (const json& row : results().at("table1")) {
    SCOPED_TRACE(row.at("id").get<std::string>());
    EXPECT_EQ(row.at("first_contacts"), 20);
    EXPECT_GE(row.at("box_tests").at("mean").get<double>(), 1);
    EXPECT_GE(row.at("triangle_tests").at("mean").get<double>(), 1);
    EXPECT_GE(row.at("box_tests").at("max").get<double>(), row.at("box_tests").at("mean").get<double>());
    EXPECT_GT(row.at("query_time_ns").get<double>(), 0);
    if (row.at("tree") != "binary") continue;
    // A single root-to-leaf path through a binary tree of depth D costs 2D − 1 box tests; a
    // segment near a box boundary enters a few more nodes, so the mean stays near it.
    const int depth = row.at("binary_depth");
    const double entered = row.at("nodes_entered").at("mean");
    EXPECT_GE(entered, depth - 1 - 1e-9);
    EXPECT_LE(row.at("box_tests").at("mean").get<double>(), 2.0 * (2 * depth + 1));
    EXPECT_NEAR(entered, (row.at("box_tests").at("mean").get<double>() - 1) / 2, 1e-9);
  }
  // Larger organs need more tests: the 2,500-triangle binary tree is deeper than the 500.
  const json& t = results().at("table1");
  EXPECT_GT(t[4].at("binary_depth").get<int>(), t[0].at("binary_depth").get<int>());
  EXPECT_GT(t[4].at("nodes_entered").at("mean").get<double>(), t[0].at("nodes_entered").at("mean").get<double>());
}

void check_prediction_cost() {
  for (const json& row : results().at("cycle_cost")) {
    SCOPED_TRACE(row.at("organ").get<std::string>() + " " + row.at("tree").get<std::string>() + " " +
                 row.at("bounding_volume").get<std::string>() + " " + row.at("mode").get<std::string>());
    const json& approach = row.at("phases").at("approach");
    const json& all = row.at("phases").at("all");
    EXPECT_GT(approach.at("cycles").get<long long>(), 0);
    EXPECT_GT(row.at("phases").at("contact").at("cycles").get<long long>(), 0);
    EXPECT_EQ(all.at("cycles").get<long long>(), approach.at("cycles").get<long long>() +
                                                     row.at("phases").at("contact").at("cycles").get<long long>() +
                                                     row.at("phases").at("release").at("cycles").get<long long>());
    if (row.at("mode") == "full_detection") {
      EXPECT_DOUBLE_EQ(approach.at("surface_queries_per_cycle").get<double>(), 1.0);
      EXPECT_DOUBLE_EQ(approach.at("distances_per_cycle").get<double>(), 0.0);
      continue;
    }
    const json& e = row.at("prediction");
    EXPECT_GT(e.at("free_cycles").get<long long>(), 0);
    EXPECT_EQ(e.at("free_cycle_distances_min"), 1);
    EXPECT_EQ(e.at("free_cycle_distances_max"), 1);
    EXPECT_EQ(e.at("free_cycle_surface_tests"), 0);
    EXPECT_EQ(e.at("misses"), 0);
    EXPECT_EQ(e.at("spurious_contacts"), 0);
    EXPECT_EQ(e.at("contacts"), e.at("reference_contacts"));
    EXPECT_GT(e.at("cheap_fraction_before_contact").get<double>(), 0.8);
    // Far fewer surface queries before contact than full detection's one per cycle.
    EXPECT_LT(approach.at("surface_queries_per_cycle").get<double>(), 0.2);
  }
}

void check_tremor_distributions() {
  for (const json& row : results().at("tremor")) {
    SCOPED_TRACE(row.at("id").get<std::string>());
    EXPECT_EQ(row.at("skipped"), 0);
    const json& e = row.at("error_m");
    EXPECT_EQ(e.at("count"), 20);
    if (e.at("max").is_null()) continue;  // a ray missed the organ
    EXPECT_LE(e.at("median").get<double>(), e.at("p90").get<double>());
    EXPECT_LE(e.at("p90").get<double>(), e.at("max").get<double>());
  }
  // m = 30 at 100 Hz predicts better than eq. 1 (m = 1 at 1 kHz).
  const json& t = results().at("tremor");
  ASSERT_EQ(t[0].at("window_samples"), 1);
  ASSERT_EQ(t[0].at("sample_period_cycles"), 1);
  ASSERT_EQ(t[2].at("window_samples"), 30);
  ASSERT_EQ(t[2].at("sample_period_cycles"), 10);
  EXPECT_LT(t[2].at("error_m").at("median").get<double>(), t[0].at("error_m").at("median").get<double>());
}

void check_report_numbers() {
  const std::string md = report();
  for (const json& r : results().at("table1")) {
    const std::vector<std::string> cells = row_cells(md, "| " + r.at("organ").get<std::string>() + " | " +
                                                             r.at("tree").get<std::string>() + " | " +
                                                             r.at("bounding_volume").get<std::string>() + " |");
    ASSERT_EQ(cells.size(), 10u) << r.at("id");
    EXPECT_EQ(cells[3], std::to_string(r.at("depth").get<int>()));
    EXPECT_EQ(cells[5], format("%.1f", r.at("box_tests").at("mean").get<double>()) + " / " + format("%.0f", r.at("box_tests").at("max").get<double>()));
    EXPECT_EQ(cells[6],
              format("%.1f", r.at("triangle_tests").at("mean").get<double>()) + " / " + format("%.0f", r.at("triangle_tests").at("max").get<double>()));
    EXPECT_EQ(cells[8], format("%.0f", r.at("query_time_ns").get<double>()));
  }
  // The replica's row: the paper's number (9 at 500 triangles) next to the binary tree's count.
  const std::vector<std::string> replica = row_cells(md, "| stomach-500 | ", 12);
  ASSERT_EQ(replica.size(), 12u);
  const json& binary_obb = results().at("table1")[0];
  ASSERT_EQ(binary_obb.at("tree"), "binary");
  EXPECT_EQ(replica[2], std::to_string(binary_obb.at("binary_depth").get<int>()));
  EXPECT_EQ(replica[3], std::to_string(binary_obb.at("binary_depth").get<int>() - 1));
  EXPECT_EQ(replica[4], "9");
  EXPECT_EQ(replica[5], format("%.1f", binary_obb.at("nodes_entered").at("mean").get<double>()) + " / " +
                            format("%.0f", binary_obb.at("nodes_entered").at("max").get<double>()));
  EXPECT_EQ(replica[11].rfind("1 distance + 1 comparison (", 0), 0u) << replica[11];
  // Tremor rows.
  for (const json& r : results().at("tremor")) {
    const std::string prefix = "| " + format("%.2f", r.at("amplitude_m").get<double>() * 1e3) + " | " +
                               std::to_string(r.at("window_samples").get<int>()) + " | " +
                               format("%.0f", r.at("sample_rate_hz").get<double>()) + " |";
    const std::vector<std::string> cells = row_cells(md, prefix);
    ASSERT_EQ(cells.size(), 8u) << prefix;
    const json& median = r.at("error_m").at("median");
    EXPECT_EQ(cells[4], median.is_null() ? "miss" : format("%.3f", 1e3 * median.get<double>()));
  }
  // Per-cycle cost rows: full detection and prediction side by side.
  const json& cost = results().at("cycle_cost");
  for (std::size_t i = 0; i + 1 < cost.size(); i += 2) {
    const json& full = cost[i].at("phases").at("approach");
    const json& predicted = cost[i + 1].at("phases").at("approach");
    const std::string prefix = "| " + cost[i].at("organ").get<std::string>() + " | " + cost[i].at("tree").get<std::string>() +
                               " | " + cost[i].at("bounding_volume").get<std::string>() + " | approach |";
    const std::vector<std::string> cells = row_cells(md, prefix, 14);
    ASSERT_EQ(cells.size(), 14u) << prefix;
    EXPECT_EQ(cells[4], std::to_string(full.at("cycles").get<long long>()));
    EXPECT_EQ(cells[6], format("%.2f", full.at("box_tests_per_cycle").get<double>()));
    EXPECT_EQ(cells[9], format("%.3f", predicted.at("distances_per_cycle").get<double>()));
    EXPECT_EQ(cells[11], format("%.2f", predicted.at("box_tests_per_cycle").get<double>()));
  }
  EXPECT_NE(md.find("benchmarks/collision_benchmark"), std::string::npos);
}

// One test runs the study (ctest runs every test in its own process; meshing dominates).
TEST(CollisionStudy, SmallStudyEndToEnd) {
  {
    SCOPED_TRACE("results.json has every section and the contract fields");
    check_sections_and_contract_fields();
  }
  {
    SCOPED_TRACE("first-contact counts are positive and follow the tree depth");
    check_first_contact_counts();
  }
  {
    SCOPED_TRACE("prediction costs one distance per free cycle and misses nothing");
    check_prediction_cost();
  }
  {
    SCOPED_TRACE("tremor distributions are ordered");
    check_tremor_distributions();
  }
  {
    SCOPED_TRACE("report.md shows the numbers of results.json");
    check_report_numbers();
  }
}

TEST(CollisionStudy, ConfigErrorsNameTheFileAndTheKey) {
  EXPECT_EQ(config_error(small_config), "");
  std::string e = config_error(edited("trajectories = 20\nseed", "trajectorie = 20\nseed"));
  EXPECT_NE(e.find("bad.toml"), std::string::npos) << e;
  EXPECT_NE(e.find("approach.trajectorie"), std::string::npos) << e;
  e = config_error(edited("trajectories = 20\nseed", "trajectories = 0\nseed"));
  EXPECT_NE(e.find("bad.toml"), std::string::npos) << e;
  EXPECT_NE(e.find("approach.trajectories"), std::string::npos) << e;
  e = config_error(edited("windows = [1, 30]", "windows = [1, 0]"));
  EXPECT_NE(e.find("tremor_study.windows"), std::string::npos) << e;
  e = config_error(edited("rms_per_axis = \"0.1 mm\"", "rms_per_axis = \"0.1 kPa\""));
  EXPECT_NE(e.find("approach.tremor.rms_per_axis"), std::string::npos) << e;
  e = config_error(edited("[timing]", "[bvh]\nbounding_volume = [\"obb\", \"sphere\"]\n[timing]"));
  EXPECT_NE(e.find("bvh.bounding_volume"), std::string::npos) << e;
  e = config_error(edited("[timing]", "[bvh.binary]\nchildren_per_node = 3\n[timing]"));
  EXPECT_NE(e.find("bvh.binary"), std::string::npos) << e;
  EXPECT_NE(e.find("children_per_node"), std::string::npos) << e;
  e = config_error(edited("stomach_triangles = [500, 2500]", "stomach_triangles = [5]"));
  EXPECT_NE(e.find("organ.stomach_triangles"), std::string::npos) << e;
}

// One settings table reads the study, writes config.resolved.toml and results.json params: a
// study changed away from its defaults in every section reads back from its resolved config with
// every param equal, and params hold one key per setting.
TEST(CollisionStudy, ResolvedConfigReadsBackEverySetting) {
  CollisionStudy study = default_collision_study();
  study.name = "every_setting";
  study.organs.resize(2);
  study.organs[1].shape = meshes::OrganShape::hemisphere;
  for (auto& organ : study.organs) organ.stomach_scale = 1.25;
  study.bounding_volumes = {realtime::collision::BoundingVolume::aabb};
  study.trees[1].settings.split = realtime::collision::SplitRule::mean;
  study.trajectories = 17;
  study.seed = 123456789012ull;
  study.approach.press_depth_max_m = 0.0045;
  study.approach.tremor.spectrum = realtime::hand_motion::TremorSpectrum::sinusoids;
  study.approach.tremor.band_high_hz = 11.5;
  study.prediction.window_samples = 12;
  study.prediction.direction_threshold_rad = 0.3;
  study.prediction.audit = true;
  study.tremor.amplitudes_m = {0.0, 3e-4};
  study.tremor.windows = {2, 5};
  study.tremor.shape = meshes::OrganShape::hemisphere;
  study.min_timing_s = 0.125;
  study.validate();

  ConfigTable resolved = ConfigTable::from_string(resolved_config_toml(study), "resolved.toml");
  const CollisionStudy back = read_collision_study(resolved);
  const json params = collision_params(study);
  EXPECT_EQ(collision_params(back), params);
  EXPECT_EQ(back.organs.size(), 2u);
  EXPECT_EQ(back.organs[1].shape, meshes::OrganShape::hemisphere);
  EXPECT_EQ(back.bounding_volumes, study.bounding_volumes);
  EXPECT_EQ(back.trees[1].settings.split, realtime::collision::SplitRule::mean);
  EXPECT_EQ(params.at("window_samples"), 12);
  EXPECT_EQ(params.at("approach_seed"), 123456789012);
  EXPECT_EQ(params.at("tremor_study_seed"), study.tremor.seed);
  EXPECT_EQ(params.at("spectrum"), "sinusoids");
  EXPECT_EQ(params.at("organ"), "hemisphere");
  EXPECT_EQ(params.at("stomach_scale"), 1.25);
  EXPECT_EQ(params.at("amplitudes"), json::array({0.0, 3e-4}));
}

TEST(CollisionStudy, PaperTable1Numbers) {
  EXPECT_EQ(paper_table1_overlap_tests(500), 9);
  EXPECT_EQ(paper_table1_overlap_tests(2480), 12);
  EXPECT_EQ(paper_table1_overlap_tests(16900), 14);
  EXPECT_EQ(paper_table1_overlap_tests(35300), 16);
  EXPECT_EQ(paper_table1_overlap_tests(8000), 0);
}

}  // namespace
}  // namespace touchstone::studies
