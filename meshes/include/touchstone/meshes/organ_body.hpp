#pragma once
/// @file
/// A user's organ as an indentation problem: its closed surface file, where the tool touches it
/// and where the organ is held. MeshParameters with benchmark = Organ carries one of these; the
/// mesher (organ_body_mesh.hpp) turns it into a graded tetrahedral mesh with the same physical
/// groups as the benchmark bodies (base = the attachment, tool_patch, free, tissue).

#include <array>
#include <string>

namespace touchstone::meshes {

/// Which surface triangles of the organ are held (u = 0). Exactly one rule is set.
struct OrganAttachment {
  /// Plane rule: the triangles whose three corners lie at (x − plane_point)·plane_normal ≤
  /// 1e-6 × the organ's bounding-box diagonal ("below the plane"). A zero normal: no plane rule.
  std::array<double, 3> plane_point_m{{0.0, 0.0, 0.0}};
  std::array<double, 3> plane_normal{{0.0, 0.0, 0.0}};
  /// .msh surfaces: the triangles of this physical group.
  std::string msh_group;
  /// A text file of triangle numbers counted from 0 in the surface file's order (after
  /// triangulation of polygons), separated by white space; '#' starts a comment.
  std::string triangles_path;

  bool has_plane() const { return plane_normal[0] != 0 || plane_normal[1] != 0 || plane_normal[2] != 0; }
  /// How many of the three rules are set.
  int rule_count() const { return (has_plane() ? 1 : 0) + (msh_group.empty() ? 0 : 1) + (triangles_path.empty() ? 0 : 1); }
};

struct OrganBody {
  std::string surface_path;  ///< closed, outward-oriented triangle surface (.msh, .obj, .stl, .vtk, .vtp)
  double unit_scale = 1.0;   ///< metres per file unit (1e-3 for a file in millimetres)
  /// A point on or near the surface: the tool patch is centred at the closest surface point [m].
  std::array<double, 3> contact_point_m{{0.0, 0.0, 0.0}};
  /// The tool axis (pointing into the organ; normalised on use). Zero: the inward surface normal
  /// at the contact.
  std::array<double, 3> tool_axis{{0.0, 0.0, 0.0}};
  OrganAttachment attachment;
  /// Surface creases sharper than this split the surface into separately remeshed pieces, so
  /// they are kept (e.g. the rim of a hemisphere's flat base) [rad].
  double feature_angle_rad = 0.6981317007977318;  // 40°

  /// Throws std::invalid_argument naming the field and value (the files are checked when read).
  void validate() const;
};

}  // namespace touchstone::meshes
