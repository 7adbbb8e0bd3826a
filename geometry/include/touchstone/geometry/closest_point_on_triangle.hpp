#pragma once
/// @file
/// The closest point on a triangle, with the feature (face, edge or corner) it lies on: shared
/// by TriangleSurface and the collision BVH, whose inside tests pick the pseudo-normal of that
/// feature.

#include <Eigen/Core>

namespace touchstone::geometry {

/// Closest-point features: 0 the face interior, 1 + k edge k (corner k → k + 1), 4 + k corner k.
inline constexpr int face_feature = 0;
inline constexpr int first_edge_feature = 1;
inline constexpr int first_vertex_feature = 4;

/// Closest point to p on triangle abc and the Voronoi region it lies in (Ericson, Real-Time
/// Collision Detection, §5.1.5). The region decides which pseudo-normal an inside/outside sign
/// test uses (Bærentzen & Aanæs 2005).
inline Eigen::Vector3d closest_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                           const Eigen::Vector3d& b, const Eigen::Vector3d& c, int& feature) noexcept {
  const Eigen::Vector3d ab = b - a;
  const Eigen::Vector3d ac = c - a;
  const Eigen::Vector3d ap = p - a;
  const double d1 = ab.dot(ap);
  const double d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) {
    feature = first_vertex_feature + 0;
    return a;
  }
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp);
  const double d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) {
    feature = first_vertex_feature + 1;
    return b;
  }
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    feature = first_edge_feature + 0;
    return a + (d1 / (d1 - d3)) * ab;
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp);
  const double d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) {
    feature = first_vertex_feature + 2;
    return c;
  }
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    feature = first_edge_feature + 2;
    return a + (d2 / (d2 - d6)) * ac;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    feature = first_edge_feature + 1;
    return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
  }
  const double denominator = 1 / (va + vb + vc);
  feature = face_feature;
  return a + ab * (vb * denominator) + ac * (vc * denominator);
}

/// The closest point alone.
inline Eigen::Vector3d closest_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                           const Eigen::Vector3d& b, const Eigen::Vector3d& c) noexcept {
  int feature = face_feature;
  return closest_on_triangle(p, a, b, c, feature);
}

}  // namespace touchstone::geometry
