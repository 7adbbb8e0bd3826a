#include "touchstone/realtime/mfs/clamped_surface.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <stdexcept>
#include <string>

namespace touchstone::realtime::mfs {

void ClampedSurface::validate() const {
  const int count = static_cast<int>(vertices.size());
  for (std::size_t t = 0; t < triangles.size(); ++t)
    for (int k = 0; k < 3; ++k) {
      const int v = triangles[t][k];
      if (v < 0 || v >= count)
        throw std::invalid_argument("ClampedSurface: triangle " + std::to_string(t) + " refers to vertex " +
                                    std::to_string(v) + " of " + std::to_string(count));
      if (!vertices[v].allFinite())
        throw std::invalid_argument("ClampedSurface: triangle " + std::to_string(t) + " has a non-finite vertex " +
                                    std::to_string(v));
    }
}

namespace {

using Triangle = std::array<Eigen::Vector3d, 3>;

/// Dunavant's 7-point rule (degree 5) in barycentric coordinates; weights sum to 1.
struct Dunavant7 {
  std::array<std::array<double, 3>, 7> point;
  std::array<double, 7> weight;
};

const Dunavant7& dunavant7() {
  static const Dunavant7 rule = [] {
    Dunavant7 r;
    const double a1 = 0.059715871789770, b1 = 0.470142064105115, a2 = 0.797426985353087, b2 = 0.101286507323456;
    const double w0 = 0.225, w1 = 0.132394152788506, w2 = 0.125939180544827;
    r.point = {{{1.0 / 3, 1.0 / 3, 1.0 / 3}, {a1, b1, b1}, {b1, a1, b1}, {b1, b1, a1}, {a2, b2, b2}, {b2, a2, b2}, {b2, b2, a2}}};
    r.weight = {w0, w1, w1, w1, w2, w2, w2};
    return r;
  }();
  return rule;
}

void integrate(const Triangle& t, const Eigen::Vector3d& normal, const Eigen::Vector3d& centre, double radius,
               double max_edge, PatchQuadrature& q) {
  const double longest = std::max({(t[1] - t[0]).norm(), (t[2] - t[1]).norm(), (t[0] - t[2]).norm()});
  // Far from the ball: nothing of it is inside.
  const Eigen::Vector3d middle = (t[0] + t[1] + t[2]) / 3;
  if ((middle - centre).norm() > radius + longest) return;
  if (longest > max_edge) {
    const Eigen::Vector3d m01 = 0.5 * (t[0] + t[1]), m12 = 0.5 * (t[1] + t[2]), m20 = 0.5 * (t[2] + t[0]);
    for (const Triangle& child : {Triangle{t[0], m01, m20}, Triangle{m01, t[1], m12}, Triangle{m20, m12, t[2]},
                                  Triangle{m01, m12, m20}})
      integrate(child, normal, centre, radius, max_edge, q);
    return;
  }
  const double area = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).norm();
  const Dunavant7& rule = dunavant7();
  for (int k = 0; k < 7; ++k) {
    const Eigen::Vector3d x = rule.point[k][0] * t[0] + rule.point[k][1] * t[1] + rule.point[k][2] * t[2];
    if ((x - centre).norm() >= radius) continue;
    q.points.push_back(x);
    q.normals.push_back(normal);
    q.weights.push_back(area * rule.weight[k]);
  }
}

}  // namespace

PatchQuadrature clamped_quadrature(const ClampedSurface& clamped, const Eigen::Vector3d& centre_m, double local_radius_m,
                                   double max_edge_m) {
  clamped.validate();
  if (!(max_edge_m > 0)) throw std::invalid_argument("clamped_quadrature: max_edge_m must be > 0");
  PatchQuadrature q;
  for (const Eigen::Vector3i& t : clamped.triangles) {
    const Triangle corners{clamped.vertices[t[0]], clamped.vertices[t[1]], clamped.vertices[t[2]]};
    const Eigen::Vector3d cross = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
    if (!(cross.norm() > 0)) continue;  // a degenerate triangle holds no area
    const Eigen::Vector3d normal = cross.normalized();
    integrate(corners, normal, centre_m, local_radius_m, max_edge_m, q);
  }
  return q;
}

}  // namespace touchstone::realtime::mfs
