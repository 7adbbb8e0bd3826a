// `touchstone study`: one study file → the FEM references (cached), the MFS series, the errors
// of every MFS case against its reference next to the reference's own error estimate, Table 2,
// the targets, results.json, the CSV tables and the report. This file runs the steps in order
// (FEM solves under MPI, MFS cases `jobs` at a time); the steps live beside it.
#include "comparison_parts.hpp"

#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/provenance.hpp"
#include "touchstone/studies/report_launcher.hpp"
#include "touchstone/version.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <optional>
#include <set>
#include <stdexcept>
#include <thread>

namespace touchstone::studies {
namespace fs = std::filesystem;
namespace mfs = realtime::mfs;
using nlohmann::json;

namespace {
using namespace comparison;

class StudyRun {
 public:
  StudyRun(const ComparisonStudy& study, const StudyRunOptions& options) : study_(study), options_(options) {
    out_ = options.output_directory.empty() ? "output/" + study.name : options.output_directory;
    for (const auto& sp : study.problems) {
      ProblemRun r;
      r.sp = &sp;
      r.d = sp.problem.direction.normalized();
      r.reference_part = sp.id_prefix + "reference";
      problems_.push_back(std::move(r));
    }
  }

  json run() {
    start_ = std::chrono::steady_clock::now();
    const bool rank0 = fem::MpiSession::rank() == 0;
    config_text_ = study_.config_text;

    // The cases of every problem; a problem with none selected skips its reference (unless it
    // is the only one: every error and the summary need it).
    total_ = (study_.table2_fem ? 1 : 0) + (study_.table2_reference ? 1 : 0);
    for (auto& r : problems_) {
      for (const auto& s : r.sp->series)
        for (const int n : s.study.node_counts)
          if (selected(mfs_case_id(r, s, n))) r.mfs_cases.push_back({&s, n});
      r.runs_reference = problems_.size() == 1 || !r.mfs_cases.empty();
      total_ += r.mfs_cases.size() + (r.runs_reference ? 1 : 0);
    }
    // --only that matches nothing is a typo, not a study with no cases.
    if (!options_.only.empty() &&
        std::all_of(problems_.begin(), problems_.end(), [](const ProblemRun& r) { return r.mfs_cases.empty(); })) {
      std::string example;
      for (const auto& r : problems_)
        if (example.empty() && !r.sp->series.empty() && !r.sp->series.front().study.node_counts.empty())
          example = mfs_case_id(r, r.sp->series.front(), r.sp->series.front().study.node_counts.front());
      throw std::invalid_argument("--only matches no MFS case of study " + study_.name + " (case ids look like '" +
                                  example + "')");
    }
    if (rank0) fs::create_directories(out_);
    if (rank0 && !config_text_.empty()) write_file_atomically(out_ + "/study.toml", config_text_);

    ProblemRun& first = problems_.front();
    json document{{"study", study_.name},
                  {"provenance", provenance(config_text_)},
                  {"problem", problem_json(first.problem())},
                  {"cases", json::array()}};
    json& cases = document["cases"];

    // The references first: every error needs them. Each FEM solve comes from the cache when the
    // same inputs were solved by the same code version (identical problems share it).
    json problems = json::array();
    for (auto& r : problems_) {
      json entry{{"name", r.sp->name},
                 {"id_prefix", r.sp->id_prefix},
                 {"problem", problem_json(r.problem())},
                 {"overridden_keys", r.sp->overridden_keys},
                 {"notes", problem_notes(r.problem())},
                 {"reference_config", r.sp->reference.name},
                 {"series", json::array()},
                 {"mfs_cases", r.mfs_cases.size()}};
      for (const auto& s : r.sp->series) entry["series"].push_back(s.name);
      if (r.runs_reference && r.problem().point_tool) {
        entry["punch_references"] = run_point_tool_references(r, cases);
        entry["reference_summary"] = r.reference.summary;
      } else if (r.runs_reference) {
        const json reference_doc = run_fem(r.reference_part, r.sp->reference);
        r.reference = pick_reference(reference_doc, r.reference_part + "/", r.d);
        add_fem_cases(reference_doc, r.reference_part + "/", r.reference, r.problem(), r, cases);
        entry["reference_summary"] = r.reference.summary;
      } else {
        entry["reference_summary"] = nullptr;
      }
      problems.push_back(entry);
    }
    document["problems"] = problems;
    document["reference_summary"] = first.reference.summary;

    std::optional<ReferenceValue> full_reference;
    if (study_.table2_reference) {
      const json doc = run_fem("table2_reference", *study_.table2_reference);
      full_reference = pick_reference(doc, "table2_reference/", first.d);
      add_fem_cases(doc, "table2_reference/", *full_reference, first.problem(), first, cases);
      document["table2_reference_summary"] = full_reference->summary;
    }
    const ReferenceValue& fe_row_reference = full_reference ? *full_reference : first.reference;
    if (study_.table2_fem) {
      const json doc = run_fem("table2_fem", *study_.table2_fem);
      add_fem_cases(doc, "table2_fem/", fe_row_reference, first.problem(), first, cases);
    }

    // Under mpirun every rank takes part in the FEM solves and runs its share of the MFS cases
    // (case i on rank i mod K, `jobs` at a time; each case writes only its own folder and
    // record); rank 0 then reads the others' records and writes the files and the report.
    const unsigned rank = fem::MpiSession::rank(), ranks = fem::MpiSession::size();
    // The organ surfaces first (gmsh, one at a time, rank 0), then the cases. Results keep the
    // study's order.
    struct Job {
      ProblemRun* run;
      const MfsSeries* series;
      int n;
      const ReferenceValue* reference;
      std::size_t case_index;  ///< in run->mfs_cases
    };
    std::vector<Job> jobs_list;
    for (auto& r : problems_)
      for (std::size_t k = 0; k < r.mfs_cases.size(); ++k) {
        const auto& [series, n] = r.mfs_cases[k];
        if (rank == 0) organ_path(series->study);
        jobs_list.push_back({&r, series, n, &r.reference_of(k), k});
      }
    fem::MpiSession::barrier();
    std::vector<json> computed(jobs_list.size());
    std::vector<std::size_t> mine;
    for (std::size_t i = rank; i < jobs_list.size(); i += ranks) mine.push_back(i);
    const int jobs = std::max(1, std::min<int>(options_.jobs, static_cast<int>(mine.size())));
    document["mfs_jobs"] = jobs;
    document["mfs_ranks"] = ranks;
    const auto compute = [&](std::size_t i) {
      const Job& job = jobs_list[i];
      computed[i] = run_mfs_case(*job.run, *job.series, job.n, *job.reference);
    };
    std::string failure;
    try {
      if (jobs == 1) {
        for (const std::size_t i : mine) compute(i);
      } else {
        std::atomic<std::size_t> next{0};
        std::vector<std::exception_ptr> errors(static_cast<std::size_t>(jobs));
        std::vector<std::thread> workers;
        for (int w = 0; w < jobs; ++w)
          workers.emplace_back([&, w] {
            try {
              for (std::size_t k; (k = next.fetch_add(1)) < mine.size();) compute(mine[k]);
            } catch (...) {
              errors[static_cast<std::size_t>(w)] = std::current_exception();
            }
          });
        for (auto& worker : workers) worker.join();
        for (const auto& error : errors)
          if (error) std::rethrow_exception(error);
      }
    } catch (const std::exception& e) {
      failure = e.what();
    }
    // Every rank learns whether any failed (entry 0) and which of its cases it resumed from an
    // earlier run's record (entry 1 + i) before rank 0 reads the others' records.
    std::vector<double> shared(1 + jobs_list.size(), 0.0);
    shared[0] = failure.empty() ? 0.0 : 1.0;
    if (failure.empty())
      for (const std::size_t i : mine) shared[1 + i] = computed[i].value("resumed", false) ? 1.0 : 0.0;
    fem::MpiSession::sum_over_ranks(shared);
    if (!failure.empty()) throw std::runtime_error(failure);
    if (shared[0] != 0) throw std::runtime_error("an MFS case failed on another rank (its message is above)");
    if (rank != 0) return document;
    for (std::size_t i = 0; i < jobs_list.size(); ++i) {
      if (i % ranks == 0) continue;
      // Rank i mod K ran or resumed it; rank 0 reads the record that rank left.
      compute(i);
      computed[i]["resumed"] = shared[1 + i] != 0;
      computed[i]["mpi_rank"] = i % ranks;
    }
    // Each case's predecessor in its series (the next smaller N), for the convergence-in-N flag.
    std::vector<json> previous(jobs_list.size());
    for (std::size_t i = 0; i < jobs_list.size(); ++i)
      for (std::size_t j = 0; j < jobs_list.size(); ++j) {
        const Job &a = jobs_list[i], &b = jobs_list[j];
        if (a.run != b.run || a.series != b.series || !(b.n < a.n)) continue;
        if (previous[i].is_null() || b.n > previous[i].at("params").at("node_count_requested").get<int>())
          previous[i] = {{"status", computed[j].at("status")},
                         {"qoi", {{"force_N", json_at_path(computed[j], {"qoi", "force_N"})}}},
                         {"params", {{"node_count_requested", b.n}}}};
      }
    for (std::size_t i = 0; i < jobs_list.size(); ++i) {
      json c = std::move(computed[i]);
      const ProblemRun& r = *jobs_list[i].run;
      const ReferenceValue& reference = *jobs_list[i].reference;
      // The full-domain error: the first problem's cases, when Table 2's reference is another domain.
      const bool full_domain = &r == &first && full_reference &&
                               r.problem().benchmark != study_.table2_reference->geometry.benchmark;
      add_mfs_errors(c, r, reference, full_domain ? &*full_reference : nullptr,
                     previous[i].is_null() ? nullptr : &previous[i]);
      if (r.problem().point_tool) {
        const std::size_t k = jobs_list[i].case_index;
        c["params"]["tip_spacing_m"] = r.tip_spacing_m.at(k);
        c["params"]["fem_punch_radius_m"] = ProblemRun::punch_radius_m(r.tip_spacing_m.at(k));
      }
      const json& flags = c.at("accuracy").at("flags");
      std::string flag_text;
      for (const auto& f : flags) flag_text += (flag_text.empty() ? " [" : ", ") + f.get<std::string>();
      if (!flag_text.empty()) flag_text += "]";
      progress(c.at("id").get<std::string>() + (c.value("resumed", false) ? " (resumed)" : ""),
               "F = " + format_number(1e3 * value_or_nan(c.at("qoi"), "axial_force_N")) + " mN, error " +
                   format_number(100 * value_or_nan(c.at("error"), "force_rel")) + " % (reference's own error " +
                   (std::isfinite(reference.uncertainty_rel) ? format_number(100 * reference.uncertainty_rel) + " %"
                                                             : std::string("not estimated")) +
                   ")  " + c.at("status").get<std::string>() + flag_text);
      cases.push_back(std::move(c));
    }

    document["table2"] = table2(cases, first, fe_row_reference, study_.table2_mfs_series, problems_);
    document["targets"] = targets(cases, document["table2"], full_reference.has_value(), problems_);
    document["depths_m"] = first.problem().depths_m;
    document["default_formulation"] = mfs::to_string(mfs::LocalModelSettings{}.formulation);
    document["series"] = series_json();
    document["accuracy_thresholds"] = {{"force_method_spread_limit", force_method_spread_limit},
                                       {"support_growth_tolerance", support_growth_tolerance},
                                       {"rcond_margin", rcond_margin},
                                       {"force_change_limit", force_change_limit},
                                       {"stiffness_ratio_min", stiffness_ratio_min},
                                       {"stiffness_ratio_max", stiffness_ratio_max}};
    document["elapsed_s"] = seconds_since(start_);

    write_file_atomically(out_ + "/results.json", document.dump(2) + "\n");
    write_csv_tables(document, problems_, out_);
    write_comparison_pvds(cases, out_);
    if (!options_.quiet) print_summary(document, problems_);
    if (options_.write_report) make_report();
    return document;
  }

