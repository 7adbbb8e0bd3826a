// The bounding-volume hierarchy's queries: first hit of a segment or ray, closest point and
// inside/outside, each a traversal of the nodes bounding_volume_hierarchy.cpp builds, counting
// its box and triangle tests (the paper's Table 1). One file: the traversals share the box
// tests (double, and float for AABB nodes), the watertight triangle test and the counting.
#include "touchstone/realtime/collision/bounding_volume_hierarchy.hpp"

#include "touchstone/geometry/closest_point_on_triangle.hpp"

#include <Eigen/Geometry>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <vector>

namespace touchstone::realtime::collision {

namespace {

using Eigen::Vector3d;

constexpr double infinity = std::numeric_limits<double>::infinity();

// Traversal stacks are fixed arrays: the build keeps every binary tree within 57 levels, and a
// traversal stacks at most width − 1 children per level: 57 for a binary tree, 3 · 29 for a
// 4-wide one.
constexpr int max_stack = 96;
// contains(): a crossing closer to the query point than this fraction of the diagonal is "on
// the surface" for the parity test, which then defers to the pseudo-normal sign.
constexpr double relative_surface_tolerance = 1e-9;

using geometry::closest_on_triangle;
using geometry::face_feature;

/// A ray (or segment) origin + t·direction prepared for the watertight ray–triangle test of
/// Woop, Benthin & Wald (JCGT 2013): the coordinates are permuted so that z is the dominant
/// direction component and sheared so that the ray becomes the z axis. In that frame the
/// 2-D edge functions of a shared edge are computed from the same numbers in both triangles,
/// so they are exact negatives of each other and no ray slips between two triangles.
/// (Needs the compiler not to contract a·b − c·d into a fused multiply-add differently in
/// different places: ISO C++ mode without -ffp-contract=fast, as this project builds.)
struct WatertightRay {
  Vector3d origin;
  Vector3d direction;
  // The sheared frame as three rows: x' = shear_x·p, y' = shear_y·p, z' = shear_z·p for p
  // relative to the origin. Each row has one entry 1 (or 1/d_kz) and one −S or zero; the others
  // are exact zeros, so a dot product computes exactly Woop's p_kx − S_x p_kz for every vertex,
  // whichever triangle it belongs to.
  Vector3d shear_x, shear_y, shear_z;
  int kx = 0, ky = 1, kz = 2;  // the permutation: kz the dominant direction component

  WatertightRay(const Vector3d& origin_in, const Vector3d& direction_in) noexcept
      : origin(origin_in), direction(direction_in) {
    direction.cwiseAbs().maxCoeff(&kz);
    kx = (kz + 1) % 3;
    ky = (kx + 1) % 3;
    // Keep the winding of the projected triangles when the dominant component is negative.
    if (direction[kz] < 0) std::swap(kx, ky);
    shear_x = Vector3d::Zero();
    shear_y = Vector3d::Zero();
    shear_z = Vector3d::Zero();
    shear_x[kx] = 1;
    shear_x[kz] = -direction[kx] / direction[kz];
    shear_y[ky] = 1;
    shear_y[kz] = -direction[ky] / direction[kz];
    shear_z[kz] = 1 / direction[kz];
  }
};

/// Where a ray meets a triangle's plane inside the triangle (either side): t (in units of the
/// ray's direction) and whether the ray passed exactly through an edge or a vertex (some edge
/// function zero) — a hit then, so that nothing leaks, but possibly counted twice by parity.
/// `in_plane`: the ray lies in the triangle's plane and touches it — no hit (its neighbours
/// report the crossing), but a parity count cannot trust that ray.
struct Crossing {
  double t = 0;
  bool on_edge = false;
  bool in_plane = false;
};

inline bool intersect(const WatertightRay& ray, const Vector3d& a, const Vector3d& b, const Vector3d& c,
                      Crossing& crossing) noexcept {
  const Vector3d pa = a - ray.origin;
  const Vector3d pb = b - ray.origin;
  const Vector3d pc = c - ray.origin;
  const double ax = ray.shear_x.dot(pa), ay = ray.shear_y.dot(pa);
  const double bx = ray.shear_x.dot(pb), by = ray.shear_y.dot(pb);
  const double cx = ray.shear_x.dot(pc), cy = ray.shear_y.dot(pc);
  // Scaled barycentric coordinates: the signed areas seen from the ray.
  const double u = cx * by - cy * bx;
  const double v = ax * cy - ay * cx;
  const double w = bx * ay - by * ax;
  if ((u < 0 || v < 0 || w < 0) && (u > 0 || v > 0 || w > 0)) return false;
  const double determinant = u + v + w;
  crossing.on_edge = u == 0 || v == 0 || w == 0;
  if (determinant == 0) {
    crossing.in_plane = true;
    return false;
  }
  const double scaled_t = u * ray.shear_z.dot(pa) + v * ray.shear_z.dot(pb) + w * ray.shear_z.dot(pc);
  crossing.t = scaled_t / determinant;
  return true;
}

/// A WatertightRay in float, for the conservative pre-test of a leaf's triangles
/// (leaf_candidates): coordinates relative to the tree's float origin.
struct FloatRay {
  bool usable = false;  // false: every triangle goes to the double test
  int kx = 0, ky = 1, kz = 2;
  float origin[3] = {0, 0, 0};  // origin − float origin, in float [m]
  float shear_x = 0, shear_y = 0;  // d_kx / d_kz and d_ky / d_kz, each in [−1, 1]
  float error = 0;  // bound on the error of every sheared corner coordinate [m]

