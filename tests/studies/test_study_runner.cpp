// `touchstone study` pieces that need no solver: reading a study file (the problem imposed on
// every sub-study, errors naming the key), probe comparison, the MFS force ramp and the CI
// baseline check.
#include "touchstone/studies/study_runner.hpp"

#include "touchstone/studies/fem_reference/config_reader.hpp"
#include "touchstone/studies/fem_reference/probes.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
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

  std::string read_text(const std::string& name) const {
    std::ifstream in(directory_ / name);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }

  /// `text` with the first `from` replaced by `to`.
  static std::string replaced(std::string text, const std::string& from, const std::string& to) {
    text.replace(text.find(from), from.size(), to);
    return text;
  }

  fs::path directory_;
};

TEST_F(StudyFiles, ProblemIsImposedOnTheReferenceAndEverySeries) {
  const ComparisonStudy study = read_comparison_study(write("s.toml", study_text()));
  EXPECT_EQ(study.name, "s");
  // No [problems.*]: one problem, case ids without a prefix.
  ASSERT_EQ(study.problems.size(), 1u);
  EXPECT_EQ(study.first().id_prefix, "");
  const StudyProblem& s = study.first();
  // The reference file's own geometry, material, depth and contact sweep are replaced.
  EXPECT_DOUBLE_EQ(s.reference.geometry.body_radius_m, 0.05);
  EXPECT_DOUBLE_EQ(s.reference.geometry.tool_radius_m, 0.0025);
  EXPECT_DOUBLE_EQ(s.reference.geometry.local_radius_m, 0.0125);
  EXPECT_DOUBLE_EQ(s.reference.material.youngs_modulus_Pa, 12e3);
  EXPECT_DOUBLE_EQ(s.reference.material.poisson_ratio, 0.4);
  EXPECT_DOUBLE_EQ(s.reference.punch.depth_m, 0.2e-3);  // the largest depth of the ramp
  EXPECT_TRUE(s.reference.contacts.empty());
  EXPECT_EQ(s.reference.punch.contact, geometry::ContactCondition::frictionless);
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
  EXPECT_EQ(study.table2_mfs_series, "p");
}

TEST_F(StudyFiles, ReferenceOverridesReplaceFamiliesAndLevels) {
  const ComparisonStudy study = read_comparison_study(
      write("s.toml", replaced(study_text(), "config = \"ref.toml\"",
                               "config = \"ref.toml\"\nedge_sizes = [\"1 mm\"]\nrefinements = [1, 2, 3]")));
  const StudyProblem& s = study.first();
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

// B4 is the paper's point tool on B2: a B2 reference file, paper-mode series only.
TEST_F(StudyFiles, PointToolIsB2WithPaperModeSeriesOnly) {
  write("ref_b2.toml", replaced(replaced(read_text("ref.toml"), "benchmark = \"B3\"", "benchmark = \"B2\""),
                                "local_radius = \"10 mm\"\n", ""));
  const std::string variant = R"(
[problems.point]
benchmark = "B4"
series = ["p"]
[problems.point.reference]
config = "ref_b2.toml"
)";
  const ComparisonStudy study = read_comparison_study(write("b4.toml", study_text("", variant)));
  ASSERT_EQ(study.problems.size(), 1u);
  const StudyProblem& point = study.problems.front();
  EXPECT_TRUE(point.problem.point_tool);
  EXPECT_EQ(point.problem.benchmark, meshes::Benchmark::B2);
  EXPECT_EQ(point.reference.geometry.benchmark, meshes::Benchmark::B2);
  ASSERT_EQ(point.series.size(), 1u);
  EXPECT_TRUE(point.series.front().study.model.paper_mode);
  EXPECT_EQ(point.series.front().study.geometry.benchmark, meshes::Benchmark::B2);

  // The Galerkin series has no tip node to pair a punch with: named, with the way out.
  std::string m;
  try {
    read_comparison_study(write("b4_bad.toml", study_text("", replaced(variant, "series = [\"p\"]", "series = [\"p\", \"g\"]"))));
  } catch (const ConfigError& e) {
    m = e.what();
  }
  EXPECT_NE(m.find("b4_bad.toml"), std::string::npos) << m;
  EXPECT_NE(m.find("problems.point"), std::string::npos) << m;
  EXPECT_NE(m.find("series 'g' is not in paper mode"), std::string::npos) << m;
  // Its reference must be on B2, like the problem's domain.
  m.clear();
  try {
    read_comparison_study(write("b4_b3.toml", study_text("", replaced(variant, "ref_b2.toml", "ref.toml"))));
  } catch (const ConfigError& e) {
    m = e.what();
  }
  EXPECT_NE(m.find("is a B3 study, but problem.benchmark is B2"), std::string::npos) << m;
}

