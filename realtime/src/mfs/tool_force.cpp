#include "touchstone/realtime/mfs/tool_force.hpp"

#include <Eigen/Geometry>

#include <cmath>

namespace touchstone::realtime::mfs {
namespace {

constexpr double pi = 3.14159265358979323846;

/// Gauss–Legendre nodes and weights on [0, 1] (Golub–Welsch would be overkill: Newton on P_n).
void gauss_legendre(int n, std::vector<double>& x, std::vector<double>& w) {
  x.resize(n);
  w.resize(n);
  for (int i = 0; i < n; ++i) {
    double z = std::cos(pi * (i + 0.75) / (n + 0.5)), dp = 0;
    for (int iteration = 0; iteration < 100; ++iteration) {
      double p0 = 1, p1 = z;
      for (int k = 2; k <= n; ++k) {
        const double p2 = ((2 * k - 1) * z * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = n * (z * p1 - p0) / (z * z - 1);
      const double step = p1 / dp;
      z -= step;
      if (std::abs(step) < 1e-15) break;
    }
    x[i] = 0.5 * (1 - z);
    w[i] = 1.0 / ((1 - z * z) * dp * dp);  // 2/((1−z²)P'²) on [−1,1], halved for [0,1]
  }
}

}  // namespace

PatchQuadrature patch_quadrature(const geometry::TriangleSurface& organ, const ToolContact& contact,
                                 int radial_points, int angular_points) {
  PatchQuadrature q;
  const geometry::SurfaceProjection centre = organ.project(contact.point);
  const Eigen::Vector3d n = centre.normal;
  const Eigen::Vector3d helper = std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d t1 = n.cross(helper).normalized(), t2 = n.cross(t1);
  std::vector<double> x, w;
  gauss_legendre(radial_points, x, w);
  const double a = contact.radius_m;
  for (int i = 0; i < radial_points; ++i) {
    // r = a sin φ, φ = (π/2) x: dA = r dr dθ = a² sin φ cos φ (π/2) dx dθ.
    const double phi = 0.5 * pi * x[i], r = a * std::sin(phi);
    const double radial_weight = w[i] * 0.5 * pi * a * a * std::sin(phi) * std::cos(phi);
    for (int k = 0; k < angular_points; ++k) {
      const double theta = 2 * pi * (k + 0.5 * (i % 2)) / angular_points;
      const geometry::SurfaceProjection p = organ.project(centre.point + r * (std::cos(theta) * t1 + std::sin(theta) * t2));
      q.points.push_back(p.point);
      q.normals.push_back(p.normal);
      // The projected area element differs from the tangent-plane one by 1/(n·n_c).
      q.weights.push_back(radial_weight * 2 * pi / angular_points / std::max(0.5, p.normal.dot(n)));
    }
  }
  return q;
}

bool traction_force_map(const NodeCloud& cloud, const Material& material, const MlsSettings& mls,
                        const PatchQuadrature& quadrature, Eigen::Matrix<double, 3, Eigen::Dynamic>& map) {
  const double lambda = material.lambda_Pa(), mu = material.mu_Pa();
  map.setZero(3, 3 * static_cast<Eigen::Index>(cloud.size()));
  MlsEvaluation evaluation;
  static const std::vector<int> all_nodes;
  for (std::size_t p = 0; p < quadrature.points.size(); ++p) {
    evaluate_mls(quadrature.points[p], cloud.positions, cloud.radii, all_nodes, mls, Derivatives::gradients, evaluation);
    if (evaluation.status != MlsStatus::ok) {
      map.resize(3, 0);
      return false;
    }
    const Eigen::Vector3d& n = quadrature.normals[p];
    for (std::size_t k = 0; k < evaluation.neighbours.size(); ++k) {
      const Eigen::Vector3d& g = evaluation.gradient[k];
      // t_i = λ n_i div u + μ (∂_j u_i + ∂_i u_j) n_j; ∂u_i/∂x_j = g_j u_Ji.
      Eigen::Matrix3d dt_du = lambda * n * g.transpose() + mu * (g.dot(n) * Eigen::Matrix3d::Identity() + g * n.transpose());
      map.block<3, 3>(0, 3 * evaluation.neighbours[k]) += quadrature.weights[p] * dt_du;
    }
  }
  return true;
}

}  // namespace touchstone::realtime::mfs
