#pragma once
/// @file
/// A closed triangle surface (an organ's boundary) with the queries node sprinkling needs:
/// closest point with its normal, signed distance and inside/outside, through an AABB tree;
/// and the validation that every surface passes on load, also available as a non-throwing
/// list of every defect (validate_surface) for `touchstone surface check`.
/// (collision/bounding_volume_hierarchy.hpp adds OBB trees, segment queries and overlap-test
/// counters.)

#include <Eigen/Core>

#include <cstddef>
#include <string>
#include <vector>

namespace touchstone::geometry {

/// How a file numbers its vertices and triangles, so that messages point into the file:
/// "triangle 12 (STL facet 12)", "edge (3, 5) (gmsh nodes 40, 50)". Tags are optional: empty
/// vectors name vertices and triangles by their index only.
struct SurfaceLabels {
  std::string vertex_kind = "node";          ///< singular noun, e.g. "gmsh node", "OBJ vertex"
  std::vector<long long> vertex_tags;        ///< one per vertex, or empty
  std::string triangle_kind = "element";     ///< singular noun, e.g. "gmsh element", "VTK cell"
  std::vector<long long> triangle_tags;      ///< one per triangle, or empty
};

/// The largest coordinate a surface's vertex may have [m]: far beyond any organ, and far enough
/// below the overflow of the checks' squared lengths and triple products.
constexpr double max_surface_coordinate_m = 1e9;

/// What can be wrong with a surface, in the order validate_surface reports them (a defect
/// earlier in the list often causes later ones: a seam of duplicated vertices is also a hole).
enum class SurfaceDefectKind {
  no_triangles,
  too_large,                 ///< more triangles or vertices than int indices address
  non_finite_coordinate,     ///< NaN or ±∞, or beyond ±max_surface_coordinate_m
  index_out_of_range,
  degenerate_triangle,       ///< a repeated vertex index or (near-)zero area
  duplicate_triangle,        ///< the same three vertices as another triangle, in any order
  duplicate_vertex,          ///< two used vertices at the same point (weld an STL-like soup)
  non_manifold_edge,         ///< an edge of more than two triangles
  boundary_edge,             ///< an edge of one triangle only: the surface has a hole
  inconsistent_orientation,  ///< neighbours traverse their common edge in the same direction
  non_manifold_vertex,       ///< a vertex whose triangles form separate fans
  inward_orientation,        ///< closed and consistent, but the enclosed volume is negative
  self_intersection,         ///< two triangles sharing no vertex pass through each other
};

/// Short name of a defect kind, e.g. "hole (boundary edge)", "non-manifold edge".
const char* to_string(SurfaceDefectKind kind);

/// One kind of defect: how often it occurs and one example, named precisely.
struct SurfaceDefect {
  SurfaceDefectKind kind = SurfaceDefectKind::no_triangles;
  std::size_t count = 0;   ///< offending triangles, edges, vertices or vertex pairs
  std::string message;     ///< "<source>: <what> ... e.g. <example with its elements>"
};

/// Every defect of the surface (vertices [m], triangles counter-clockwise seen from outside),
/// one entry per kind in SurfaceDefectKind order; empty when the surface is valid. Checks run
/// on whatever the earlier defects leave checkable (triangles with an index out of range are
/// skipped by the later checks; the volume sign is checked only on a closed, manifold,
/// consistently oriented surface). Thresholds: a triangle is degenerate when its area is
/// <= 1e-14 · (bounding-box diagonal)², two vertices coincide within 1e-12 · diagonal.
/// Does not throw on bad data.
std::vector<SurfaceDefect> validate_surface(const std::vector<Eigen::Vector3d>& vertices,
                                            const std::vector<Eigen::Vector3i>& triangles,
                                            const std::string& source = "surface",
                                            const SurfaceLabels& labels = {});

/// For each vertex, the lowest-numbered earlier vertex within `tolerance_m` of it, or itself
/// when there is none: the map that welding applies (vertices are visited in order and join
/// the lowest representative in reach, so the result does not depend on hashing). Non-finite
/// vertices, and vertices with `used` false when `used` is given, map to themselves.
std::vector<int> coincident_vertices(const std::vector<Eigen::Vector3d>& vertices, double tolerance_m,
                                     const std::vector<char>& used = {});

/// A surface as a file holds it, before validation (file readers live in meshes/; the
/// TriangleSurface constructor takes the three members).
struct SurfaceData {
  std::vector<Eigen::Vector3d> vertices;   ///< [m]
  std::vector<Eigen::Vector3i> triangles;
  SurfaceLabels labels;                    ///< the file's vertex and triangle numbers
};

/// Closest point on the surface to a query point.
struct SurfaceProjection {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();   ///< [m]
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  ///< outward unit pseudo-normal: the face normal inside a face, the sum of the two face normals on an edge, the angle-weighted normal at a vertex
  double distance_m = 0;                              ///< unsigned distance
  int triangle = -1;
};

class TriangleSurface {
 public:
  /// Vertices [m] and triangles (counter-clockwise seen from outside). Validates as
  /// validate_surface does (finite coordinates, indices in range, no degenerate or duplicate
  /// triangle, no coincident vertices, every edge shared by exactly two triangles with opposite
  /// orientation, one fan per vertex, positive enclosed volume) and throws
  /// std::invalid_argument with the first defect's message (it names `source` and the
  /// offending triangle, edge or vertex) followed by the kinds of the others.
  TriangleSurface(std::vector<Eigen::Vector3d> vertices, std::vector<Eigen::Vector3i> triangles,
                  const std::string& source = "surface");
  /// The same, naming vertices and triangles with a file's own numbers in messages.
  TriangleSurface(std::vector<Eigen::Vector3d> vertices, std::vector<Eigen::Vector3i> triangles,
                  const std::string& source, const SurfaceLabels& labels);

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
  /// The vertices v with |v − centre| ≤ radius [m], in ascending order (through the tree: the
  /// cost follows the vertices near the ball, not the surface's size). Empty for a non-finite
  /// centre or a negative or NaN radius.
  std::vector<int> vertices_within(const Eigen::Vector3d& centre_m, double radius_m) const;

  double area_m2() const;
  double volume_m3() const;

 private:
  struct Node {
    Eigen::Vector3d lower, upper;
    int first, count;  ///< leaf: range in order_; inner: count = 0 and children at first, first + 1
  };
  void build_tree();

  std::vector<Eigen::Vector3d> vertices_;
  std::vector<Eigen::Vector3i> triangles_;
  std::vector<Eigen::Vector3d> vertex_normals_;
  std::vector<Eigen::Vector3d> face_normals_;  ///< unit, one per triangle
  std::vector<Eigen::Vector3d> edge_normals_;  ///< 3 per triangle; edge k runs from corner k to k + 1
  std::vector<Eigen::Vector3d> corners_;       ///< 3 per triangle, in tree (order_) order
  std::vector<char> owns_vertex_;              ///< per corner: the first corner (in that order) of its vertex
  std::vector<int> order_;
  std::vector<Node> nodes_;
  double area_m2_ = 0;
  double volume_m3_ = 0;
};

}  // namespace touchstone::geometry
