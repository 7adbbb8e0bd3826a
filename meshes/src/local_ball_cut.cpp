// Cutting the local ball out of an organ surface and closing the hole with the sphere cap (see
// the header).
#include "touchstone/meshes/local_ball_cut.hpp"

#include "text_of.hpp"
#include "gmsh_session.hpp"
#include "level_set_split.hpp"

#include <Eigen/Geometry>
#include <gmsh.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <utility>

namespace touchstone::meshes {

namespace {

using internal::text_of;

std::string text_of(const Eigen::Vector3d& v) { return "(" + text_of(v.x()) + ", " + text_of(v.y()) + ", " + text_of(v.z()) + ")"; }

/// The sphere's level set f(x) = |x − c| − L: negative inside the ball.
class Sphere {
 public:
  Sphere(const Eigen::Vector3d& centre, double radius) : c_(centre), radius_(radius) {}
  double level(const Eigen::Vector3d& x) const { return (x - c_).norm() - radius_; }
  Eigen::Vector3d onto(const Eigen::Vector3d& x) const { return c_ + radius_ * (x - c_).normalized(); }
  /// The root in [0, 1] of |p − c + t (q − p)|² = L² (f changes sign along p→q).
  Eigen::Vector3d crossing(const Eigen::Vector3d& p, const Eigen::Vector3d& q) const {
    const Eigen::Vector3d w = p - c_, d = q - p;
    const double qa = d.squaredNorm(), qb = 2 * w.dot(d), qc = w.squaredNorm() - radius_ * radius_;
    const double root = std::sqrt(std::max(0.0, qb * qb - 4 * qa * qc));
    const double t1 = qb >= 0 ? (-qb - root) / (2 * qa) : 2 * qc / (-qb + root);
    const double t2 = qb >= 0 ? 2 * qc / (-qb - root) : (-qb + root) / (2 * qa);
    const double t = (t1 >= 0 && t1 <= 1) ? t1 : t2;
    return p + std::clamp(t, 0.0, 1.0) * d;
  }

 private:
  Eigen::Vector3d c_;
  double radius_;
};

/// Stereographic projection of the sphere (c, L) from its point c + L n onto the plane through c
/// perpendicular to n, in units of L: the antipode c − L n maps to the origin.
class Stereographic {
 public:
  Stereographic(const Eigen::Vector3d& centre, double radius, const Eigen::Vector3d& pole_direction)
      : c_(centre), radius_(radius), n_(pole_direction.normalized()), e1_(n_.unitOrthogonal()), e2_(n_.cross(e1_)) {}
  /// Plane coordinates of a sphere point; false when it is (numerically) the pole.
  bool project(const Eigen::Vector3d& x, Eigen::Vector2d& s) const {
    const Eigen::Vector3d u = (x - c_).normalized();
    const double denominator = 1 - u.dot(n_);
    if (!(denominator > 1e-9)) return false;
    s = Eigen::Vector2d(u.dot(e1_), u.dot(e2_)) / denominator;
    return true;
  }
  Eigen::Vector3d unproject(double x, double y) const {
    const double r2 = x * x + y * y;
    return c_ + radius_ * (2 * x * e1_ + 2 * y * e2_ + (r2 - 1) * n_) / (r2 + 1);
  }

