#pragma once
/// @file
/// An organ surface with a ball cut out of it: the boundary of the EXTERIOR BODY organ ∖ ball(c, L)
/// whose stiffness under the punch fields' trace the organ atlas records.
///
/// Two steps:
/// 1. the surface is split along the sphere |x − c| = L (every new vertex the exact root on its
///    edge; vertices closer to the sphere than a fraction of their shortest edge are first moved
///    radially onto it) and the part inside the ball is dropped, leaving one closed cut curve;
/// 2. the hole is closed by the cap, the part of the sphere inside the organ: the cut curve is
///    mapped to a plane by the stereographic projection from the sphere point c + L n (n: the
///    direction pointing out of the organ, so that point lies outside it), gmsh triangulates the
///    plane polygon without adding points on its edges (the cap shares the surface's cut-curve
///    vertices), and the triangles are mapped back onto the sphere. The projection is conformal:
///    a plane size h (1 + r²)/(2L) at radius r gives the size h on the sphere.
///
/// A surface that the sphere meets in more than one curve (an organ thinner than the ball, or a
/// second lobe within reach) is refused: its cap is not one disk.

#include <Eigen/Core>

#include <cstddef>
#include <vector>

namespace touchstone::meshes {

struct LocalBall {
  Eigen::Vector3d centre_m = Eigen::Vector3d::Zero();  ///< c: the contact point [m]
  double radius_m = 0.0125;                            ///< L [m]
  /// Points out of the organ at c (normalised on use): the projection pole is c + L n.
  Eigen::Vector3d outward_direction{0.0, 0.0, 1.0};
  double cap_edge_m = 0.001;    ///< triangle size on the cap [m]
  double snap_fraction = 0.25;  ///< vertices this close to the sphere (× shortest edge) are moved onto it, in [0, 0.5)
  /// Throws std::invalid_argument naming the field and value.
  void validate() const;
};

struct BallCutSurface {
  std::vector<Eigen::Vector3d> vertices;   ///< [m]
  std::vector<Eigen::Vector3i> triangles;  ///< the surface outside the ball (input orientation), then the cap
  std::vector<char> on_cap;                ///< per triangle: part of the cap (on the sphere)
  /// Per triangle outside the ball: the input triangle it was cut from; cap triangles: none (SIZE_MAX).
  std::vector<std::size_t> source_triangle;
  std::vector<int> cut_curve;              ///< the cut curve's vertices in order (a closed loop)
  std::size_t snapped_vertex_count = 0;
  std::size_t split_triangle_count = 0;
  double cap_area_m2 = 0;                  ///< area of the cap triangles [m²]
  /// Largest distance of a cut-curve or cap vertex from the sphere, relative to L (rounding: ~1e-15).
  double sphere_relative_deviation = 0;
};

/// Cuts the ball out of a closed surface and closes the hole with the cap. Runs gmsh (holds the
/// library's gmsh session). Throws std::invalid_argument when the ball does not meet the surface,
/// holds all of it, or meets it in more than one curve, and when the cap would contain the
/// projection pole (the outward direction points into the organ); std::runtime_error when gmsh
/// cannot triangulate the cap.
BallCutSurface cut_out_local_ball(const std::vector<Eigen::Vector3d>& vertices, const std::vector<Eigen::Vector3i>& triangles,
                                  const LocalBall& ball);

}  // namespace touchstone::meshes
