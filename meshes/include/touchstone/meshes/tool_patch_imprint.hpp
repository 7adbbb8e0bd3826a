#pragma once
/// @file
/// The tool patch cut into a triangle surface: the part of an organ's surface that a flat
/// cylindrical tool of radius a touches, bounded by the exact rim curve.
///
/// The patch is the sheet of surface inside the cylinder |P⊥(x − c)| < a around the tool axis
/// through the contact point c (P⊥ removes the axis component) that contains the triangle nearest
/// to c; sheets further along the axis (the far side of a thin organ) are left alone. Triangles
/// crossing the rim are split along it; every new vertex lies exactly on the cylinder (the root of
/// |P⊥(p(t) − c)|² = a² on the crossed edge), so the patch edge is the surface's own intersection
/// with the cylinder, resolved as finely as the surface is. Vertices within a fraction of their
/// shortest edge from the rim are first moved onto it (radially, perpendicular to the axis), so
/// that splitting makes no sliver triangles.
///
/// Used by the organ mesher before volume meshing; pure geometry (Eigen), tested against circles
/// on planes and spheres.

#include <Eigen/Core>

#include <cstddef>
#include <vector>

namespace touchstone::meshes {

/// Where the tool meets the surface and how large it is.
struct ToolPatchCylinder {
  Eigen::Vector3d contact_point_m = Eigen::Vector3d::Zero();  ///< c, on (or near) the surface [m]
  Eigen::Vector3d axis{0.0, 0.0, -1.0};  ///< tool axis (normalised on use; its sign is irrelevant)
  double radius_m = 0.0025;             ///< a [m]
  /// Vertices whose distance to the rim is below this fraction of their shortest incident edge
  /// are moved onto the rim (dimensionless, in [0, 0.5)).
  double snap_fraction = 0.25;

  /// Throws std::invalid_argument naming the field and value.
  void validate() const;
};

/// The surface with the patch cut in.
struct ImprintedSurface {
  std::vector<Eigen::Vector3d> vertices;   ///< [m]: the input's (some moved onto the rim), then the new rim points
  std::vector<Eigen::Vector3i> triangles;  ///< the input's orientation kept
  std::vector<char> in_patch;              ///< per triangle: part of the tool patch
  std::vector<std::size_t> source_triangle;  ///< per triangle: the input triangle it was cut from
  std::vector<int> rim_vertices;           ///< vertices on the rim curve (moved or new)
  std::size_t snapped_vertex_count = 0;    ///< input vertices moved onto the rim
  std::size_t split_triangle_count = 0;    ///< input triangles cut along the rim
  double patch_area_m2 = 0;                ///< area of the patch triangles [m²]
  /// Largest distance of a rim vertex from the cylinder, relative to a (rounding only: ~1e-15).
  double rim_relative_deviation = 0;
};

/// Cuts the tool patch into the surface (vertices [m], triangles of a closed or open surface).
/// Throws std::invalid_argument when the patch is not enclosed by the rim: no triangle near c lies
/// inside the cylinder, or the patch sheet reaches a boundary edge or a triangle larger than the
/// patch (the cylinder passes between its corners) — the message names the cause and the sizes.
ImprintedSurface imprint_tool_patch(const std::vector<Eigen::Vector3d>& vertices,
                                    const std::vector<Eigen::Vector3i>& triangles,
                                    const ToolPatchCylinder& tool);

}  // namespace touchstone::meshes
