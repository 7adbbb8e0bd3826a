// `touchstone atlas <study>`: the organ atlas of the enriched real-time model, K_ext by FEM per
// sample contact (MPI for the solves).
#include "commands.hpp"

#include "touchstone/fem/elasticity_problem.hpp"
#include "touchstone/studies/fem_reference/config_reader.hpp"
#include "touchstone/studies/organ_atlas.hpp"
#include "touchstone/studies/output_files.hpp"

#include <cstdio>
#include <memory>
#include <string>

namespace touchstone::app {

namespace {
struct AtlasOptions {
  std::string config, output;
  bool no_cache = false, quiet = false;
  studies::AtlasRunOptions run;
};

int run_atlas(AtlasOptions o, ProgramArguments arguments) {
  fem::MpiSession mpi(*arguments.argc, *arguments.argv);
  studies::ConfigTable config = studies::ConfigTable::from_file(o.config);
  o.run.config_text = config.source_text();
  o.run.quiet = o.quiet;
  if (o.no_cache) o.run.cache_directory.clear();
  const studies::OrganAtlasStudy study = studies::read_organ_atlas_study(config);
  print_defaults_filled(o.config, config.defaults_filled(), o.quiet || fem::MpiSession::rank() != 0);
  o.run.output_directory = o.output.empty() ? "output/" + study.name : o.output;
  studies::run_organ_atlas_study(study, o.run);
  if (fem::MpiSession::rank() == 0 && !o.quiet)
    std::printf("\natlas: %s/organ_atlas.json, results: %s/results.json\n", o.run.output_directory.c_str(),
                o.run.output_directory.c_str());
  return 0;
}
}  // namespace

void add_atlas_command(CLI::App& program, std::vector<Command>& commands, ProgramArguments arguments) {
  auto o = std::make_shared<AtlasOptions>();
  CLI::App* atlas_cmd = program.add_subcommand(
      "atlas", "Organ atlas: the exterior stiffness K_ext [N/m] of the enriched MFS model (body minus ball(c, L), "
               "trace = the punch fields on the cut) by FEM per sample contact, Richardson-extrapolated, with the "
               "half-space closed form; writes organ_atlas.json and results.json");
  atlas_cmd->add_option("config", o->config, "Study file (TOML), e.g. studies/configs/atlas_hemisphere.toml (benchmark B1 or B2) or studies/configs/atlas_stomach.toml (benchmark = \"organ\": [organ] surface or generate, attachment_*; [atlas] region_centre, region_radius, sample_spacing)")
      ->required()->check(readable_file);
  atlas_cmd->add_option("--out", o->output, "Output folder (default: output/<study name>)")->check(output_folder);
  atlas_cmd->add_option("--cache", o->run.cache_directory, "Cache of finished solves")->capture_default_str();
  atlas_cmd->add_flag("--no-cache", o->no_cache, "Solve everything again and cache nothing");
  atlas_cmd->add_flag("--quiet", o->quiet, "Print only errors");
  commands.push_back({atlas_cmd, [o, arguments] { return run_atlas(*o, arguments); }});
}

}  // namespace touchstone::app
