#pragma once
/// @file
/// Test support: a brute-force SurfaceQueries over a TriangleSurface — every query visits every
/// triangle (each behind its own bounding-box rejection, counted as a box test; an exact test
/// is counted as a triangle test). Möller–Trumbore for segments and rays (exact comparisons,
/// no widening), Ericson's closest point on a triangle, and inside/outside from the surface's
/// own pseudo-normal test. The reference for the prediction tests and for the BVH.
///
/// Also a counting wrapper that records which queries were called, for tests that claim a
/// cycle made none.

#include "touchstone/realtime/collision/surface_queries.hpp"
#include "touchstone/geometry/triangle_surface.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <vector>

namespace touchstone::realtime::collision::testing {

class BruteForceQueries final : public SurfaceQueries {
 public:
  explicit BruteForceQueries(const geometry::TriangleSurface& surface) : surface_(surface) {
    for (const Eigen::Vector3i& t : surface.triangles()) {
      const Eigen::Vector3d& a = surface.vertices()[t[0]];
      const Eigen::Vector3d& b = surface.vertices()[t[1]];
      const Eigen::Vector3d& c = surface.vertices()[t[2]];
      corners_.push_back({a, b, c});
      normals_.push_back((b - a).cross(c - a).normalized());
      lower_.push_back(a.cwiseMin(b).cwiseMin(c));
      upper_.push_back(a.cwiseMax(b).cwiseMax(c));
    }
  }

  SurfaceHit first_hit_segment(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                               QueryCounters* counters = nullptr) const noexcept override {
    const double length = (to - from).norm();
    SurfaceHit hit = first_hit(from, to - from, 1.0, counters);
    hit.distance_m *= length;
    return hit;
  }

  SurfaceHit first_hit_ray(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, double max_distance_m,
                           QueryCounters* counters = nullptr) const noexcept override {
    return first_hit(origin, direction, max_distance_m, counters);
  }

  ClosestSurfacePoint closest_point(const Eigen::Vector3d& x, QueryCounters* counters = nullptr) const noexcept override {
    ClosestSurfacePoint best;
    if (counters != nullptr) ++counters->queries;
    if (!x.allFinite()) {
      best.distance_m = std::numeric_limits<double>::quiet_NaN();
      return best;
    }
    double best2 = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < corners_.size(); ++i) {
      // The box is a lower bound: skip the triangle when it cannot be closer.
      if (counters != nullptr) ++counters->box_tests;
      const Eigen::Vector3d outside = (lower_[i] - x).cwiseMax(x - upper_[i]).cwiseMax(0.0);
      if (outside.squaredNorm() >= best2) continue;
      if (counters != nullptr) ++counters->triangle_tests;
      const Eigen::Vector3d p = closest_on_triangle(x, corners_[i][0], corners_[i][1], corners_[i][2]);
      const double d2 = (p - x).squaredNorm();
      if (d2 < best2) {
        best2 = d2;
        best.point = p;
        best.triangle = static_cast<int>(i);
      }
    }
    best.distance_m = std::sqrt(best2);
    return best;
  }

  bool contains(const Eigen::Vector3d& x, QueryCounters* counters = nullptr) const noexcept override {
    if (counters != nullptr) ++counters->queries;
    return x.allFinite() && surface_.contains(x);
  }

  const geometry::TriangleSurface& surface() const { return surface_; }

