// The targets of `touchstone study` are data in, data out: from the cases' errors and times to
// each target's measured value, whether it is met and by how much it is missed. Hand-made cases
// with round numbers make every expected value obvious.
#include "comparison/comparison_parts.hpp"

#include <gtest/gtest.h>

namespace touchstone::studies::comparison {
namespace {

using nlohmann::json;

json mfs_case(const std::string& id, int n, double force_rel, double disp_rel, double total_s) {
  return {{"id", id},      {"model", "mfs"}, {"status", "ok"}, {"problem", "base"}, {"series", "enriched"},
          {"part", "mfs"}, {"params", {{"node_count_requested", n}, {"node_count", n}}},
          {"error", {{"force_rel", force_rel}, {"disp_rel_l2", disp_rel}}},
          {"time_s", {{"total", total_s}}}};
}

json fem_level(const std::string& id, int refinement, double force_rel, double total_s, double dofs) {
  return {{"id", id},         {"model", "fem"}, {"status", "ok"}, {"part", "reference"},
          {"params", {{"refinement", refinement}}},
          {"error", {{"force_rel", force_rel}}}, {"time_s", {{"total", total_s}}}, {"mesh", {{"dofs", dofs}}}};
}

class Targets : public ::testing::Test {
 protected:
  void SetUp() override {
    problem.name = "base";
    problem.problem.benchmark = meshes::Benchmark::B3;
    MfsSeries series;
    series.name = "enriched";
    series.engine_default = true;
    problem.series.push_back(series);
    ProblemRun r;
    r.sp = &problem;
    r.d = Eigen::Vector3d(0, 0, -1);
    r.reference_part = "reference";
    r.runs_reference = true;
    r.reference.id = "reference/b3-reference";
    r.reference.uncertainty_rel = 0.002;
    r.reference.summary = {{"study", "b3_reference"}};
    runs.push_back(r);
  }
  const json* find(const json& list, const std::string& id) {
    for (const auto& t : list)
      if (t.at("id") == id) return &t;
    return nullptr;
  }
  StudyProblem problem;
  std::vector<ProblemRun> runs;
};

TEST_F(Targets, ForceSpeedAndReferenceTargetsAreScoredFromTheCases) {
  const json cases = json::array({mfs_case("MFS-enriched-N34", 34, 0.004, 0.01, 0.004),
                                  mfs_case("MFS-enriched-N60", 60, 0.03, 0.03, 0.010),
                                  fem_level("reference/L0", 0, 0.04, 2.0, 1e4),
                                  fem_level("reference/L1", 1, 0.002, 50.0, 8e4)});
  const json list = targets(cases, json::object(), false, runs);

  const json* reference = find(list, "fem_reference_uncertainty");
  ASSERT_NE(reference, nullptr);
  EXPECT_EQ(reference->at("met"), true);
  EXPECT_DOUBLE_EQ(reference->at("measured").get<double>(), 0.002);

  // The best force error at N <= 60 is N = 34's 0.4 %: within 5 %, and within 1 % for N <= 300.
  const json* n60 = find(list, "mfs_force_n60:enriched");
  ASSERT_NE(n60, nullptr);
  EXPECT_DOUBLE_EQ(n60->at("measured").get<double>(), 0.004);
  EXPECT_EQ(n60->at("basis"), "MFS-enriched-N34");
  EXPECT_EQ(find(list, "mfs_force_n300:enriched")->at("met"), true);

  // 5 %: the fastest MFS within it (N = 34, 4 ms) against the cheapest FEM level within it (L0,
  // 4 % in 2 s): 2 / 0.004 = 500x, the 10^4 target missed.
  const json* speed = find(list, "speedup_at_5_percent");
  ASSERT_NE(speed, nullptr);
  EXPECT_DOUBLE_EQ(speed->at("measured").get<double>(), 2.0 / 0.004);
  EXPECT_EQ(speed->at("met"), false);
  EXPECT_EQ(speed->at("shortfall"), "missed: 500x");

  // At the default model's own error (0.4 %) only L1 (0.2 %) is as accurate: 50 / 0.004 = 12,500x, met.
  const json* own = find(list, "speedup_at_default_error");
  ASSERT_NE(own, nullptr);
  EXPECT_DOUBLE_EQ(own->at("measured").get<double>(), 50.0 / 0.004);
  EXPECT_EQ(own->at("met"), true);
  EXPECT_EQ(own->at("lower_bound"), false);
}

TEST_F(Targets, AMissedForceTargetSaysByHowMuchAndWhereTheSeriesWouldReachIt) {
  // Errors falling as N^-1 from 40 % at N = 34: the 5 % target is missed at N = 60 (22.7 %), and
  // the fitted line reaches it at N = 34 · 0.40 / 0.05 = 272.
  const json cases = json::array({mfs_case("MFS-enriched-N34", 34, 0.40, 0.5, 0.005),
                                  mfs_case("MFS-enriched-N51", 51, 0.40 * 34 / 51, 0.5, 0.006),
                                  mfs_case("MFS-enriched-N60", 60, 0.40 * 34 / 60, 0.5, 0.007)});
  const json list = targets(cases, json::object(), false, runs);
  const json* n60 = find(list, "mfs_force_n60:enriched");
  ASSERT_NE(n60, nullptr);
  EXPECT_EQ(n60->at("met"), false);
  EXPECT_NEAR(n60->at("measured").get<double>(), 0.40 * 34 / 60, 1e-15);
  EXPECT_NEAR(n60->at("convergence_in_n").at("order").get<double>(), -1.0, 1e-9);
  EXPECT_NEAR(n60->at("convergence_in_n").at("n_at_target").get<double>(), 272.0, 1e-6);
  EXPECT_NE(n60->at("shortfall").get<std::string>().find("N ~ 272"), std::string::npos) << n60->at("shortfall");
  // No FEM level: the speed-up is not measured, and says why.
  EXPECT_TRUE(find(list, "speedup_at_5_percent")->at("met").is_null());
}

TEST_F(Targets, TheSpeedUpAtTheDefaultErrorTakesTheFewestNodesNotTheFastestSample) {
  // N = 51 ran 0.1 ms faster than N = 34 (noise: single samples of builds that cost about the
  // same). The basis is N = 34 (0.6 %), which L1 (0.5 %, 10 s) matches: 10 / 0.005 = 2,000x,
  // missed. Taking the fastest sample would compare N = 51's 0.2 % with L2 and read 20,408x, met.
  const json cases = json::array({mfs_case("MFS-enriched-N34", 34, 0.006, 0.01, 0.0050),
                                  mfs_case("MFS-enriched-N51", 51, 0.002, 0.01, 0.0049),
                                  fem_level("reference/L0", 0, 0.04, 2.0, 1e4),
                                  fem_level("reference/L1", 1, 0.005, 10.0, 8e4),
                                  fem_level("reference/L2", 2, 0.001, 100.0, 6e5)});
  const json list = targets(cases, json::object(), false, runs);
  const json* own = find(list, "speedup_at_default_error");
  ASSERT_NE(own, nullptr);
  EXPECT_EQ(own->at("basis"), "MFS-enriched-N34 vs reference/L1");
  EXPECT_DOUBLE_EQ(own->at("measured").get<double>(), 10.0 / 0.005);
  EXPECT_EQ(own->at("met"), false);
}

TEST_F(Targets, TheLocalModelAgainstTheWholeBodyIsMeasuredOnTheWholeBodyProblem) {
  // B3 alone with the full body's reference: its cases' comparison with the full body is the row.
  json b3 = mfs_case("MFS-enriched-N34", 34, 0.004, 0.01, 0.004);
  b3["error_full_domain"] = {{"force_rel", 0.34}};
  json list = targets(json::array({b3}), json::object(), true, runs);
  const json* clamped = find(list, "mfs_vs_full_domain:enriched");
  ASSERT_NE(clamped, nullptr);
  EXPECT_DOUBLE_EQ(clamped->at("measured").get<double>(), 0.34);

  // With a whole-hemisphere problem (B2) beside it, the row is that problem's own force error
  // (the model with its exterior), and B3's clamped cut no longer stands in for it.
  StudyProblem whole = problem;
  whole.name = "whole";
  whole.id_prefix = "whole/";
  whole.problem.benchmark = meshes::Benchmark::B2;
  ProblemRun w = runs.front();
  w.sp = &whole;
  w.reference_part = "whole/reference";
  runs.push_back(w);
  json on_body = mfs_case("whole/MFS-enriched-N30", 30, 0.012, 0.02, 0.004);
  on_body["problem"] = "whole";
  json worse = mfs_case("whole/MFS-enriched-N45", 45, 0.015, 0.02, 0.005);
  worse["problem"] = "whole";
  list = targets(json::array({b3, on_body, worse}), json::object(), true, runs);
  EXPECT_EQ(find(list, "mfs_vs_full_domain:enriched"), nullptr);
  const json* full = find(list, "mfs_vs_full_domain:whole/enriched");
  ASSERT_NE(full, nullptr);
  EXPECT_DOUBLE_EQ(full->at("measured").get<double>(), 0.012);
  EXPECT_EQ(full->at("basis"), "whole/MFS-enriched-N30");
  EXPECT_EQ(full->at("met"), true);
}

TEST_F(Targets, Table2AddsTheEngineDefaultOnTheWholeHemisphere) {
  // The paper compares its local model with the whole body: a whole-hemisphere (B2) problem's
  // engine-default series gives Table 2 a row of its first case, scored against that problem's
  // own FEM; the B3 problem's row stays as it is.
  problem.series.front().study.node_counts = {34};
  const auto table2_case = [](const std::string& id, int requested, int nodes, double force_rel) {
    json c = mfs_case(id, nodes, force_rel, 0.006, 0.008);
    c["params"]["node_count_requested"] = requested;
    c["time_s"]["model"] = 0.008;
    c["time_s"]["solution"] = 1e-6;
    c["qoi"] = {{"axial_force_N", 0.0163}};
    return c;
  };
  const json local = table2_case("MFS-enriched-N34", 34, 33, 0.005);
  json only_local = table2(json::array({local}), runs.front(), ReferenceValue{}, "", runs);
  EXPECT_EQ(only_local.at("ours").at("mfs_default").at("case"), "MFS-enriched-N34");
  EXPECT_FALSE(only_local.at("ours").contains("mfs_default_whole_body"));

  StudyProblem whole = problem;
  whole.name = "whole";
  whole.id_prefix = "whole/";
  whole.problem.benchmark = meshes::Benchmark::B2;
  whole.series.front().study.node_counts = {30, 45};
  ProblemRun w = runs.front();
  w.sp = &whole;
  w.reference_part = "whole/reference";
  w.reference.id = "whole/reference/b2-reference";
  w.reference.uncertainty_rel = 0.0026;
  runs.push_back(w);
  const json cases = json::array({local, table2_case("whole/MFS-enriched-N30", 30, 26, 0.0001),
                                  table2_case("whole/MFS-enriched-N45", 45, 39, 0.0002)});
  const json t = table2(cases, runs.front(), ReferenceValue{}, "", runs);
  EXPECT_EQ(t.at("ours").at("mfs_default").at("case"), "MFS-enriched-N34");
  const json& row = t.at("ours").at("mfs_default_whole_body");
  EXPECT_EQ(row.at("case"), "whole/MFS-enriched-N30");
  EXPECT_EQ(row.at("nodes"), 26);
  EXPECT_DOUBLE_EQ(row.at("force_rel").get<double>(), 0.0001);
  EXPECT_DOUBLE_EQ(row.at("force_rel_full_domain").get<double>(), 0.0001);
  EXPECT_EQ(row.at("reference"), "whole/reference/b2-reference");
  EXPECT_DOUBLE_EQ(row.at("reference_uncertainty_rel").get<double>(), 0.0026);
}

}  // namespace
}  // namespace touchstone::studies::comparison
