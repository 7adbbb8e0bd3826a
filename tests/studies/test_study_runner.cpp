// `touchstone study` pieces that need no solver: reading a study file (the problem imposed on
// every sub-study, errors naming the key), probe comparison, the MFS force ramp and the CI
// baseline check.
#include "touchstone/studies/study_runner.hpp"

#include "touchstone/studies/config_reader.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using namespace touchstone;
using namespace touchstone::studies;

class StudyFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    directory_ = fs::temp_directory_path() /
                 ("touchstone_study_runner_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(directory_);
    fs::create_directories(directory_);
    write("ref.toml", R"(study = "ref"
[geometry]
benchmark = "B3"
local_radius = "10 mm"
body_radius = "40 mm"
tool_radius = "2 mm"
[mesh]
edge_size = ["0.5 mm", "0.25 mm"]
refinements = [0, 1, 2]
[tool]
depth = "0.1 mm"
[sweep]
contact = ["frictionless", "bonded"]
)");
  }
  void TearDown() override { fs::remove_all(directory_); }

  std::string write(const std::string& name, const std::string& text) {
    const fs::path path = directory_ / name;
    std::ofstream(path) << text;
    return path.string();
  }

  std::string study_text(const std::string& extra_problem = "", const std::string& extra = "") const {
    return R"(study = "s"
[problem]
benchmark = "B3"
body_radius = "50 mm"
tool_radius = "2.5 mm"
local_radius = "12.5 mm"
youngs_modulus = "12 kPa"
poisson_ratio = 0.4
depths = ["0.1 mm", "0.2 mm"]
)" + extra_problem + R"(
[reference]
config = "ref.toml"
[table2]
mfs_series = "p"
[mfs.g]
formulation = "galerkin"
[mfs.g.sprinkling]
node_count = [34, 100]
[mfs.p]
paper_mode = true
)" + extra;
  }

  /// `text` with the first `from` replaced by `to`.
  static std::string replaced(std::string text, const std::string& from, const std::string& to) {
    text.replace(text.find(from), from.size(), to);
    return text;
  }

  fs::path directory_;
};

TEST_F(StudyFiles, ProblemIsImposedOnTheReferenceAndEverySeries) {
  const ComparisonStudy s = read_comparison_study(write("s.toml", study_text()));
  EXPECT_EQ(s.name, "s");
  // The reference file's own geometry, material, depth and contact sweep are replaced.
  EXPECT_DOUBLE_EQ(s.reference.geometry.body_radius_m, 0.05);
  EXPECT_DOUBLE_EQ(s.reference.geometry.tool_radius_m, 0.0025);
  EXPECT_DOUBLE_EQ(s.reference.geometry.local_radius_m, 0.0125);
  EXPECT_DOUBLE_EQ(s.reference.material.youngs_modulus_Pa, 12e3);
  EXPECT_DOUBLE_EQ(s.reference.material.poisson_ratio, 0.4);
  EXPECT_DOUBLE_EQ(s.reference.punch.depth_m, 0.2e-3);  // the largest depth of the ramp
  EXPECT_TRUE(s.reference.contacts.empty());
  EXPECT_EQ(s.reference.punch.contact, fem::Contact::frictionless);
  // Its mesh families are kept.
  ASSERT_EQ(s.reference.edge_sizes_m.size(), 2u);
  EXPECT_DOUBLE_EQ(s.reference.edge_sizes_m[1], 0.25e-3);

  ASSERT_EQ(s.series.size(), 2u);
  const MfsSeries& g = s.series[0];
  EXPECT_EQ(g.name, "g");
  EXPECT_EQ(g.study.model.formulation, realtime::mfs::Formulation::galerkin);
  EXPECT_EQ(g.study.node_counts, (std::vector<int>{34, 100}));
  EXPECT_DOUBLE_EQ(g.study.depth_m, 0.2e-3);
  EXPECT_DOUBLE_EQ(g.study.material.youngs_modulus_Pa, 12e3);
  EXPECT_DOUBLE_EQ(g.study.model.sprinkling.local_radius_m, 0.0125);
  EXPECT_NEAR(g.study.direction.z(), -1.0, 1e-15);
  EXPECT_TRUE(s.series[1].study.model.paper_mode);
  EXPECT_EQ(s.table2_mfs_series, "p");
}

TEST_F(StudyFiles, ReferenceOverridesReplaceFamiliesAndLevels) {
  const ComparisonStudy s = read_comparison_study(
      write("s.toml", replaced(study_text(), "config = \"ref.toml\"",
                               "config = \"ref.toml\"\nedge_sizes = [\"1 mm\"]\nrefinements = [1, 2, 3]")));
  EXPECT_TRUE(s.reference.edge_sizes_m.empty());
  EXPECT_DOUBLE_EQ(s.reference.geometry.edge_size_m, 1e-3);
  EXPECT_EQ(s.reference.refinements, (std::vector<int>{1, 2, 3}));
}

