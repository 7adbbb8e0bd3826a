// `touchstone mfs`: the MFS local model on a study file's cases (one process, no MPI).
#include "commands.hpp"

#include "touchstone/studies/fem_reference/config_reader.hpp"
#include "touchstone/studies/mfs_study.hpp"
#include "touchstone/studies/output_files.hpp"

#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

namespace touchstone::app {

namespace {
struct MfsOptions {
  std::string config;
  studies::MfsRunOptions run;
};

int run_mfs(MfsOptions o) {
  studies::ConfigTable config = studies::ConfigTable::from_file(o.config);
  o.run.config_text = config.source_text();
  const studies::MfsStudy study = studies::read_mfs_study(config, std::filesystem::path(o.config).parent_path().string());
  print_defaults_filled(o.config, config.defaults_filled(), o.run.quiet);
  if (o.run.output_directory.empty()) o.run.output_directory = "output/" + study.name;
  const nlohmann::json results = studies::run_mfs_study(study, o.run);
  std::printf("\nresults: %s/results.json\n", o.run.output_directory.c_str());
  write_short_report("mfs", o.run.output_directory, o.run.quiet);
  // A run whose every case failed has no result to use: say so in the exit status.
  for (const auto& c : results.at("cases"))
    if (c.at("status") == "ok") return 0;
  const auto& first = results.at("cases").at(0);
  std::fprintf(stderr, "touchstone: error: every case of %s failed (%s: %s)\n", study.name.c_str(),
               first.at("id").get<std::string>().c_str(), first.at("status").get<std::string>().c_str());
  return 1;
}
}  // namespace

void add_mfs_command(CLI::App& program, std::vector<Command>& commands) {
  auto o = std::make_shared<MfsOptions>();
  o->run.output_directory.clear();
  CLI::App* mfs_cmd = program.add_subcommand(
      "mfs", "MFS local model (Method of Finite Spheres): one case per contact condition and node count; "
             "writes results.json, config.resolved.toml and one node-cloud VTU per case");
  mfs_cmd->add_option("config", o->config, "Study file (TOML), e.g. studies/configs/mfs_b3.toml")->required()->check(readable_file);
  mfs_cmd->add_option("--out", o->run.output_directory, "Output folder (default: output/<study name>)")->check(output_folder);
  mfs_cmd->add_flag("--quiet", o->run.quiet, "Print only errors");
  commands.push_back({mfs_cmd, [o] { return run_mfs(*o); }});
}

}  // namespace touchstone::app
