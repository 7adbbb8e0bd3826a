// Cutting the tool patch into a triangle surface along the rim curve (see the header).
#include "touchstone/meshes/tool_patch_imprint.hpp"

#include "touchstone/geometry/closest_point_on_triangle.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

namespace touchstone::meshes {

namespace {

std::string text_of(double value) {
  std::ostringstream text;
  text << value;
  return text.str();
}

std::uint64_t edge_key(int a, int b) {
  const auto lo = static_cast<std::uint64_t>(std::min(a, b)), hi = static_cast<std::uint64_t>(std::max(a, b));
  return (lo << 32) | hi;
}

/// The cylinder's level set f(x) = |P⊥(x − c)| − a: negative inside the patch's cylinder.
class Cylinder {
 public:
  explicit Cylinder(const ToolPatchCylinder& tool)
      : c_(tool.contact_point_m), n_(tool.axis.normalized()), a_(tool.radius_m) {}

  Eigen::Vector3d perpendicular(const Eigen::Vector3d& x) const {
    const Eigen::Vector3d w = x - c_;
    return w - w.dot(n_) * n_;
  }
  double level(const Eigen::Vector3d& x) const { return perpendicular(x).norm() - a_; }

  /// x moved perpendicular to the axis onto the cylinder (x off the axis).
  Eigen::Vector3d onto(const Eigen::Vector3d& x) const {
    const Eigen::Vector3d w = perpendicular(x);
    return x + (a_ / w.norm() - 1.0) * w;
  }

  /// The point of segment p→q on the cylinder, for f(p) < 0 < f(q) or the reverse: the root in
  /// (0, 1) of |P⊥(p − c) + t P⊥(q − p)|² = a², a quadratic in t.
  Eigen::Vector3d crossing(const Eigen::Vector3d& p, const Eigen::Vector3d& q) const {
    const Eigen::Vector3d w = perpendicular(p), d = perpendicular(q) - w;
    const double qa = d.squaredNorm(), qb = 2 * w.dot(d), qc = w.squaredNorm() - a_ * a_;
    const double root = std::sqrt(std::max(0.0, qb * qb - 4 * qa * qc));
    // The two roots; the one in [0, 1] is the crossing (the stable form avoids cancellation).
    const double t1 = qb >= 0 ? (-qb - root) / (2 * qa) : 2 * qc / (-qb + root);
    const double t2 = qb >= 0 ? 2 * qc / (-qb - root) : (-qb + root) / (2 * qa);
    const double t = (t1 >= 0 && t1 <= 1) ? t1 : t2;
    return p + std::clamp(t, 0.0, 1.0) * (q - p);
  }

  double radius() const { return a_; }

 private:
  Eigen::Vector3d c_, n_;
  double a_;
};

}  // namespace

void ToolPatchCylinder::validate() const {
  const auto fail = [](const char* field, const std::string& value, const char* requirement) {
    throw std::invalid_argument(std::string("ToolPatchCylinder.") + field + " = " + value + " " + requirement);
  };
  if (!contact_point_m.allFinite())
    fail("contact_point_m", text_of(contact_point_m.x()) + ", " + text_of(contact_point_m.y()) + ", " + text_of(contact_point_m.z()),
         "must be finite");
  if (!axis.allFinite() || !(axis.norm() > 0))
    fail("axis", text_of(axis.x()) + ", " + text_of(axis.y()) + ", " + text_of(axis.z()), "must be a finite nonzero vector");
  if (!std::isfinite(radius_m) || !(radius_m > 0)) fail("radius_m", text_of(radius_m), "must be finite and > 0");
  if (!(snap_fraction >= 0 && snap_fraction < 0.5)) fail("snap_fraction", text_of(snap_fraction), "must be in [0, 0.5)");
}

ImprintedSurface imprint_tool_patch(const std::vector<Eigen::Vector3d>& vertices,
                                    const std::vector<Eigen::Vector3i>& triangles,
                                    const ToolPatchCylinder& tool) {
  tool.validate();
  const Cylinder cylinder(tool);
  const double a = tool.radius_m;
  const auto position = [&](const Eigen::Vector3i& t, int k) -> const Eigen::Vector3d& { return vertices.at(static_cast<std::size_t>(t[k])); };

  // The seed: the triangle nearest to the contact point.
  std::size_t seed = triangles.size();
  double nearest = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    const Eigen::Vector3i& t = triangles[i];
    const double d = (geometry::closest_on_triangle(tool.contact_point_m, position(t, 0), position(t, 1), position(t, 2)) -
                      tool.contact_point_m)
                         .squaredNorm();
    if (d < nearest) nearest = d, seed = i;
  }
  if (seed == triangles.size()) throw std::invalid_argument("imprint_tool_patch: the surface has no triangles");

