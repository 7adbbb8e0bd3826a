#pragma once
/// @file
/// Oriented bounding box (OBB) of a set of triangles, fitted as in OBBTree / RAPID (Gottschalk,
/// Lin & Manocha 1996), with the two overlap tests a bounding-volume hierarchy needs: segment
/// against box (separating axes, Gottschalk; Ericson, Real-Time Collision Detection §5.3.3) and
/// the distance from a point to the box.

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace touchstone::realtime::collision {

/// The points c + Σ_i s_i a_i with |s_i| ≤ e_i: centre c, unit axes a_i (the rows of `axes`,
/// orthonormal and right-handed), half extents e_i. An axis-aligned box is the case axes = I.
struct OrientedBox {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();        ///< c [m]
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();      ///< rows a_0, a_1, a_2 (the box frame R)
  Eigen::Vector3d half_extents = Eigen::Vector3d::Zero();  ///< e [m], ≥ 0

  /// x in the box frame: R (x − c) [m].
  Eigen::Vector3d to_local(const Eigen::Vector3d& x) const noexcept { return axes * (x - center); }
};

/// Gottschalk's OBB of triangles (`corners`: 3 per triangle) [m]. The axes are the eigenvectors
/// of the covariance of the triangles taken as continuous area distributions,
///   C = (1/A_H) Σ_i (A_i/12) (9 m_i m_iᵀ + p_i p_iᵀ + q_i q_iᵀ + r_i r_iᵀ) − m_H m_Hᵀ,
/// with A_i the area and m_i the centroid of triangle (p_i, q_i, r_i), A_H = Σ A_i and
/// m_H = Σ A_i m_i / A_H; weighting by area makes the fit independent of how finely a region is
/// triangulated. The extents enclose every corner exactly (up to rounding). Falls back to the
/// covariance of the corners when all triangles are degenerate, and to the coordinate axes when
/// that is singular too. Empty input: an empty box at the origin.
OrientedBox fit_oriented_box(const std::vector<Eigen::Vector3d>& corners);

/// The smallest box with the given axes (rows, orthonormal) enclosing points[0 .. count) [m]:
/// e_i = (max_k a_i·p_k − min_k a_i·p_k) / 2 (used to refit a deformed surface).
OrientedBox enclose_with_axes(const Eigen::Matrix3d& axes, const Eigen::Vector3d* points, std::size_t count);

/// Separating-axis test of the segment m ± h against the centred axis-aligned box |x_i| ≤ e_i
/// (all in the box frame). Candidate axes: the three box axes, |m_i| > e_i + |h_i|, and the
/// three cross products h × a_i. Division-free, so a segment parallel to a face needs no special
/// case. Touching counts as overlapping.
inline bool segment_overlaps_centred_box(const Eigen::Vector3d& m, const Eigen::Vector3d& h,
                                         const Eigen::Vector3d& e) noexcept {
  const double ax = std::abs(h.x()), ay = std::abs(h.y()), az = std::abs(h.z());
  if (std::abs(m.x()) > e.x() + ax) return false;
  if (std::abs(m.y()) > e.y() + ay) return false;
  if (std::abs(m.z()) > e.z() + az) return false;
  if (std::abs(m.y() * h.z() - m.z() * h.y()) > e.y() * az + e.z() * ay) return false;
  if (std::abs(m.z() * h.x() - m.x() * h.z()) > e.x() * az + e.z() * ax) return false;
  if (std::abs(m.x() * h.y() - m.y() * h.x()) > e.x() * ay + e.y() * ax) return false;
  return true;
}

/// True when the segment with midpoint m and half vector h (endpoints m ± h) [m] meets the box:
/// the segment is rotated into the box frame (m → R(m − c), h → R h) and tested there.
inline bool segment_overlaps(const OrientedBox& box, const Eigen::Vector3d& m, const Eigen::Vector3d& h) noexcept {
  return segment_overlaps_centred_box(box.to_local(m), box.axes * h, box.half_extents);
}

/// Squared distance from x to the centred axis-aligned box |y_i| ≤ e_i, x in the box frame:
/// Σ_i max(|x_i| − e_i, 0)² [m²] (0 inside).
inline double squared_distance_to_centred_box(const Eigen::Vector3d& x, const Eigen::Vector3d& e) noexcept {
  const double dx = std::max(std::abs(x.x()) - e.x(), 0.0);
  const double dy = std::max(std::abs(x.y()) - e.y(), 0.0);
  const double dz = std::max(std::abs(x.z()) - e.z(), 0.0);
  return dx * dx + dy * dy + dz * dz;
}

/// Squared distance from x to the box [m²] (0 inside).
inline double squared_distance(const OrientedBox& box, const Eigen::Vector3d& x) noexcept {
  return squared_distance_to_centred_box(box.to_local(x), box.half_extents);
}

}  // namespace touchstone::realtime::collision
