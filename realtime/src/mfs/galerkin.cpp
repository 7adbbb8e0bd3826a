#include "touchstone/realtime/mfs/galerkin.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace touchstone::realtime::mfs {

void GalerkinSettings::validate() const {
  if (!std::isfinite(penalty_factor) || penalty_factor <= 0)
    throw std::invalid_argument("GalerkinSettings.penalty_factor = " + std::to_string(penalty_factor) + " must be > 0");
}

GalerkinSystem assemble_galerkin(const NodeCloud& cloud, const Material& material, const ToolContact& contact,
                                 const PatchQuadrature& volume, const PatchQuadrature& patch,
                                 const PatchQuadrature& cut, const GalerkinSettings& settings) {
  const Eigen::Index n = static_cast<Eigen::Index>(cloud.size());
  GalerkinSystem system;
  system.stiffness.setZero(3 * n, 3 * n);
  system.tool_rhs.setZero(3 * n, 3);
  system.patch_map.setZero(3, 3 * n);
  system.cut_map.setZero(3, 3 * n);
  const double lambda = material.lambda_Pa(), mu = material.mu_Pa();
  Eigen::Matrix<double, 6, 6> elasticity = Eigen::Matrix<double, 6, 6>::Zero();  // Voigt: xx yy zz xy yz zx
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) elasticity(i, j) = lambda;
    elasticity(i, i) += 2 * mu;
    elasticity(i + 3, i + 3) = mu;
  }
  MlsEvaluation mls;
  static const std::vector<int> all_nodes;
  const auto fail = [&](MlsStatus status, int point) {
    system.status = status;
    system.failed_point = point;
    system.stiffness.resize(0, 0);
    return system;
  };

  // ∫ Bᵀ D B dV, B = the engineering-strain operator of the neighbours at a quadrature point.
  Eigen::MatrixXd strain, product;
  for (std::size_t q = 0; q < volume.points.size(); ++q) {
    evaluate_mls(volume.points[q], cloud.positions, cloud.radii, all_nodes, settings.mls, Derivatives::gradients, mls);
    if (mls.status != MlsStatus::ok) return fail(mls.status, static_cast<int>(q));
    const int k = static_cast<int>(mls.neighbours.size());
    strain.setZero(6, 3 * k);
    for (int a = 0; a < k; ++a) {
      const Eigen::Vector3d& g = mls.gradient[a];
      strain(0, 3 * a) = g[0];
      strain(1, 3 * a + 1) = g[1];
      strain(2, 3 * a + 2) = g[2];
      strain(3, 3 * a) = g[1], strain(3, 3 * a + 1) = g[0];
      strain(4, 3 * a + 1) = g[2], strain(4, 3 * a + 2) = g[1];
      strain(5, 3 * a) = g[2], strain(5, 3 * a + 2) = g[0];
    }
    product.noalias() = volume.weights[q] * strain.transpose() * (elasticity * strain);
    for (int a = 0; a < k; ++a)
      for (int b = 0; b < k; ++b)
        system.stiffness.block<3, 3>(3 * mls.neighbours[a], 3 * mls.neighbours[b]) += product.block<3, 3>(3 * a, 3 * b);
  }

  // Penalty α ∫ Hᵀ P H dA with P = d dᵀ (frictionless patch) or I; the force on the tissue is
  // α ∫ P (ū − u_h) dA.
  const double finest = *std::min_element(cloud.spacing.begin(), cloud.spacing.end());
  const double alpha = settings.penalty_factor * material.youngs_modulus_Pa / finest;
  system.penalty_Pa_per_m = alpha;
  const Eigen::Vector3d d = contact.direction.normalized();
  const auto add_penalty = [&](const PatchQuadrature& surface, const Eigen::Matrix3d& projection, bool on_patch,
                               int offset) {
    for (std::size_t q = 0; q < surface.points.size(); ++q) {
      evaluate_mls(surface.points[q], cloud.positions, cloud.radii, all_nodes, settings.mls, Derivatives::values, mls);
      if (mls.status != MlsStatus::ok) return static_cast<int>(offset + q);
      const double w = alpha * surface.weights[q];
      Eigen::Matrix<double, 3, Eigen::Dynamic>& map = on_patch ? system.patch_map : system.cut_map;
      for (std::size_t a = 0; a < mls.neighbours.size(); ++a) {
        const int i = mls.neighbours[a];
        map.block<3, 3>(0, 3 * i) += w * mls.value[a] * projection;
        if (on_patch) system.tool_rhs.block<3, 3>(3 * i, 0) += w * mls.value[a] * projection;
        for (std::size_t b = 0; b < mls.neighbours.size(); ++b)
          system.stiffness.block<3, 3>(3 * i, 3 * mls.neighbours[b]) += w * mls.value[a] * mls.value[b] * projection;
      }
      if (on_patch) system.patch_tool_map += w * projection;
    }
    return -1;
  };
  const Eigen::Matrix3d patch_projection = contact.condition == PatchCondition::bonded
                                               ? Eigen::Matrix3d(Eigen::Matrix3d::Identity())
                                               : Eigen::Matrix3d(d * d.transpose());
  const int volume_count = static_cast<int>(volume.points.size());
  int failed = add_penalty(patch, patch_projection, true, volume_count);
  if (failed < 0) failed = add_penalty(cut, Eigen::Matrix3d::Identity(), false, volume_count + static_cast<int>(patch.points.size()));
  if (failed >= 0) return fail(mls.status, failed);
  return system;
}

}  // namespace touchstone::realtime::mfs