 private:
  bool selected(const std::string& id) const {
    if (options_.only.empty()) return true;
    return std::any_of(options_.only.begin(), options_.only.end(),
                       [&](const std::string& part) { return id.find(part) != std::string::npos; });
  }

  void progress(const std::string& what, const std::string& detail) {
    ++done_;
    if (options_.quiet || fem::MpiSession::rank() != 0) return;
    const double elapsed = seconds_since(start_);
    std::printf("[%zu/%zu] %-34s %s  (elapsed %.0f s, ~%.0f s left)\n", done_, total_, what.c_str(), detail.c_str(),
                elapsed, elapsed / static_cast<double>(done_) * static_cast<double>(total_ - done_));
    std::fflush(stdout);
  }

  json series_json() const {
    const auto entry = [](const MfsSeries& s) {
      return json{{"name", s.name},
                  {"formulation", mfs::to_string(s.study.model.formulation)},
                  {"paper_mode", s.study.model.paper_mode},
                  {"basis", s.study.model.collocation.mls.basis == mfs::Basis::quadratic ? "quadratic" : "linear"},
                  {"haptic_method", mfs::to_string(s.study.model.force.haptic_method)},
                  {"node_counts", s.study.node_counts},
                  {"engine_default", s.engine_default}};
    };
    json list = json::array();
    for (const auto& s : study_.first().series) list.push_back(entry(s));
    // Series that run on other problems only (a variant's `series` subset) are listed too.
    for (const auto& sp : study_.problems)
      for (const auto& s : sp.series)
        if (std::none_of(list.begin(), list.end(), [&](const json& e) { return e.at("name") == s.name; }))
          list.push_back(entry(s));
    return list;
  }

