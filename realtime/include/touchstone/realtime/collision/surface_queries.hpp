#pragma once
/// @file
/// What collision prediction and the runtime ask of a collision detector: the
/// first hit of a segment or ray, the closest point, inside/outside — each able to count the
/// bounding-volume overlap tests and triangle tests it made (the paper's Table 1 metric).
/// The own bounding-volume hierarchy implements it; tests implement it by brute force.

#include <Eigen/Core>

namespace touchstone::realtime::collision {

/// Work done by queries; accumulated, never reset by a query.
struct QueryCounters {
  long long box_tests = 0;       ///< bounding-volume overlap tests (OBB or AABB against the query)
  long long triangle_tests = 0;  ///< exact primitive tests (segment–triangle, point–triangle)
  long long queries = 0;         ///< queries answered
};

/// First intersection of a segment or ray with the surface.
struct SurfaceHit {
  bool hit = false;
  double distance_m = 0;   ///< from the segment's start or the ray's origin along it
  Eigen::Vector3d point = Eigen::Vector3d::Zero();   ///< [m]
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  ///< outward unit face normal of `triangle`
  int triangle = -1;
};

/// Closest point on the surface.
struct ClosestSurfacePoint {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  ///< [m]
  double distance_m = 0;                             ///< unsigned
  int triangle = -1;                                 ///< −1 only for a non-finite query
};

/// The queries, in double precision. Every method is noexcept and thread-safe for concurrent
/// readers; `counters` may be null.
class SurfaceQueries {
 public:
  virtual ~SurfaceQueries() = default;

  /// First hit of the segment from → to (the tool tip's motion in one cycle, or the tool shaft).
  virtual SurfaceHit first_hit_segment(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                                       QueryCounters* counters = nullptr) const noexcept = 0;
  /// First hit of the ray origin + t·direction, 0 ≤ t ≤ max_distance_m (direction: unit vector).
  virtual SurfaceHit first_hit_ray(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                   double max_distance_m,
                                   QueryCounters* counters = nullptr) const noexcept = 0;
  virtual ClosestSurfacePoint closest_point(const Eigen::Vector3d& x,
                                            QueryCounters* counters = nullptr) const noexcept = 0;
  /// True when x is strictly inside the closed surface.
  virtual bool contains(const Eigen::Vector3d& x, QueryCounters* counters = nullptr) const noexcept = 0;
};

}  // namespace touchstone::realtime::collision
