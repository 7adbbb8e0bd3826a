#pragma once
/// @file
/// A sphere triangulated by subdividing an icosahedron: a closed, outward-oriented surface
/// with near-uniform triangles, for tests, benchmarks and simple scenes.

#include <Eigen/Core>

#include <vector>

namespace touchstone::geometry {

struct TriangleMeshData {
  std::vector<Eigen::Vector3d> vertices;   ///< [m]
  std::vector<Eigen::Vector3i> triangles;  ///< counter-clockwise seen from outside
};

/// Icosahedron subdivided `level` times onto the sphere of radius `radius_m` centred at the
/// origin: 20 · 4^level triangles.
TriangleMeshData icosphere(int level, double radius_m);

}  // namespace touchstone::geometry
