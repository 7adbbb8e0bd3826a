#pragma once
/// @file
/// The organ most MFS tests share: the B2 hemisphere (R = 50 mm) as a closed gmsh triangle
/// surface, meshed once per process, and the frictionless punch (a = 2.5 mm) at its pole.

#include "touchstone/meshes/benchmark_geometry.hpp"
#include "touchstone/meshes/msh_reader.hpp"
#include "touchstone/geometry/triangle_surface.hpp"
#include "touchstone/realtime/mfs/node_sprinkling.hpp"

#include <unistd.h>

#include <cstdio>
#include <string>

namespace touchstone::realtime::mfs::testing {

constexpr double hemisphere_radius_m = 0.05, tool_radius_m = 0.0025;

inline const geometry::TriangleSurface& hemisphere() {
  static const geometry::TriangleSurface surface = [] {
    meshes::MeshParameters g;
    g.benchmark = meshes::Benchmark::B2;
    g.edge_size_m = 0.0005;
    g.size_growth = 0.3;
    g.max_size_m = 0.004;
    // One file per process: ctest -j runs each test case in its own process, all in one folder.
    const std::string path = "test_hemisphere_" + std::to_string(::getpid()) + ".msh";
    meshes::generate_mesh(g, path);
    geometry::TriangleSurface loaded = meshes::load_msh_surface(path);
    std::remove(path.c_str());
    return loaded;
  }();
  return surface;
}

inline ToolContact pole_contact(geometry::ContactCondition condition = geometry::ContactCondition::frictionless) {
  ToolContact contact;
  contact.point = {0.0, 0.0, hemisphere_radius_m};
  contact.radius_m = tool_radius_m;
  contact.condition = condition;
  return contact;
}

}  // namespace touchstone::realtime::mfs::testing
