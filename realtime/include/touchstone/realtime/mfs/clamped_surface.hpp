#pragma once
/// @file
/// Parts of the organ surface held at u = 0 — an organ's attachment, the clamped base of the
/// benchmark hemisphere. When the local ball reaches them (a contact near the
/// base of B5), the local model must hold them too, or it treats the attachment as free
/// surface and comes out too soft. The weak form imposes them like the cut: a penalty on a
/// surface quadrature, whose force joins the reaction (force extraction (b), global
/// equilibrium: minus the reaction on all fixed boundaries).

#include "touchstone/realtime/mfs/node_sprinkling.hpp"
#include "touchstone/realtime/mfs/tool_force.hpp"

#include <Eigen/Core>

#include <vector>

namespace touchstone::realtime::mfs {

/// Triangles of the organ surface [m] held at u = 0 (an open surface: no closedness required).
/// Their orientation gives the outward normal (counter-clockwise seen from outside).
struct ClampedSurface {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<Eigen::Vector3i> triangles;
  bool empty() const { return triangles.empty(); }
  /// Throws std::invalid_argument naming the triangle (index out of range, non-finite vertex).
  void validate() const;
};

/// Quadrature of the clamped triangles inside ball(centre, L): each triangle near the ball is
/// split (into four, recursively) until its longest edge is below max_edge_m, then integrated by
/// the 7-point degree-5 rule; points outside the ball are dropped, so the ball's edge is resolved
/// to max_edge_m. Normals are the triangles' outward normals; weights in [m²].
PatchQuadrature clamped_quadrature(const ClampedSurface& clamped, const Eigen::Vector3d& centre_m, double local_radius_m,
                                   double max_edge_m);

}  // namespace touchstone::realtime::mfs
