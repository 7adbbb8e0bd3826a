#pragma once
/// @file
/// Shared pieces of the end-to-end `touchstone study` tests: a fresh scratch folder per test
/// and process (tests of two checkouts may run at once), the [problem]/[reference] text of the
/// benchmark problem they all solve (a = 2.5 mm, E = 10 kPa, ν = 0.45, two depths up to
/// 0.25 mm) on a coarse reference, and case lookup in results.
#include "touchstone/studies/study_runner.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include <filesystem>
#include <string>

#ifndef TOUCHSTONE_SOURCE_DIR
#error "TOUCHSTONE_SOURCE_DIR must point at the source tree"
#endif

namespace touchstone::studies::testing {

/// <temp>/touchstone_<name>_<pid>, emptied and created.
inline std::filesystem::path scratch_directory(const std::string& name) {
  const std::filesystem::path out =
      std::filesystem::temp_directory_path() / ("touchstone_" + name + "_" + std::to_string(getpid()));
  std::filesystem::remove_all(out);
  std::filesystem::create_directories(out);
  return out;
}

/// The [problem] (body R or W = 50 mm, L = 12.5 mm) and a [reference] on studies/configs/<config> with
/// one mesh family of level-0 edge `edge_size` and two levels.
inline std::string problem_text(const std::string& benchmark, const std::string& config, const std::string& edge_size) {
  return R"([problem]
benchmark = ")" + benchmark + R"("
body_radius = "50 mm"
tool_radius = "2.5 mm"
local_radius = "12.5 mm"
youngs_modulus = "10 kPa"
poisson_ratio = 0.45
depths = ["0.125 mm", "0.25 mm"]
[reference]
config = ")" + std::string(TOUCHSTONE_SOURCE_DIR) + "/studies/configs/" + config + R"("
edge_sizes = [")" + edge_size + R"("]
refinements = [0, 1]
)";
}

/// Options writing into <out>/run with its own cache under <out>: no report, no console output.
inline StudyRunOptions quiet_run_options(const std::filesystem::path& out) {
  StudyRunOptions options;
  options.output_directory = (out / "run").string();
  options.cache_directory = (out / "cache").string();
  options.write_report = false;
  options.quiet = true;
  return options;
}

/// The case of `results` with this id (fails the test when there is none).
inline const nlohmann::json& case_with_id(const nlohmann::json& results, const std::string& id) {
  for (const auto& c : results.at("cases"))
    if (c.at("id") == id) return c;
  ADD_FAILURE() << "no case " << id;
  static const nlohmann::json none = nlohmann::json::object();
  return none;
}

}  // namespace touchstone::studies::testing
