// Every comparison study shipped in studies/ (a *.toml with a [problem] table, i.e. a
// `touchstone study` file) is read by read_comparison_study without error and expands to at
// least one MFS case. No solver runs: reading checks every key, the referenced FEM files and
// every [mfs.<name>] section against the engine's validation.
#include "touchstone/studies/study_runner.hpp"

#include <gtest/gtest.h>
#include <toml++/toml.h>

#include <algorithm>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using namespace touchstone::studies;

/// studies/*.toml files that have a [problem] table, sorted.
std::vector<fs::path> comparison_studies() {
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(fs::path(TOUCHSTONE_SOURCE_DIR) / "studies")) {
    if (!entry.is_regular_file() || entry.path().extension() != ".toml") continue;
    const toml::table document = toml::parse_file(entry.path().string());
    if (document.contains("problem") && document.get("problem")->is_table()) files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

TEST(ShippedStudies, TheIssueFourStudiesAreShipped) {
  std::set<std::string> names;
  for (const auto& path : comparison_studies()) names.insert(path.stem().string());
  for (const char* expected : {"hemisphere", "ci_accuracy", "sprinkling", "paper_mode", "truncation", "formulation",
                               "stability", "poisson_0p30", "poisson_0p45", "poisson_0p49"})
    EXPECT_TRUE(names.count(expected)) << "studies/" << expected << ".toml is missing or has no [problem] table";
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
    for (const auto& series : study.series)
      for (const int n : series.study.node_counts) {
        ++cases;
        EXPECT_TRUE(ids.insert("MFS-" + series.name + "-N" + std::to_string(n)).second)
            << "duplicate case MFS-" << series.name << "-N" << n;
      }
    EXPECT_GE(cases, 1u);
    EXPECT_EQ(study.name, path.stem().string()) << "the study name should be the file's name (its default output folder)";
  }
}

}  // namespace
