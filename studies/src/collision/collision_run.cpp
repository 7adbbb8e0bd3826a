// `touchstone collision`: the run. Table 1 replica, tremor and per-cycle cost over the same
// organs, trees and approach trajectories; results.json (the study contract), config.resolved.toml
// and the CSV tables; report.md and the plots are the reports package's (report_launcher.hpp).
#include "touchstone/studies/collision_study.hpp"

#include "collision_measurements.hpp"
#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/provenance.hpp"
#include "touchstone/studies/report_launcher.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace touchstone::studies {
namespace fs = std::filesystem;
namespace rc = realtime::collision;
namespace hm = realtime::hand_motion;
using namespace collision;
using Eigen::Vector3d;
using nlohmann::json;

namespace {

constexpr double infinity = std::numeric_limits<double>::infinity();

std::string printf_string(const char* format, double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, format, value);
  return buffer;
}

/// Null fields of the results.json contract that a collision case has no value for.
json contract_qoi() { return {{"force_N", nullptr}, {"stiffness_N_per_m", nullptr}, {"energy_J", nullptr}}; }
json contract_error() { return {{"force_rel", nullptr}, {"disp_rel_l2", nullptr}, {"disp_max_m", nullptr}}; }

// ---------------------------------------------------------------------------------------------
// CSV tables.

std::string write_csv(const std::vector<std::string>& header, const std::vector<std::vector<std::string>>& rows) {
  std::ostringstream out;
  for (std::size_t i = 0; i < header.size(); ++i) out << (i ? "," : "") << header[i];
  out << "\n";
  for (const auto& row : rows) {
    for (std::size_t i = 0; i < row.size(); ++i) out << (i ? "," : "") << row[i];
    out << "\n";
  }
  return out.str();
}

/// report.md and the plots by the reports package. Plots asked for but not made (no matplotlib):
/// the report is written again without them and says why. Throws when no report is written.
void write_report(const CollisionRunOptions& options) {
  ReportLaunchOptions launch;
  launch.python = options.python;
  if (options.quiet) launch.arguments.push_back("--quiet");
  if (!options.plots) launch.arguments.push_back("--no-plots");
  ReportStatus status = run_report("collision", options.output_directory, launch);
  if (status.exit_status > 0 && options.plots) {  // the package ran and failed: retry without plots
    std::fprintf(stderr, "collision report: %s; writing it without plots\n", status.message.c_str());
    launch.arguments.insert(launch.arguments.end(), {"--no-plots", "--plot-note", "the plot step failed: " + status.message});
    status = run_report("collision", options.output_directory, launch);
  }
  if (!status.ok())
    throw std::runtime_error("the collision report failed: " + status.message +
                             "; results.json and the CSV tables are written");
}

}  // namespace