  json run_fem(const std::string& part, const ReferenceStudy& fem_study) {
    RunOptions o;
    o.output_directory = out_ + "/fem/" + part;
    o.cache_directory = options_.cache_directory;
    o.config_text = config_text_;
    o.quiet = options_.quiet;
    if (!options_.quiet && fem::MpiSession::rank() == 0) {
      std::printf("FEM %s: %s, %zu mesh famil%s x %zu levels\n", part.c_str(), fem_study.name.c_str(),
                  std::max<std::size_t>(1, fem_study.edge_sizes_m.size()), fem_study.edge_sizes_m.size() > 1 ? "ies" : "y",
                  fem_study.refinements.size());
      std::fflush(stdout);
    }
    const json doc = run_reference_study(fem_study, o);
    progress("FEM " + part, "done");
    return doc;
  }

  /// B4: a point displacement has no finite force in the continuum, so B4 pairs the paper's
  /// tool-tip node with a flat punch of radius equal to the tip's node spacing s (the radius of
  /// eq. 9's tributary disc π s²). s changes with N and the layout, so each distinct
  /// s gets its own converged reference (the problem's FEM file, every mesh size scaled by s/a,
  /// so that each punch is resolved alike), and both models' forces move with the resolution.
  /// Returns one entry per punch for results.json.
  json run_point_tool_references(ProblemRun& r, json& cases) {
    std::vector<double> spacing;
    if (fem::MpiSession::rank() == 0)
      for (const auto& [series, n] : r.mfs_cases) {
        MfsStudy s = series->study;
        s.surface_path = organ_path(series->study);
        spacing.push_back(paper_tip_spacing_m(s, n));
      }
    // Only rank 0 meshes the organ; every rank takes part in the FEM solves below.
    fem::MpiSession::broadcast_from_root(spacing);
    r.tip_spacing_m = spacing;
    // The progress count had one reference for the problem: it has one per distinct spacing.
    std::set<long long> distinct;
    for (const double s : spacing) distinct.insert(ProblemRun::micrometres(s));
    if (!distinct.empty()) total_ += distinct.size() - 1;
    json entries = json::array();
    const ComparisonProblem& problem = r.problem();
    for (const long long key : distinct) {
      const double radius_m = 1e-6 * static_cast<double>(key);
      const double scale = radius_m / problem.tool_radius_m;
      ComparisonProblem punch = problem;
      punch.tool_radius_m = radius_m;
      ReferenceStudy fem_study = r.sp->reference;
      fem_study.name += "_a" + std::to_string(key) + "um";
      fem_study.geometry.tool_radius_m = radius_m;
      fem_study.geometry.edge_size_m *= scale;
      for (double& edge : fem_study.edge_sizes_m) edge *= scale;
      try {
        fem_study.validate();
      } catch (const std::invalid_argument& e) {
        throw std::invalid_argument("problem " + r.sp->name + " (B4): the FEM punch of radius " + format_number(1e3 * radius_m) +
                                    " mm (a tip spacing): " + e.what());
      }
      const std::string part = r.reference_part + "_a" + std::to_string(key) + "um";
      const json doc = run_fem(part, fem_study);
      ReferenceValue value = pick_reference(doc, part + "/", r.d);
      add_fem_cases(doc, part + "/", value, punch, r, cases);
      entries.push_back({{"punch_radius_m", radius_m}, {"summary", value.summary}});
      r.punch_references.emplace(key, std::move(value));
    }
    if (!spacing.empty()) r.reference = r.reference_of(0);
    return entries;
  }

