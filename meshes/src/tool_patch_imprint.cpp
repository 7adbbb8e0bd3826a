// Cutting the tool patch into a triangle surface along the rim curve (see the header).
#include "touchstone/meshes/tool_patch_imprint.hpp"

#include "text_of.hpp"
#include "level_set_split.hpp"
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
#include <vector>

namespace touchstone::meshes {

namespace {

using internal::text_of;

using internal::edge_key;

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

  internal::LevelSetSplit split = internal::split_along_level_set(vertices, triangles, in_sheet, cylinder, tool.snap_fraction);
  ImprintedSurface out;
  out.vertices = std::move(split.vertices);
  out.triangles = std::move(split.triangles);
  out.in_patch = std::move(split.inside);
  out.source_triangle = std::move(split.source_triangle);
  out.snapped_vertex_count = split.snapped_vertex_count;
  out.split_triangle_count = split.split_triangle_count;
  const std::vector<char>& on_rim = split.on_curve;

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