  std::vector<double> level(vertices.size());
  for (std::size_t v = 0; v < vertices.size(); ++v) level[v] = cylinder.level(vertices[v]);
  const auto touches_inside = [&](const Eigen::Vector3i& t) {
    return std::min({level[static_cast<std::size_t>(t[0])], level[static_cast<std::size_t>(t[1])], level[static_cast<std::size_t>(t[2])]}) < 0;
  };
  if (!touches_inside(triangles[seed])) {
    const Eigen::Vector3i& t = triangles[seed];
    const double edge = std::max({(position(t, 1) - position(t, 0)).norm(), (position(t, 2) - position(t, 1)).norm(),
                                  (position(t, 0) - position(t, 2)).norm()});
    throw std::invalid_argument("imprint_tool_patch: no corner of the triangle nearest to the contact point (triangle " +
                                std::to_string(seed) + ", longest edge " + text_of(edge) + " m) lies within the tool radius " +
                                text_of(a) + " m of the tool axis: the surface is too coarse for the patch, or the contact point is " +
                                text_of(std::sqrt(nearest)) + " m off the surface");
  }

  // The patch sheet: triangles with a corner inside the cylinder, edge-connected to the seed.
  std::unordered_map<std::uint64_t, std::vector<std::size_t>> edge_triangles;
  for (std::size_t i = 0; i < triangles.size(); ++i)
    for (int k = 0; k < 3; ++k) edge_triangles[edge_key(triangles[i][k], triangles[i][(k + 1) % 3])].push_back(i);
  std::vector<char> in_sheet(triangles.size(), 0);
  std::vector<std::size_t> stack{seed};
  in_sheet[seed] = 1;
  while (!stack.empty()) {
    const std::size_t i = stack.back();
    stack.pop_back();
    for (int k = 0; k < 3; ++k)
      for (const std::size_t j : edge_triangles[edge_key(triangles[i][k], triangles[i][(k + 1) % 3])])
        if (!in_sheet[j] && touches_inside(triangles[j])) in_sheet[j] = 1, stack.push_back(j);
  }

  ImprintedSurface out;
  out.vertices = vertices;
  std::vector<char> on_rim(vertices.size(), 0);

  // Snap sheet vertices close to the rim onto it, measured against their shortest sheet edge.
  std::vector<double> shortest_edge(vertices.size(), std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    if (!in_sheet[i]) continue;
    for (int k = 0; k < 3; ++k) {
      const int p = triangles[i][k], q = triangles[i][(k + 1) % 3];
      const double length = (vertices[static_cast<std::size_t>(p)] - vertices[static_cast<std::size_t>(q)]).norm();
      shortest_edge[static_cast<std::size_t>(p)] = std::min(shortest_edge[static_cast<std::size_t>(p)], length);
      shortest_edge[static_cast<std::size_t>(q)] = std::min(shortest_edge[static_cast<std::size_t>(q)], length);
    }
  }
  for (std::size_t v = 0; v < vertices.size(); ++v) {
    if (!std::isfinite(shortest_edge[v]) || !(std::abs(level[v]) <= tool.snap_fraction * shortest_edge[v])) continue;
    out.vertices[v] = cylinder.onto(vertices[v]);
    level[v] = 0;
    on_rim[v] = 1;
    ++out.snapped_vertex_count;
  }

  // Split the sheet's triangles along the rim; one new vertex per crossed edge.
  std::unordered_map<std::uint64_t, int> crossing_vertex;
  const auto crossing = [&](int p, int q) {
    const auto [it, inserted] = crossing_vertex.try_emplace(edge_key(p, q), static_cast<int>(out.vertices.size()));
    if (inserted) {
      out.vertices.push_back(cylinder.crossing(out.vertices[static_cast<std::size_t>(p)], out.vertices[static_cast<std::size_t>(q)]));
      on_rim.push_back(1);
    }
    return it->second;
  };
  const auto sign_of = [&](int v) {
    const double f = static_cast<std::size_t>(v) < level.size() ? level[static_cast<std::size_t>(v)] : 0.0;
    return on_rim[static_cast<std::size_t>(v)] ? 0 : (f < 0 ? -1 : 1);
  };
  const auto add_piece = [&](int p, int q, int r, std::size_t source, bool inside) {
    out.triangles.emplace_back(p, q, r);
    out.in_patch.push_back(inside ? 1 : 0);
    out.source_triangle.push_back(source);
  };

