#pragma once
// Tensor Gauss–Legendre rules on an axis-aligned box and on its six faces, for tests that check a
// boundary form against the volume integral it replaces (divergence theorem).

#include "touchstone/realtime/mfs/quadrature_rules.hpp"

#include <Eigen/Core>

#include <vector>

namespace touchstone::testing {

struct BoxPoint {
  Eigen::Vector3d position_m;
  Eigen::Vector3d normal;  ///< outward; zero for volume points
  double weight;           ///< [m³] inside, [m²] on a face
};

/// n × n × n Gauss points inside the box [low, high].
inline std::vector<BoxPoint> box_volume_rule(const Eigen::Vector3d& low, const Eigen::Vector3d& high, int n) {
  std::vector<double> x, w;
  realtime::mfs::gauss_legendre(n, x, w);
  const Eigen::Vector3d size = high - low;
  std::vector<BoxPoint> points;
  for (std::size_t i = 0; i < x.size(); ++i)
    for (std::size_t j = 0; j < x.size(); ++j)
      for (std::size_t k = 0; k < x.size(); ++k)
        points.push_back({low + size.cwiseProduct(Eigen::Vector3d(x[i], x[j], x[k])), Eigen::Vector3d::Zero(),
                          w[i] * w[j] * w[k] * size.prod()});
  return points;
}

/// n × n Gauss points on each of the six faces of the box [low, high], with outward normals.
inline std::vector<BoxPoint> box_surface_rule(const Eigen::Vector3d& low, const Eigen::Vector3d& high, int n) {
  std::vector<double> x, w;
  realtime::mfs::gauss_legendre(n, x, w);
  const Eigen::Vector3d size = high - low;
  std::vector<BoxPoint> points;
  for (int axis = 0; axis < 3; ++axis)
    for (const int side : {-1, 1}) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      for (std::size_t i = 0; i < x.size(); ++i)
        for (std::size_t j = 0; j < x.size(); ++j) {
          Eigen::Vector3d p = low;
          p[axis] = side > 0 ? high[axis] : low[axis];
          p[u] += size[u] * x[i];
          p[v] += size[v] * x[j];
          points.push_back({p, side * Eigen::Vector3d::Unit(axis), w[i] * w[j] * size[u] * size[v]});
        }
    }
  return points;
}

}  // namespace touchstone::testing
