// touchstone — one program, one subcommand per job (DESIGN.md §2).
#include "touchstone/fem/elasticity_problem.hpp"
#include "touchstone/meshes/benchmark_geometry.hpp"
#include "touchstone/studies/config_reader.hpp"
#include "touchstone/studies/mfs_study.hpp"
#include "touchstone/studies/provenance.hpp"
#include "touchstone/studies/reference_study.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>

namespace {

using namespace touchstone;

/// `touchstone mesh`: the meshes of a study file's geometry, one per refinement level.
int run_mesh(const std::string& config_path, std::optional<int> refinement, const std::string& output,
             const std::string& geo_output) {
  studies::ConfigTable config = studies::ConfigTable::from_file(config_path);
  const studies::ReferenceStudy study = studies::read_reference_study(config);
  std::vector<int> levels = study.refinements;
  if (refinement) levels = {*refinement};
  const std::filesystem::path out(output);
  for (const int level : levels) {
    meshes::MeshParameters parameters = study.geometry;
    parameters.refinement = level;
    const std::string path =
        levels.size() == 1 && out.extension() == ".msh"
            ? out.string()
            : (out / (study.name + "-L" + std::to_string(level) + ".msh")).string();
    if (out.has_parent_path()) std::filesystem::create_directories(std::filesystem::path(path).parent_path());
    const meshes::MeshSummary summary = meshes::generate_mesh(parameters, path);
    std::printf("%s: %zu vertices, %zu tetrahedra, %zu patch triangles (%.2f s)\n", path.c_str(),
                summary.node_count, summary.tetrahedron_count, summary.patch_triangle_count, summary.seconds);
  }
  if (!geo_output.empty()) {
    meshes::write_geometry_script(study.geometry, geo_output);
    std::printf("%s: geometry script\n", geo_output.c_str());
  }
  return 0;
}

int run_fem(int& argc, char**& argv, const std::string& config_path, const studies::RunOptions& options_in) {
  fem::MpiSession mpi(argc, argv);
  studies::RunOptions options = options_in;
  options.config_text = studies::read_file(config_path);
  studies::ConfigTable config = studies::ConfigTable::from_file(config_path);
  const studies::ReferenceStudy study = studies::read_reference_study(config);
  if (options.output_directory.empty()) options.output_directory = "output/" + study.name;
  studies::run_reference_study(study, options);
  if (fem::MpiSession::rank() == 0) std::printf("\nresults: %s/results.json\n", options.output_directory.c_str());
  return 0;
}

/// `touchstone mfs`: the MFS local model on a study file's cases (no MPI: one process).
int run_mfs(const std::string& config_path, const studies::MfsRunOptions& options_in) {
  studies::MfsRunOptions options = options_in;
  options.config_text = studies::read_file(config_path);
  studies::ConfigTable config = studies::ConfigTable::from_file(config_path);
  const studies::MfsStudy study =
      studies::read_mfs_study(config, std::filesystem::path(config_path).parent_path().string());
  if (options.output_directory.empty()) options.output_directory = "output/" + study.name;
  studies::run_mfs_study(study, options);
  std::printf("\nresults: %s/results.json\n", options.output_directory.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Touchstone: a real-time meshless tissue model checked against a converged FEM reference"};
  app.require_subcommand(1);

  std::string mesh_config, mesh_output = "output/meshes", geo_output;
  std::optional<int> mesh_refinement;
  CLI::App* mesh = app.add_subcommand("mesh", "Generate the gmsh meshes of a study's benchmark geometry (MSH 2.2)");
  mesh->add_option("config", mesh_config, "Study file (TOML) with [geometry] and [mesh]")->required()->check(CLI::ExistingFile);
  mesh->add_option("--refinement", mesh_refinement, "Only this refinement level (each level halves every size)")
      ->check(CLI::Range(0, 6));
  mesh->add_option("--out", mesh_output, "Output folder, or a .msh path when one level is asked for")->capture_default_str();
  mesh->add_option("--geo", geo_output, "Also write the geometry as a gmsh script (.geo_unrolled)");

  std::string fem_config;
  studies::RunOptions fem_options;
  fem_options.output_directory.clear();
  bool no_cache = false;
  CLI::App* fem_cmd = app.add_subcommand(
      "fem", "Converged deal.II reference: solve on successive meshes, Richardson-extrapolate the force, "
             "write results.json, VTU/PVD (run under mpirun -np N for N processes)");
  fem_cmd->add_option("config", fem_config, "Study file (TOML), e.g. studies/b2_reference.toml")->required()->check(CLI::ExistingFile);
  fem_cmd->add_option("--out", fem_options.output_directory, "Output folder (default: output/<study name>)");
  fem_cmd->add_option("--cache", fem_options.cache_directory, "Cache of finished solves, keyed by inputs and code version")
      ->capture_default_str();
  fem_cmd->add_flag("--no-cache", no_cache, "Solve everything again and cache nothing");
  fem_cmd->add_flag("--quiet", fem_options.quiet, "Print only errors");

  std::string mfs_config;
  studies::MfsRunOptions mfs_options;
  mfs_options.output_directory.clear();
  CLI::App* mfs_cmd = app.add_subcommand(
      "mfs", "MFS local model (Method of Finite Spheres): one case per contact condition and node count; "
             "writes results.json, config.resolved.toml and one node-cloud VTU per case");
  mfs_cmd->add_option("config", mfs_config, "Study file (TOML), e.g. studies/mfs_b3.toml")->required()->check(CLI::ExistingFile);
  mfs_cmd->add_option("--out", mfs_options.output_directory, "Output folder (default: output/<study name>)");
  mfs_cmd->add_flag("--quiet", mfs_options.quiet, "Print only errors");

  CLI11_PARSE(app, argc, argv);
  try {
    if (*mesh) return run_mesh(mesh_config, mesh_refinement, mesh_output, geo_output);
    if (*fem_cmd) {
      if (no_cache) fem_options.cache_directory.clear();
      return run_fem(argc, argv, fem_config, fem_options);
    }
    if (*mfs_cmd) return run_mfs(mfs_config, mfs_options);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "touchstone: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