  for (std::size_t i = 0; i < triangles.size(); ++i) {
    const Eigen::Vector3i& t = triangles[i];
    if (!in_sheet[i]) {
      add_piece(t[0], t[1], t[2], i, false);
      continue;
    }
    // The triangle's boundary walked in its own orientation, with the rim points inserted.
    std::array<int, 6> polygon{};
    std::size_t size = 0;
    for (int k = 0; k < 3; ++k) {
      const int p = t[k], q = t[(k + 1) % 3];
      polygon[size++] = p;
      if (sign_of(p) * sign_of(q) < 0) polygon[size++] = crossing(p, q);
    }
    std::array<std::size_t, 6> rim_positions{};
    std::size_t rim_count = 0;
    int sign_sum = 0;
    for (std::size_t k = 0; k < size; ++k) {
      if (sign_of(polygon[k]) == 0) rim_positions[rim_count++] = k;
      sign_sum += sign_of(polygon[k]);
    }
    const bool chord = rim_count == 2 && rim_positions[1] - rim_positions[0] != 1 && rim_positions[1] - rim_positions[0] != size - 1;
    if (!chord) {
      // No chord across the triangle: it lies on one side (touching the rim at most along an edge
      // or a corner).
      add_piece(t[0], t[1], t[2], i, sign_sum < 0);
      continue;
    }
    ++out.split_triangle_count;
    // Two sub-polygons (3 or 4 corners, convex) on either side of the chord.
    for (int side = 0; side < 2; ++side) {
      std::array<int, 6> piece{};
      std::size_t corners = 0;
      const std::size_t from = rim_positions[static_cast<std::size_t>(side)], to = rim_positions[static_cast<std::size_t>(1 - side)];
      for (std::size_t k = from;; k = (k + 1) % size) {
        piece[corners++] = polygon[k];
        if (k == to) break;
      }
      const bool inside = sign_of(piece[1]) < 0;
      if (corners == 3) {
        add_piece(piece[0], piece[1], piece[2], i, inside);
      } else {
        // Split the quadrilateral along its shorter diagonal.
        const auto at = [&](std::size_t k) -> const Eigen::Vector3d& { return out.vertices[static_cast<std::size_t>(piece[k])]; };
        if ((at(0) - at(2)).squaredNorm() <= (at(1) - at(3)).squaredNorm()) {
          add_piece(piece[0], piece[1], piece[2], i, inside);
          add_piece(piece[0], piece[2], piece[3], i, inside);
        } else {
          add_piece(piece[0], piece[1], piece[3], i, inside);
          add_piece(piece[1], piece[2], piece[3], i, inside);
        }
      }
    }
  }

  // The patch must be closed by the rim: every patch edge not on the rim is shared by two patch
  // triangles.
  std::unordered_map<std::uint64_t, int> patch_edge_count;
  for (std::size_t i = 0; i < out.triangles.size(); ++i) {
    if (!out.in_patch[i]) continue;
    const Eigen::Vector3i& t = out.triangles[i];
    const Eigen::Vector3d& p0 = out.vertices[static_cast<std::size_t>(t[0])];
    out.patch_area_m2 += 0.5 * (out.vertices[static_cast<std::size_t>(t[1])] - p0).cross(out.vertices[static_cast<std::size_t>(t[2])] - p0).norm();
    for (int k = 0; k < 3; ++k) ++patch_edge_count[edge_key(t[k], t[(k + 1) % 3])];
  }
  for (const auto& [key, count] : patch_edge_count) {
    const int p = static_cast<int>(key >> 32), q = static_cast<int>(key & 0xffffffffu);
    if (count == 1 && !(on_rim[static_cast<std::size_t>(p)] && on_rim[static_cast<std::size_t>(q)])) {
      std::ostringstream message;
      message << "imprint_tool_patch: the tool patch (radius " << a << " m) is not enclosed by its rim: its edge between "
              << "surface points (" << out.vertices[static_cast<std::size_t>(p)].transpose() << ") and ("
              << out.vertices[static_cast<std::size_t>(q)].transpose()
              << ") m is a boundary of the surface or lies across the rim (is the surface open there, or coarser than the patch?)";
      throw std::invalid_argument(message.str());
    }
  }
  for (std::size_t v = 0; v < out.vertices.size(); ++v) {
    if (!on_rim[v]) continue;
    out.rim_vertices.push_back(static_cast<int>(v));
    out.rim_relative_deviation = std::max(out.rim_relative_deviation, std::abs(cylinder.level(out.vertices[v])) / a);
  }
  return out;
}

}  // namespace touchstone::meshes
