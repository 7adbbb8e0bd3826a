#pragma once
/// @file
/// The graded tetrahedral mesh of a user's organ for the FEM reference, from its closed
/// triangle surface.
///
/// Steps (gmsh, then our own geometry):
/// 1. the surface is read, validated (closed, manifold, outward) and split by gmsh at creases
///    sharper than the feature angle into pieces gmsh can reparametrise;
/// 2. gmsh remeshes those pieces with the benchmarks' size law, h(d) = min(max, edge + growth ·
///    a · g(d/a)) / 2^refinement, d the distance to the rim circle (the circle of radius a around
///    the tool axis, at the height where the surface crosses the cylinder); new surface points
///    lie on the input surface;
/// 3. the tool patch is cut into the remeshed surface along its exact rim (tool_patch_imprint);
/// 4. the triangles are grouped: tool_patch, base (the attachment, inherited from the input
///    triangle each remeshed triangle lies on), free; a patch touching the attachment is refused;
/// 5. gmsh fills the volume with tetrahedra under the same size law and writes MSH 2.2 with the
///    benchmark bodies' physical groups and tags (base = 1, tool_patch = 2, free = 3,
///    tissue = 100), so the FEM reference solves it exactly as it solves B2.

#include "touchstone/meshes/benchmark_geometry.hpp"

#include <array>
#include <string>

namespace touchstone::meshes {

/// The organ's contact: the surface point closest to organ.contact_point_m, the outward normal
/// there (the triangle's inside a face; averaged over the neighbours on an edge or a corner), and
/// the tool axis used (organ.tool_axis, or the inward normal). Reads and validates the surface;
/// throws std::invalid_argument naming the file and the defect.
struct OrganContactSite {
  std::array<double, 3> point_m{{0.0, 0.0, 0.0}};
  std::array<double, 3> outward_normal{{0.0, 0.0, 1.0}};
  std::array<double, 3> tool_axis{{0.0, 0.0, -1.0}};
  double distance_to_given_point_m = 0;  ///< how far organ.contact_point_m lies off the surface
  double bounding_box_diagonal_m = 0;    ///< of the organ
};
OrganContactSite organ_contact_site(const OrganBody& organ);

/// The centre of the tool patch's rim circle [m]: on the tool axis through the contact, at the
/// mean height where lines parallel to the axis at distance tool_radius_m from it meet the
/// surface (the origin of the punch fields' frame). Reads the surface; throws as organ_contact_site
/// does, and when the patch does not fit on the surface.
std::array<double, 3> organ_rim_centre(const OrganBody& organ, double tool_radius_m);

/// Meshes parameters.organ (parameters.benchmark == Benchmark::Organ) with the size law of
/// `parameters` and writes MSH 2.2 ASCII to msh_path. With parameters.exterior_of_local_ball it
/// meshes the organ MINUS ball(c, local_radius_m) instead, c the contact: steps 1–2 with d the
/// distance to the cut sphere, then the ball cut out and its hole closed by the sphere cap
/// (local_ball_cut.hpp), grouped base (the attachment), cut (the cap) and free. Throws std::invalid_argument for a bad
/// surface, an attachment that selects nothing, a patch the surface cannot hold or that touches
/// the attachment (each naming the file, rule or sizes), std::runtime_error when gmsh fails.
MeshSummary generate_organ_body_mesh(const MeshParameters& parameters, const std::string& msh_path);

}  // namespace touchstone::meshes
