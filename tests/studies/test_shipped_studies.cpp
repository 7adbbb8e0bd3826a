// Every comparison study shipped in studies/ (a *.toml with a [problem] table, i.e. a
// `touchstone study` file) is read by read_comparison_study without error and expands to at
// least one MFS case. No solver runs: reading checks every key, the referenced FEM files and
// every [mfs.<name>] section against the engine's validation.
#include "touchstone/studies/fem_reference/reference_study.hpp"
#include "touchstone/studies/study_runner.hpp"

#include <gtest/gtest.h>
#include <toml++/toml.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using namespace touchstone::studies;

/// studies/configs/*.toml files that have a [problem] table, sorted.
std::vector<fs::path> comparison_studies() {
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(fs::path(TOUCHSTONE_SOURCE_DIR) / "studies" / "configs")) {
    if (!entry.is_regular_file() || entry.path().extension() != ".toml") continue;
    const toml::table document = toml::parse_file(entry.path().string());
    if (document.contains("problem") && document.get("problem")->is_table()) files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

// The FEM reference studies (studies/configs/b<k>_*.toml) read, and their resolved config
// (every default filled in, SI) reads back to the same study: resolving it again gives the same
// text, key for key.
TEST(ShippedStudies, EveryFemStudyReadsBackFromItsResolvedConfig) {
  int studies = 0;
  for (const auto& entry : fs::directory_iterator(fs::path(TOUCHSTONE_SOURCE_DIR) / "studies" / "configs")) {
    const std::string name = entry.path().filename().string();
    if (entry.path().extension() != ".toml" || name.size() < 3 || name[0] != 'b' || !std::isdigit(name[1])) continue;
    SCOPED_TRACE(name);
    ConfigTable config = ConfigTable::from_file(entry.path().string());
    const ReferenceStudy study = read_reference_study(config);
    const std::string resolved = resolved_reference_study_toml(study);
    ConfigTable again = ConfigTable::from_string(resolved, name + ".resolved");
    const ReferenceStudy back = read_reference_study(again);
    EXPECT_EQ(resolved_reference_study_toml(back), resolved);
    EXPECT_EQ(back.geometry.max_size_m, study.geometry.max_size_m);
    EXPECT_EQ(back.edge_sizes_m, study.edge_sizes_m);
    EXPECT_EQ(back.geometry.edge_size_m, study.geometry.edge_size_m);
    EXPECT_EQ(back.punch.depth_m, study.punch.depth_m);
    ++studies;
  }
  EXPECT_GE(studies, 6);
}

TEST(ShippedStudies, TheComparisonStudiesAreShipped) {
  std::set<std::string> names;
  for (const auto& path : comparison_studies()) names.insert(path.stem().string());
  for (const char* expected : {"hemisphere", "ci_accuracy", "sprinkling", "paper_mode", "truncation", "formulation",
                               "stability", "poisson", "half_space"})
    EXPECT_TRUE(names.count(expected)) << "studies/configs/" << expected << ".toml is missing or has no [problem] table";
}

TEST(ShippedStudies, EveryComparisonStudyReadsAndHasMfsCases) {
  const std::vector<fs::path> files = comparison_studies();
  ASSERT_FALSE(files.empty());
  for (const auto& path : files) {
    SCOPED_TRACE(path.string());
    ComparisonStudy study;
    ASSERT_NO_THROW(study = read_comparison_study(path.string())) << [&] {
      try {
        read_comparison_study(path.string());
      } catch (const std::exception& e) {
        return std::string(e.what());
      }
      return std::string();
    }();
    std::size_t cases = 0;
    std::set<std::string> ids;
    for (const auto& problem : study.problems) {
      std::size_t problem_cases = 0;
      for (const auto& series : problem.series)
        for (const int n : series.study.node_counts) {
          ++problem_cases;
          const std::string id = problem.id_prefix + "MFS-" + series.name + "-N" + std::to_string(n);
          EXPECT_TRUE(ids.insert(id).second) << "duplicate case " << id;
        }
      EXPECT_GE(problem_cases, 1u) << "problem " << problem.name << " has no MFS case";
      cases += problem_cases;
    }
    EXPECT_GE(cases, 1u);
    EXPECT_EQ(study.name, path.stem().string()) << "the study name should be the file's name (its default output folder)";
  }
}

}  // namespace