  /// Closest point on triangle abc (Ericson, Real-Time Collision Detection, §5.1.5).
  static Eigen::Vector3d closest_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                             const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
    const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
    const double d1 = ab.dot(ap), d2 = ac.dot(ap);
    if (d1 <= 0 && d2 <= 0) return a;
    const Eigen::Vector3d bp = p - b;
    const double d3 = ab.dot(bp), d4 = ac.dot(bp);
    if (d3 >= 0 && d4 <= d3) return b;
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
    const Eigen::Vector3d cp = p - c;
    const double d5 = ab.dot(cp), d6 = ac.dot(cp);
    if (d6 >= 0 && d5 <= d6) return c;
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
    const double denominator = 1 / (va + vb + vc);
    return a + ab * (vb * denominator) + ac * (vc * denominator);
  }

  /// Möller–Trumbore: o + t d meets triangle abc at t (any t; the caller bounds it).
  static bool moller_trumbore(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& a,
                              const Eigen::Vector3d& b, const Eigen::Vector3d& c, double& t) {
    const Eigen::Vector3d e1 = b - a, e2 = c - a;
    const Eigen::Vector3d p = d.cross(e2);
    const double det = e1.dot(p);
    if (det == 0) return false;
    const double inverse = 1 / det;
    const Eigen::Vector3d s = o - a;
    const double u = s.dot(p) * inverse;
    if (u < 0 || u > 1) return false;
    const Eigen::Vector3d q = s.cross(e1);
    const double v = d.dot(q) * inverse;
    if (v < 0 || u + v > 1) return false;
    t = e2.dot(q) * inverse;
    return true;
  }

 private:
  /// First hit of o + t d, 0 ≤ t ≤ t_max; distance_m = t (the caller scales for segments).
  SurfaceHit first_hit(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_max,
                       QueryCounters* counters) const noexcept {
    SurfaceHit hit;
    if (counters != nullptr) ++counters->queries;
    if (!o.allFinite() || !d.allFinite() || !(t_max >= 0)) return hit;
    const Eigen::Vector3d end = o + t_max * d;
    const Eigen::Vector3d box_lower = o.cwiseMin(end), box_upper = o.cwiseMax(end);
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < corners_.size(); ++i) {
      if (counters != nullptr) ++counters->box_tests;
      if ((box_upper.array() < lower_[i].array()).any() || (box_lower.array() > upper_[i].array()).any()) continue;
      if (counters != nullptr) ++counters->triangle_tests;
      double t = 0;
      if (moller_trumbore(o, d, corners_[i][0], corners_[i][1], corners_[i][2], t) && t >= 0 && t <= t_max &&
          t < best) {
        best = t;
        hit.hit = true;
        hit.distance_m = t;
        hit.point = o + t * d;
        hit.normal = normals_[i];
        hit.triangle = static_cast<int>(i);
      }
    }
    return hit;
  }

  const geometry::TriangleSurface& surface_;
  std::vector<std::array<Eigen::Vector3d, 3>> corners_;
  std::vector<Eigen::Vector3d> normals_;
  std::vector<Eigen::Vector3d> lower_, upper_;
};

/// Forwards to another SurfaceQueries and counts the calls of each kind (single-threaded use).
class CountingQueries final : public SurfaceQueries {
 public:
  explicit CountingQueries(const SurfaceQueries& inner) : inner_(inner) {}

  SurfaceHit first_hit_segment(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                               QueryCounters* counters = nullptr) const noexcept override {
    ++segment_calls;
    QueryCounters local;
    const SurfaceHit hit = inner_.first_hit_segment(from, to, &local);
    add(local, counters);
    return hit;
  }
  SurfaceHit first_hit_ray(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, double max_distance_m,
                           QueryCounters* counters = nullptr) const noexcept override {
    ++ray_calls;
    QueryCounters local;
    const SurfaceHit hit = inner_.first_hit_ray(origin, direction, max_distance_m, &local);
    add(local, counters);
    return hit;
  }
  ClosestSurfacePoint closest_point(const Eigen::Vector3d& x, QueryCounters* counters = nullptr) const noexcept override {
    ++closest_calls;
    QueryCounters local;
    const ClosestSurfacePoint closest = inner_.closest_point(x, &local);
    add(local, counters);
    return closest;
  }
  bool contains(const Eigen::Vector3d& x, QueryCounters* counters = nullptr) const noexcept override {
    ++contains_calls;
    QueryCounters local;
    const bool inside = inner_.contains(x, &local);
    add(local, counters);
    return inside;
  }

  long long calls() const { return segment_calls + ray_calls + closest_calls + contains_calls; }

  mutable long long segment_calls = 0, ray_calls = 0, closest_calls = 0, contains_calls = 0;
  mutable QueryCounters work;  ///< box and triangle tests of every call

 private:
  void add(const QueryCounters& local, QueryCounters* counters) const noexcept {
    for (QueryCounters* target : {&work, counters}) {
      if (target == nullptr) continue;
      target->box_tests += local.box_tests;
      target->triangle_tests += local.triangle_tests;
      target->queries += local.queries;
    }
  }

  const SurfaceQueries& inner_;
};

}  // namespace touchstone::realtime::collision::testing