  /// `extent`: max |corner − float_origin|∞ over the surface [m].
  FloatRay(const WatertightRay& ray, const Vector3d& float_origin, double extent) noexcept
      : kx(ray.kx), ky(ray.ky), kz(ray.kz) {
    const Vector3d relative = ray.origin - float_origin;
    // M bounds every |coordinate| the float test subtracts: corner and origin, relative.
    const double bound = std::max(extent, relative.cwiseAbs().maxCoeff());
    // Beyond 1e15 m a product of coordinates could overflow float (the double test decides).
    if (!(bound < 1e15)) return;
    usable = true;
    for (int axis = 0; axis < 3; ++axis) origin[axis] = static_cast<float>(relative[axis]);
    shear_x = static_cast<float>(ray.direction[kx] / ray.direction[kz]);
    shear_y = static_cast<float>(ray.direction[ky] / ray.direction[kz]);
    // With ε = 2⁻²⁴ float's unit roundoff and M = bound: the stored corner and the origin are
    // each within ε·M of their double values, their difference p within 4ε·M of the exact one,
    // and a sheared coordinate p_kx − S·p_kz (|S| ≤ 1, S rounded too) within 16ε·M; twice that
    // covers the double test's own rounding.
    error = static_cast<float>(32 * std::ldexp(1.0, -24) * bound);
  }
};

#if defined(__SSE2__)
/// Which of (up to) four triangles of a leaf the segment's line may pass through: bit i clear
/// only when the float edge functions prove that the double test of intersect() rejects
/// triangle i. `rows`: the leaf's float rows (BoundingVolumeHierarchy::leaf_corners_) at the
/// first of the four, `stride`: the leaf's triangle count; `valid`: the lanes that hold one.
///
/// Why it is conservative: each sheared coordinate x̃ is within D (FloatRay::error) of the value
/// the double test computes, and |x̃| ≤ X; with X' = X + D an edge function u = c_x b_y − c_y b_x
/// is then within 4X'D + 4.1ε·X'² (ε = 2⁻²⁴; its two products and the subtraction rounded in
/// float) of the double test's, so η = 5X'(D + ε·X') bounds the difference with room for η's
/// own rounding. A triangle is rejected only when one edge function is below −η and another above
/// η: the double test then sees one negative and one positive, and rejects it too.
inline int leaf_candidates(const float* rows, int stride, int valid, const FloatRay& ray) noexcept {
  const auto load = [&](int corner, int axis) { return _mm_loadu_ps(rows + (3 * corner + axis) * stride); };
  const __m128 sign = _mm_set1_ps(-0.0f);
  const __m128 error = _mm_set1_ps(ray.error);
  const __m128 shear_x = _mm_set1_ps(ray.shear_x), shear_y = _mm_set1_ps(ray.shear_y);
  const __m128 origin_x = _mm_set1_ps(ray.origin[ray.kx]), origin_y = _mm_set1_ps(ray.origin[ray.ky]),
               origin_z = _mm_set1_ps(ray.origin[ray.kz]);
  __m128 x[3], y[3];
  __m128 largest = _mm_setzero_ps();
  for (int k = 0; k < 3; ++k) {
    const __m128 z = _mm_sub_ps(load(k, ray.kz), origin_z);
    x[k] = _mm_sub_ps(_mm_sub_ps(load(k, ray.kx), origin_x), _mm_mul_ps(shear_x, z));
    y[k] = _mm_sub_ps(_mm_sub_ps(load(k, ray.ky), origin_y), _mm_mul_ps(shear_y, z));
    largest = _mm_max_ps(largest, _mm_max_ps(_mm_andnot_ps(sign, x[k]), _mm_andnot_ps(sign, y[k])));
  }
  const __m128 u = _mm_sub_ps(_mm_mul_ps(x[2], y[1]), _mm_mul_ps(y[2], x[1]));
  const __m128 v = _mm_sub_ps(_mm_mul_ps(x[0], y[2]), _mm_mul_ps(y[0], x[2]));
  const __m128 w = _mm_sub_ps(_mm_mul_ps(x[1], y[0]), _mm_mul_ps(y[1], x[0]));
  const __m128 widened = _mm_add_ps(largest, error);
  const __m128 eta = _mm_mul_ps(_mm_mul_ps(_mm_set1_ps(5.0f), widened),
                                _mm_add_ps(error, _mm_mul_ps(_mm_set1_ps(0x1p-24f), widened)));
  const __m128 negative = _mm_cmplt_ps(_mm_min_ps(u, _mm_min_ps(v, w)), _mm_sub_ps(_mm_setzero_ps(), eta));
  const __m128 positive = _mm_cmpgt_ps(_mm_max_ps(u, _mm_max_ps(v, w)), eta);
  return valid & ~_mm_movemask_ps(_mm_and_ps(negative, positive));
}
#else
inline int leaf_candidates(const float*, int, int valid, const FloatRay&) noexcept { return valid; }
#endif

/// Work done by one query, added to the caller's counters at the end (local counts avoid
/// stores through a pointer in the loop, and vanish when `count` is false).
struct Tally {
  long long boxes = 0;
  long long triangles = 0;
};

template <bool count>
inline void report(QueryCounters* counters, const Tally& tally) noexcept {
  if constexpr (count) {
    counters->box_tests += tally.boxes;
    counters->triangle_tests += tally.triangles;
    ++counters->queries;
  } else {
    (void)counters;
    (void)tally;
  }
}

/// Fixed, irrational-looking unit directions for the parity rays: a mesh built on a grid or
/// with symmetry is unlikely to have edges exactly along them.
const std::array<Vector3d, 4>& parity_directions() {
  static const std::array<Vector3d, 4> directions = {
      Vector3d(0.5366563145999495, 0.6549300393463394, 0.5321858898237543).normalized(),
      Vector3d(-0.7071790128412461, 0.3141592653589793, 0.6333371924213391).normalized(),
      Vector3d(0.2718281828459045, -0.8660254037844386, 0.4195498771298743).normalized(),
      Vector3d(-0.3819660112501051, -0.4142135623730950, -0.8263898763381267).normalized(),
  };
  return directions;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Queries.

struct BoundingVolumeHierarchy::Traversal {
  /// Bit k set when lane k holds a child whose box the segment m ± h meets: the separating-axis
  /// test of segment_overlaps_centred_box, lane by lane (plain loops over the lanes, which the
  /// compiler turns into packed instructions), as the largest (|projection| − radius) over the
  /// six axes being ≤ 0; fl(a − b) > 0 exactly when a > b, so this is the same test. NaN, only
  /// from overflowing coordinates, counts as separated.
  template <class Node>
  static inline int overlap_mask(const Node& node, const Vector3d& m, const Vector3d& h) noexcept {
    constexpr int width = Node::width;
    double separation[width];
    for (int k = 0; k < width; ++k) {
      const double mx = m.x() - node.center[0][k];
      const double my = m.y() - node.center[1][k];
      const double mz = m.z() - node.center[2][k];
      double lx = mx, ly = my, lz = mz, hx = h.x(), hy = h.y(), hz = h.z();
      if constexpr (Node::oriented) {
        const auto& r = node.axes;
        lx = r[0][k] * mx + r[1][k] * my + r[2][k] * mz;
        ly = r[3][k] * mx + r[4][k] * my + r[5][k] * mz;
        lz = r[6][k] * mx + r[7][k] * my + r[8][k] * mz;
        hx = r[0][k] * h.x() + r[1][k] * h.y() + r[2][k] * h.z();
        hy = r[3][k] * h.x() + r[4][k] * h.y() + r[5][k] * h.z();
        hz = r[6][k] * h.x() + r[7][k] * h.y() + r[8][k] * h.z();
      }
      const double ax = std::abs(hx), ay = std::abs(hy), az = std::abs(hz);
      const double ex = node.half_extents[0][k], ey = node.half_extents[1][k], ez = node.half_extents[2][k];
      double worst = std::abs(lx) - (ex + ax);
      worst = std::max(worst, std::abs(ly) - (ey + ay));
      worst = std::max(worst, std::abs(lz) - (ez + az));
      worst = std::max(worst, std::abs(ly * hz - lz * hy) - (ey * az + ez * ay));
      worst = std::max(worst, std::abs(lz * hx - lx * hz) - (ex * az + ez * ax));
      worst = std::max(worst, std::abs(lx * hy - ly * hx) - (ex * ay + ey * ax));
      separation[k] = worst;
    }
    int mask = 0;
    for (int k = 0; k < width; ++k) mask |= (separation[k] <= 0 ? 1 : 0) << k;
    return mask & node.lanes;
  }

  /// The segment m ± h of overlap_mask_float, in float, with its pad [m].
  struct FloatSegment {
    float m0, m1, m2, hx, hy, hz, ax, ay, az, pad;
  };
  static FloatSegment float_segment(const Vector3d& m, const Vector3d& h, double pad) noexcept {
    FloatSegment s;
    s.m0 = static_cast<float>(m.x());
    s.m1 = static_cast<float>(m.y());
    s.m2 = static_cast<float>(m.z());
    s.hx = static_cast<float>(h.x());
    s.hy = static_cast<float>(h.y());
    s.hz = static_cast<float>(h.z());
    s.ax = std::abs(s.hx);
    s.ay = std::abs(s.hy);
    s.az = std::abs(s.hz);
    s.pad = static_cast<float>(pad);
    return s;
  }
  /// The pad for the segment m ± h and for every part of it that a hit shortens it to (whose
  /// |m|∞ + |h|∞ is at most |m|∞ + 2|h|∞) [m].
  static double float_pad(const Vector3d& m, const Vector3d& h, double bound) noexcept {
    const double magnitude = m.cwiseAbs().maxCoeff() + 2 * h.cwiseAbs().maxCoeff() + bound;
    // −1: too large for float (the double test is taken).
    return magnitude < 1e15 ? 8 * std::numeric_limits<float>::epsilon() * magnitude : -1;
  }

#if defined(__SSE2__)
  /// Whether a node type takes overlap_mask_float: float boxes, four lanes (one SSE register).
  template <class Node>
  static constexpr bool float_test = std::is_same_v<typename Node::Scalar, float> && Node::width == 4;

  /// overlap_mask for 4-wide nodes of float boxes, computed in float with SSE: four lanes per
  /// instruction instead of two, and no conversion. Every box is widened by
  /// pad = 8 ε_f (|m|∞ + 2|h|∞ + bound), bound ≥ |c|∞ + e of every box: each float rounding
  /// (of m and h, of the differences, products and sums) errs by at most ε_f times a quantity
  /// below that sum, so the padded test passes every box the exact test passes (pad ≈ 5e-8 m
  /// at a 10 cm organ: no measurable extra tests). Below 1e15 m no float product overflows
  /// (so nothing is NaN); beyond, the double test is taken.
  template <class Node>
  static inline int overlap_mask_float(const Node& node, const FloatSegment& s) noexcept {
    static_assert(float_test<Node>);
    const __m128 sign = _mm_set1_ps(-0.0f);
    const auto abs = [&](__m128 v) { return _mm_andnot_ps(sign, v); };
    const __m128 pad = _mm_set1_ps(s.pad);
    const __m128 hx = _mm_set1_ps(s.hx), hy = _mm_set1_ps(s.hy), hz = _mm_set1_ps(s.hz);
    const __m128 ax = _mm_set1_ps(s.ax), ay = _mm_set1_ps(s.ay), az = _mm_set1_ps(s.az);
    const __m128 lx = _mm_sub_ps(_mm_set1_ps(s.m0), _mm_load_ps(node.center[0]));
    const __m128 ly = _mm_sub_ps(_mm_set1_ps(s.m1), _mm_load_ps(node.center[1]));
    const __m128 lz = _mm_sub_ps(_mm_set1_ps(s.m2), _mm_load_ps(node.center[2]));
    const __m128 ex = _mm_add_ps(_mm_load_ps(node.half_extents[0]), pad);
    const __m128 ey = _mm_add_ps(_mm_load_ps(node.half_extents[1]), pad);
    const __m128 ez = _mm_add_ps(_mm_load_ps(node.half_extents[2]), pad);
    __m128 worst = _mm_sub_ps(abs(lx), _mm_add_ps(ex, ax));
    worst = _mm_max_ps(worst, _mm_sub_ps(abs(ly), _mm_add_ps(ey, ay)));
    worst = _mm_max_ps(worst, _mm_sub_ps(abs(lz), _mm_add_ps(ez, az)));
    worst = _mm_max_ps(worst, _mm_sub_ps(abs(_mm_sub_ps(_mm_mul_ps(ly, hz), _mm_mul_ps(lz, hy))),
                                         _mm_add_ps(_mm_mul_ps(ey, az), _mm_mul_ps(ez, ay))));
    worst = _mm_max_ps(worst, _mm_sub_ps(abs(_mm_sub_ps(_mm_mul_ps(lz, hx), _mm_mul_ps(lx, hz))),
                                         _mm_add_ps(_mm_mul_ps(ex, az), _mm_mul_ps(ez, ax))));
    worst = _mm_max_ps(worst, _mm_sub_ps(abs(_mm_sub_ps(_mm_mul_ps(lx, hy), _mm_mul_ps(ly, hx))),
                                         _mm_add_ps(_mm_mul_ps(ex, ay), _mm_mul_ps(ey, ax))));
    return _mm_movemask_ps(_mm_cmple_ps(worst, _mm_setzero_ps())) & node.lanes;
  }
#else
  template <class Node>
  static constexpr bool float_test = false;
#endif

  /// Squared distances from x to the lanes' boxes [m²].
  template <class Node>
  static inline void squared_distances(const Node& node, const Vector3d& x, double (&distance)[Node::width]) noexcept {
    for (int k = 0; k < Node::width; ++k) {
      const double mx = x.x() - node.center[0][k];
      const double my = x.y() - node.center[1][k];
      const double mz = x.z() - node.center[2][k];
      double lx = mx, ly = my, lz = mz;
      if constexpr (Node::oriented) {
        const auto& r = node.axes;
        lx = r[0][k] * mx + r[1][k] * my + r[2][k] * mz;
        ly = r[3][k] * mx + r[4][k] * my + r[5][k] * mz;
        lz = r[6][k] * mx + r[7][k] * my + r[8][k] * mz;
      }
      const double dx = std::max(std::abs(lx) - node.half_extents[0][k], 0.0);
      const double dy = std::max(std::abs(ly) - node.half_extents[1][k], 0.0);
      const double dz = std::max(std::abs(lz) - node.half_extents[2][k], 0.0);
      distance[k] = dx * dx + dy * dy + dz * dz;
    }
  }

  /// Starts loading the inner children's nodes while this node's boxes are tested: the next
  /// node is one of them, and its address does not depend on the test.
  template <class Node>
  static void prefetch_children(const std::vector<Node>& all, const Node& node) noexcept {
    for (int k = 0; k < Node::width; ++k) {
      if ((node.lanes >> k & 1) == 0 || node.count[k] != 0) continue;
      const char* address = reinterpret_cast<const char*>(&all[node.child[k]]);
      for (std::size_t line = 0; line < sizeof(Node); line += 64) __builtin_prefetch(address + line);
    }
  }

  /// The lanes in the order a query running along `direction` meets them: of two sibling
  /// children (lanes 2g, 2g + 1) the one whose centre comes first, and for W = 4 first the
  /// pair whose centres come first.
  template <class Node>
  static inline void visiting_order(const Node& node, const Vector3d& direction, int (&order)[Node::width]) noexcept {
    const auto along = [&](int from, int to) {
      return (node.center[0][to] - node.center[0][from]) * direction.x() +
             (node.center[1][to] - node.center[1][from]) * direction.y() +
             (node.center[2][to] - node.center[2][from]) * direction.z();
    };
    if constexpr (Node::width == 2) {
      const int first = along(0, 1) >= 0 ? 0 : 1;
      order[0] = first;
      order[1] = 1 - first;
    } else {
      const double pairs = (node.center[0][2] + node.center[0][3] - node.center[0][0] - node.center[0][1]) * direction.x() +
                           (node.center[1][2] + node.center[1][3] - node.center[1][0] - node.center[1][1]) * direction.y() +
                           (node.center[2][2] + node.center[2][3] - node.center[2][0] - node.center[2][1]) * direction.z();
      const int near = pairs >= 0 ? 0 : 2;
      const int far = 2 - near;
      const int near_first = along(near, near + 1) >= 0 ? 0 : 1;
      const int far_first = along(far, far + 1) >= 0 ? 0 : 1;
      order[0] = near + near_first;
      order[1] = near + 1 - near_first;
      order[2] = far + far_first;
      order[3] = far + 1 - far_first;
    }
  }

  /// Calls f with the tree's node vector (its type decides the traversal's instantiation).
  template <class F>
  static decltype(auto) with_nodes(const BoundingVolumeHierarchy& bvh, F&& f) noexcept {
    const bool binary_width = bvh.settings_.children_per_node == 2;
    if (bvh.settings_.bounding_volume == BoundingVolume::obb) {
      return binary_width ? f(bvh.obb2_) : f(bvh.obb4_);
    }
    return binary_width ? f(bvh.aabb2_) : f(bvh.aabb4_);
  }

  /// The nearest hit so far: the segment the boxes are tested against ends there.
  struct Nearest {
    double t;
    int slot = -1;
    Vector3d middle, half;
  };

  /// The float form of a ray for the leaves' float test (unusable when the settings turn it off).
  static FloatRay leaf_ray(const BoundingVolumeHierarchy& bvh, const WatertightRay& ray) noexcept {
    FloatRay float_ray(ray, bvh.leaf_corners_origin_, bvh.leaf_corners_extent_);
    float_ray.usable = float_ray.usable && bvh.settings_.float_leaf_test;
    return float_ray;
  }

  /// Calls visit(slot) in slot order for the triangles of the leaf [first, first + size) that the
  /// float test (leaf_candidates, four at a time) cannot set aside, until visit returns true;
  /// returns whether it did. The others are those the double test would reject.
  template <class Visit>
  static bool visit_leaf_candidates(const BoundingVolumeHierarchy& bvh, int first, int size,
                                    const FloatRay& float_ray, Visit&& visit) noexcept {
    const float* rows = bvh.leaf_corners_.data() + 9 * static_cast<std::size_t>(first);
    for (int chunk = 0; chunk < size; chunk += 4) {
      const int valid = (1 << std::min(4, size - chunk)) - 1;
      int candidates = float_ray.usable ? leaf_candidates(rows + chunk, size, valid, float_ray) : valid;
      while (candidates != 0) {
        const int slot = first + chunk + __builtin_ctz(static_cast<unsigned>(candidates));
        candidates &= candidates - 1;
        if (visit(slot)) return true;
      }
    }
    return false;
  }

  /// Tests a leaf's triangles: float first, then the double test. Every triangle counts as tested.
  template <bool count>
  static void hit_leaf(const BoundingVolumeHierarchy& bvh, int first, int size, const WatertightRay& ray,
                       const FloatRay& float_ray, Nearest& nearest, Tally& tally) noexcept {
    if constexpr (count) tally.triangles += size;
    const Vector3d* corners = bvh.corners_.data();
    visit_leaf_candidates(bvh, first, size, float_ray, [&](int slot) {
      Crossing crossing;
      if (!intersect(ray, corners[3 * slot], corners[3 * slot + 1], corners[3 * slot + 2], crossing)) return false;
      // The end of the segment is inclusive until a hit; then only strictly nearer hits count.
      if (crossing.t >= 0 && (crossing.t < nearest.t || (nearest.slot < 0 && crossing.t == nearest.t))) {
        nearest.t = crossing.t;
        nearest.slot = slot;
        nearest.half = (0.5 * crossing.t) * ray.direction;
        nearest.middle = ray.origin + nearest.half;
      }
      return false;
    });
  }

  /// First hit of origin + t·direction for 0 ≤ t ≤ t_end: all children of an entered node are
  /// tested at once, leaves among them at once, the nearest inner child entered next and the
  /// others stacked (nearer on top); every hit shortens the segment later boxes are tested
  /// against, which prunes every box beyond it.
  template <class Node, bool count>
  static Nearest first_hit(const BoundingVolumeHierarchy& bvh, const std::vector<Node>& all, const WatertightRay& ray,
                           const FloatRay& float_ray, double t_end, Tally& tally) noexcept {
    constexpr int width = Node::width;
    Nearest nearest;
    nearest.t = t_end;
    nearest.half = (0.5 * t_end) * ray.direction;
    nearest.middle = ray.origin + nearest.half;
    int index = 0;
    const Node* cover = nullptr;  // the first node, when the entry grid starts at a cover node
    const EntryGrid& grid = bvh.grid_;
    if (grid.cell_m > 0 && 2 * nearest.half.cwiseAbs().maxCoeff() <= grid.reach_m) {
      // A short move: start below the root, at the entry of the start's cell.
      const Vector3d cell = (ray.origin - grid.origin) / grid.cell_m;
      if (!(cell.minCoeff() >= 0 && cell.x() < grid.dims.x() && cell.y() < grid.dims.y() && cell.z() < grid.dims.z())) {
        return nearest;
      }
      index = grid.entry[static_cast<std::int64_t>(cell.x()) +
                         grid.dims.x() * (static_cast<std::int64_t>(cell.y()) +
                                          grid.dims.y() * static_cast<std::int64_t>(cell.z()))];
      if (index == -1) return nearest;
      if (index < -1) cover = &cover_nodes<Node>(grid)[-2 - index];
    } else {
      if constexpr (count) ++tally.boxes;
      if (!segment_overlaps(bvh.root_box_, nearest.middle, nearest.half)) return nearest;
      if (all.empty()) {
        hit_leaf<count>(bvh, 0, static_cast<int>(bvh.slot_triangle_.size()), ray, float_ray, nearest, tally);
        return nearest;
      }
    }
    // Every box lies in the root box (AABB trees), which bounds |c|∞ + e for the float test.
    [[maybe_unused]] const double pad =
        float_pad(nearest.middle, nearest.half,
                  (bvh.root_box_.center.cwiseAbs() + bvh.root_box_.half_extents).maxCoeff());
    [[maybe_unused]] double shortened = -1;  // nearest.t when segment_float was made
    [[maybe_unused]] FloatSegment segment_float{};
    std::array<int, max_stack> stack;
    int size = 0;
    for (;;) {
      const Node& node = cover != nullptr ? *cover : all[index];
      cover = nullptr;
      if constexpr (count) tally.boxes += __builtin_popcount(static_cast<unsigned>(node.lanes));
      prefetch_children(all, node);
      int mask = 0;
      if constexpr (float_test<Node>) {
        if (pad >= 0) {
          if (shortened != nearest.t) {
            segment_float = float_segment(nearest.middle, nearest.half, pad);
            shortened = nearest.t;
          }
          mask = overlap_mask_float(node, segment_float);
        } else {
          mask = overlap_mask(node, nearest.middle, nearest.half);
        }
      } else {
        mask = overlap_mask(node, nearest.middle, nearest.half);
      }
      int next = -1;
      if (mask != 0 && (mask & (mask - 1)) == 0) {
        // One box met (the common case on a path to the surface): no ordering needed.
        const int k = __builtin_ctz(static_cast<unsigned>(mask));
        if (node.count[k] > 0) {
          hit_leaf<count>(bvh, node.child[k], node.count[k], ray, float_ray, nearest, tally);
        } else {
          next = node.child[k];
        }
      } else if (mask != 0) {
        int order[width];
        visiting_order(node, ray.direction, order);
        int inner[width];
        int inner_count = 0;
        for (int step = 0; step < width; ++step) {
          const int k = order[step];
          if ((mask >> k & 1) == 0) continue;
          if (node.count[k] > 0) {
            hit_leaf<count>(bvh, node.child[k], node.count[k], ray, float_ray, nearest, tally);
          } else {
            inner[inner_count++] = node.child[k];
          }
        }
        if (inner_count > 0) {
          next = inner[0];
          for (int i = inner_count - 1; i > 0; --i) stack[size++] = inner[i];
        }
      }
      if (next >= 0) {
        index = next;
        continue;
      }
      if (size == 0) break;
      index = stack[--size];
    }
    return nearest;
  }

  template <bool count>
  static SurfaceHit segment(const BoundingVolumeHierarchy& bvh, const Vector3d& origin, const Vector3d& direction,
                            double t_end, double metres_per_t, QueryCounters* counters) noexcept {
    Tally tally;
    const WatertightRay ray(origin, direction);
    const FloatRay float_ray = leaf_ray(bvh, ray);
    const Nearest nearest = with_nodes(bvh, [&](const auto& all) {
      return first_hit<typename std::decay_t<decltype(all)>::value_type, count>(bvh, all, ray, float_ray, t_end, tally);
    });
    SurfaceHit hit;
    if (nearest.slot >= 0) {
      hit.hit = true;
      hit.distance_m = nearest.t * metres_per_t;
      hit.point = origin + nearest.t * direction;
      hit.normal = bvh.face_normals_[nearest.slot];
      hit.triangle = bvh.slot_triangle_[nearest.slot];
    }
    report<count>(counters, tally);
    return hit;
  }

  /// Closest point: slot, feature, point and squared distance.
  struct Closest {
    int slot = -1;
    int feature = face_feature;
    Vector3d point = Vector3d::Zero();
    double squared_distance = infinity;
  };

  template <bool count>
  static void closest_in_leaf(const BoundingVolumeHierarchy& bvh, int first, int size, const Vector3d& x,
                              Closest& best, Tally& tally) noexcept {
    const Vector3d* corners = bvh.corners_.data();
    for (int slot = first; slot < first + size; ++slot) {
      if constexpr (count) ++tally.triangles;
      // The distance to the triangle's plane is a lower bound that costs one dot product.
      const double height = (x - corners[3 * slot]).dot(bvh.face_normals_[slot]);
      if (height * height > best.squared_distance) continue;
      int feature = face_feature;
      const Vector3d point =
          closest_on_triangle(x, corners[3 * slot], corners[3 * slot + 1], corners[3 * slot + 2], feature);
      const double distance = (point - x).squaredNorm();
      // `best.slot < 0`: accept a first candidate even when squared distances overflow to +∞.
      if (distance < best.squared_distance || best.slot < 0) {
        best.squared_distance = distance;
        best.slot = slot;
        best.feature = feature;
        best.point = point;
      }
    }
  }

  /// Children nearest first; a child farther than the best distance so far is skipped, a
  /// stacked subtree that has fallen out of reach is dropped without a test. The comparisons
  /// are strict so that the search proceeds while `best` is still +∞.
  template <class Node, bool count>
  static Closest closest(const BoundingVolumeHierarchy& bvh, const std::vector<Node>& all, const Vector3d& x,
                         Tally& tally) noexcept {
    constexpr int width = Node::width;
    Closest best;
    if (all.empty()) {
      closest_in_leaf<count>(bvh, 0, static_cast<int>(bvh.slot_triangle_.size()), x, best, tally);
      return best;
    }
    std::array<std::pair<int, double>, max_stack> stack;
    int size = 0;
    int index = 0;
    for (;;) {
      const Node& node = all[index];
      if constexpr (count) tally.boxes += __builtin_popcount(static_cast<unsigned>(node.lanes));
      prefetch_children(all, node);
      double distance[width];
      squared_distances(node, x, distance);
      // The lanes within reach, sorted by distance (insertion sort of at most 4).
      int order[width];
      int within = 0;
      for (int k = 0; k < width; ++k) {
        if ((node.lanes >> k & 1) == 0 || distance[k] > best.squared_distance) continue;
        int i = within++;
        for (; i > 0 && distance[order[i - 1]] > distance[k]; --i) order[i] = order[i - 1];
        order[i] = k;
      }
      std::pair<int, double> inner[width];
      int inner_count = 0;
      for (int i = 0; i < within; ++i) {
        const int k = order[i];
        if (distance[k] > best.squared_distance) continue;
        if (node.count[k] > 0) {
          closest_in_leaf<count>(bvh, node.child[k], node.count[k], x, best, tally);
        } else {
          inner[inner_count++] = {node.child[k], distance[k]};
        }
      }
      int next = -1;
      if (inner_count > 0) {
        next = inner[0].first;
        for (int i = inner_count - 1; i > 0; --i) stack[size++] = inner[i];
      }
      if (next >= 0) {
        index = next;
        continue;
      }
      while (size > 0 && stack[size - 1].second > best.squared_distance) --size;
      if (size == 0) break;
      index = stack[--size].first;
    }
    return best;
  }

  template <bool count>
  static Closest closest(const BoundingVolumeHierarchy& bvh, const Vector3d& x, Tally& tally) noexcept {
    return with_nodes(bvh, [&](const auto& all) {
      return closest<typename std::decay_t<decltype(all)>::value_type, count>(bvh, all, x, tally);
    });
  }

  enum class Parity { even, odd, on_edge, on_surface };

  /// Crossings of origin + t·direction, surface_t < t ≤ t_end, in one leaf: flips `odd` per
  /// crossing; stops at the first ambiguous one. The float test sets aside only triangles whose
  /// double test fails on the signs, before it could report a ray in their plane.
  template <bool count>
  static Parity parity_in_leaf(const BoundingVolumeHierarchy& bvh, int first, int size, const WatertightRay& ray,
                               const FloatRay& float_ray, double t_end, double surface_t, bool& odd,
                               Tally& tally) noexcept {
    if constexpr (count) tally.triangles += size;
    const Vector3d* corners = bvh.corners_.data();
    Parity result = Parity::even;
    visit_leaf_candidates(bvh, first, size, float_ray, [&](int slot) {
      Crossing crossing;
      if (!intersect(ray, corners[3 * slot], corners[3 * slot + 1], corners[3 * slot + 2], crossing)) {
        if (crossing.in_plane) result = Parity::on_edge;
        return crossing.in_plane;
      }
      if (std::abs(crossing.t) <= surface_t) {
        result = Parity::on_surface;
        return true;
      }
      if (crossing.t < 0 || crossing.t > t_end) return false;
      if (crossing.on_edge) {
        result = Parity::on_edge;
        return true;
      }
      odd = !odd;
      return false;
    });
    return result;
  }

  /// Crossings of the whole segment, mod 2 (no ordering or pruning: every crossing counts).
  template <class Node, bool count>
  static Parity parity(const BoundingVolumeHierarchy& bvh, const std::vector<Node>& all, const WatertightRay& ray,
                       const FloatRay& float_ray, double t_end, double surface_t, Tally& tally) noexcept {
    constexpr int width = Node::width;
    bool odd = false;
    if (all.empty()) {
      const Parity result =
          parity_in_leaf<count>(bvh, 0, static_cast<int>(bvh.slot_triangle_.size()), ray, float_ray, t_end, surface_t,
                                odd, tally);
      if (result != Parity::even) return result;
      return odd ? Parity::odd : Parity::even;
    }
    const Vector3d half = (0.5 * t_end) * ray.direction;
    const Vector3d middle = ray.origin + half;
    std::array<int, max_stack> stack;
    int size = 0;
    int index = 0;
    for (;;) {
      const Node& node = all[index];
      if constexpr (count) tally.boxes += __builtin_popcount(static_cast<unsigned>(node.lanes));
      const int mask = overlap_mask(node, middle, half);
      int next = -1;
      for (int k = 0; k < width; ++k) {
        if ((mask >> k & 1) == 0) continue;
        if (node.count[k] > 0) {
          const Parity result =
              parity_in_leaf<count>(bvh, node.child[k], node.count[k], ray, float_ray, t_end, surface_t, odd, tally);
          if (result != Parity::even) return result;
        } else if (next < 0) {
          next = node.child[k];
        } else {
          stack[size++] = node.child[k];
        }
      }
      if (next >= 0) {
        index = next;
        continue;
      }
      if (size == 0) break;
      index = stack[--size];
    }
    return odd ? Parity::odd : Parity::even;
  }

  template <bool count>
  static bool contains(const BoundingVolumeHierarchy& bvh, const Vector3d& x, QueryCounters* counters) noexcept {
    Tally tally;
    const bool inside = contains_impl<count>(bvh, x, tally);
    report<count>(counters, tally);
    return inside;
  }

  template <bool count>
  static bool contains_impl(const BoundingVolumeHierarchy& bvh, const Vector3d& x, Tally& tally) noexcept {
    if (!x.allFinite()) return false;
    const OrientedBox& root = bvh.root_box_;
    if constexpr (count) ++tally.boxes;
    const Vector3d local = root.to_local(x);
    if ((local.cwiseAbs() - root.half_extents).maxCoeff() > 0) return false;
    const double surface_t = relative_surface_tolerance * 2 * root.half_extents.norm();
    for (const Vector3d& direction : parity_directions()) {
      // To where the ray leaves the root box (x is inside it).
      const Vector3d local_direction = root.axes * direction;
      double t_end = infinity;
      for (int i = 0; i < 3; ++i) {
        if (local_direction[i] == 0) continue;
        const double face = local_direction[i] > 0 ? root.half_extents[i] : -root.half_extents[i];
        t_end = std::min(t_end, (face - local[i]) / local_direction[i]);
      }
      const WatertightRay ray(x, direction);
      const FloatRay float_ray = leaf_ray(bvh, ray);
      const Parity result = with_nodes(bvh, [&](const auto& all) {
        return parity<typename std::decay_t<decltype(all)>::value_type, count>(bvh, all, ray, float_ray, t_end,
                                                                               surface_t, tally);
      });
      if (result == Parity::odd) return true;
      if (result == Parity::even) return false;
      if (result == Parity::on_surface) break;
    }
    // On or next to the surface (or every ray met an edge): the pseudo-normal sign at the
    // closest point, which is exact there.
    const Closest closest_point = closest<count>(bvh, x, tally);
    if (closest_point.slot < 0 || !(closest_point.squared_distance > 0)) return false;
    const int slot = closest_point.slot;
    return (x - closest_point.point).dot(bvh.pseudo_normal(slot, closest_point.feature)) < 0;
  }
};

SurfaceHit BoundingVolumeHierarchy::first_hit_segment(const Vector3d& from, const Vector3d& to,
                                                      QueryCounters* counters) const noexcept {
  const Vector3d direction = to - from;
  const double length = direction.norm();
  if (!from.allFinite() || !(length > 0) || !std::isfinite(length)) {
    if (counters != nullptr) ++counters->queries;
    return {};
  }
  return counters != nullptr ? Traversal::segment<true>(*this, from, direction, 1, length, counters)
                             : Traversal::segment<false>(*this, from, direction, 1, length, counters);
}

SurfaceHit BoundingVolumeHierarchy::first_hit_ray(const Vector3d& origin, const Vector3d& direction,
                                                  double max_distance_m, QueryCounters* counters) const noexcept {
  const double length = direction.norm();
  if (!origin.allFinite() || !(length > 0) || !std::isfinite(length) || !(max_distance_m >= 0)) {
    if (counters != nullptr) ++counters->queries;
    return {};
  }
  const Vector3d unit = direction / length;
  // Nothing lies farther than this from the origin; the box tests need a finite segment.
  const double reach = (origin - root_box_.center).norm() + 2 * root_box_.half_extents.norm();
  const double t_end = std::min(max_distance_m, reach);
  return counters != nullptr ? Traversal::segment<true>(*this, origin, unit, t_end, 1, counters)
                             : Traversal::segment<false>(*this, origin, unit, t_end, 1, counters);
}

ClosestSurfacePoint BoundingVolumeHierarchy::closest_point(const Vector3d& x, QueryCounters* counters) const noexcept {
  ClosestSurfacePoint result;
  if (!x.allFinite()) {
    result.distance_m = infinity;
    if (counters != nullptr) ++counters->queries;
    return result;
  }
  Tally tally;
  const Traversal::Closest best =
      counters != nullptr ? Traversal::closest<true>(*this, x, tally) : Traversal::closest<false>(*this, x, tally);
  result.point = best.point;
  result.distance_m = std::sqrt(best.squared_distance);
  result.triangle = best.slot >= 0 ? slot_triangle_[best.slot] : -1;
  if (counters != nullptr) report<true>(counters, tally);
  return result;
}

bool BoundingVolumeHierarchy::contains(const Vector3d& x, QueryCounters* counters) const noexcept {
  return counters != nullptr ? Traversal::contains<true>(*this, x, counters)
                             : Traversal::contains<false>(*this, x, counters);
}

}  // namespace touchstone::realtime::collision