namespace {

/// The B1 study: the cylinder, its own B1 reference, the engine's default series and the paper's.
TEST(ShippedStudies, HalfSpaceIsBenchmarkB1AgainstItsOwnReference) {
  const ComparisonStudy study = read_comparison_study(std::string(TOUCHSTONE_SOURCE_DIR) + "/studies/configs/half_space.toml");
  ASSERT_EQ(study.problems.size(), 1u);
  const StudyProblem& p = study.first();
  EXPECT_EQ(p.problem.benchmark, touchstone::meshes::Benchmark::B1);
  EXPECT_EQ(p.reference.geometry.benchmark, touchstone::meshes::Benchmark::B1);
  EXPECT_EQ(p.reference.name, "b1_reference");
  EXPECT_GE(p.reference.refinements.size(), 3u);  // Richardson, with an error estimate
  bool engine_default = false, paper = false;
  for (const auto& s : p.series) {
    engine_default = engine_default || s.engine_default;
    paper = paper || s.study.model.paper_mode;
    EXPECT_EQ(s.study.geometry.benchmark, touchstone::meshes::Benchmark::B1) << s.name;
  }
  EXPECT_TRUE(engine_default);
  EXPECT_TRUE(paper);
}

/// The reworked stress test and Poisson study: one file each, several problems.
TEST(ShippedStudies, StabilityAndPoissonCoverTheirRangesInOneFile) {
  const std::string dir = std::string(TOUCHSTONE_SOURCE_DIR) + "/studies/configs/";
  const ComparisonStudy poisson = read_comparison_study(dir + "poisson.toml");
  std::set<double> nus, bonded_nus;
  for (const auto& p : poisson.problems) {
    nus.insert(p.problem.material.poisson_ratio);
    if (p.problem.contact == touchstone::geometry::ContactCondition::bonded) bonded_nus.insert(p.problem.material.poisson_ratio);
  }
  EXPECT_EQ(nus, (std::set<double>{0.30, 0.45, 0.49}));
  EXPECT_EQ(bonded_nus, nus);  // the bonded tool at every ratio too
  // At ν = 0.49 the displacement P2 ladder converges at its usual order while the mixed P2–P0
  // ladder rises without one (README, Measured), so every Poisson reference is displacement P2.
  for (const auto& p : poisson.problems)
    EXPECT_EQ(p.reference.solver.formulation, touchstone::fem::Formulation::displacement) << p.name;

  const ComparisonStudy stability = read_comparison_study(dir + "stability.toml");
  double nu_max = 0, e_min = 1e300, e_max = 0, depth_over_l = 0;
  bool near_base = false, grazing = false, b5 = false;
  for (const auto& p : stability.problems) {
    const ComparisonProblem& q = p.problem;
    nu_max = std::max(nu_max, q.material.poisson_ratio);
    e_min = std::min(e_min, q.material.youngs_modulus_Pa);
    e_max = std::max(e_max, q.material.youngs_modulus_Pa);
    depth_over_l = std::max(depth_over_l, q.max_depth_m() / q.local_radius_m);
    b5 = b5 || q.benchmark == touchstone::meshes::Benchmark::B5;
    near_base = near_base || (q.benchmark == touchstone::meshes::Benchmark::B5 && q.ball_reaches_base());
    grazing = grazing || q.angle_to_normal_rad() >= 60 * M_PI / 180 - 1e-12;
  }
  EXPECT_DOUBLE_EQ(nu_max, 0.499);
  // Closer to ν = 0.5 P2 locks strongly: there the reference is the mixed form.
  for (const auto& p : stability.problems)
    if (p.problem.material.poisson_ratio >= 0.499) {
      EXPECT_EQ(p.reference.solver.formulation, touchstone::fem::Formulation::mixed_p0disc) << p.name;
    }
  EXPECT_DOUBLE_EQ(e_min, 1.0);
  EXPECT_DOUBLE_EQ(e_max, 1e9);
  EXPECT_NEAR(depth_over_l, 0.5, 1e-12);
  EXPECT_TRUE(b5);
  EXPECT_TRUE(near_base);
  EXPECT_TRUE(grazing);
}

}  // namespace