 private:
  Eigen::Vector3d c_;
  double radius_;
  Eigen::Vector3d n_, e1_, e2_;
};

}  // namespace

void LocalBall::validate() const {
  const auto fail = [](const char* field, const std::string& value, const char* requirement) {
    throw std::invalid_argument(std::string("LocalBall.") + field + " = " + value + " " + requirement);
  };
  if (!centre_m.allFinite()) fail("centre_m", text_of(centre_m), "must be finite");
  if (!std::isfinite(radius_m) || !(radius_m > 0)) fail("radius_m", text_of(radius_m), "must be finite and > 0");
  if (!outward_direction.allFinite() || !(outward_direction.norm() > 0))
    fail("outward_direction", text_of(outward_direction), "must be a finite nonzero vector");
  if (!std::isfinite(cap_edge_m) || !(cap_edge_m > 0) || cap_edge_m > radius_m)
    fail("cap_edge_m", text_of(cap_edge_m), "must be finite, > 0 and <= radius_m");
  if (!(snap_fraction >= 0 && snap_fraction < 0.5)) fail("snap_fraction", text_of(snap_fraction), "must be in [0, 0.5)");
}

BallCutSurface cut_out_local_ball(const std::vector<Eigen::Vector3d>& vertices, const std::vector<Eigen::Vector3i>& triangles,
                                  const LocalBall& ball) {
  ball.validate();
  const Sphere sphere(ball.centre_m, ball.radius_m);
  const std::string where = "the local ball (centre " + text_of(ball.centre_m) + " m, radius " + text_of(ball.radius_m) + " m)";
  internal::LevelSetSplit split = internal::split_along_level_set(vertices, triangles, std::vector<char>(triangles.size(), 1), sphere,
                                                                  ball.snap_fraction);
  std::size_t kept = 0;
  for (const char inside : split.inside) kept += inside ? 0 : 1;
  if (kept == split.triangles.size()) throw std::invalid_argument(where + " does not cut the surface");
  if (kept == 0) throw std::invalid_argument(where + " holds the whole surface");

  // The cut curve: the directed boundary edges p → q of the kept triangles.
  std::unordered_map<std::uint64_t, int> edge_count;
  for (std::size_t i = 0; i < split.triangles.size(); ++i)
    if (!split.inside[i])
      for (int k = 0; k < 3; ++k) ++edge_count[internal::edge_key(split.triangles[i][k], split.triangles[i][(k + 1) % 3])];
  std::unordered_map<int, int> next;
  for (std::size_t i = 0; i < split.triangles.size(); ++i) {
    if (split.inside[i]) continue;
    for (int k = 0; k < 3; ++k) {
      const int p = split.triangles[i][k], q = split.triangles[i][(k + 1) % 3];
      if (edge_count[internal::edge_key(p, q)] != 1) continue;
      if (!split.on_curve[static_cast<std::size_t>(p)] || !split.on_curve[static_cast<std::size_t>(q)])
        throw std::invalid_argument("cutting " + where + ": the surface has a boundary edge off the sphere near " +
                                    text_of(split.vertices[static_cast<std::size_t>(p)]) + " m (it must be closed)");
      if (!next.emplace(p, q).second)
        throw std::invalid_argument("cutting " + where + ": the cut curve touches itself at " +
                                    text_of(split.vertices[static_cast<std::size_t>(p)]) + " m (move the contact, or the mesh is too coarse there)");
    }
  }
  std::vector<std::vector<int>> curves;
  std::unordered_map<int, char> walked;
  for (const auto& [first, unused] : next) {
    if (walked.count(first)) continue;
    std::vector<int> curve;
    for (int v = first; !walked.count(v);) {
      walked[v] = 1;
      curve.push_back(v);
      const auto it = next.find(v);
      if (it == next.end()) throw std::invalid_argument("cutting " + where + ": the cut curve is not closed");
      v = it->second;
    }
    curves.push_back(std::move(curve));
  }
  if (curves.size() != 1)
    throw std::invalid_argument(where + " meets the organ surface in " + std::to_string(curves.size()) +
                                " separate curves: the organ is thinner than the ball there or another part of it lies within reach; "
                                "the exterior body needs a ball that cuts the surface once (a smaller local radius, or another contact)");

  // Keep the outside triangles and the vertices they use, renumbered.
  BallCutSurface out;
  out.snapped_vertex_count = split.snapped_vertex_count;
  out.split_triangle_count = split.split_triangle_count;
  std::vector<int> renumbered(split.vertices.size(), -1);
  const auto keep_vertex = [&](int v) {
    int& r = renumbered[static_cast<std::size_t>(v)];
    if (r < 0) {
      r = static_cast<int>(out.vertices.size());
      out.vertices.push_back(split.vertices[static_cast<std::size_t>(v)]);
    }
    return r;
  };
  for (std::size_t i = 0; i < split.triangles.size(); ++i) {
    if (split.inside[i]) continue;
    const Eigen::Vector3i& t = split.triangles[i];
    out.triangles.emplace_back(keep_vertex(t[0]), keep_vertex(t[1]), keep_vertex(t[2]));
    out.on_cap.push_back(0);
    out.source_triangle.push_back(split.source_triangle[i]);
  }
  for (const int v : curves.front()) out.cut_curve.push_back(renumbered[static_cast<std::size_t>(v)]);

  // The cap: the cut curve as a plane polygon, triangulated by gmsh with no points added on it.
  const Stereographic plane(ball.centre_m, ball.radius_m, ball.outward_direction);
  std::vector<Eigen::Vector2d> polygon(out.cut_curve.size());
  for (std::size_t k = 0; k < polygon.size(); ++k)
    if (!plane.project(out.vertices[static_cast<std::size_t>(out.cut_curve[k])], polygon[k]))
      throw std::invalid_argument("cutting " + where + ": the cut curve passes through the projection pole c + L n, n = " +
                                  text_of(ball.outward_direction.normalized()) + " (the outward direction must point out of the organ)");
  const double plane_size_scale = ball.cap_edge_m / ball.radius_m / 2;
  std::vector<Eigen::Vector3i> cap;
  {
    internal::GmshSession session("sphere_cap");
    try {
      gmsh::option::setNumber("Mesh.MeshSizeExtendFromBoundary", 0);
      gmsh::option::setNumber("Mesh.MeshSizeFromPoints", 0);
      gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
      gmsh::option::setNumber("Mesh.Algorithm", 6);
      gmsh::model::mesh::setSizeCallback(
          [plane_size_scale](int, int, double x, double y, double) { return plane_size_scale * (1 + x * x + y * y); });
      std::vector<int> points, lines;
      for (const Eigen::Vector2d& s : polygon) points.push_back(gmsh::model::geo::addPoint(s.x(), s.y(), 0));
      for (std::size_t k = 0; k < points.size(); ++k) lines.push_back(gmsh::model::geo::addLine(points[k], points[(k + 1) % points.size()]));
      const int loop = gmsh::model::geo::addCurveLoop(lines);
      const int surface = gmsh::model::geo::addPlaneSurface({loop});
      gmsh::model::geo::synchronize();
      for (const int line : lines) gmsh::model::mesh::setTransfiniteCurve(line, 2);
      gmsh::model::mesh::generate(2);

      std::unordered_map<std::size_t, int> vertex_of_node;
      std::vector<std::size_t> node_tags;
      std::vector<double> coordinates, parametric;
      for (std::size_t k = 0; k < points.size(); ++k) {
        gmsh::model::mesh::getNodes(node_tags, coordinates, parametric, 0, points[k]);
        for (const std::size_t tag : node_tags) vertex_of_node[tag] = out.cut_curve[k];
      }
      gmsh::model::mesh::getNodes(node_tags, coordinates, parametric, 2, surface, false, false);
      for (std::size_t i = 0; i < node_tags.size(); ++i) {
        vertex_of_node[node_tags[i]] = static_cast<int>(out.vertices.size());
        out.vertices.push_back(plane.unproject(coordinates[3 * i], coordinates[3 * i + 1]));
      }
      std::vector<std::size_t> element_tags, element_nodes;
      gmsh::model::mesh::getElementsByType(2, element_tags, element_nodes, surface);
      for (std::size_t e = 0; e < element_tags.size(); ++e) {
        Eigen::Vector3i t;
        for (int k = 0; k < 3; ++k) {
          const auto it = vertex_of_node.find(element_nodes[3 * e + static_cast<std::size_t>(k)]);
          if (it == vertex_of_node.end()) throw std::string("the cap triangulation added a point on the cut curve");
          t[k] = it->second;
        }
        cap.push_back(t);
      }
    } catch (const std::string& message) {
      throw std::runtime_error("cutting " + where + ": gmsh could not triangulate the cap: " + message);
    }
  }
  if (cap.empty()) throw std::runtime_error("cutting " + where + ": the cap triangulation is empty");

  // Cap triangles face into the ball (out of the exterior body). The kept surface's boundary runs
  // p → q along the curve, so a cap on the right side of the sphere runs each curve edge q → p.
  const auto directed = [](int p, int q) { return static_cast<std::uint64_t>(p) << 32 | static_cast<std::uint32_t>(q); };
  std::unordered_set<std::uint64_t> cap_edges;
  const auto at = [&](int v) -> const Eigen::Vector3d& { return out.vertices[static_cast<std::size_t>(v)]; };
  for (Eigen::Vector3i t : cap) {
    const Eigen::Vector3d normal = (at(t[1]) - at(t[0])).cross(at(t[2]) - at(t[0]));
    if (normal.dot(ball.centre_m - (at(t[0]) + at(t[1]) + at(t[2])) / 3) < 0) std::swap(t[1], t[2]);
    out.cap_area_m2 += 0.5 * normal.norm();
    for (int k = 0; k < 3; ++k) {
      cap_edges.insert(directed(t[k], t[(k + 1) % 3]));
      out.sphere_relative_deviation = std::max(out.sphere_relative_deviation, std::abs(sphere.level(at(t[k]))) / ball.radius_m);
    }
    out.triangles.push_back(t);
    out.on_cap.push_back(1);
    out.source_triangle.push_back(std::numeric_limits<std::size_t>::max());
  }
  for (std::size_t k = 0; k < out.cut_curve.size(); ++k) {
    const int p = out.cut_curve[k], q = out.cut_curve[(k + 1) % out.cut_curve.size()];
    if (!cap_edges.count(directed(q, p)))
      throw std::invalid_argument("cutting " + where + ": the cap on the sphere does not close the surface consistently; the outward "
                                  "direction " + text_of(ball.outward_direction.normalized()) +
                                  " must point out of the organ, so that the projection pole c + L n lies outside it");
  }
  return out;
}

}  // namespace touchstone::meshes
