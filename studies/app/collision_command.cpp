// `touchstone collision`: the Table 1 replica, the tremor study and the per-cycle cost of
// collision prediction.
#include "commands.hpp"

#include "touchstone/studies/collision_study.hpp"
#include "touchstone/studies/fem_reference/config_reader.hpp"
#include "touchstone/studies/output_files.hpp"

#include <cstdio>
#include <memory>
#include <string>

namespace touchstone::app {

namespace {
struct CollisionOptions {
  std::string config, output;
  bool quiet = false, no_plots = false;
};

int run_collision(const CollisionOptions& o) {
  studies::CollisionRunOptions options;
  studies::ConfigTable config = studies::ConfigTable::from_file(o.config);
  options.config_text = config.source_text();
  options.quiet = o.quiet;
  options.plots = !o.no_plots;
  const studies::CollisionStudy study = studies::read_collision_study(config);
  print_defaults_filled(o.config, config.defaults_filled(), o.quiet);
  options.output_directory = o.output.empty() ? "output/" + study.name : o.output;
  studies::run_collision_study(study, options);
  std::printf("\nresults: %s/results.json, report: %s/report.md\n", options.output_directory.c_str(),
              options.output_directory.c_str());
  return 0;
}
}  // namespace

void add_collision_command(CLI::App& program, std::vector<Command>& commands) {
  auto o = std::make_shared<CollisionOptions>();
  CLI::App* collision_cmd = program.add_subcommand(
      "collision", "Collision detection study: Table 1 overlap tests at first contact (OBB/AABB), tremor "
                   "predicted-point error, per-cycle cost with and without prediction; writes results.json, "
                   "CSV tables and report.md");
  collision_cmd->add_option("config", o->config, "Study file (TOML), e.g. studies/configs/collision_table1.toml")
      ->required()->check(readable_file);
  collision_cmd->add_option("--out", o->output, "Output folder (default: output/<study name>)")->check(output_folder);
  collision_cmd->add_flag("--quiet", o->quiet, "Print only errors");
  collision_cmd->add_flag("--no-plots", o->no_plots, "No PNG plots (the collision report then needs no matplotlib)");
  commands.push_back({collision_cmd, [o] { return run_collision(*o); }});
}

}  // namespace touchstone::app
