// `touchstone surface organ|check`: organ surface meshes for collision detection and the MFS.
#include "commands.hpp"

#include "touchstone/meshes/organ_geometry.hpp"
#include "touchstone/meshes/surface_mesh_io.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

namespace touchstone::app {

namespace {
struct OrganOptions {
  meshes::OrganParameters organ;
  std::string shape = "stomach", output;
};
struct CheckOptions {
  std::string path;
  meshes::SurfaceReadOptions read;
};

void print_sizes(const meshes::SurfaceStatistics& s) {
  // Coordinates near the double range overflow the sums; the defect list names those vertices.
  if (!std::isfinite(s.area_m2) || !std::isfinite(s.volume_m3) || !std::isfinite(s.max_edge_m)) {
    std::printf("  area, volume and edges overflow: coordinates out of range (box (%.4g, %.4g, %.4g) to (%.4g, %.4g, %.4g) m)\n",
                s.lower.x(), s.lower.y(), s.lower.z(), s.upper.x(), s.upper.y(), s.upper.z());
    return;
  }
  std::printf("  area %.6g m^2, volume %.6g m^3, edges %.4g to %.4g m, box (%.4g, %.4g, %.4g) to (%.4g, %.4g, %.4g) m\n",
              s.area_m2, s.volume_m3, s.min_edge_m, s.max_edge_m, s.lower.x(), s.lower.y(), s.lower.z(), s.upper.x(),
              s.upper.y(), s.upper.z());
}

int run_organ(OrganOptions o) {
  o.organ.shape = meshes::organ_shape_from_string(o.shape);
  const std::filesystem::path out(o.output);
  if (out.has_parent_path()) std::filesystem::create_directories(out.parent_path());
  const meshes::OrganMesh mesh = meshes::write_organ_mesh(o.organ, o.output);
  std::printf("%s: %s, %zu triangles, %zu vertices (target %d, size %.4g m, %d meshing pass%s, %.2f s)\n",
              o.output.c_str(), o.shape.c_str(), mesh.triangles.size(), mesh.vertices.size(), o.organ.target_triangles,
              mesh.mesh_size_m, mesh.passes, mesh.passes == 1 ? "" : "es", mesh.seconds);
  print_sizes(meshes::surface_statistics(mesh.vertices, mesh.triangles));
  std::printf("  CAD geometry: area %.6g m^2, volume %.6g m^3\n", mesh.geometry_area_m2, mesh.geometry_volume_m3);
  return 0;
}

/// Exit status 2 when the surface has defects (each kind printed), 0 when it is valid.
int run_check(const CheckOptions& o) {
  const meshes::SurfaceMesh mesh = meshes::read_surface_mesh(o.path, o.read);
  std::printf("%s: %s, %zu triangles (%zu polygons split), %zu vertices (%zu welded, %zu unused)\n", o.path.c_str(),
              meshes::to_string(mesh.format).c_str(), mesh.triangles.size(), mesh.polygons_triangulated,
              mesh.vertices.size(), mesh.vertices_welded, mesh.unused_vertices);
  print_sizes(meshes::surface_statistics(mesh.vertices, mesh.triangles));
  const std::vector<geometry::SurfaceDefect> defects = meshes::validate_surface_mesh(mesh);
  if (defects.empty()) {
    std::printf("  valid: closed, manifold, consistently oriented outward\n");
    return 0;
  }
  std::printf("  %zu kind%s of defect:\n", defects.size(), defects.size() == 1 ? "" : "s");
  for (const auto& defect : defects)
    std::printf("  - %s (%zu): %s\n", geometry::to_string(defect.kind), defect.count, defect.message.c_str());
  return 2;
}
}  // namespace

void add_surface_commands(CLI::App& program, std::vector<Command>& commands) {
  CLI::App* surface = program.add_subcommand("surface", "Organ surface meshes: generate one, or check a file");
  surface->require_subcommand(1);

  auto organ = std::make_shared<OrganOptions>();
  CLI::App* organ_cmd = surface->add_subcommand(
      "organ", "Generate a closed organ surface at a triangle count (within 5 %) and write it (.msh: MSH 2.2; "
               ".vtp, .vtk, .stl, .obj)");
  organ_cmd->add_option("--triangles", organ->organ.target_triangles, "Requested number of triangles")
      ->required()->check(CLI::Range(100, 1000000));
  organ_cmd->add_option("--out", organ->output, "Output file; the extension chooses the format")->required();
  organ_cmd->add_option("--shape", organ->shape, "stomach (J-shaped, 0.2 m) or hemisphere (B2, R = 0.05 m)")
      ->check(CLI::IsMember({"stomach", "hemisphere"}))->capture_default_str();
  commands.push_back({organ_cmd, [organ] { return run_organ(*organ); }});

  auto check = std::make_shared<CheckOptions>();
  CLI::App* check_cmd = surface->add_subcommand(
      "check", "Read a surface mesh (.msh, .obj, .stl, .vtk, .vtp), print its sizes and every defect; "
               "exit code 2 when it has defects");
  check_cmd->add_option("file", check->path, "Surface mesh file")->required();
  check_cmd->add_option("--unit-scale", check->read.unit_scale, "Metres per file unit (0.001 for millimetres)")
      ->capture_default_str();
  check_cmd->add_flag("--weld", check->read.weld_vertices, "Merge coincident vertices (STL files always are)");
  commands.push_back({check_cmd, [check] { return run_check(*check); }});
}

}  // namespace touchstone::app