TEST_F(StudyFiles, ErrorsNameTheFileAndTheKey) {
  const auto message = [&](const std::string& text) {
    try {
      read_comparison_study(write("bad.toml", text));
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  // A series must not redefine the problem.
  std::string m = message(study_text("", "[mfs.g.material]\nyoungs_modulus = \"1 kPa\"\n"));
  EXPECT_NE(m.find("bad.toml"), std::string::npos) << m;
  EXPECT_NE(m.find("mfs.g.material"), std::string::npos) << m;
  // Unknown keys.
  m = message(study_text("depht = \"1 mm\"\n"));
  EXPECT_NE(m.find("depht"), std::string::npos) << m;
  m = message(study_text("", "[mfs.g.mls]\nbasiss = \"linear\"\n"));
  EXPECT_NE(m.find("basiss"), std::string::npos) << m;
  EXPECT_NE(m.find("mfs.g"), std::string::npos) << m;
  // Depths must ascend.
  m = message(replaced(study_text(), "depths = [\"0.1 mm\", \"0.2 mm\"]", "depths = [\"0.2 mm\", \"0.1 mm\"]"));
  EXPECT_NE(m.find("ascending"), std::string::npos) << m;
  // Table 2 must name a series.
  m = message(replaced(study_text(), "mfs_series = \"p\"", "mfs_series = \"q\""));
  EXPECT_NE(m.find("table2.mfs_series"), std::string::npos) << m;
}

TEST(ProbeComparison, MatchesByNameAndSkipsMissingProbes) {
  const json probes = json::array({{{"name", "axis_1a"}, {"displacement_m", {0.0, 0.0, -1e-4}}, {"found", true}},
                                   {{"name", "only_here"}, {"displacement_m", {0.0, 0.0, 5.0}}, {"found", true}},
                                   {{"name", "axis_2a"}, {"displacement_m", nullptr}, {"found", false}}});
  const json reference = json::array({{{"name", "axis_2a"}, {"displacement_m", {0.0, 0.0, -3e-4}}, {"found", true}},
                                      {{"name", "axis_1a"}, {"displacement_m", {0.0, 0.0, -2e-4}}, {"found", true}}});
  const ProbeComparison c = compare_probes(probes, reference);
  EXPECT_EQ(c.count, 1);
  EXPECT_NEAR(c.rel_l2, 0.5, 1e-14);  // |1e-4| / |2e-4|
  EXPECT_NEAR(c.max_abs_m, 1e-4, 1e-18);
}

TEST(ForceRamp, IsTheToolStiffnessAlongTheDirection) {
  Eigen::Matrix3d kt;
  kt << 90, 1, 2, 3, 80, 4, 5, 6, 88.5;  // N/m
  const auto f = mfs_force_ramp_N(kt, Eigen::Vector3d(0, 0, -2), {1e-4, 2e-4, 2.5e-4});
  ASSERT_EQ(f.size(), 3u);
  // F·d = dᵀ K_t d δ with d = −e_z: K_zz δ.
  EXPECT_NEAR(f[0], 88.5e-4, 1e-15);
  EXPECT_NEAR(f[1], 2 * f[0], 1e-15);
  EXPECT_NEAR(f[2], 2.5 * f[0], 1e-15);
}

json synthetic_results(double force_rel, double disp_rel, double reference_force) {
  return {{"study", "ci"},
          {"provenance", {{"git", "test"}}},
          {"reference_summary", {{"case", "reference/x"}, {"axial_force_N", reference_force}, {"uncertainty_rel", 0.001}}},
          {"cases", json::array({{{"id", "reference/x"}, {"model", "fem"}, {"qoi", {{"axial_force_N", reference_force}}},
                                  {"error", {{"force_rel", nullptr}}}, {"status", "ok"}},
                                 {{"id", "MFS-g-N34"}, {"model", "mfs"}, {"qoi", {{"axial_force_N", 0.03}}},
                                  {"error", {{"force_rel", force_rel}, {"disp_rel_l2", disp_rel}}}, {"status", "ok"}}})}};
}

TEST(Baseline, PassesWithinTolerancesAndFailsBeyond) {
  const json baseline = make_baseline(synthetic_results(0.20, 0.10, 0.022), RegressionTolerances{});
  const auto all_pass = [](const std::vector<RegressionFinding>& findings) {
    for (const auto& f : findings)
      if (!f.passed) return false;
    return !findings.empty();
  };
  EXPECT_TRUE(all_pass(check_against_baseline(synthetic_results(0.20, 0.10, 0.022), baseline)));
  // 0.4 percentage points worse: allowed (0.5); 0.6 points: a regression, in either direction.
  EXPECT_TRUE(all_pass(check_against_baseline(synthetic_results(0.204, 0.10, 0.022), baseline)));
  EXPECT_FALSE(all_pass(check_against_baseline(synthetic_results(0.206, 0.10, 0.022), baseline)));
  EXPECT_FALSE(all_pass(check_against_baseline(synthetic_results(0.194, 0.10, 0.022), baseline)));
  EXPECT_FALSE(all_pass(check_against_baseline(synthetic_results(0.20, 0.107, 0.022), baseline)));
  // The reference force itself may move by 0.1 %.
  EXPECT_TRUE(all_pass(check_against_baseline(synthetic_results(0.20, 0.10, 0.022 * 1.0009), baseline)));
  EXPECT_FALSE(all_pass(check_against_baseline(synthetic_results(0.20, 0.10, 0.022 * 1.002), baseline)));
  // A case that disappeared fails.
  json missing = synthetic_results(0.20, 0.10, 0.022);
  missing["cases"].erase(1);
  EXPECT_FALSE(all_pass(check_against_baseline(missing, baseline)));
}

TEST(Baseline, DescribesWhatChanged) {
  const json a = make_baseline(synthetic_results(0.20, 0.10, 0.022), RegressionTolerances{});
  EXPECT_EQ(describe_baseline_change(a, a), "  unchanged\n");
  const json b = make_baseline(synthetic_results(0.25, 0.10, 0.022), RegressionTolerances{});
  const std::string diff = describe_baseline_change(a, b);
  EXPECT_NE(diff.find("MFS-g-N34 force_rel: 20.000 % -> 25.000 %"), std::string::npos) << diff;
  EXPECT_EQ(diff.find("disp_rel_l2"), std::string::npos) << diff;
}

}  // namespace
