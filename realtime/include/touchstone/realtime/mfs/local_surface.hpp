#pragma once
/// @file
/// The organ surface near one contact, as the enriched model's sprinkling and quadratures ask
/// it: is a point inside, and where does a line parallel to the tool axis meet the surface.
///
/// The exact answers (closest points on the triangle surface) cost microseconds each and a build
/// asks thousands of them. Where the organ is a height field over its tangent plane at the
/// contact (no fold within the ball: every vertex normal within 1.3 L makes less than 75° with the
/// contact normal), the surface is fitted there by a polynomial depth d(u, v) of degree 4 in the
/// tangent coordinates (least squares over the vertices, which lie on the true surface), and both
/// questions become a few dozen flops. A fit whose largest residual exceeds 1e-3 L, or too few
/// vertices, falls back to the exact queries; `fitted()` says which one answers.

#include "touchstone/geometry/triangle_surface.hpp"

#include <Eigen/Core>

namespace touchstone::realtime::mfs {

/// The reach of the enriched model's LocalSurface, in local radii L: past the ball, so that
/// every point of the local domain and the cut's rim lie inside the fitted patch.
constexpr double enriched_surface_reach_local_radii = 1.3;

class LocalSurface {
 public:
  /// The surface near `contact_point_m` (projected onto the organ) within `reach_m`.
  LocalSurface(const geometry::TriangleSurface& organ, const Eigen::Vector3d& contact_point_m, double reach_m);

  bool fitted() const { return fitted_; }
  /// The contact point on the surface and the outward normal there (of the fitted surface when
  /// fitted, else of the closest feature).
  const Eigen::Vector3d& centre() const { return centre_; }
  const Eigen::Vector3d& normal() const { return normal_; }
  /// Largest fit residual over the vertices used [m] (0 when not fitted).
  double fit_residual_m() const { return residual_m_; }
  /// How far the contact point given to the constructor lies from the organ's triangles [m].
  /// centre() may lie farther from it, by up to the fit's residual: the fit is smooth where the
  /// triangles are faceted, so whether a contact is on the organ is asked of this distance.
  double contact_offset_m() const { return contact_offset_m_; }

  /// True when x is inside the organ by more than margin_m (measured along the normal when
  /// fitted: the vertical depth below the surface).
  bool inside(const Eigen::Vector3d& x, double margin_m = 0) const;

  /// The surface point on the line x₀ + s d (d unit), the one nearest x₀, and the outward normal
  /// there. False when the line misses the surface near x₀ (an organ edge, a fold).
  bool on_line(const Eigen::Vector3d& x0, const Eigen::Vector3d& d, Eigen::Vector3d& point, Eigen::Vector3d& normal) const;

  /// The fitted depth below the tangent plane at the contact [m], at tangent coordinates (u, v)
  /// [m] along the surface's own tangent axes, and its slopes ∂d/∂u, ∂d/∂v when asked (fitted
  /// surfaces only; without slopes it is evaluated by Horner's rule, the inside tests' case).
  double depth(double u, double v, double* du = nullptr, double* dv = nullptr) const;

 private:
  /// Least-squares fit of the depth in the current frame; false when not a height field.
  bool fit(const geometry::TriangleSurface& organ, double reach_m);

  const geometry::TriangleSurface& organ_;
  Eigen::Vector3d centre_, normal_, t1_, t2_;
  double reach_m_ = 0, residual_m_ = 0, contact_offset_m_ = 0;
  bool fitted_ = false;
  Eigen::Matrix<double, 15, 1> coefficients_ = Eigen::Matrix<double, 15, 1>::Zero();  ///< depth monomials u^i v^j, i + j ≤ 4
};

}  // namespace touchstone::realtime::mfs
