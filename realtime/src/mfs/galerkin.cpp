#include "touchstone/realtime/mfs/galerkin.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace touchstone::realtime::mfs {

std::string to_string(Constraint constraint) { return constraint == Constraint::nitsche ? "nitsche" : "penalty"; }

namespace {

/// T (3 × 3): the traction σ(h e_k) n of shape function h with gradient g, column k.
Eigen::Matrix3d shape_traction(const geometry::Material& material, const Eigen::Vector3d& g, const Eigen::Vector3d& n) {
  const double lambda = material.lame_lambda_Pa(), mu = material.shear_modulus_Pa();
  return lambda * n * g.transpose() + mu * (g.dot(n) * Eigen::Matrix3d::Identity() + g * n.transpose());
}

double stabilisation_Pa_per_m(const NodeCloud& cloud, const geometry::Material& material, const GalerkinSettings& settings) {
  const double finest = *std::min_element(cloud.spacing.begin(), cloud.spacing.end());
  return settings.penalty_factor * material.youngs_modulus_Pa / finest;
}

}  // namespace

void GalerkinSettings::validate() const {
  if (!std::isfinite(penalty_factor) || penalty_factor <= 0)
    throw std::invalid_argument("GalerkinSettings.penalty_factor = " + std::to_string(penalty_factor) + " must be > 0");
}

GalerkinSystem assemble_galerkin(const NodeCloud& cloud, const geometry::Material& material, const ToolContact& contact,
                                 const PatchQuadrature& volume, const PatchQuadrature& patch,
                                 const PatchQuadrature& cut, const GalerkinSettings& settings) {
  const Eigen::Index n = static_cast<Eigen::Index>(cloud.size());
  GalerkinSystem system;
  system.stiffness.setZero(3 * n, 3 * n);
  system.tool_rhs.setZero(3 * n, 3);
  system.patch_map.setZero(3, 3 * n);
  system.cut_map.setZero(3, 3 * n);
  const double lambda = material.lame_lambda_Pa(), mu = material.shear_modulus_Pa();
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
    system.min_rcond = std::min(system.min_rcond, mls.rcond);
    system.max_support_scale = std::max(system.max_support_scale, mls.support_scale);
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

  // The tool-patch nodes' rows of the elastic K, before the constraints are added (eq. 9's
  // K_aa U_a + K_ab U_b), and ∫_patch h_a dA, the weight that turns a row into a traction.
  for (std::size_t j = 0; j < cloud.size(); ++j)
    if (cloud.kinds[j] == NodeKind::tool_patch) system.patch_nodes.push_back(static_cast<int>(j));
  system.patch_node_rows.resize(3 * static_cast<Eigen::Index>(system.patch_nodes.size()), 3 * n);
  for (std::size_t i = 0; i < system.patch_nodes.size(); ++i)
    system.patch_node_rows.middleRows<3>(3 * static_cast<Eigen::Index>(i)) =
        system.stiffness.middleRows<3>(3 * static_cast<Eigen::Index>(system.patch_nodes[i]));
  const Eigen::Index patch_count = static_cast<Eigen::Index>(system.patch_nodes.size());
  system.patch_node_shape_integral_m2.assign(system.patch_nodes.size(), 0.0);
  system.patch_node_mass_m2.setZero(patch_count, patch_count);
  std::vector<std::pair<Eigen::Index, double>> on_patch;
  for (std::size_t q = 0; q < patch.points.size(); ++q) {
    evaluate_mls(patch.points[q], cloud.positions, cloud.radii, all_nodes, settings.mls, Derivatives::values, mls);
    if (mls.status != MlsStatus::ok) return fail(mls.status, static_cast<int>(volume.points.size() + q));
    on_patch.clear();
    for (std::size_t a = 0; a < mls.neighbours.size(); ++a) {
      const auto it = std::lower_bound(system.patch_nodes.begin(), system.patch_nodes.end(), mls.neighbours[a]);
      if (it != system.patch_nodes.end() && *it == mls.neighbours[a]) on_patch.emplace_back(it - system.patch_nodes.begin(), mls.value[a]);
    }
    for (const auto& [i, hi] : on_patch) {
      system.patch_node_shape_integral_m2[i] += patch.weights[q] * hi;
      for (const auto& [j, hj] : on_patch) system.patch_node_mass_m2(i, j) += patch.weights[q] * hi * hj;
    }
  }

  // The constraint P u = P ū on a surface. Penalty: α ∫ (P u)·v. Nitsche adds the consistency
  // terms −∫ (σ(u)n)·P v − ∫ (σ(v)n)·P u; with T_a the traction of shape function a, the
  // block (a, b) of K gains w (α h_a h_b P − h_a P T_b − T_aᵀ P h_b), and the boundary force
  // on the tissue is ∫ P (σ(u_h)n − α (u_h − ū)) dA.
  const double alpha = stabilisation_Pa_per_m(cloud, material, settings);
  system.penalty_Pa_per_m = alpha;
  const bool nitsche = settings.constraint == Constraint::nitsche;
  const Eigen::Vector3d d = contact.direction.normalized();
  std::vector<Eigen::Matrix3d> flux;  // per neighbour: w (α h_a P − P T_a), the force map block
  const auto add_constraint = [&](const PatchQuadrature& surface, const Eigen::Matrix3d& projection, bool on_patch,
                                  int offset) {
    for (std::size_t q = 0; q < surface.points.size(); ++q) {
      evaluate_mls(surface.points[q], cloud.positions, cloud.radii, all_nodes, settings.mls,
                   nitsche ? Derivatives::gradients : Derivatives::values, mls);
      if (mls.status != MlsStatus::ok) return static_cast<int>(offset + q);
      const double w = surface.weights[q];
      const std::size_t k = mls.neighbours.size();
      flux.resize(k);
      for (std::size_t a = 0; a < k; ++a) {
        flux[a] = w * alpha * mls.value[a] * projection;
        if (nitsche) flux[a] -= w * projection * shape_traction(material, mls.gradient[a], surface.normals[q]);
      }
      Eigen::Matrix<double, 3, Eigen::Dynamic>& map = on_patch ? system.patch_map : system.cut_map;
      for (std::size_t a = 0; a < k; ++a) {
        const int i = mls.neighbours[a];
        map.block<3, 3>(0, 3 * i) += flux[a];
        // The tool's right-hand side ∫ (α h_a − T_aᵀ) P U_tool: the transpose of the force block.
        if (on_patch) system.tool_rhs.block<3, 3>(3 * i, 0) += flux[a].transpose();
        for (std::size_t b = 0; b < k; ++b) {
          Eigen::Matrix3d block = mls.value[a] * flux[b];  // w (α h_a h_b P − h_a P T_b)
          if (nitsche) block -= w * mls.value[b] * shape_traction(material, mls.gradient[a], surface.normals[q]).transpose() * projection;
          system.stiffness.block<3, 3>(3 * i, 3 * mls.neighbours[b]) += block;
        }
      }
      if (on_patch) system.patch_tool_map += w * alpha * projection;
    }
    return -1;
  };
  const Eigen::Matrix3d patch_projection = contact.condition == geometry::ContactCondition::bonded
                                               ? Eigen::Matrix3d(Eigen::Matrix3d::Identity())
                                               : Eigen::Matrix3d(d * d.transpose());
  const int volume_count = static_cast<int>(volume.points.size());
  int failed = add_constraint(patch, patch_projection, true, volume_count);
  if (failed < 0) failed = add_constraint(cut, Eigen::Matrix3d::Identity(), false, volume_count + static_cast<int>(patch.points.size()));
  if (failed >= 0) return fail(mls.status, failed);
  return system;
}

