// `touchstone study [accept] <config>`: the MFS against the converged FEM reference, and the CI
// accuracy baseline (checked after every run that has one; rewritten by `accept`).
#include "commands.hpp"

#include "touchstone/fem/elasticity_problem.hpp"
#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/palpation_replay.hpp"
#include "touchstone/studies/report_launcher.hpp"
#include "touchstone/studies/study_runner.hpp"

#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace touchstone::app {

namespace {
struct StudyOptions {
  std::vector<std::string> args;  ///< <config> or accept <config>
  studies::StudyRunOptions run;
  bool no_cache = false, no_report = false;
};

/// Exit status 3 when a check against the CI baseline finds a regression.
int check_baseline(const studies::ComparisonStudy& study, const nlohmann::json& results, const std::string& config) {
  const auto findings =
      studies::check_against_baseline(results, nlohmann::json::parse(studies::read_file(study.baseline_path)));
  std::size_t failed = 0;
  std::printf("\nCI baseline %s:\n", study.baseline_path.c_str());
  for (const auto& f : findings) {
    std::printf("  %s %s\n", f.passed ? "ok  " : "FAIL", f.message.c_str());
    failed += f.passed ? 0 : 1;
  }
  if (failed == 0) return 0;
  std::printf("%zu regression%s against the baseline (accept a deliberate change with `touchstone study accept %s`)\n",
              failed, failed == 1 ? "" : "s", config.c_str());
  return 3;
}

void accept_baseline(const studies::ComparisonStudy& study, const nlohmann::json& results) {
  const nlohmann::json baseline = studies::make_baseline(results, study.tolerances);
  const bool existed = std::filesystem::exists(study.baseline_path);
  const nlohmann::json old =
      existed ? nlohmann::json::parse(studies::read_file(study.baseline_path)) : nlohmann::json::object();
  studies::write_file_atomically(study.baseline_path, baseline.dump(2) + "\n");
  std::printf("\nbaseline %s %s:\n%s", study.baseline_path.c_str(), existed ? "rewritten" : "created",
              studies::describe_baseline_change(old, baseline).c_str());
}

/// A [replay] study file: the palpation replayed through the real-time model and the reference.
int run_replay(const StudyOptions& o, const std::string& config) {
  studies::ConfigTable table = studies::ConfigTable::from_file(config);
  studies::PalpationReplayStudy study = studies::read_palpation_replay_study(table);
  study.config_path = config;
  studies::ReplayRunOptions run;
  run.output_directory = o.run.output_directory.empty() ? "output/" + study.name : o.run.output_directory;
  run.cache_directory = o.no_cache ? "" : o.run.cache_directory;
  run.config_text = table.source_text();
  run.only = o.run.only;
  run.quiet = o.run.quiet;
  const nlohmann::json results = studies::run_palpation_replay(study, run);
  if (fem::MpiSession::rank() != 0) return 0;
  const auto& summary = results.at("summary");
  std::printf("\npalpation replay: %zu contacts, %lld ticks verified: force error %.2f %% (relative L2 over the ticks), "
              "%.2f %% RMS over the contacts, max %.3g N; reference uncertainty up to %.2f %%\n",
              summary.at("verified_contacts").get<std::size_t>(), summary.at("verified_frames").get<long long>(),
              100 * summary.at("force_error_l2").get<double>(), 100 * summary.at("force_error_rms_over_contacts").get<double>(),
              summary.at("force_error_max_N").get<double>(), 100 * summary.at("reference_uncertainty_max").get<double>());
  std::printf("results: %s/results.json\n", run.output_directory.c_str());
  if (o.no_report) return 0;
  studies::ReportLaunchOptions launch;
  launch.python = o.run.python;
  const studies::ReportStatus report = studies::run_report("replay", run.output_directory, launch);
  if (!report.ok()) {
    std::fprintf(stderr, "report: %s\n", report.message.c_str());
    return 2;
  }
  return 0;
}

int run_study(StudyOptions o, ProgramArguments arguments) {
  const bool accept = o.args.size() == 2 && o.args[0] == "accept";
  if (o.args.size() == 2 && !accept) throw std::invalid_argument("study takes <config> or accept <config>");
  const std::string& config = o.args.back();
  fem::MpiSession mpi(*arguments.argc, *arguments.argv);
  if (studies::is_palpation_replay_config(config)) {
    if (accept) throw std::invalid_argument(config + ": a palpation replay has no CI baseline: `study accept` does not apply");
    return run_replay(o, config);
  }
  if (o.no_cache) o.run.cache_directory.clear();
  o.run.write_report = !o.no_report;
  if ((o.run.jobs > 1 || fem::MpiSession::size() > 1) && !o.run.quiet && fem::MpiSession::rank() == 0)
    std::printf("note: %d MPI rank(s) x --jobs %d: MFS run times are measured while other cases run\n",
                static_cast<int>(fem::MpiSession::size()), o.run.jobs);
  const studies::ComparisonStudy study = studies::read_comparison_study(config);
  // Refused before the study runs, not after an hour of it.
  if (accept && study.baseline_path.empty())
    throw std::invalid_argument(config + ": [ci] baseline is not set: `study accept` has no baseline to rewrite");
  if (o.run.output_directory.empty()) o.run.output_directory = "output/" + study.name;
  const nlohmann::json results = studies::run_comparison_study(study, o.run);
  if (fem::MpiSession::rank() != 0) return 0;  // under mpirun, rank 0 reports
  std::printf("\nresults: %s/results.json\n", o.run.output_directory.c_str());
  if (o.run.write_report) std::printf("report:  %s/report.md\n", o.run.output_directory.c_str());
  if (accept) {
    accept_baseline(study, results);
    return 0;
  }
  if (!study.baseline_path.empty() && std::filesystem::exists(study.baseline_path))
    return check_baseline(study, results, config);
  return 0;
}
}  // namespace

