#pragma once
// Closed triangle surfaces the geometry and collision tests share (the icosphere is the
// library's own: geometry/icosphere.hpp).

#include "touchstone/geometry/icosphere.hpp"  // TriangleMeshData

#include <cmath>

namespace touchstone::testing {

/// Torus of radii (major, minor) [m] about the z axis, `around` × `tube` quads cut into two
/// outward triangles each: non-convex, genus 1, with saddle regions for concave features.
inline geometry::TriangleMeshData torus(int around, int tube, double major, double minor) {
  constexpr double pi = 3.14159265358979323846;
  geometry::TriangleMeshData mesh;
  for (int i = 0; i < around; ++i) {
    const double u = 2 * pi * i / around;
    for (int j = 0; j < tube; ++j) {
      const double v = 2 * pi * j / tube;
      const double r = major + minor * std::cos(v);
      mesh.vertices.push_back({r * std::cos(u), r * std::sin(u), minor * std::sin(v)});
    }
  }
  const auto index = [&](int i, int j) { return (i % around) * tube + (j % tube); };
  for (int i = 0; i < around; ++i) {
    for (int j = 0; j < tube; ++j) {
      mesh.triangles.push_back({index(i, j), index(i + 1, j), index(i + 1, j + 1)});
      mesh.triangles.push_back({index(i, j), index(i + 1, j + 1), index(i, j + 1)});
    }
  }
  return mesh;
}

}  // namespace touchstone::testing
