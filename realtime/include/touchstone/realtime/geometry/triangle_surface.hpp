#pragma once
/// @file
/// A closed triangle surface (an organ's boundary) with the queries node sprinkling needs:
/// closest point with its normal, signed distance and inside/outside, through an AABB tree.
/// (Collision detection, issue 5, adds OBB trees, segment queries and overlap-test counters.)

#include <Eigen/Core>

#include <string>
#include <vector>

namespace touchstone::realtime::geometry {

/// Closest point on the surface to a query point.
struct SurfaceProjection {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();   ///< [m]
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  ///< outward unit pseudo-normal: the face normal inside a face, the sum of the two face normals on an edge, the angle-weighted normal at a vertex
  double distance_m = 0;                              ///< unsigned distance
  int triangle = -1;
};

class TriangleSurface {
 public:
  /// Vertices [m] and triangles (counter-clockwise seen from outside). Validates: finite
  /// coordinates, indices in range, no degenerate (zero-area) triangle, every edge shared by
  /// exactly two triangles with opposite orientation (closed, manifold, consistently
  /// oriented), positive enclosed volume. Throws std::invalid_argument naming `source` and the
  /// offending triangle or edge.
  TriangleSurface(std::vector<Eigen::Vector3d> vertices, std::vector<Eigen::Vector3i> triangles,
                  const std::string& source = "surface");

  /// The boundary triangles of a gmsh MSH 2.2/4.1 ASCII file (all 2-D elements, or only the
  /// physical groups named in `groups` when not empty). Throws naming the file.
  static TriangleSurface from_msh(const std::string& path, const std::vector<std::string>& groups = {});

  const std::vector<Eigen::Vector3d>& vertices() const { return vertices_; }
  const std::vector<Eigen::Vector3i>& triangles() const { return triangles_; }
  const std::vector<Eigen::Vector3d>& vertex_normals() const { return vertex_normals_; }

  /// Closest point on the surface (exact, via the AABB tree).
  SurfaceProjection project(const Eigen::Vector3d& x) const;
  /// True when x is inside the closed surface: the sign of (x − closest point) against the
  /// pseudo-normal at the closest feature (Bærentzen & Aanæs 2005). Fast near the surface;
  /// points deep inside visit many leaves (all of them at a sphere's centre).
  bool contains(const Eigen::Vector3d& x) const;
  /// Negative inside, positive outside [m].
  double signed_distance(const Eigen::Vector3d& x) const;

  double area_m2() const;
  double volume_m3() const;

 private:
  struct Node {
    Eigen::Vector3d lower, upper;
    int first, count;  ///< leaf: range in order_; inner: count = 0 and children at first, first + 1
  };
  /// The public constructor with file labels: from_msh passes gmsh node and element tags so
  /// that errors name them (empty vectors: no labels).
  TriangleSurface(std::vector<Eigen::Vector3d> vertices, std::vector<Eigen::Vector3i> triangles,
                  const std::string& source, const std::vector<long long>& vertex_tags,
                  const std::vector<long long>& triangle_tags);
  void build_tree();

  std::vector<Eigen::Vector3d> vertices_;
  std::vector<Eigen::Vector3i> triangles_;
  std::vector<Eigen::Vector3d> vertex_normals_;
  std::vector<Eigen::Vector3d> face_normals_;  ///< unit, one per triangle
  std::vector<Eigen::Vector3d> edge_normals_;  ///< 3 per triangle; edge k runs from corner k to k + 1
  std::vector<Eigen::Vector3d> corners_;       ///< 3 per triangle, in tree (order_) order
  std::vector<int> order_;
  std::vector<Node> nodes_;
  double area_m2_ = 0;
  double volume_m3_ = 0;
};

}  // namespace touchstone::realtime::geometry