void add_study_command(CLI::App& program, std::vector<Command>& commands, ProgramArguments arguments) {
  auto o = std::make_shared<StudyOptions>();
  CLI::App* study_cmd = program.add_subcommand(
      "study", "Compare the MFS with the converged FEM reference: force error vs N, displacement error, run time, "
               "Table 2 replica, speed and accuracy targets; writes results.json, CSV tables and report.md. "
               "`touchstone study accept <config>` also rewrites the study's CI baseline and prints what changed");
  study_cmd->add_option("config", o->args,
                        "Study file (TOML), e.g. studies/configs/hemisphere.toml; a file with a [replay] table "
                        "(studies/configs/palpation_replay.toml) replays a palpation through both models; or: accept <config>")
      ->required()->expected(1, 2);
  study_cmd->add_option("--out", o->run.output_directory, "Output folder (default: output/<study name>)")->check(output_folder);
  study_cmd->add_option("--only", o->run.only,
                        "Run only MFS cases whose id contains this text (repeatable); a problem variant's ids start "
                        "with '<variant>/', so --only nu0p49/ runs one variant (and only its FEM reference)");
  study_cmd->add_option("--jobs", o->run.jobs, "MFS cases run this many at a time (1: alone, so their run times are clean)")
      ->check(CLI::Range(1, 64))->capture_default_str();
  study_cmd->add_option("--cache", o->run.cache_directory, "Cache of FEM solves")->capture_default_str();
  study_cmd->add_flag("--no-cache", o->no_cache, "Solve every FEM level again and cache nothing");
  study_cmd->add_flag("--no-report", o->no_report, "Write results.json and CSV only (no matplotlib needed)");
  study_cmd->add_option("--python", o->run.python, "Python with matplotlib for the report")->capture_default_str();
  study_cmd->add_flag("--quiet", o->run.quiet, "Print only errors and the result");
  commands.push_back({study_cmd, [o, arguments] { return run_study(*o, arguments); }});
}

}  // namespace touchstone::app