  /// The organ surface of a series, generated once per distinct organ (as `touchstone mfs`
  /// does: B3 cuts the local ball from the whole hemisphere; B1, B2 and B5 are their own organ).
  std::string organ_path(const MfsStudy& s) {
    if (!s.surface_path.empty()) return s.surface_path;
    meshes::MeshParameters g = s.geometry;
    if (g.benchmark == meshes::Benchmark::B3) g.benchmark = meshes::Benchmark::B2;
    g.refinement = 0;
    const std::string key = sha256_hex(meshes::to_string(g.benchmark) + format_number(g.body_radius_m) + "|" +
                                       format_number(g.tool_radius_m) + "|" + format_number(g.edge_size_m) + "|" +
                                       format_number(g.size_growth) + "|" + format_number(g.max_size_m) + "|" +
                                       format_number(g.size_exponent) + "|" + format_number(g.contact_polar_angle_rad))
                                .substr(0, 16);
    const std::string path = fs::absolute(fs::path(out_) / "organ" / (key + ".msh")).lexically_normal().string();
    if (!fs::exists(path)) {
      fs::create_directories(fs::path(path).parent_path());
      const std::string temporary = path + ".partial.msh";
      meshes::generate_mesh(g, temporary);
      fs::rename(temporary, path);
    }
    return path;
  }

