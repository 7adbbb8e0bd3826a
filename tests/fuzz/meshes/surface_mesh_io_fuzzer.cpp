// libFuzzer harness of the surface readers behind read_surface_mesh: the bytes as a file of the
// extension TOUCHSTONE_FUZZ_SURFACE_EXTENSION (one harness per format: .obj is the project's own
// reader, .stl/.vtk/.vtp go through VTK's readers as the project drives them), then the surface
// validation that `touchstone surface check` and load_surface run, and the TriangleSurface when
// valid. std::invalid_argument is the documented answer to a bad file; anything else escaping,
// a sanitizer report or a hang is a finding.
#include "touchstone/geometry/triangle_surface.hpp"
#include "touchstone/meshes/surface_mesh_io.hpp"

#include "fuzz_input_file.hpp"

#include <stdexcept>
#include <utility>

#ifndef TOUCHSTONE_FUZZ_SURFACE_EXTENSION
#error "TOUCHSTONE_FUZZ_SURFACE_EXTENSION (\".obj\", \".stl\", \".vtk\" or \".vtp\") must be defined"
#endif

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace meshes = touchstone::meshes;
  const std::string path =
      touchstone::fuzz::write_input_file(std::string("input") + TOUCHSTONE_FUZZ_SURFACE_EXTENSION, data, size);
  try {
    meshes::SurfaceMesh mesh = meshes::read_surface_mesh(path);
    (void)meshes::surface_statistics(mesh.vertices, mesh.triangles);
    if (meshes::validate_surface_mesh(mesh).empty())
      (void)touchstone::geometry::TriangleSurface(std::move(mesh.vertices), std::move(mesh.triangles), path,
                                                  mesh.labels);
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
