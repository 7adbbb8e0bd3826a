// `touchstone fem`: the converged deal.II reference of a study file (MPI: run under mpirun).
#include "commands.hpp"

#include "touchstone/fem/elasticity_problem.hpp"
#include "touchstone/studies/fem_reference/config_reader.hpp"
#include "touchstone/studies/output_files.hpp"
#include "touchstone/studies/fem_reference/reference_study.hpp"

#include <cstdio>
#include <memory>
#include <string>

namespace touchstone::app {

namespace {
struct FemOptions {
  std::string config;
  studies::RunOptions run;
  bool no_cache = false;
};

int run_fem(FemOptions o, ProgramArguments arguments) {
  fem::MpiSession mpi(*arguments.argc, *arguments.argv);
  if (o.no_cache) o.run.cache_directory.clear();
  studies::ConfigTable config = studies::ConfigTable::from_file(o.config);
  o.run.config_text = config.source_text();
  const studies::ReferenceStudy study = studies::read_reference_study(config);
  print_defaults_filled(o.config, config.defaults_filled(), o.run.quiet || fem::MpiSession::rank() != 0);
  if (o.run.output_directory.empty()) o.run.output_directory = "output/" + study.name;
  studies::run_reference_study(study, o.run);
  if (fem::MpiSession::rank() == 0) {
    std::printf("\nresults: %s/results.json\n", o.run.output_directory.c_str());
    write_short_report("fem", o.run.output_directory, o.run.quiet);
  }
  return 0;
}
}  // namespace

void add_fem_command(CLI::App& program, std::vector<Command>& commands, ProgramArguments arguments) {
  auto o = std::make_shared<FemOptions>();
  o->run.output_directory.clear();
  CLI::App* fem_cmd = program.add_subcommand(
      "fem", "Converged deal.II reference: solve on successive meshes, Richardson-extrapolate the force, "
             "write results.json, VTU/PVD (run under mpirun -np N for N processes)");
  fem_cmd->add_option("config", o->config, "Study file (TOML), e.g. studies/configs/b2_reference.toml, or studies/configs/organ_hemisphere.toml for an organ surface file ([geometry] benchmark = \"organ\", [organ] surface)")->required()->check(readable_file);
  fem_cmd->add_option("--out", o->run.output_directory, "Output folder (default: output/<study name>)")->check(output_folder);
  fem_cmd->add_option("--cache", o->run.cache_directory, "Cache of finished solves, keyed by inputs and code version")
      ->capture_default_str();
  fem_cmd->add_flag("--no-cache", o->no_cache, "Solve everything again and cache nothing");
  fem_cmd->add_flag("--quiet", o->run.quiet, "Print only errors");
  commands.push_back({fem_cmd, [o, arguments] { return run_fem(*o, arguments); }});
}

}  // namespace touchstone::app