  /// The problem a case belongs to: its name and values in params (results.json groups by it).
  static void label_problem(json& c, const ProblemRun& r) {
    c["problem"] = r.sp->name;
    c["params"]["problem"] = r.sp->name;
    c["params"]["problem_values"] = problem_json(r.problem());
  }

  /// One MFS case: reused from <out>/mfs/<id>/case.json when its hash matches, else run by
  /// the MFS study (one node count).
  json run_mfs_case(const ProblemRun& r, const MfsSeries& series, int n, const ReferenceValue& reference) {
    const std::string id = mfs_case_id(r, series, n);
    MfsStudy s = series.study;
    s.name = id;
    s.node_counts = {n};
    s.model.sprinkling.node_count = n;
    const std::string hash = sha256_hex(resolved_config_toml(s) + touchstone::version::git_hash +
                                        touchstone::version::build_type);
    s.surface_path = organ_path(series.study);
    const std::string directory = out_ + "/mfs/" + id;
    const std::string record_path = directory + "/case.json";
    if (fs::exists(record_path)) {
      try {
        json record = json::parse(read_file(record_path));
        if (record.value("case_sha256", "") == hash) {
          json c = record.at("case");
          c["resumed"] = true;
          label_problem(c, r);
          return c;
        }
      } catch (const std::exception&) {
        // An unreadable record is recomputed.
      }
    }
    MfsRunOptions o;
    o.output_directory = directory;
    o.config_text = series.config_text;
    o.quiet = true;
    // The MFS field on the reference's finest mesh, for ParaView (and a field error).
    if (!reference.field_vtu.empty()) o.reference_field_path = out_ + "/fem/" + reference.part + "/" + reference.field_vtu;
    const json doc = run_mfs_study(s, o);
    json c = doc.at("cases").at(0);
    c["id"] = id;
    c["series"] = series.name;
    c["part"] = "mfs";
    label_problem(c, r);
    if (c.value("vtu", json(nullptr)).is_string()) c["vtu"] = "mfs/" + id + "/" + c.at("vtu").get<std::string>();
    if (c.value("comparison_vtu", json(nullptr)).is_string())
      c["comparison_vtu"] = "mfs/" + id + "/" + c.at("comparison_vtu").get<std::string>();
    const json& t = c["time_s"];
    // Table 2's split: model = sprinkle + shape functions + assembly (the paper's "time to
    // generate the stiffness matrix"); solution = factorisation + condensation to K_t + solve.
    c["time_s"]["model"] = value_or_nan(t, "sprinkle") + value_or_nan(t, "assembly");
    c["time_s"]["solution"] = value_or_nan(t, "factorize") + value_or_nan(t, "condense") + value_or_nan(t, "solve");
    write_file_atomically(record_path, json{{"case_sha256", hash}, {"case", c}}.dump(2) + "\n");
    c["resumed"] = false;
    return c;
  }

  /// report.md and its plots from the reports package (the C++ side writes data only).
  void make_report() const {
    ReportLaunchOptions launch;
    launch.python = options_.python;
    std::fflush(stdout);
    const ReportStatus status = run_report("study", out_, launch);
    if (!status.ok()) throw std::runtime_error(status.message + "; results.json and the CSV tables are written");
  }

  const ComparisonStudy& study_;
  const StudyRunOptions& options_;
  std::string out_, config_text_;
  std::vector<ProblemRun> problems_;
  std::chrono::steady_clock::time_point start_;
  std::size_t done_ = 0, total_ = 0;
};

}  // namespace

nlohmann::json run_comparison_study(const ComparisonStudy& study, const StudyRunOptions& options) {
  study.validate();
  return StudyRun(study, options).run();
}

}  // namespace touchstone::studies
