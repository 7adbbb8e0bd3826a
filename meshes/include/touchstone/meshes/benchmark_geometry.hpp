#pragma once
/// @file
/// gmsh geometry and tetrahedral meshes of the indentation benchmarks B1–B5.
///
/// Every mesh is written as MSH 2.2 ASCII with named physical groups whose numeric tags are
/// fixed (see boundary_tags below), so that a reader that sees only numbers (deal.II's
/// GridIn::read_msh) and a reader that sees names agree. The tool-patch circle is a curve of the
/// geometry, so the patch edge is exact; a size field grades the mesh toward that edge, where
/// the contact stress is singular.

#include "touchstone/meshes/organ_body.hpp"

#include <array>
#include <cstddef>
#include <string>

namespace touchstone::meshes {

/// Which benchmark domain to build.
enum class Benchmark {
  B1,   ///< cylinder of radius W and height W, top face z = 0, base z = −W clamped, patch at the top centre
  B2,   ///< hemisphere of radius R, flat base z = 0, patch (radius a) at the pole (0, 0, R)
  B3,   ///< B2 ∩ ball(pole, L): the MFS local domain; the sphere of radius L is the "cut" surface
  B5,   ///< B2 with the patch centred at polar angle θ from the pole (rotated about the y axis)
  Box,  ///< box [0, Lx]×[0, Ly]×[0, Lz] for tests; faces named x_min … z_max
  Organ,  ///< a user's closed surface (MeshParameters::organ), meshed by organ_body_mesh.hpp
};

/// Fixed physical-group tags. Surfaces: base, tool_patch, free, cut (benchmarks) and the six box
/// faces. Volume: tissue.
namespace boundary_tags {
inline constexpr int base = 1;
inline constexpr int tool_patch = 2;
inline constexpr int free = 3;
inline constexpr int cut = 4;
inline constexpr int x_min = 11;
inline constexpr int x_max = 12;
inline constexpr int y_min = 13;
inline constexpr int y_max = 14;
inline constexpr int z_min = 15;
inline constexpr int z_max = 16;
inline constexpr int tissue = 100;  ///< volume group
}  // namespace boundary_tags

/// Geometry and mesh-size parameters. All lengths in metres, angles in radians.
struct MeshParameters {
  Benchmark benchmark = Benchmark::B2;
  double body_radius_m = 0.05;        ///< R (B2, B3, B5) or W (B1: cylinder radius = height)
  double tool_radius_m = 0.0025;      ///< a, radius of the tool patch circle
  double local_radius_m = 0.0125;     ///< L (B3, and exterior meshes), radius of the ball around the contact
  double contact_polar_angle_rad = 0; ///< θ (B5 only), polar angle of the patch centre, 0 < θ < π/2
  std::array<double, 3> box_size_m{{1.0, 1.0, 1.0}};  ///< Box only
  OrganBody organ;  ///< Organ only: the surface, the contact and the attachment (body_radius_m unused)
  /// B1, B2, B5, Organ: mesh the body MINUS ball(c, local_radius_m) instead of the body, c the
  /// patch centre on the surface (B1: the top centre (0, 0, 0); B2: the pole; B5: R (sin θ, 0,
  /// cos θ); Organ: the contact site, the sphere cap closing the surface as a triangulation).
  /// This is the exterior of the MFS local domain, whose stiffness the enriched model needs. The
  /// ball's sphere is the group "cut"; there is no tool patch (it lies inside the ball), and the
  /// size field grades from the cut instead of the patch edge: d below is the distance |x − c| − L
  /// to the cut sphere, edge_size_m the size on it.
  bool exterior_of_local_ball = false;

  /// Element size at the patch edge (exterior meshes: on the cut sphere) at refinement 0 [m].
  /// Box: the uniform size.
  double edge_size_m = 0.0025 / 4;
  /// Growth of the element size with distance d from the patch edge:
  /// h(d) = min(max_size_m, edge_size_m + size_growth · d) at refinement 0 (dimensionless).
  double size_growth = 0.5;
  /// Grading exponent β: h(d) = min(max_size_m, edge_size_m + size_growth · a · g(d/a)) with
  /// g(t) = t^β for t ≤ t₀ and its tangent line beyond (t₀ = power_grading_extent). β = 1 is
  /// the linear law above; β < 1 concentrates elements at the singular edge (β ≈ 1 − λ/p = 3/4
  /// suits the r^(1/2) edge singularity with P2 elements).
  double size_exponent = 1.0;
  /// t₀ [tool radii]: beyond this distance from the edge the size grows linearly. Large (the
  /// default) keeps the power law everywhere; a few radii keep large domains affordable.
  double power_grading_extent = 1.0e6;
  /// Largest element size at refinement 0 [m].
  double max_size_m = 0.01;
  /// Each refinement level halves every size (edge, growth law, max): h → h / 2^refinement.
  int refinement = 0;

  /// Throws std::invalid_argument naming the offending field and value.
  void validate() const;
};

/// What was written.
struct MeshSummary {
  std::string path;
  std::size_t node_count = 0;         ///< mesh vertices
  std::size_t tetrahedron_count = 0;
  std::size_t patch_triangle_count = 0;  ///< 0 for exterior meshes (no patch)
  double seconds = 0;                 ///< wall time to build and mesh
};

/// Where the tool meets a benchmark body: the patch centre c on the surface [m] and the unit
/// outward surface normal there. B1: (0, 0, 0) and +z; B2, B3: (0, 0, R) and +z; B5:
/// R (sin θ, 0, cos θ) and (sin θ, 0, cos θ). Organ: the surface point nearest to
/// organ.contact_point_m and minus the tool axis (organ_contact_site). Box: throws
/// std::invalid_argument.
struct ContactSite {
  std::array<double, 3> point_m{{0.0, 0.0, 0.0}};
  std::array<double, 3> outward_normal{{0.0, 0.0, 1.0}};
};
ContactSite contact_site(const MeshParameters& parameters);

/// Builds the geometry with gmsh's OpenCASCADE kernel, meshes it with tetrahedra (first order)
/// and writes MSH 2.2 ASCII to msh_path. Thread-safe (gmsh is global: calls are serialised).
/// Throws std::runtime_error with the parameters named when gmsh fails.
MeshSummary generate_mesh(const MeshParameters& parameters, const std::string& msh_path);

/// The mesher's name and version (e.g. "gmsh 4.8.0"): part of any key under which meshes are kept,
/// since another gmsh may mesh the same parameters differently.
std::string mesher_version();

/// Writes the same geometry as a .geo_unrolled script (opens in the gmsh GUI) for inspection.
void write_geometry_script(const MeshParameters& parameters, const std::string& geo_path);

/// "B1" … "B5", "box", "organ"; and back (throws std::invalid_argument naming the value).
std::string to_string(Benchmark benchmark);
Benchmark benchmark_from_string(const std::string& name);

}  // namespace touchstone::meshes
