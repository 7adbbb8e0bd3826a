#pragma once
// Splitting a triangle surface along the zero set of a level-set function, shared by the tool
// patch imprint (a cylinder) and the local-ball cut (a sphere).

#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <unordered_map>
#include <vector>

namespace touchstone::meshes::internal {

inline std::uint64_t edge_key(int a, int b) {
  const auto lo = static_cast<std::uint64_t>(std::min(a, b)), hi = static_cast<std::uint64_t>(std::max(a, b));
  return (lo << 32) | hi;
}

/// The surface after the split.
struct LevelSetSplit {
  std::vector<Eigen::Vector3d> vertices;     ///< the input's (some moved onto the zero set), then the new crossing points
  std::vector<Eigen::Vector3i> triangles;    ///< the input's orientation kept
  std::vector<char> inside;                  ///< per triangle: on the negative side
  std::vector<std::size_t> source_triangle;  ///< per triangle: the input triangle it was cut from
  std::vector<char> on_curve;                ///< per vertex: lies on the zero set (moved or new)
  std::size_t snapped_vertex_count = 0;
  std::size_t split_triangle_count = 0;
};

/// Splits the triangles marked `active` along f = 0, f negative inside. LevelSet provides
/// level(x) (a signed distance-like value), onto(x) (x moved onto f = 0) and crossing(p, q) (the
/// exact point of segment p→q on f = 0 when f changes sign along it). Vertices of active
/// triangles closer to f = 0 than snap_fraction × their shortest active edge are first moved onto
/// it, so that splitting makes no slivers. Inactive triangles are copied, marked outside.
template <class LevelSet>
LevelSetSplit split_along_level_set(const std::vector<Eigen::Vector3d>& vertices, const std::vector<Eigen::Vector3i>& triangles,
                                    const std::vector<char>& active, const LevelSet& f, double snap_fraction) {
  LevelSetSplit out;
  out.vertices = vertices;
  out.on_curve.assign(vertices.size(), 0);
  std::vector<double> level(vertices.size());
  for (std::size_t v = 0; v < vertices.size(); ++v) level[v] = f.level(vertices[v]);

  std::vector<double> shortest_edge(vertices.size(), std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    if (!active[i]) continue;
    for (int k = 0; k < 3; ++k) {
      const auto p = static_cast<std::size_t>(triangles[i][k]), q = static_cast<std::size_t>(triangles[i][(k + 1) % 3]);
      const double length = (vertices[p] - vertices[q]).norm();
      shortest_edge[p] = std::min(shortest_edge[p], length);
      shortest_edge[q] = std::min(shortest_edge[q], length);
    }
  }
  for (std::size_t v = 0; v < vertices.size(); ++v) {
    if (!std::isfinite(shortest_edge[v]) || !(std::abs(level[v]) <= snap_fraction * shortest_edge[v])) continue;
    out.vertices[v] = f.onto(vertices[v]);
    level[v] = 0;
    out.on_curve[v] = 1;
    ++out.snapped_vertex_count;
  }

  // One new vertex per crossed edge.
  std::unordered_map<std::uint64_t, int> crossing_vertex;
  const auto crossing = [&](int p, int q) {
    const auto [it, inserted] = crossing_vertex.try_emplace(edge_key(p, q), static_cast<int>(out.vertices.size()));
    if (inserted) {
      out.vertices.push_back(f.crossing(out.vertices[static_cast<std::size_t>(p)], out.vertices[static_cast<std::size_t>(q)]));
      out.on_curve.push_back(1);
    }
    return it->second;
  };
  const auto sign_of = [&](int v) {
    const auto i = static_cast<std::size_t>(v);
    if (out.on_curve[i]) return 0;
    return level[i] < 0 ? -1 : 1;
  };
  const auto add_piece = [&](int p, int q, int r, std::size_t source, bool is_inside) {
    out.triangles.emplace_back(p, q, r);
    out.inside.push_back(is_inside ? 1 : 0);
    out.source_triangle.push_back(source);
  };
  const auto centroid_inside = [&](int p, int q, int r) {
    return f.level((out.vertices[static_cast<std::size_t>(p)] + out.vertices[static_cast<std::size_t>(q)] +
                    out.vertices[static_cast<std::size_t>(r)]) / 3) < 0;
  };

  for (std::size_t i = 0; i < triangles.size(); ++i) {
    const Eigen::Vector3i& t = triangles[i];
    if (!active[i]) {
      add_piece(t[0], t[1], t[2], i, false);
      continue;
    }
    // The triangle's boundary walked in its own orientation, with the crossing points inserted.
    std::array<int, 6> polygon{};
    std::size_t size = 0;
    for (int k = 0; k < 3; ++k) {
      const int p = t[k], q = t[(k + 1) % 3];
      polygon[size++] = p;
      if (sign_of(p) * sign_of(q) < 0) polygon[size++] = crossing(p, q);
    }
    std::array<std::size_t, 6> curve_positions{};
    std::size_t curve_count = 0;
    int sign_sum = 0, negative = 0, positive = 0;
    for (std::size_t k = 0; k < size; ++k) {
      const int s = sign_of(polygon[k]);
      if (s == 0) curve_positions[curve_count++] = k;
      sign_sum += s;
      negative += s < 0 ? 1 : 0;
      positive += s > 0 ? 1 : 0;
    }
    const bool chord = curve_count == 2 && negative > 0 && positive > 0;
    if (!chord) {
      // No chord across the triangle: it lies on one side (touching f = 0 at most along an edge
      // or a corner); with every corner on f = 0 its centroid decides.
      const bool is_inside = sign_sum < 0 || (sign_sum == 0 && negative == 0 && positive == 0 && centroid_inside(t[0], t[1], t[2]));
      add_piece(t[0], t[1], t[2], i, is_inside);
      continue;
    }
    ++out.split_triangle_count;
    // Two sub-polygons (3 or 4 corners, convex) on either side of the chord.
    for (int side = 0; side < 2; ++side) {
      std::array<int, 6> piece{};
      std::size_t corners = 0;
      const std::size_t from = curve_positions[static_cast<std::size_t>(side)], to = curve_positions[static_cast<std::size_t>(1 - side)];
      for (std::size_t k = from;; k = (k + 1) % size) {
        piece[corners++] = polygon[k];
        if (k == to) break;
      }
      const bool is_inside = sign_of(piece[1]) < 0;
      if (corners == 3) {
        add_piece(piece[0], piece[1], piece[2], i, is_inside);
      } else {
        // Split the quadrilateral along its shorter diagonal.
        const auto at = [&](std::size_t k) -> const Eigen::Vector3d& { return out.vertices[static_cast<std::size_t>(piece[k])]; };
        if ((at(0) - at(2)).squaredNorm() <= (at(1) - at(3)).squaredNorm()) {
          add_piece(piece[0], piece[1], piece[2], i, is_inside);
          add_piece(piece[0], piece[2], piece[3], i, is_inside);
        } else {
          add_piece(piece[0], piece[1], piece[3], i, is_inside);
          add_piece(piece[1], piece[2], piece[3], i, is_inside);
        }
      }
    }
  }
  return out;
}

}  // namespace touchstone::meshes::internal