nlohmann::json run_collision_study(const CollisionStudy& study, const CollisionRunOptions& options) {
  study.validate();
  const auto start = std::chrono::steady_clock::now();
  fs::create_directories(options.output_directory);
  write_file_atomically(options.output_directory + "/config.resolved.toml", resolved_config_toml(study));
  const auto say = [&](const char* format, auto... values) {
    if (options.quiet) return;
    std::printf(format, values...);
    std::fflush(stdout);
  };

  json document{{"study", study.name},
                {"provenance", provenance(options.config_text)},
                {"config_resolved", "config.resolved.toml"},
                {"output_directory", options.output_directory},
                {"embree_comparison", "benchmarks/collision_benchmark (first_contact vs first_contact_embree); "
                                      "Embree is not linked into the touchstone program"},
                {"organs", json::array()},
                {"table1", json::array()},
                {"tremor", json::array()},
                {"cycle_cost", json::array()},
                {"cases", json::array()}};
  {
    // What reading the clock around a cycle costs: the median of empty timed regions.
    std::vector<double> empty(10000);
    for (double& ns : empty) {
      const auto a = std::chrono::steady_clock::now();
      const auto b = std::chrono::steady_clock::now();
      ns = elapsed_ns(a, b);
    }
    document["timer_overhead_ns"] = distribution(empty)["median"];
  }
  // The settings the report quotes (the full study is config.resolved.toml). The detailed tree
  // of the per-cycle cost tables is the second tree when there are several (the first is the
  // paper's binary tree), with the first bounding volume.
  document["settings"] = {
      {"trajectories", study.trajectories},
      {"approach_tremor_rms_per_axis_m", study.approach.tremor.rms_per_axis_m},
      {"tremor", {{"trajectories", study.tremor.trajectories},
                  {"start_distance_min_m", study.tremor.start_distance_min_m},
                  {"evaluate_at_m", study.tremor.evaluate_at_m}}},
      {"prediction", {{"window_samples", study.prediction.window_samples},
                      {"sample_period_cycles", study.prediction.sample_period_cycles},
                      {"straight_line_range_m", study.prediction.straight_line_range_m}}},
      {"detailed_tree", study.trees.size() > 1 ? study.trees[1].name : study.trees[0].name},
      {"detailed_bounding_volume", to_string(study.bounding_volumes.front())}};
  document["params"] = collision_params(study);
  json seeds{{"approach", study.seed}, {"tremor_study", study.tremor.seed}};
  document["provenance"]["seeds"] = seeds;

  const std::size_t total_cases = study.organs.size() * study.trees.size() * study.bounding_volumes.size();
  std::size_t done = 0;
  std::map<std::pair<meshes::OrganShape, int>, std::size_t> organ_index;
  std::vector<Organ> organs;

  // Table 1 and the per-cycle cost: per organ, one set of trajectories for every tree.
  for (const meshes::OrganParameters& parameters : study.organs) {
    organs.push_back(make_organ(parameters));
    Organ& organ = organs.back();
    organ_index[{parameters.shape, parameters.target_triangles}] = organs.size() - 1;
    const auto trajectories_start = std::chrono::steady_clock::now();
    const std::vector<hm::ApproachTrajectory> trajectories =
        make_trajectories(*organ.surface, study.approach, study.trajectories, study.seed);
    long long cycles = 0;
    for (const auto& t : trajectories) cycles += static_cast<long long>(t.tip.size());
    organ.info["trajectories"] = study.trajectories;
    organ.info["cycles"] = cycles;
    organ.info["trajectories_s"] = seconds_since(trajectories_start);
    document["organs"].push_back(organ.info);
    say("organ %s: %zu triangles (meshing %.2f s), %d trajectories, %lld cycles (%.2f s)\n",
        organ.info["id"].get<std::string>().c_str(), organ.surface->triangles().size(),
        organ.info["mesh_s"].get<double>(), study.trajectories, cycles, organ.info["trajectories_s"].get<double>());

    for (const CollisionTree& tree : study.trees)
      for (const rc::BoundingVolume volume : study.bounding_volumes) {
        const auto case_start = std::chrono::steady_clock::now();
        rc::BvhSettings settings = tree.settings;
        settings.bounding_volume = volume;
        const auto build_start = std::chrono::steady_clock::now();
        const rc::BoundingVolumeHierarchy bvh(*organ.surface, settings);
        const double build_s = seconds_since(build_start);
        const rc::BvhStats stats = bvh.stats();

        const ReferenceRun reference = run_full_detection(bvh, trajectories);
        const PredictionRun prediction = run_prediction(bvh, study.prediction, trajectories, reference);
        const double query_ns = first_contact_query_ns(bvh, reference.first_segments, study.min_timing_s);

        // Table 1 row.
        const std::string id = organ.info["id"].get<std::string>() + "-" + tree.name + "-" + to_string(volume);
        const bool binary_no_grid = settings.children_per_node == 2 && settings.entry_grid_cell == 0;
        std::vector<double> overlap(reference.first_box.size()), entered(reference.first_box.size());
        for (std::size_t i = 0; i < overlap.size(); ++i) {
          overlap[i] = reference.first_box[i] + reference.first_triangle[i];
          entered[i] = (reference.first_box[i] - 1) / 2;
        }
        const int triangles = static_cast<int>(organ.surface->triangles().size());
        const int paper = paper_table1_overlap_tests(triangles);
        json row{{"id", id},
                 {"organ", organ.info["id"]},
                 {"triangles", triangles},
                 {"tree", tree.name},
                 {"bounding_volume", to_string(volume)},
                 {"children_per_node", settings.children_per_node},
                 {"max_leaf_triangles", settings.max_leaf_triangles},
                 {"entry_grid_cell", settings.entry_grid_cell},
                 {"depth", stats.depth},
                 {"binary_depth", stats.binary_depth},
                 {"node_count", stats.node_count},
                 {"memory_bytes", stats.memory_bytes},
                 {"build_ms", 1e3 * build_s},
                 {"first_contacts", reference.first_box.size()},
                 {"trajectories_without_contact", reference.without_contact},
                 {"paper_overlap_tests", paper > 0 ? json(paper) : json(nullptr)},
                 {"box_tests", mean_max(reference.first_box)},
                 {"triangle_tests", mean_max(reference.first_triangle)},
                 {"overlap_tests", mean_max(overlap)},
                 {"nodes_entered", binary_no_grid ? mean_max(entered) : json{{"mean", nullptr}, {"max", nullptr}}},
                 {"query_time_ns", json_number(query_ns)},
                 {"prediction_free_cycle", {{"distances", 1}, {"comparisons", 1}, {"box_tests", 0}}}};
        document["table1"].push_back(row);

        // Per-cycle cost rows.
        const rc::PredictionCounters& c = prediction.counters;
        json full{{"organ", organ.info["id"]}, {"tree", tree.name}, {"bounding_volume", to_string(volume)},
                  {"mode", "full_detection"}, {"phases", phases_json(reference.cost)}};
        json predicted{{"organ", organ.info["id"]}, {"tree", tree.name}, {"bounding_volume", to_string(volume)},
                       {"mode", "prediction"}, {"phases", phases_json(prediction.cost)}};
        predicted["prediction"] = {
            {"free_cycles", prediction.free_cycles},
            {"free_cycle_distances_min", prediction.free_cycle_distances_min},
            {"free_cycle_distances_max", prediction.free_cycle_distances_max},
            {"free_cycle_surface_tests", prediction.free_cycle_surface_tests},
            {"cheap_fraction_before_contact",
             prediction.approach_cycles > 0
                 ? static_cast<double>(prediction.cheap_before_contact) / static_cast<double>(prediction.approach_cycles)
                 : 0.0},
            {"predictions", c.predictions},
            {"repredictions", c.repredictions()},
            {"repredictions_by_cause", {{"direction_change", c.repredictions_direction},
                                        {"retreat", c.repredictions_retreat},
                                        {"out_of_range", c.repredictions_range},
                                        {"ball_exit", c.repredictions_ball_exit}}},
            {"handovers", c.handovers},
            {"corridor_advances", c.corridor_advances},
            {"closest_point_queries", c.closest_point_queries},
            {"ray_casts", c.ray_casts},
            {"full_detections", c.full_detections},
            {"contact_checks", c.contact_checks},
            {"contacts", c.contacts},
            {"reference_contacts", reference.contacts},
            {"misses", prediction.misses},
            {"spurious_contacts", prediction.spurious},
            {"audit_misses", c.misses()}};
        document["cycle_cost"].push_back(full);
        document["cycle_cost"].push_back(predicted);

        // The contract's case: parameters, the QoIs above, times.
        const double total_s = seconds_since(case_start);
        json qoi = contract_qoi();
        qoi["first_contact"] = {{"box_tests", row["box_tests"]},
                                {"triangle_tests", row["triangle_tests"]},
                                {"overlap_tests", row["overlap_tests"]},
                                {"nodes_entered", row["nodes_entered"]},
                                {"query_time_ns", row["query_time_ns"]}};
        qoi["cycle_cost"] = {{"full_detection", full["phases"]}, {"prediction", predicted["phases"]}};
        qoi["prediction_events"] = predicted["prediction"];
        const bool ok = reference.without_contact == 0 && prediction.misses == 0 && prediction.spurious == 0;
        document["cases"].push_back(
            {{"id", id},
             {"model", "collision"},
             {"params", {{"organ", organ.info["id"]}, {"triangles", triangles}, {"tree", tree.name},
                         {"bounding_volume", to_string(volume)}, {"children_per_node", settings.children_per_node},
                         {"max_leaf_triangles", settings.max_leaf_triangles}, {"entry_grid_cell", settings.entry_grid_cell},
                         {"split", to_string(settings.split)}, {"trajectories", study.trajectories}}},
             {"qoi", qoi},
             {"error", contract_error()},
             {"reference", "full detection every cycle (exact queries)"},
             {"time_s", {{"build", build_s}, {"solve", total_s - build_s}, {"total", total_s}}},
             {"status", ok ? "ok" : (prediction.misses > 0 ? "prediction missed a contact"
                                     : prediction.spurious > 0 ? "prediction reported a spurious contact"
                                                               : "a trajectory without contact")}});
        ++done;
        const double elapsed = seconds_since(start);
        const json& full_approach = full["phases"]["approach"];
        const json& predicted_approach = predicted["phases"]["approach"];
        say("[%zu/%zu] %-30s first contact: box %.1f (max %.0f), triangle %.1f, query %.0f ns; approach per cycle: "
            "box tests %.2f with prediction vs %.2f; misses %lld  (elapsed %.1f s)\n",
            done, total_cases, id.c_str(), row["box_tests"]["mean"].is_null() ? 0.0 : row["box_tests"]["mean"].get<double>(),
            row["box_tests"]["max"].is_null() ? 0.0 : row["box_tests"]["max"].get<double>(),
            row["triangle_tests"]["mean"].is_null() ? 0.0 : row["triangle_tests"]["mean"].get<double>(), query_ns,
            predicted_approach["box_tests_per_cycle"].is_null() ? 0.0 : predicted_approach["box_tests_per_cycle"].get<double>(),
            full_approach["box_tests_per_cycle"].is_null() ? 0.0 : full_approach["box_tests_per_cycle"].get<double>(),
            prediction.misses, elapsed);
      }
  }

  // Tremor: the predicted-point error distribution per amplitude, window and sampling period.
  {
    const TremorStudySettings& t = study.tremor;
    const auto found = organ_index.find({t.shape, t.target_triangles});
    std::size_t index = 0;
    if (found != organ_index.end()) {
      index = found->second;
    } else {
      meshes::OrganParameters parameters = study.organs.front();
      parameters.shape = t.shape;
      parameters.target_triangles = t.target_triangles;
      organs.push_back(make_organ(parameters));
      index = organs.size() - 1;
    }
    const Organ& organ = organs[index];
    document["tremor_organ"] = organ.info["id"];
    rc::BvhSettings settings;  // the default tree: the predictor's
    const rc::BoundingVolumeHierarchy bvh(*organ.surface, settings);
    for (const double amplitude : t.amplitudes_m) {
      const auto amplitude_start = std::chrono::steady_clock::now();
      hm::ApproachSettings approach = study.approach;
      approach.start_distance_min_m = t.start_distance_min_m;
      approach.tremor.rms_per_axis_m = amplitude;
      const std::vector<hm::ApproachTrajectory> trajectories =
          make_trajectories(*organ.surface, approach, t.trajectories, t.seed);
      for (const int period : t.sample_period_cycles)
        for (const int m : t.windows) {
          if (m == 1 && period != t.sample_period_cycles.front()) continue;  // eq. 1: the same at any period
          std::vector<double> errors;
          int skipped = 0, no_hit = 0;
          for (const auto& trajectory : trajectories) {
            const double e = predicted_point_error_m(bvh, trajectory, m, period, t.evaluate_at_m);
            if (std::isnan(e)) {
              ++skipped;
              continue;
            }
            no_hit += std::isinf(e);
            errors.push_back(e);
          }
          const json error = distribution(errors);
          const double rate = approach.sample_rate_hz / period;
          const std::string id = "tremor-" + printf_string("%.3gmm", 1e3 * amplitude) + "-m" + std::to_string(m) + "-s" +
                                 std::to_string(period);
          json row{{"id", id},
                   {"organ", organ.info["id"]},
                   {"amplitude_m", amplitude},
                   {"window_samples", m},
                   {"sample_period_cycles", period},
                   {"sample_rate_hz", rate},
                   {"window_s", m / rate},
                   {"filter", m == 1 ? "eq. 1 (last tool path vector)" : "eq. 2 (mean tool path)"},
                   {"trajectories", t.trajectories},
                   {"skipped", skipped},
                   {"no_hit", no_hit},
                   {"error_m", error}};
          document["tremor"].push_back(row);
          json qoi = contract_qoi();
          qoi["predicted_point_error_m"] = error;
          qoi["no_hit"] = no_hit;
          document["cases"].push_back({{"id", id},
                                       {"model", "prediction"},
                                       {"params", {{"organ", organ.info["id"]}, {"amplitude_m", amplitude},
                                                   {"window_samples", m}, {"sample_period_cycles", period},
                                                   {"evaluate_at_m", t.evaluate_at_m}, {"trajectories", t.trajectories}}},
                                       {"qoi", qoi},
                                       {"error", contract_error()},
                                       {"reference", "contact point of the smooth hand motion"},
                                       {"time_s", {{"build", 0.0}, {"solve", 0.0}, {"total", 0.0}}},
                                       {"status", skipped == 0 ? "ok" : "window reaches before the trajectory"}});
        }
      say("tremor %.2f mm: %d trajectories (%.2f s)\n", 1e3 * amplitude, t.trajectories, seconds_since(amplitude_start));
    }
  }

  document["time_s"] = {{"total", seconds_since(start)}};

  // CSV tables.
  {
    std::vector<std::vector<std::string>> rows;
    for (const json& r : document["table1"])
      rows.push_back({r["organ"].get<std::string>(), csv_value(r["triangles"]), r["tree"].get<std::string>(),
                      r["bounding_volume"].get<std::string>(), csv_value(r["depth"]), csv_value(r["binary_depth"]),
                      csv_value(r["paper_overlap_tests"]), csv_value(r["first_contacts"]),
                      csv_value(r["nodes_entered"]["mean"]), csv_value(r["nodes_entered"]["max"]),
                      csv_value(r["box_tests"]["mean"]), csv_value(r["box_tests"]["max"]),
                      csv_value(r["triangle_tests"]["mean"]), csv_value(r["triangle_tests"]["max"]),
                      csv_value(r["query_time_ns"]), csv_value(r["build_ms"])});
    write_file_atomically(options.output_directory + "/table1.csv",
                          write_csv({"organ", "triangles", "tree", "bounding_volume", "depth", "binary_depth", "paper",
                                     "first_contacts", "nodes_entered_mean", "nodes_entered_max", "box_tests_mean",
                                     "box_tests_max", "triangle_tests_mean", "triangle_tests_max", "query_time_ns",
                                     "build_ms"},
                                    rows));
  }
  {
    std::vector<std::vector<std::string>> rows;
    for (const json& r : document["tremor"])
      rows.push_back({r["organ"].get<std::string>(), csv_value(r["amplitude_m"]), csv_value(r["window_samples"]),
                      csv_value(r["sample_period_cycles"]), csv_value(r["window_s"]), csv_value(r["trajectories"]),
                      csv_value(r["no_hit"]), csv_value(r["error_m"]["median"]), csv_value(r["error_m"]["p90"]),
                      csv_value(r["error_m"]["max"]), csv_value(r["error_m"]["mean"])});
    write_file_atomically(options.output_directory + "/tremor.csv",
                          write_csv({"organ", "amplitude_m", "window_samples", "sample_period_cycles", "window_s",
                                     "trajectories", "no_hit", "error_median_m", "error_p90_m", "error_max_m",
                                     "error_mean_hit_m"},
                                    rows));
  }
  {
    std::vector<std::vector<std::string>> rows;
    for (const json& r : document["cycle_cost"])
      for (const char* phase : {"approach", "contact", "release", "all"}) {
        const json& p = r["phases"][phase];
        rows.push_back({r["organ"].get<std::string>(), r["tree"].get<std::string>(), r["bounding_volume"].get<std::string>(),
                        r["mode"].get<std::string>(), phase, csv_value(p["cycles"]), csv_value(p["distances_per_cycle"]),
                        csv_value(p["surface_queries_per_cycle"]), csv_value(p["box_tests_per_cycle"]),
                        csv_value(p["triangle_tests_per_cycle"]), csv_value(p["max_box_tests_in_a_cycle"]),
                        csv_value(p["time_ns"]["mean"]), csv_value(p["time_ns"]["median"]),
                        csv_value(p["time_ns"]["trimmed_mean"]), csv_value(p["time_ns"]["p99"]),
                        csv_value(p["time_ns"]["max"])});
      }
    write_file_atomically(options.output_directory + "/cycle_cost.csv",
                          write_csv({"organ", "tree", "bounding_volume", "mode", "phase", "cycles", "distances_per_cycle",
                                     "surface_queries_per_cycle", "box_tests_per_cycle", "triangle_tests_per_cycle",
                                     "max_box_tests_in_a_cycle", "time_mean_ns", "time_median_ns", "time_trimmed_mean_ns",
                                     "time_p99_ns", "time_max_ns"},
                                    rows));
  }
  write_file_atomically(options.output_directory + "/results.json", document.dump(2) + "\n");
  if (options.report) write_report(options);
  say("done in %.1f s\n", seconds_since(start));
  return document;
}

}  // namespace touchstone::studies
