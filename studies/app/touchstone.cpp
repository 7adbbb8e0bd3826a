// touchstone — one program, one subcommand per job, `--help` on each.
#include "touchstone/fem/elasticity_problem.hpp"
#include "touchstone/meshes/benchmark_geometry.hpp"
#include "touchstone/meshes/organ_geometry.hpp"
#include "touchstone/meshes/surface_mesh_io.hpp"
#include "touchstone/studies/collision_study.hpp"
#include "touchstone/studies/config_reader.hpp"
#include "touchstone/studies/mfs_study.hpp"
#include "touchstone/studies/organ_atlas.hpp"
#include "touchstone/studies/provenance.hpp"
#include "touchstone/studies/reference_study.hpp"
#include "touchstone/studies/sim_scene.hpp"
#include "touchstone/studies/study_runner.hpp"

#include <CLI/CLI.hpp>

#include <atomic>
#include <csignal>
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

  // `touchstone surface organ|check`: organ surface meshes for collision detection.
  // The work runs in CLI11 callbacks; a failure leaves through CLI::RuntimeError, which makes
  // CLI11_PARSE return its exit code (1: error, 2: the checked surface has defects).
  CLI::App* surface = app.add_subcommand("surface", "Organ surface meshes: generate one, or check a file");
  surface->require_subcommand(1);
  meshes::OrganParameters organ;
  std::string organ_shape = "stomach", organ_output;
  CLI::App* organ_cmd = surface->add_subcommand(
      "organ", "Generate a closed organ surface at a triangle count (within 5 %) and write it (.msh: MSH 2.2; "
               ".vtp, .vtk, .stl, .obj)");
  organ_cmd->add_option("--triangles", organ.target_triangles, "Requested number of triangles")
      ->required()->check(CLI::Range(100, 1000000));
  organ_cmd->add_option("--out", organ_output, "Output file; the extension chooses the format")->required();
  organ_cmd->add_option("--shape", organ_shape, "stomach (J-shaped, 0.2 m) or hemisphere (B2, R = 0.05 m)")
      ->check(CLI::IsMember({"stomach", "hemisphere"}))->capture_default_str();
  std::string check_path;
  meshes::SurfaceReadOptions check_options;
  CLI::App* check_cmd = surface->add_subcommand(
      "check", "Read a surface mesh (.msh, .obj, .stl, .vtk, .vtp), print its sizes and every defect; "
               "exit code 2 when it has defects");
  check_cmd->add_option("file", check_path, "Surface mesh file")->required();
  check_cmd->add_option("--unit-scale", check_options.unit_scale, "Metres per file unit (0.001 for millimetres)")
      ->capture_default_str();
  check_cmd->add_flag("--weld", check_options.weld_vertices, "Merge coincident vertices (STL files always are)");
  const auto print_sizes = [](const meshes::SurfaceStatistics& s) {
    std::printf("  area %.6g m^2, volume %.6g m^3, edges %.4g to %.4g m, box (%.4g, %.4g, %.4g) to (%.4g, %.4g, %.4g) m\n",
                s.area_m2, s.volume_m3, s.min_edge_m, s.max_edge_m, s.lower.x(), s.lower.y(), s.lower.z(), s.upper.x(),
                s.upper.y(), s.upper.z());
  };
  organ_cmd->callback([&] {
    try {
      organ.shape = meshes::organ_shape_from_string(organ_shape);
      const std::filesystem::path out(organ_output);
      if (out.has_parent_path()) std::filesystem::create_directories(out.parent_path());
      const meshes::OrganMesh mesh = meshes::write_organ_mesh(organ, organ_output);
      std::printf("%s: %s, %zu triangles, %zu vertices (target %d, size %.4g m, %d meshing pass%s, %.2f s)\n",
                  organ_output.c_str(), organ_shape.c_str(), mesh.triangles.size(), mesh.vertices.size(),
                  organ.target_triangles, mesh.mesh_size_m, mesh.passes, mesh.passes == 1 ? "" : "es", mesh.seconds);
      print_sizes(meshes::surface_statistics(mesh.vertices, mesh.triangles));
      std::printf("  CAD geometry: area %.6g m^2, volume %.6g m^3\n", mesh.geometry_area_m2, mesh.geometry_volume_m3);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "touchstone: error: %s\n", e.what());
      throw CLI::RuntimeError(1);
    }
  });
  check_cmd->callback([&] {
    std::vector<geometry::SurfaceDefect> defects;
    try {
      const meshes::SurfaceMesh mesh = meshes::read_surface_mesh(check_path, check_options);
      std::printf("%s: %s, %zu triangles (%zu polygons split), %zu vertices (%zu welded, %zu unused)\n",
                  check_path.c_str(), meshes::to_string(mesh.format).c_str(), mesh.triangles.size(),
                  mesh.polygons_triangulated, mesh.vertices.size(), mesh.vertices_welded, mesh.unused_vertices);
      print_sizes(meshes::surface_statistics(mesh.vertices, mesh.triangles));
      defects = meshes::validate_surface_mesh(mesh);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "touchstone: error: %s\n", e.what());
      throw CLI::RuntimeError(1);
    }
    if (defects.empty()) {
      std::printf("  valid: closed, manifold, consistently oriented outward\n");
      return;
    }
    std::printf("  %zu kind%s of defect:\n", defects.size(), defects.size() == 1 ? "" : "s");
    for (const auto& defect : defects) {
      std::printf("  - %s (%zu): %s\n", geometry::to_string(defect.kind), defect.count, defect.message.c_str());
    }
    throw CLI::RuntimeError(2);
  });

  // `touchstone collision`: Table 1 replica, tremor and per-cycle cost of collision prediction;
  // runs in its callback like `surface`, errors leave through CLI::RuntimeError(1).
  std::string collision_config, collision_output;
  bool collision_quiet = false, collision_no_plots = false;
  CLI::App* collision_cmd = app.add_subcommand(
      "collision", "Collision detection study: Table 1 overlap tests at first contact (OBB/AABB), tremor "
                   "predicted-point error, per-cycle cost with and without prediction; writes results.json, "
                   "CSV tables and report.md");
  collision_cmd->add_option("config", collision_config, "Study file (TOML), e.g. studies/collision_table1.toml")
      ->required()->check(CLI::ExistingFile);
  collision_cmd->add_option("--out", collision_output, "Output folder (default: output/<study name>)");
  collision_cmd->add_flag("--quiet", collision_quiet, "Print only errors");
  collision_cmd->add_flag("--no-plots", collision_no_plots, "No PNG plots (reports/collision_plots.py, matplotlib)");
  collision_cmd->callback([&] {
    try {
      studies::CollisionRunOptions options;
      options.config_text = studies::read_file(collision_config);
      options.quiet = collision_quiet;
      options.plots = !collision_no_plots;
      studies::ConfigTable config = studies::ConfigTable::from_file(collision_config);
      const studies::CollisionStudy study = studies::read_collision_study(config);
      options.output_directory = collision_output.empty() ? "output/" + study.name : collision_output;
      studies::run_collision_study(study, options);
      std::printf("\nresults: %s/results.json, report: %s/report.md\n", options.output_directory.c_str(),
                  options.output_directory.c_str());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "touchstone: error: %s\n", e.what());
      throw CLI::RuntimeError(1);
    }
  });

  // `touchstone study [accept] <config>`: MFS against the converged FEM reference;
  // runs in its callback like `collision`. Exit codes: 1 error, 3 a CI baseline check failed.
  std::vector<std::string> study_args;
  studies::StudyRunOptions study_options;
  bool study_no_cache = false, study_no_report = false;
  CLI::App* study_cmd = app.add_subcommand(
      "study", "Compare the MFS with the converged FEM reference: force error vs N, displacement error, run time, "
               "Table 2 replica, speed and accuracy targets; writes results.json, CSV tables and report.md. "
               "`touchstone study accept <config>` also rewrites the study's CI baseline and prints what changed");
  study_cmd->add_option("config", study_args, "Study file (TOML), e.g. studies/hemisphere.toml; or: accept <config>")
      ->required()->expected(1, 2);
  study_cmd->add_option("--out", study_options.output_directory, "Output folder (default: output/<study name>)");
  study_cmd->add_option("--only", study_options.only,
                        "Run only MFS cases whose id contains this text (repeatable); a problem variant's ids start "
                        "with '<variant>/', so --only nu0p49/ runs one variant (and only its FEM reference)");
  study_cmd->add_option("--jobs", study_options.jobs,
                        "MFS cases run this many at a time (1: alone, so their run times are clean)")
      ->check(CLI::Range(1, 64))->capture_default_str();
  study_cmd->add_option("--cache", study_options.cache_directory, "Cache of FEM solves")->capture_default_str();
  study_cmd->add_flag("--no-cache", study_no_cache, "Solve every FEM level again and cache nothing");
  study_cmd->add_flag("--no-report", study_no_report, "Write results.json and CSV only (no matplotlib needed)");
  study_cmd->add_option("--python", study_options.python, "Python with matplotlib for the report")->capture_default_str();
  study_cmd->add_flag("--quiet", study_options.quiet, "Print only errors and the result");
  study_cmd->callback([&] {
    const bool accept = study_args.size() == 2 && study_args[0] == "accept";
    if (study_args.size() == 2 && !accept) {
      std::fprintf(stderr, "touchstone: error: study takes <config> or accept <config>\n");
      throw CLI::RuntimeError(1);
    }
    int status = 0;
    try {
      fem::MpiSession mpi(argc, argv);
      if (study_no_cache) study_options.cache_directory.clear();
      study_options.write_report = !study_no_report;
      if (study_options.jobs > 1 && !study_options.quiet)
        std::printf("note: --jobs %d: MFS run times are measured while other cases run\n", study_options.jobs);
      const studies::ComparisonStudy study = studies::read_comparison_study(study_args.back());
      if (study_options.output_directory.empty()) study_options.output_directory = "output/" + study.name;
      const nlohmann::json results = studies::run_comparison_study(study, study_options);
      if (fem::MpiSession::rank() != 0) return;  // under mpirun, rank 0 reports
      std::printf("\nresults: %s/results.json\nreport:  %s/report.md\n", study_options.output_directory.c_str(),
                  study_options.output_directory.c_str());
      if (accept) {
        if (study.baseline_path.empty()) throw std::runtime_error(study_args.back() + ": [ci] baseline is not set");
        const nlohmann::json baseline = studies::make_baseline(results, study.tolerances);
        const bool existed = std::filesystem::exists(study.baseline_path);
        const nlohmann::json old = existed ? nlohmann::json::parse(studies::read_file(study.baseline_path)) : nlohmann::json::object();
        studies::write_file_atomically(study.baseline_path, baseline.dump(2) + "\n");
        std::printf("\nbaseline %s %s:\n%s", study.baseline_path.c_str(), existed ? "rewritten" : "created",
                    studies::describe_baseline_change(old, baseline).c_str());
      } else if (!study.baseline_path.empty() && std::filesystem::exists(study.baseline_path)) {
        const auto findings = studies::check_against_baseline(results, nlohmann::json::parse(studies::read_file(study.baseline_path)));
        std::size_t failed = 0;
        std::printf("\nCI baseline %s:\n", study.baseline_path.c_str());
        for (const auto& f : findings) {
          std::printf("  %s %s\n", f.passed ? "ok  " : "FAIL", f.message.c_str());
          failed += f.passed ? 0 : 1;
        }
        if (failed > 0) {
          std::printf("%zu regression%s against the baseline (accept a deliberate change with `touchstone study accept %s`)\n",
                      failed, failed == 1 ? "" : "s", study_args.back().c_str());
          status = 3;
        }
      }
    } catch (const std::exception& e) {
      std::fprintf(stderr, "touchstone: error: %s\n", e.what());
      throw CLI::RuntimeError(1);
    }
    if (status != 0) throw CLI::RuntimeError(status);
  });

  // `touchstone atlas <study>`: the organ atlas of the enriched real-time model, K_ext by FEM per
  // sample contact; runs in its callback like `study` (MPI for the solves).
  std::string atlas_config, atlas_output;
  bool atlas_no_cache = false, atlas_quiet = false;
  studies::AtlasRunOptions atlas_options;
  CLI::App* atlas_cmd = app.add_subcommand(
      "atlas", "Organ atlas: the exterior stiffness K_ext [N/m] of the enriched MFS model (body minus ball(c, L), "
               "trace = the punch fields on the cut) by FEM per sample contact, Richardson-extrapolated, with the "
               "half-space closed form; writes organ_atlas.json and results.json");
  atlas_cmd->add_option("config", atlas_config, "Study file (TOML), e.g. studies/atlas_hemisphere.toml")
      ->required()->check(CLI::ExistingFile);
  atlas_cmd->add_option("--out", atlas_output, "Output folder (default: output/<study name>)");
  atlas_cmd->add_option("--cache", atlas_options.cache_directory, "Cache of finished solves")->capture_default_str();
  atlas_cmd->add_flag("--no-cache", atlas_no_cache, "Solve everything again and cache nothing");
  atlas_cmd->add_flag("--quiet", atlas_quiet, "Print only errors");
  atlas_cmd->callback([&] {
    try {
      fem::MpiSession mpi(argc, argv);
      atlas_options.config_text = studies::read_file(atlas_config);
      atlas_options.quiet = atlas_quiet;
      if (atlas_no_cache) atlas_options.cache_directory.clear();
      studies::ConfigTable config = studies::ConfigTable::from_file(atlas_config);
      const studies::OrganAtlasStudy study = studies::read_organ_atlas_study(config);
      atlas_options.output_directory = atlas_output.empty() ? "output/" + study.name : atlas_output;
      studies::run_organ_atlas_study(study, atlas_options);
      if (fem::MpiSession::rank() == 0 && !atlas_quiet)
        std::printf("\natlas: %s/organ_atlas.json, results: %s/results.json\n", atlas_options.output_directory.c_str(),
                    atlas_options.output_directory.c_str());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "touchstone: error: %s\n", e.what());
      throw CLI::RuntimeError(1);
    }
  });

  // `touchstone sim <scene>`: the real-time runtime on real threads or, with
  // --virtual, lock-step on a virtual clock (study mode). Ctrl-C ends the run cleanly (zero force).
  std::string sim_scene_path, sim_output, sim_record, sim_replay, sim_screenshot, sim_force_mode;
  double sim_duration = -1;
  bool sim_virtual = false, sim_window = false, sim_no_window = false;
  CLI::App* sim_cmd = app.add_subcommand(
      "sim", "Run a scene: haptic (1 kHz), model (~200 Hz) and graphics (30 Hz) loops with a device, until the "
             "trajectory ends, the device disconnects or Ctrl-C; prints and writes summary.json");
  sim_cmd->add_option("scene", sim_scene_path, "Scene file (TOML), e.g. studies/scenes/palpation.toml")
      ->required()->check(CLI::ExistingFile);
  sim_cmd->add_option("--duration", sim_duration, "Run length [s] (overrides the scene; 0: until the device ends)");
  sim_cmd->add_option("--out", sim_output, "Output folder (default: the scene's [output] directory)");
  sim_cmd->add_option("--record", sim_record, "Record every tick's pose and force as CSV (replay with device.kind = \"replay\")");
  sim_cmd->add_option("--replay", sim_replay, "Play a recording (from --record) instead of the scene's device")
      ->check(CLI::ExistingFile);
  sim_cmd->add_option("--force-mode", sim_force_mode, "Override the scene's force mode")
      ->check(CLI::IsMember({"stiffness", "extrapolation"}));
  sim_cmd->add_flag("--virtual", sim_virtual, "Study mode: lock-step on a virtual clock, bit-reproducible");
  sim_cmd->add_flag("--window", sim_window, "Open the interactive VTK window (needs a display)");
  sim_cmd->add_flag("--no-window", sim_no_window, "Do not open the window even if the scene asks for it");
  sim_cmd->add_option("--screenshot", sim_screenshot, "PNG of the window at the end (relative to the output folder)");
  sim_cmd->callback([&] {
    try {
      static std::atomic<bool> interrupted{false};
      std::signal(SIGINT, [](int) { interrupted.store(true); });
      std::signal(SIGTERM, [](int) { interrupted.store(true); });
      const studies::SimScene scene = studies::read_sim_scene(sim_scene_path);
      studies::SimOptions options;
      if (sim_duration >= 0) options.duration_s = sim_duration;
      if (!sim_output.empty()) options.output_directory = sim_output;
      options.record_path = sim_record;
      options.replay_path = sim_replay;
      if (!sim_force_mode.empty())
        options.force_mode = sim_force_mode == "extrapolation" ? realtime::runtime::ForceMode::extrapolation
                                                               : realtime::runtime::ForceMode::stiffness;
      options.virtual_clock = sim_virtual;
      if (sim_window) options.window = true;
      if (sim_no_window) options.window = false;
      options.screenshot_path = sim_screenshot;
      options.stop = &interrupted;
      studies::run_sim(scene, options);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "touchstone: error: %s\n", e.what());
      throw CLI::RuntimeError(1);
    }
  });

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
