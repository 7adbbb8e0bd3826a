#include "touchstone/realtime/mfs/tool_force.hpp"

#include "touchstone/realtime/mfs/quadrature_rules.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace touchstone::realtime::mfs {
namespace {

constexpr double pi = 3.14159265358979323846;

/// The contact frame: the projected contact point, the outward normal there and two tangents.
struct ContactFrame {
  Eigen::Vector3d centre, normal, t1, t2;
};

ContactFrame contact_frame(const geometry::TriangleSurface& organ, const ToolContact& contact) {
  const geometry::SurfaceProjection p = organ.project(contact.point);
  const Eigen::Vector3d helper = std::abs(p.normal.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d t1 = p.normal.cross(helper).normalized();
  return {p.point, p.normal, t1, p.normal.cross(t1)};
}

/// Unit direction at polar angle θ from the inward normal −n and azimuth φ.
Eigen::Vector3d direction(const ContactFrame& f, double theta, double phi) {
  return -std::cos(theta) * f.normal + std::sin(theta) * (std::cos(phi) * f.t1 + std::sin(phi) * f.t2);
}

}  // namespace

// Newton on P_n from Chebyshev-like starts (Golub–Welsch would be overkill at these sizes).
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

PatchQuadrature cut_quadrature(const geometry::TriangleSurface& organ, const ToolContact& contact, double local_radius_m,
                               int polar_points, int azimuth_points, int marching_steps) {
  PatchQuadrature q;
  const ContactFrame f = contact_frame(organ, contact);
  const double length = local_radius_m;
  std::vector<double> x, w;
  gauss_legendre(polar_points, x, w);
  for (int k = 0; k < azimuth_points; ++k) {
    const double phi = 2 * pi * (k + 0.5) / azimuth_points;
    const double theta_max = first_exit(
        [&](double theta) { return organ.signed_distance(f.centre + length * direction(f, theta, phi)) < 0; }, pi,
        marching_steps);
    for (int i = 0; i < polar_points; ++i) {
      const double theta = theta_max * x[i];
      const Eigen::Vector3d d = direction(f, theta, phi);
      q.points.push_back(f.centre + length * d);
      q.normals.push_back(d);
      q.weights.push_back(length * length * std::sin(theta) * theta_max * w[i] * 2 * pi / azimuth_points);
    }
  }
  return q;
}

double extraction_cutoff(double distance_m, double inner_m, double outer_m, double* slope_per_m) {
  const double width = outer_m - inner_m, s = std::clamp((distance_m - inner_m) / width, 0.0, 1.0);
  // 1 − (10s³ − 15s⁴ + 6s⁵): C² at both ends, so ∇w is continuous where it switches on and off.
  if (slope_per_m) *slope_per_m = -30 * s * s * (1 - s) * (1 - s) / width;
  return 1 - s * s * s * (10 - 15 * s + 6 * s * s);
}

PatchQuadrature extraction_quadrature(const geometry::TriangleSurface& organ, const ToolContact& contact, double inner_m,
                                      double outer_m, int radial_points, int polar_points, int azimuth_points) {
  // Shells of radius ρ_k (Gauss–Legendre in [inner, outer]), each the cut-surface quadrature of
  // radius ρ_k: the organ ∩ sphere(c, ρ) is found per azimuth, so the free surface crossing the
  // shell is resolved instead of smeared by points that fall outside.
  PatchQuadrature q;
  std::vector<double> x, w;
  gauss_legendre(radial_points, x, w);
  for (int k = 0; k < radial_points; ++k) {
    const double rho = inner_m + (outer_m - inner_m) * x[k];
    double slope = 0;
    extraction_cutoff(rho, inner_m, outer_m, &slope);
    // 32 marching steps in the polar angle: the shells are inside the local ball, where the
    // organ's surface crosses each once (the cut needs 128 for far, folded surfaces).
    const PatchQuadrature shell = cut_quadrature(organ, contact, rho, polar_points, azimuth_points, 32);
    for (std::size_t p = 0; p < shell.points.size(); ++p) {
      q.points.push_back(shell.points[p]);
      q.normals.push_back(slope * shell.normals[p]);  // ∇w = w'(ρ) (x − c)/ρ
      q.weights.push_back(shell.weights[p] * (outer_m - inner_m) * w[k]);
    }
  }
  return q;
}

PatchQuadrature volume_quadrature(const geometry::TriangleSurface& organ, const ToolContact& contact, double local_radius_m,
                                  int radial_points, int polar_points, int azimuth_points) {
  PatchQuadrature q;
  const ContactFrame f = contact_frame(organ, contact);
  const double length = local_radius_m;
  std::vector<double> xr, wr, xt, wt;
  gauss_legendre(radial_points, xr, wr);
  gauss_legendre(polar_points, xt, wt);
  for (int k = 0; k < azimuth_points; ++k) {
    const double phi = 2 * pi * (k + 0.5) / azimuth_points;
    for (int j = 0; j < polar_points; ++j) {
      const double theta = pi * xt[j];
      const Eigen::Vector3d d = direction(f, theta, phi);
      const double reach = first_exit(
          [&](double rho) { return organ.signed_distance(f.centre + rho * d) < 0; }, length, 64);
      if (reach <= 0) continue;
      // ρ = a (e^{κt} − 1), κ = ln(1 + reach/a), t ∈ [0, 1]: uniform for ρ ≪ a, geometric
      // beyond — the grading of the node cloud, whose spacing grows like max(a, ρ). Uniform
      // points in ρ left the fine nodes near the patch under-integrated (spurious soft modes
      // of the Galerkin K: the uniform-pressure deflection jumped back and forth with N).
      const double scale = contact.radius_m, kappa = std::log1p(reach / scale);
      for (int i = 0; i < radial_points; ++i) {
        const double rho = scale * std::expm1(kappa * xr[i]);
        const double jacobian = kappa * (rho + scale);
        q.points.push_back(f.centre + rho * d);
        q.normals.push_back(Eigen::Vector3d::Zero());
        q.weights.push_back(rho * rho * jacobian * wr[i] * std::sin(theta) * pi * wt[j] * 2 * pi / azimuth_points);
      }
    }
  }
  return q;
}

bool strain_energy(const NodeCloud& cloud, const geometry::Material& material, const MlsSettings& mls,
                   const PatchQuadrature& volume, const Eigen::VectorXd& parameters, double& energy_J) {
  const double lambda = material.lame_lambda_Pa(), mu = material.shear_modulus_Pa();
  MlsEvaluation scratch;
  double energy = 0;
  for (std::size_t p = 0; p < volume.points.size(); ++p) {
    Eigen::Vector3d u;
    Eigen::Matrix3d gradient;
    if (evaluate_displacement(cloud, parameters, volume.points[p], mls, scratch, u, &gradient) != MlsStatus::ok) return false;
    const Eigen::Matrix3d strain = 0.5 * (gradient + gradient.transpose());
    // ½ σ:ε = ½ (λ (tr ε)² + 2μ ε:ε)
    energy += volume.weights[p] * 0.5 * (lambda * strain.trace() * strain.trace() + 2 * mu * strain.squaredNorm());
  }
  if (!std::isfinite(energy)) return false;
  energy_J = energy;
  return true;
}

std::vector<double> tributary_areas(const NodeCloud& cloud, const PatchQuadrature& patch) {
  std::vector<int> patch_nodes;
  for (std::size_t j = 0; j < cloud.size(); ++j)
    if (cloud.kinds[j] == NodeKind::tool_patch) patch_nodes.push_back(static_cast<int>(j));
  std::vector<double> area(cloud.size(), 0.0);
  if (patch_nodes.empty()) return area;
  for (std::size_t p = 0; p < patch.points.size(); ++p) {
    int nearest = patch_nodes.front();
    for (const int j : patch_nodes)
      if ((cloud.positions[j] - patch.points[p]).squaredNorm() < (cloud.positions[nearest] - patch.points[p]).squaredNorm())
        nearest = j;
    area[nearest] += patch.weights[p];
  }
  return area;
}

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

bool surface_traction_map(const NodeCloud& cloud, const geometry::Material& material, const MlsSettings& mls,
                          const PatchQuadrature& quadrature, Eigen::Matrix<double, 3, Eigen::Dynamic>& map) {
  const double lambda = material.lame_lambda_Pa(), mu = material.shear_modulus_Pa();
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
