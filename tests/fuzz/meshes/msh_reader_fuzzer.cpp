// libFuzzer harness of the gmsh MSH reader: the bytes as a .msh file, read for its triangles
// (then validated, and built into a TriangleSurface when valid, as load_msh_surface does) and for
// its $PhysicalNames. std::invalid_argument is the reader's documented answer to a bad file;
// anything else escaping, a sanitizer report or a hang is a finding.
#include "touchstone/geometry/triangle_surface.hpp"
#include "touchstone/meshes/msh_reader.hpp"

#include "fuzz_input_file.hpp"

#include <stdexcept>
#include <utility>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace geometry = touchstone::geometry;
  namespace meshes = touchstone::meshes;
  const std::string path = touchstone::fuzz::write_input_file("input.msh", data, size);
  try {
    geometry::SurfaceData surface = meshes::read_msh_surface(path);
    if (geometry::validate_surface(surface.vertices, surface.triangles, path, surface.labels).empty())
      (void)geometry::TriangleSurface(std::move(surface.vertices), std::move(surface.triangles), path, surface.labels);
  } catch (const std::invalid_argument&) {
  }
  try {
    (void)meshes::read_msh_physical_names(path);
  } catch (const std::invalid_argument&) {
  }
  return 0;
}
