// The committed study results fixture (tests/fixtures/results/study_results.json, a real
// `touchstone study studies/configs/ci_accuracy.toml` output trimmed to a few cases) read from C++: the
// numbers the Python report prints are the ones the runner's own functions give for the stored
// inputs. Per MFS case: the force along d, its error against the reference, the force ramp
// K_t δ d · d, the displacement error at the probes and the accuracy indicator, recomputed and
// compared with the stored values. A change of these formulas on either side fails here.
#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/study_runner.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <Eigen/Core>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace touchstone::studies {
namespace {

using nlohmann::json;

/// Stored numbers are written with 17 significant digits (nlohmann's round trip); recomputing
/// them in another order of operations differs by a few ulps.
constexpr double relative_tolerance = 1e-12;

const json& fixture() {
  static const json document =
      json::parse(read_file(std::string(TOUCHSTONE_SOURCE_DIR) + "/tests/fixtures/results/study_results.json"));
  return document;
}

Eigen::Vector3d vector3(const json& v) { return {v.at(0).get<double>(), v.at(1).get<double>(), v.at(2).get<double>()}; }

std::vector<const json*> mfs_cases() {
  std::vector<const json*> cases;
  for (const json& c : fixture().at("cases"))
    if (c.at("model") == "mfs") cases.push_back(&c);
  return cases;
}

const json& reference_case() {
  const std::string id = fixture().at("reference_summary").at("case");
  for (const json& c : fixture().at("cases"))
    if (c.at("id") == id) return c;
  throw std::runtime_error("the fixture lacks its reference case " + id);
}

void expect_relative(double actual, double expected, const std::string& what) {
  EXPECT_NEAR(actual, expected, relative_tolerance * std::abs(expected)) << what;
}

TEST(ResultsFixture, HoldsMfsCasesOfEverySeriesAndTheReference) {
  ASSERT_GE(mfs_cases().size(), 3u);
  for (const json& s : fixture().at("series")) {
    int count = 0;
    for (const json* c : mfs_cases()) count += c->at("series") == s.at("name");
    EXPECT_GE(count, 1) << s.at("name");
  }
  EXPECT_TRUE(reference_case().at("qoi").at("probes").is_array());
}

TEST(ResultsFixture, ForceAlongTheToolAndItsErrorAgainstTheReference) {
  const Eigen::Vector3d d = vector3(fixture().at("problem").at("direction")).normalized();
  const double reference_N = fixture().at("reference_summary").at("axial_force_N").get<double>();
  for (const json* c : mfs_cases()) {
    if (c->at("status") != "ok") continue;
    const std::string id = c->at("id");
    const double axial = vector3(c->at("qoi").at("force_N")).dot(d);
    expect_relative(c->at("qoi").at("axial_force_N").get<double>(), axial, id + " axial_force_N");
    expect_relative(c->at("error").at("force_rel").get<double>(), std::abs(axial - reference_N) / std::abs(reference_N),
                    id + " force_rel");
    expect_relative(c->at("error").at("force_signed_rel").get<double>(), (axial - reference_N) / std::abs(reference_N),
                    id + " force_signed_rel");
  }
}

TEST(ResultsFixture, ForceRampIsTheToolStiffnessTimesDepth) {
  const Eigen::Vector3d d = vector3(fixture().at("problem").at("direction")).normalized();
  const std::vector<double> depths = fixture().at("depths_m").get<std::vector<double>>();
  for (const json* c : mfs_cases()) {
    if (c->at("status") != "ok") continue;
    const json& m = c->at("qoi").at("tool_stiffness_matrix_N_per_m");
    Eigen::Matrix3d k;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) k(i, j) = m.at(i).at(j).get<double>();
    const std::vector<double> ramp = mfs_force_ramp_N(k, d, depths);
    const json& stored = c->at("force_depth_N");
    ASSERT_EQ(stored.size(), ramp.size()) << c->at("id");
    for (std::size_t i = 0; i < ramp.size(); ++i)
      expect_relative(stored.at(i).get<double>(), ramp[i], c->at("id").get<std::string>() + " force_depth_N");
  }
}

TEST(ResultsFixture, DisplacementErrorAtTheProbes) {
  const json& reference_probes = reference_case().at("qoi").at("probes");
  for (const json* c : mfs_cases()) {
    if (c->at("status") != "ok") continue;
    const ProbeComparison p = compare_probes(c->at("qoi").at("probes"), reference_probes);
    EXPECT_EQ(p.count, c->at("error").at("disp_probes").get<int>()) << c->at("id");
    expect_relative(p.rel_l2, c->at("error").at("disp_rel_l2").get<double>(), c->at("id").get<std::string>() + " disp_rel_l2");
    expect_relative(p.max_abs_m, c->at("error").at("disp_max_m").get<double>(), c->at("id").get<std::string>() + " disp_max_m");
  }
}

TEST(ResultsFixture, AccuracyIndicatorFromTheStoredCase) {
  const Eigen::Vector3d d = vector3(fixture().at("problem").at("direction")).normalized();
  for (const json* c : mfs_cases()) {
    const std::string id = c->at("id");
    // The runner's predecessor: the same series' case at the next smaller requested N (the
    // fixture keeps each series' node counts consecutive).
    const int n = c->at("params").at("node_count_requested");
    const json* before = nullptr;
    for (const json* other : mfs_cases()) {
      const int m = other->at("params").at("node_count_requested");
      if (other->at("series") == c->at("series") && m < n &&
          (before == nullptr || m > before->at("params").at("node_count_requested").get<int>()))
        before = other;
    }
    json previous;
    if (before != nullptr)
      previous = {{"status", before->at("status")},
                  {"qoi", {{"force_N", before->at("qoi").at("force_N")}}},
                  {"params", {{"node_count_requested", before->at("params").at("node_count_requested")}}}};
    const json stored = c->at("accuracy");
    EXPECT_EQ(stored.at("previous_node_count").get<int>(), before ? before->at("params").at("node_count_requested").get<int>() : 0)
        << id << ": the fixture lost this case's predecessor";
    const json recomputed = to_json(accuracy_indicator(*c, d, before ? &previous : nullptr));
    EXPECT_EQ(recomputed.at("flags"), stored.at("flags")) << id;
    EXPECT_EQ(recomputed.at("force_methods"), stored.at("force_methods")) << id;
    for (const char* key : {"force_method_spread", "stiffness_ratio", "force_change_from_previous_n", "rcond_min",
                            "support_scale_max"}) {
      const json& a = recomputed.at(key);
      const json& b = stored.at(key);
      ASSERT_EQ(a.is_null(), b.is_null()) << id << " " << key;
      if (!a.is_null()) expect_relative(a.get<double>(), b.get<double>(), id + " " + key);
    }
  }
}

}  // namespace
}  // namespace touchstone::studies