/// `text` read as a study; the ConfigError's message, or "no error".
std::string read_error(const std::string& path) {
  try {
    read_comparison_study(path);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "no error";
}

TEST_F(StudyFiles, VariantsAreProblemsInFileOrderWithTheirOwnReferences) {
  write("ref_b5.toml", R"(study = "ref_b5"
[geometry]
benchmark = "B5"
body_radius = "50 mm"
tool_radius = "2.5 mm"
[mesh]
edge_size = "0.5 mm"
refinements = [0, 1]
)");
  write("ref_other.toml", replaced(R"(study = "ref_other"
[geometry]
benchmark = "B3"
local_radius = "10 mm"
body_radius = "40 mm"
tool_radius = "2 mm"
[mesh]
edge_size = "1 mm"
refinements = [0, 1, 2]
)", "1 mm", "1.25 mm"));
  // Written out of alphabetical order: the study keeps the file's order.
  const ComparisonStudy study = read_comparison_study(write("v.toml", study_text("", R"(
[problems.nu0p3]
poisson_ratio = 0.3
[problems.E1GPa]
youngs_modulus = "1 GPa"
series = ["g"]
[problems.E1GPa.reference]
config = "ref_other.toml"
[problems.b5]
benchmark = "B5"
contact_polar_angle = "80 deg"
tilt = "60 deg"
depths = ["1 mm", "6.25 mm"]
series = ["g"]
[problems.b5.reference]
config = "ref_b5.toml"
)")));
  ASSERT_EQ(study.problems.size(), 3u);
  EXPECT_EQ(study.problems[0].name, "nu0p3");
  EXPECT_EQ(study.problems[1].name, "E1GPa");
  EXPECT_EQ(study.problems[2].name, "b5");
  EXPECT_EQ(study.problems[0].id_prefix, "nu0p3/");

  // ν = 0.3: the base with one value replaced, in the reference and in every series.
  const StudyProblem& nu = study.problems[0];
  EXPECT_DOUBLE_EQ(nu.problem.material.poisson_ratio, 0.3);
  EXPECT_DOUBLE_EQ(nu.problem.material.youngs_modulus_Pa, 12e3);  // the base's
  EXPECT_DOUBLE_EQ(nu.reference.material.poisson_ratio, 0.3);
  ASSERT_EQ(nu.series.size(), 2u);
  EXPECT_DOUBLE_EQ(nu.series[0].study.material.poisson_ratio, 0.3);
  EXPECT_EQ(nu.overridden_keys, (std::vector<std::string>{"poisson_ratio"}));

  // E = 1 GPa on another reference file, one series.
  const StudyProblem& e = study.problems[1];
  EXPECT_DOUBLE_EQ(e.problem.material.youngs_modulus_Pa, 1e9);
  EXPECT_DOUBLE_EQ(e.problem.material.poisson_ratio, 0.4);
  EXPECT_EQ(e.reference.name, "ref_other");
  EXPECT_DOUBLE_EQ(e.reference.geometry.edge_size_m, 1.25e-3);
  EXPECT_DOUBLE_EQ(e.reference.material.youngs_modulus_Pa, 1e9);
  ASSERT_EQ(e.series.size(), 1u);
  EXPECT_EQ(e.series[0].name, "g");

  // B5 near the base with a grazing tool: θ and the direction reach both models.
  const StudyProblem& b5 = study.problems[2];
  const double theta = 80 * M_PI / 180, tilt = 60 * M_PI / 180;
  EXPECT_EQ(b5.reference.geometry.benchmark, meshes::Benchmark::B5);
  EXPECT_NEAR(b5.reference.geometry.contact_polar_angle_rad, theta, 1e-14);
  EXPECT_NEAR(b5.series[0].study.geometry.contact_polar_angle_rad, theta, 1e-14);
  EXPECT_EQ(b5.series[0].study.geometry.benchmark, meshes::Benchmark::B5);
  // d = cos(tilt)(−n) + sin(tilt) e_θ with n = (sin θ, 0, cos θ), e_θ = (cos θ, 0, −sin θ).
  const Eigen::Vector3d d(-std::cos(tilt) * std::sin(theta) + std::sin(tilt) * std::cos(theta), 0,
                          -std::cos(tilt) * std::cos(theta) - std::sin(tilt) * std::sin(theta));
  EXPECT_NEAR((b5.problem.direction - d).norm(), 0, 1e-14);
  EXPECT_NEAR((b5.reference.punch.direction.normalized() - d).norm(), 0, 1e-14);
  EXPECT_NEAR((b5.series[0].study.direction.normalized() - d).norm(), 0, 1e-14);
  EXPECT_NEAR(b5.problem.angle_to_normal_rad(), tilt, 1e-12);
  EXPECT_TRUE(b5.problem.ball_reaches_base());     // R cos 80° = 8.7 mm < L = 12.5 mm
  EXPECT_TRUE(b5.problem.beyond_small_strain());   // 6.25 mm > a/2
  EXPECT_FALSE(nu.problem.ball_reaches_base());
  EXPECT_FALSE(nu.problem.beyond_small_strain());
  // The MFS ball is the problem's L on B5 as on B3.
  EXPECT_DOUBLE_EQ(b5.series[0].study.model.sprinkling.local_radius_m, 0.0125);
}

TEST_F(StudyFiles, AVariantsUnknownKeyNamesTheFileTheVariantAndTheKey) {
  std::string m = read_error(write("bad.toml", study_text("", "[problems.soft]\npoissson_ratio = 0.3\n")));
  EXPECT_NE(m.find("bad.toml"), std::string::npos) << m;
  EXPECT_NE(m.find("problems.soft"), std::string::npos) << m;
  EXPECT_NE(m.find("poissson_ratio"), std::string::npos) << m;
  // An unknown key in a variant's reference table, and a series that does not exist.
  m = read_error(write("bad.toml", study_text("", "[problems.soft.reference]\nrefinement = [0, 1]\n")));
  EXPECT_NE(m.find("problems.soft.reference"), std::string::npos) << m;
  EXPECT_NE(m.find("refinement"), std::string::npos) << m;
  m = read_error(write("bad.toml", study_text("", "[problems.soft]\nseries = [\"nope\"]\n")));
  EXPECT_NE(m.find("problems.soft.series"), std::string::npos) << m;
  // A bad value names the variant.
  m = read_error(write("bad.toml", study_text("", "[problems.soft]\npoisson_ratio = 0.7\n")));
  EXPECT_NE(m.find("bad.toml"), std::string::npos) << m;
  EXPECT_NE(m.find("problems.soft"), std::string::npos) << m;
}

TEST_F(StudyFiles, DepthsUpToHalfTheLocalRadiusAreAccepted) {
  // L = 12.5 mm: 6.25 mm (L/2, far beyond a/2 = 1.25 mm) is accepted, 6.3 mm is not.
  const ComparisonStudy deep = read_comparison_study(write(
      "deep.toml", replaced(study_text(), "depths = [\"0.1 mm\", \"0.2 mm\"]", "depths = [\"1 mm\", \"6.25 mm\"]")));
  EXPECT_DOUBLE_EQ(deep.first().reference.punch.depth_m, 6.25e-3);
  EXPECT_DOUBLE_EQ(deep.first().series[0].study.depth_m, 6.25e-3);
  EXPECT_TRUE(deep.first().problem.beyond_small_strain());
  const std::string m =
      read_error(write("deep.toml", replaced(study_text(), "depths = [\"0.1 mm\", \"0.2 mm\"]", "depths = [\"6.3 mm\"]")));
  EXPECT_NE(m.find("L/2"), std::string::npos) << m;
  EXPECT_NE(m.find("deep.toml"), std::string::npos) << m;
}

TEST_F(StudyFiles, TheEngineDefaultSeriesIsFoundBySettingsNotByName) {
  // "zz" has the engine's settings under an unremarkable name; "galerkin" has one knob changed;
  // "p" is the paper mode.
  const ComparisonStudy s = read_comparison_study(write("d.toml", study_text("", R"(
[mfs.zz.sprinkling]
node_count = [60]
seed = 1
[mfs.galerkin]
formulation = "galerkin"
[mfs.galerkin.sprinkling]
radius_factor = 2.0
)")));
  int defaults = 0;
  for (const auto& series : s.first().series) {
    SCOPED_TRACE(series.name);
    // Galerkin is no longer the engine's default formulation (enriched is): only "zz" is.
    EXPECT_EQ(series.engine_default, series.name == "zz");
    defaults += series.engine_default ? 1 : 0;
  }
  EXPECT_EQ(defaults, 1);
  // Only non-default series: none is marked.
  const ComparisonStudy none = read_comparison_study(write("n.toml", replaced(study_text(), "[mfs.g]\nformulation = \"galerkin\"\n",
                                                                             "[mfs.g]\nformulation = \"collocation\"\n")));
  for (const auto& series : none.first().series) EXPECT_FALSE(series.engine_default) << series.name;
}

/// A B1 study: the cylinder W = 20a, its own `touchstone fem` file (written with another W and a
/// W sweep, which the problem replaces), one Galerkin series.
std::string b1_study_text(const std::string& extra_problem = "", const std::string& extra = "") {
  return R"(study = "b1"
[problem]
benchmark = "B1"
body_radius = "50 mm"
tool_radius = "2.5 mm"
local_radius = "12.5 mm"
youngs_modulus = "10 kPa"
poisson_ratio = 0.45
depths = ["0.125 mm", "0.25 mm"]
)" + extra_problem + R"(
[reference]
config = "ref_b1.toml"
[mfs.g]
formulation = "galerkin"
[mfs.g.sprinkling]
node_count = [100]
)" + extra;
}

TEST_F(StudyFiles, BenchmarkB1IsTheCylinderWithTheToolAtTheCentreOfItsTop) {
  write("ref_b1.toml", R"(study = "ref_b1"
[geometry]
benchmark = "B1"
body_radius = "125 mm"
tool_radius = "2.5 mm"
[mesh]
edge_size = "1.25 mm"
refinements = [0, 1]
[sweep]
body_radius = ["125 mm", "250 mm"]
contact = ["frictionless", "bonded"]
)");
  const ComparisonStudy study = read_comparison_study(write("b1.toml", b1_study_text("", R"(
[problems.small]
body_radius = "20 mm"
local_radius = "25 mm"
)")));
  // With variants, [problem] is their template, not a problem of its own: one problem, "small".
  ASSERT_EQ(study.problems.size(), 1u);
  const StudyProblem& small = study.first();
  EXPECT_EQ(small.problem.benchmark, meshes::Benchmark::B1);
  EXPECT_NEAR((small.problem.outward_normal() - Eigen::Vector3d::UnitZ()).norm(), 0, 1e-15);
  EXPECT_NEAR(small.problem.angle_to_normal_rad(), 0, 1e-12);
  // The base z = −W is W below the contact point: inside ball(0, L) when W < L.
  EXPECT_TRUE(small.problem.ball_reaches_base());

  const ComparisonStudy base = read_comparison_study(write("b1.toml", b1_study_text()));
  const StudyProblem& s = base.first();
  EXPECT_FALSE(s.problem.ball_reaches_base());  // W = 50 mm > L = 12.5 mm
  // The reference is the problem's cylinder: W imposed, the file's W sweep and contacts gone.
  EXPECT_EQ(s.reference.geometry.benchmark, meshes::Benchmark::B1);
  EXPECT_DOUBLE_EQ(s.reference.geometry.body_radius_m, 0.05);
  EXPECT_TRUE(s.reference.body_radii_m.empty());
  EXPECT_TRUE(s.reference.contacts.empty());
  EXPECT_DOUBLE_EQ(s.reference.punch.depth_m, 0.25e-3);
  // The MFS organ is the generated cylinder with its clamped base, the tool at the origin.
  ASSERT_EQ(s.series.size(), 1u);
  const MfsStudy& m = s.series[0].study;
  EXPECT_EQ(m.geometry.benchmark, meshes::Benchmark::B1);
  EXPECT_DOUBLE_EQ(m.geometry.body_radius_m, 0.05);
  EXPECT_TRUE(m.surface_path.empty());
  EXPECT_EQ(m.clamped_group, "base");
  EXPECT_FALSE(m.contact_point_m.has_value());
  EXPECT_NEAR(contact_point(m.geometry).norm(), 0, 1e-15);
  EXPECT_DOUBLE_EQ(m.model.sprinkling.local_radius_m, 0.0125);
  EXPECT_NEAR((m.direction.normalized() + Eigen::Vector3d::UnitZ()).norm(), 0, 1e-15);
}

TEST_F(StudyFiles, ABadB1ProblemNamesTheFileTheKeyAndTheValue) {
  write("ref_b1.toml", "study = \"ref_b1\"\n[geometry]\nbenchmark = \"B1\"\n[mesh]\nedge_size = \"1.25 mm\"\nrefinements = [0, 1]\n");
  // B1 pushes at the centre of its top face: a polar angle is B5's.
  std::string m = read_error(write("bad.toml", b1_study_text("contact_polar_angle = \"10 deg\"\n")));
  EXPECT_NE(m.find("bad.toml"), std::string::npos) << m;
  EXPECT_NE(m.find("problem.contact_polar_angle = 0.174533"), std::string::npos) << m;
  EXPECT_NE(m.find("B5 only"), std::string::npos) << m;
  // The reference must be a B1 study.
  m = read_error(write("bad.toml", replaced(b1_study_text(), "config = \"ref_b1.toml\"", "config = \"ref.toml\"")));
  EXPECT_NE(m.find("reference.config"), std::string::npos) << m;
  EXPECT_NE(m.find("is a B3 study, but problem.benchmark is B1"), std::string::npos) << m;
  // An unknown benchmark is named with the list.
  m = read_error(write("bad.toml", replaced(b1_study_text(), "benchmark = \"B1\"", "benchmark = \"B6\"")));
  EXPECT_NE(m.find("problem.benchmark"), std::string::npos) << m;
  EXPECT_NE(m.find("'B6' is not one of 'B1', 'B2', 'B3', 'B4', 'B5'"), std::string::npos) << m;
  // W must leave room for the tool (a < W/2).
  m = read_error(write("bad.toml", replaced(b1_study_text(), "body_radius = \"50 mm\"", "body_radius = \"4 mm\"")));
  EXPECT_NE(m.find("bad.toml"), std::string::npos) << m;
  EXPECT_NE(m.find("problem.tool_radius = 0.0025 m must be < problem.body_radius / 2 = 0.002 m"), std::string::npos) << m;
}

TEST(AccuracyIndicator, EnrichedCasesAreJudgedByWhatTheEnrichmentCarries) {
  const Eigen::Vector3d d(0, 0, -1);
  const json params{{"min_rcond_threshold", 1e-12}, {"youngs_modulus_Pa", 1e4}, {"poisson_ratio", 0.45},
                    {"tool_radius_m", 0.0025}, {"depth_m", 0.25e-3}, {"exterior", "body_aware"}};
  // B3-like: the MLS part carries 8 % of the energy, the clamp raises the amplitude to 1.39.
  json ok{{"qoi", {{"force_N", {0.0, 0.0, -0.022}},
                   {"forces_by_method_N", {{"reaction", nullptr}, {"energy_along_tool", 0.022},
                                           {"traction_integral", {0.0, 0.0, -0.022}}, {"paper_partition", nullptr}}},
                   {"min_rcond", 1e-6}}},
          {"diagnostics",
           {{"max_support_scale_used", 1.0},
            {"enriched", {{"exterior_used", "body_aware"}, {"mls_energy_share", 0.08}, {"amplitudes_per_depth", {1.39}}}}}},
          {"params", params}};
  AccuracyIndicator a = accuracy_indicator(ok, d);
  EXPECT_DOUBLE_EQ(a.mls_energy_share, 0.08);
  EXPECT_DOUBLE_EQ(a.normal_amplitude, 1.39);
  EXPECT_EQ(a.exterior_used, "body_aware");
  EXPECT_TRUE(a.flags.empty());
  // The MLS part carries half the energy, the amplitude is 3, and the atlas had no answer.
  json bad = ok;
  bad["diagnostics"]["enriched"] = {{"exterior_used", "half_space"}, {"mls_energy_share", 0.5}, {"amplitudes_per_depth", {3.0}}};
  a = accuracy_indicator(bad, d);
  EXPECT_EQ(a.flags, (std::vector<std::string>{"mls_dominated", "amplitude_implausible", "exterior_fallback"}));
  // Asking for the half-space and getting it is no fallback.
  bad["params"]["exterior"] = "half_space";
  bad["diagnostics"]["enriched"]["mls_energy_share"] = 0.1;
  bad["diagnostics"]["enriched"]["amplitudes_per_depth"] = {1.0};
  EXPECT_TRUE(accuracy_indicator(bad, d).flags.empty());
  // Corrected gradients: what the correction left is judged (on the hemisphere about 1e-3).
  bad["params"]["gradient_correction"] = "linear";
  bad["diagnostics"]["enriched"]["gradient_correction_left"] = 1e-3;
  a = accuracy_indicator(bad, d);
  EXPECT_DOUBLE_EQ(a.gradient_correction_left, 1e-3);
  EXPECT_TRUE(a.flags.empty());
  bad["diagnostics"]["enriched"]["gradient_correction_left"] = 0.2;
  EXPECT_EQ(accuracy_indicator(bad, d).flags, (std::vector<std::string>{"rules_disagree"}));
  bad["diagnostics"]["enriched"].erase("gradient_correction_left");  // a correction that reported nothing
  EXPECT_EQ(accuracy_indicator(bad, d).flags, (std::vector<std::string>{"rules_disagree"}));
  // The automatic choice: the case's diagnostics say what the build applied.
  bad["params"]["gradient_correction"] = "auto";
  bad["diagnostics"]["enriched"]["gradient_correction"] = "none";
  EXPECT_TRUE(accuracy_indicator(bad, d).flags.empty());
  bad["diagnostics"]["enriched"]["gradient_correction"] = "linear";
  bad["diagnostics"]["enriched"]["gradient_correction_left"] = 0.2;
  EXPECT_EQ(accuracy_indicator(bad, d).flags, (std::vector<std::string>{"rules_disagree"}));
}

TEST(AccuracyIndicator, FlagsDisagreeingForcesGrownSupportsAndIllConditioning) {
  const Eigen::Vector3d d(0, 0, -1);
  // A clean Galerkin-like case: reaction and energy 5 % apart, well-conditioned, no growth.
  // E = 10 kPa, ν = 0.45, a = 2.5 mm, δ = 0.25 mm: the half-space force 2 E a δ / (1 − ν²) = 15.674 mN.
  const json params{{"min_rcond_threshold", 1e-12}, {"youngs_modulus_Pa", 1e4}, {"poisson_ratio", 0.45},
                    {"tool_radius_m", 0.0025}, {"depth_m", 0.25e-3}};
  const double half_space_N = 2 * 1e4 * 0.0025 * 0.25e-3 / (1 - 0.45 * 0.45);
  json clean{{"qoi", {{"force_N", {0.0, 0.0, -0.020}},
                      {"forces_by_method_N", {{"reaction", {0.0, 0.0, -0.020}}, {"energy_along_tool", 0.019},
                                              {"traction_integral", {0.0, 0.0, -0.013}}, {"paper_partition", nullptr}}},
                      {"min_rcond", 1.0}}},
             {"diagnostics", {{"max_neighbours", 0}, {"max_support_scale_used", 1.0}}},
             {"params", params}};
  AccuracyIndicator a = accuracy_indicator(clean, d);
  EXPECT_NEAR(a.force_method_spread, 0.001 / 0.020, 1e-12);
  EXPECT_NEAR(a.stiffness_ratio, 0.020 / half_space_N, 1e-12);  // 1.28: a plausible punch
  EXPECT_EQ(a.force_methods, (std::vector<std::string>{"reaction", "energy_along_tool"}));
  EXPECT_DOUBLE_EQ(a.rcond_min, 1.0);
  EXPECT_DOUBLE_EQ(a.support_scale_max, 1.0);
  EXPECT_TRUE(a.flags.empty());

  // Reaction 3x the energy force, supports grown 2x, rcond within 100x of the threshold.
  json bad = clean;
  bad["qoi"]["forces_by_method_N"]["reaction"] = {0.0, 0.0, -0.060};
  bad["diagnostics"] = {{"max_neighbours", 40}, {"max_support_scale_used", 2.0}};
  bad["qoi"]["min_rcond"] = 5e-11;
  bad["qoi"]["force_N"] = {0.0, 0.0, -0.070};  // 4.47x the half-space: implausibly stiff
  a = accuracy_indicator(bad, d);
  EXPECT_NEAR(a.force_method_spread, (0.060 - 0.019) / 0.060, 1e-12);
  EXPECT_EQ(a.flags, (std::vector<std::string>{"force_methods_disagree", "supports_grew", "ill_conditioned",
                                                "stiffness_implausible"}));
  // Just inside the bounds, and below the lower one.
  bad = clean;
  bad["qoi"]["force_N"] = {0.0, 0.0, -0.0620};  // 3.96x
  EXPECT_TRUE(accuracy_indicator(bad, d).flags.empty());
  bad["qoi"]["force_N"] = {0.0, 0.0, -0.0038};  // 0.24x
  EXPECT_EQ(accuracy_indicator(bad, d).flags, (std::vector<std::string>{"stiffness_implausible"}));

  // Collocation (no reaction/energy): the traction integral against the paper's partition.
  json collocation{{"qoi", {{"force_N", {0.0, 0.0, -0.010}},
                            {"forces_by_method_N", {{"reaction", nullptr}, {"energy_along_tool", nullptr},
                                                    {"traction_integral", {0.0, 0.0, -0.010}},
                                                    {"paper_partition", {0.0, 0.0, -0.0101}}}},
                            {"min_rcond", 1e-6}}},
                   {"diagnostics", {{"max_neighbours", 30}, {"max_support_scale_used", 1.0}}},
                   {"params", params}};
  a = accuracy_indicator(collocation, d);
  EXPECT_NEAR(a.force_method_spread, 0.0001 / 0.0101, 1e-12);
  EXPECT_DOUBLE_EQ(a.rcond_min, 1e-6);
  EXPECT_DOUBLE_EQ(a.support_scale_max, 1.0);
  EXPECT_TRUE(a.flags.empty());
  // A failed case has no forces: no spread, no force flag.
  a = accuracy_indicator(json{{"qoi", {{"forces_by_method_N", nullptr}}}}, d);
  EXPECT_TRUE(std::isnan(a.force_method_spread));
  EXPECT_TRUE(a.flags.empty());
  // A failed case that reported broken diagnostics before failing gets no flags either: there
  // is no result to judge.
  json failed = bad;
  failed["qoi"]["force_N"] = {0.0, 0.0, -0.070};
  failed["status"] = "the local ball reaches a clamped surface";
  EXPECT_TRUE(accuracy_indicator(failed, d).flags.empty());

  // Convergence in N: 20.0 mN after 20.9 mN at the previous N moved 4.5 % (under the 5 % limit);
  // after 21.2 mN, 6 % (flagged); after a failed case, nothing to compare.
  json previous{{"status", "ok"}, {"qoi", {{"force_N", {0.0, 0.0, -0.0209}}}}, {"params", {{"node_count_requested", 50}}}};
  a = accuracy_indicator(clean, d, &previous);
  EXPECT_NEAR(a.force_change_from_previous_n, 0.045, 1e-12);
  EXPECT_EQ(a.previous_node_count, 50);
  EXPECT_TRUE(a.flags.empty());
  previous["qoi"]["force_N"] = {0.0, 0.0, -0.0212};
  a = accuracy_indicator(clean, d, &previous);
  EXPECT_NEAR(a.force_change_from_previous_n, 0.06, 1e-12);
  EXPECT_EQ(a.flags, (std::vector<std::string>{"unconverged_in_n"}));
  previous["status"] = "singular";
  a = accuracy_indicator(clean, d, &previous);
  EXPECT_TRUE(std::isnan(a.force_change_from_previous_n));
  EXPECT_TRUE(a.flags.empty());
}

TEST(ConvergenceInN, FitsThePowerLawOfTheLargestNodeCounts) {
  // e = 40 N^-0.7 exactly at the four largest N; the smallest N is off the line and left out.
  std::vector<std::pair<double, double>> points{{35, 10.0}};
  for (const double n : {100.0, 205.0, 301.0, 414.0}) points.push_back({n, 40 * std::pow(n, -0.7)});
  ConvergenceInN fit = convergence_in_n(points, 0.05);
  EXPECT_NEAR(fit.order, -0.7, 1e-12);
  EXPECT_NEAR(fit.n_at_target, std::pow(40 / 0.05, 1 / 0.7), 1e-9 * std::pow(40 / 0.05, 1 / 0.7));
  EXPECT_EQ(fit.node_counts, (std::vector<double>{100, 205, 301, 414}));
  // All five points: the outlier bends the fit.
  fit = convergence_in_n(points, 0.05, 5);
  EXPECT_GT(std::abs(fit.order + 0.7), 0.05);
  // An error that grows with N has no N at which it reaches the target.
  fit = convergence_in_n({{100, 0.1}, {200, 0.2}, {400, 0.4}}, 0.05);
  EXPECT_NEAR(fit.order, 1.0, 1e-12);
  EXPECT_TRUE(std::isnan(fit.n_at_target));
  // Fewer than three usable points (failed cases are NaN, zero errors cannot be logged).
  fit = convergence_in_n({{100, 0.1}, {200, std::nan("")}, {400, 0.0}, {800, 0.05}}, 0.05);
  EXPECT_TRUE(std::isnan(fit.order));
  EXPECT_TRUE(std::isnan(fit.n_at_target));
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
