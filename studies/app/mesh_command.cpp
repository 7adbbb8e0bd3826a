// `touchstone mesh`: the gmsh meshes of a study file's geometry, one per refinement level.
#include "commands.hpp"

#include "touchstone/geometry/regular_file.hpp"
#include "touchstone/meshes/benchmark_geometry.hpp"
#include "touchstone/studies/fem_reference/config_reader.hpp"
#include "touchstone/studies/fem_reference/reference_study.hpp"

#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

namespace touchstone::app {

namespace {
struct MeshOptions {
  std::string config, output = "output/meshes", geo_output;
  std::optional<int> refinement;
};

int run_mesh(const MeshOptions& o) {
  studies::ConfigTable config = studies::ConfigTable::from_file(o.config);
  const studies::ReferenceStudy study = studies::read_reference_study(config);
  print_defaults_filled(o.config, config.defaults_filled(), false);
  std::vector<int> levels = study.refinements;
  if (o.refinement) levels = {*o.refinement};
  const std::filesystem::path out(o.output);
  for (const int level : levels) {
    meshes::MeshParameters parameters = study.geometry;
    parameters.refinement = level;
    const std::string path = levels.size() == 1 && out.extension() == ".msh"
                                 ? out.string()
                                 : (out / (study.name + "-L" + std::to_string(level) + ".msh")).string();
    // The folder of the mesh file, new or not ("--out m0" is a folder too).
    const std::filesystem::path folder = std::filesystem::path(path).parent_path();
    if (!folder.empty()) std::filesystem::create_directories(folder);
    const meshes::MeshSummary summary = meshes::generate_mesh(parameters, path);
    std::printf("%s: %zu vertices, %zu tetrahedra, %zu patch triangles (%.2f s)\n", path.c_str(), summary.node_count,
                summary.tetrahedron_count, summary.patch_triangle_count, summary.seconds);
  }
  if (!o.geo_output.empty()) {
    meshes::write_geometry_script(study.geometry, o.geo_output);
    std::printf("%s: geometry script\n", o.geo_output.c_str());
  }
  return 0;
}
}  // namespace

void add_mesh_command(CLI::App& program, std::vector<Command>& commands) {
  auto o = std::make_shared<MeshOptions>();
  CLI::App* mesh = program.add_subcommand("mesh", "Generate the gmsh meshes of a study's benchmark geometry (MSH 2.2)");
  mesh->add_option("config", o->config, "Study file (TOML) with [geometry] and [mesh]")->required()->check(readable_file);
  mesh->add_option("--refinement", o->refinement, "Only this refinement level (each level halves every size)")
      ->check(CLI::Range(0, 6));
  // Checked before the meshing: a .msh path's folder, or the folder itself, must be makeable.
  const CLI::Validator mesh_output(
      [](std::string& path) -> std::string {
        const std::filesystem::path out(path);
        if (out.extension() != ".msh") return output_folder(path);
        if (const std::string reason = geometry::non_regular_file_reason(path); !reason.empty())
          return "'" + path + "' cannot be written (" + reason + ")";
        if (const std::string reason = folder_cannot_be_made_reason(out); !reason.empty())
          return "'" + path + "' cannot be written (" + reason + ")";
        return "";
      },
      "FOLDER|FILE.msh");
  mesh->add_option("--out", o->output, "Output folder, or a .msh path when one level is asked for")
      ->capture_default_str()
      ->check(mesh_output);
  mesh->add_option("--geo", o->geo_output, "Also write the geometry as a gmsh script (.geo_unrolled)")->check(output_file);
  commands.push_back({mesh, [o] { return run_mesh(*o); }});
}

}  // namespace touchstone::app
