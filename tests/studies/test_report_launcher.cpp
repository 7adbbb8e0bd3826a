// The report launcher: where it looks for the reports package (TOUCHSTONE_REPORTS_DIR alone when
// set; else next to the executable, then the source tree), the exit statuses it hands back, and
// a report written through it.
#include "touchstone/studies/report_launcher.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace touchstone::studies {
namespace {

namespace fs = std::filesystem;

/// Sets or unsets TOUCHSTONE_REPORTS_DIR for one scope, restoring the previous value.
class ReportsDirectory {
 public:
  explicit ReportsDirectory(const char* value) {
    if (const char* old = std::getenv("TOUCHSTONE_REPORTS_DIR")) {
      previous_ = old;
      had_ = true;
    }
    set(value);
  }
  ~ReportsDirectory() { set(had_ ? previous_.c_str() : nullptr); }
  ReportsDirectory(const ReportsDirectory&) = delete;
  ReportsDirectory& operator=(const ReportsDirectory&) = delete;

 private:
  static void set(const char* value) {
    if (value != nullptr) {
      setenv("TOUCHSTONE_REPORTS_DIR", value, 1);
    } else {
      unsetenv("TOUCHSTONE_REPORTS_DIR");
    }
  }

  std::string previous_;
  bool had_ = false;
};

fs::path temp_root() {
  return fs::temp_directory_path() / ("touchstone_test_report_launcher_" + std::to_string(getpid()));
}

class RemoveTemporaries : public ::testing::Environment {
 public:
  void TearDown() override { fs::remove_all(temp_root()); }
};
const auto* const remove_temporaries = ::testing::AddGlobalTestEnvironment(new RemoveTemporaries);

fs::path fresh_directory(const std::string& name) {
  const fs::path path = temp_root() / name;
  fs::remove_all(path);
  fs::create_directories(path);
  return path;
}

TEST(ReportLauncher, InstalledLocationFirstThenSourceTree) {
  const ReportsDirectory unset(nullptr);
  const ReportsPackageLocation location = find_reports_package();
  const fs::path executable = fs::read_symlink("/proc/self/exe");
  ASSERT_EQ(location.searched.size(), 2u);
  EXPECT_EQ(location.searched[0], (executable.parent_path().parent_path() / "share/touchstone/reports").string());
  EXPECT_EQ(location.searched[1], (fs::path(TOUCHSTONE_SOURCE_DIR) / "reports").string());
  // Nothing is installed next to a test program: the source tree's package is found.
  EXPECT_EQ(location.directory, location.searched[1]);
}

TEST(ReportLauncher, EnvironmentVariableIsTheOnlyPlaceWhenSet) {
  const fs::path nowhere = fresh_directory("nowhere");
  const ReportsDirectory set(nowhere.c_str());
  const ReportsPackageLocation location = find_reports_package();
  ASSERT_EQ(location.searched.size(), 1u);
  EXPECT_EQ(location.searched[0], nowhere.string());
  EXPECT_EQ(location.directory, "");
  const ReportStatus status = run_report("fem", nowhere.string());
  EXPECT_EQ(status.exit_status, -1);
  EXPECT_FALSE(status.ok());
  EXPECT_NE(status.message.find(nowhere.string()), std::string::npos) << status.message;
  EXPECT_NE(status.message.find("TOUCHSTONE_REPORTS_DIR"), std::string::npos) << status.message;
}

TEST(ReportLauncher, WritesAReportThroughThePackage) {
  const ReportsDirectory set((fs::path(TOUCHSTONE_SOURCE_DIR) / "reports").c_str());
  const fs::path out = fresh_directory("fem");
  fs::copy_file(fs::path(TOUCHSTONE_SOURCE_DIR) / "tests/fixtures/results/fem_results.json", out / "results.json");
  const ReportStatus status = run_report("fem", out.string());
  EXPECT_EQ(status.exit_status, 0) << status.message;
  EXPECT_EQ(status.message, "");
  EXPECT_TRUE(fs::is_regular_file(out / "report.md"));
}

TEST(ReportLauncher, HandsBackThePackagesExitStatus) {
  const ReportsDirectory unset(nullptr);
  const fs::path empty = fresh_directory("empty");
  const ReportStatus status = run_report("study", empty.string());  // no results.json: status 2
  EXPECT_EQ(status.exit_status, 2);
  EXPECT_NE(status.message.find("status 2"), std::string::npos) << status.message;
  EXPECT_FALSE(fs::exists(empty / "report.md"));
}

TEST(ReportLauncher, NamesAnInterpreterThatCannotStart) {
  const ReportsDirectory unset(nullptr);
  ReportLaunchOptions options;
  options.python = "/nonexistent/python3";
  const ReportStatus status = run_report("study", fresh_directory("no_python").string(), options);
  EXPECT_EQ(status.exit_status, -1);
  EXPECT_NE(status.message.find("cannot start /nonexistent/python3"), std::string::npos) << status.message;
}

}  // namespace
}  // namespace touchstone::studies
