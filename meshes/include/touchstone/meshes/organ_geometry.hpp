#pragma once
/// @file
/// Closed triangle surfaces of organ-like shapes at a requested triangle count, for collision
/// detection studies (the paper's Table 1 sizes of about 500, 2,500, 17,000 and 35,000 triangles,
/// and the 20,000 of its stomach). Generated on demand (fast and deterministic), never committed.
///
/// Shapes, built with gmsh's OpenCASCADE kernel and meshed as surfaces (triangles only, a
/// uniform size searched until the count is within the tolerance):
/// - stomach: a J-shaped tube lofted (addThruSections, smooth B-spline) through elliptic
///   sections along a curved centre line in the x–z plane, the fundus at the top (z up) and
///   the pylorus at the right, capped with ellipsoids at both ends. Section radii fall from
///   50 mm (fundus) to 12 mm (pylorus); about 0.20 m wide (x) and 0.22 m tall (z), 1.1 L.
/// - hemisphere: the B2 body, the ball of radius R centred at the origin cut at z = 0 and
///   closed by its flat base (area 3πR², volume 2πR³/3).
/// The triangles are oriented counter-clockwise seen from outside.

#include <Eigen/Core>

#include <string>
#include <vector>

namespace touchstone::meshes {

enum class OrganShape {
  stomach,
  hemisphere,
};

/// "stomach", "hemisphere"; and back (throws std::invalid_argument naming the value).
std::string to_string(OrganShape shape);
OrganShape organ_shape_from_string(const std::string& name);

/// What to generate. Lengths in metres.
struct OrganParameters {
  OrganShape shape = OrganShape::stomach;
  /// Requested number of triangles.
  int target_triangles = 2500;
  /// Accepted relative deviation of the triangle count from the target (dimensionless).
  double relative_tolerance = 0.05;
  /// Stomach: every length of the built-in profile multiplied by this (dimensionless).
  double stomach_scale = 1.0;
  /// Stomach: depth (y) over width of the elliptic sections, in (0.3, 1) (a stomach is flatter
  /// front to back than side to side).
  double stomach_flattening = 0.85;
  /// Hemisphere: radius R (B2: 0.05 m).
  double hemisphere_radius_m = 0.05;
  /// Most meshing passes of the size search before giving up.
  int max_passes = 12;

  /// Throws std::invalid_argument naming the offending field and value.
  void validate() const;
};

/// A generated surface and how it was found.
struct OrganMesh {
  std::vector<Eigen::Vector3d> vertices;   ///< [m]
  std::vector<Eigen::Vector3i> triangles;  ///< counter-clockwise seen from outside
  double mesh_size_m = 0;         ///< the uniform gmsh element size that hit the count
  int passes = 0;                 ///< meshing passes of the size search
  double geometry_area_m2 = 0;    ///< of the exact (CAD) surface, from OpenCASCADE
  double geometry_volume_m3 = 0;  ///< of the exact (CAD) solid, from OpenCASCADE
  double seconds = 0;             ///< wall time to build, search and mesh
};

/// Builds the shape and meshes its boundary with triangles, searching the uniform element size
/// h (power-law steps N ∝ h⁻², safeguarded by bisection in log h) until the triangle count is
/// within relative_tolerance of the target. The result is checked with validate_surface
/// (closed, manifold, outward). Deterministic: the same parameters give the same mesh.
/// Thread-safe (gmsh calls are serialised). Throws std::invalid_argument for bad parameters,
/// std::runtime_error naming the parameters when gmsh fails or the search does not converge.
OrganMesh generate_organ_mesh(const OrganParameters& parameters);

/// generate_organ_mesh, then write_surface_mesh by the extension of `path` (.msh: MSH 2.2
/// ASCII; .vtp, .vtk, .stl, .obj). Fails before meshing if the path cannot be written.
OrganMesh write_organ_mesh(const OrganParameters& parameters, const std::string& path);

}  // namespace touchstone::meshes