bool traction_load(const NodeCloud& cloud, const PatchQuadrature& surface, const std::vector<Eigen::Vector3d>& traction_Pa,
                   const GalerkinSettings& settings, Eigen::VectorXd& load) {
  load.setZero(3 * static_cast<Eigen::Index>(cloud.size()));
  static const std::vector<int> all_nodes;
  MlsEvaluation mls;
  for (std::size_t q = 0; q < surface.points.size(); ++q) {
    evaluate_mls(surface.points[q], cloud.positions, cloud.radii, all_nodes, settings.mls, Derivatives::values, mls);
    if (mls.status != MlsStatus::ok) return false;
    for (std::size_t a = 0; a < mls.neighbours.size(); ++a)
      load.segment<3>(3 * mls.neighbours[a]) += surface.weights[q] * mls.value[a] * traction_Pa[q];
  }
  return true;
}

bool prescribed_displacement_load(const NodeCloud& cloud, const geometry::Material& material, const PatchQuadrature& surface,
                                  const std::vector<Eigen::Vector3d>& displacement_m, const GalerkinSettings& settings,
                                  Eigen::VectorXd& load) {
  load.setZero(3 * static_cast<Eigen::Index>(cloud.size()));
  static const std::vector<int> all_nodes;
  const double alpha = stabilisation_Pa_per_m(cloud, material, settings);
  const bool nitsche = settings.constraint == Constraint::nitsche;
  MlsEvaluation mls;
  for (std::size_t q = 0; q < surface.points.size(); ++q) {
    evaluate_mls(surface.points[q], cloud.positions, cloud.radii, all_nodes, settings.mls,
                 nitsche ? Derivatives::gradients : Derivatives::values, mls);
    if (mls.status != MlsStatus::ok) return false;
    for (std::size_t a = 0; a < mls.neighbours.size(); ++a) {
      Eigen::Vector3d term = alpha * mls.value[a] * displacement_m[q];
      if (nitsche) term -= shape_traction(material, mls.gradient[a], surface.normals[q]).transpose() * displacement_m[q];
      load.segment<3>(3 * mls.neighbours[a]) += surface.weights[q] * term;
    }
  }
  return true;
}

}  // namespace touchstone::realtime::mfs
