#include "touchstone/realtime/mfs/collocation.hpp"

#include <Eigen/SparseCore>

#include <algorithm>
#include <cmath>

namespace touchstone::realtime::mfs {

Eigen::Vector3d row_coefficients(const CollocationRow& row, const Eigen::Vector3d& normal, double lambda,
                                 double mu, double shape_value, const Eigen::Vector3d& gradient,
                                 const Eigen::Matrix3d& hessian) noexcept {
  const Eigen::Vector3d& e = row.direction;
  switch (row.type) {
    case CollocationRow::Type::navier:
      // e · (μ ∇²h δ_ik + (λ+μ) h,ik) u_Jk
      return mu * hessian.trace() * e + (lambda + mu) * (hessian * e);
    case CollocationRow::Type::traction:
      // e_i [λ n_i h,k + μ (δ_ik h,j n_j + h,i n_k)] u_Jk
      return lambda * e.dot(normal) * gradient + mu * (gradient.dot(normal) * e + e.dot(gradient) * normal);
    case CollocationRow::Type::dirichlet:
      return shape_value * e;
  }
  return Eigen::Vector3d::Zero();
}

MlsStatus evaluate_displacement(const NodeCloud& cloud, const Eigen::VectorXd& parameters, const Eigen::Vector3d& x,
                                const MlsSettings& settings, MlsEvaluation& scratch, Eigen::Vector3d& u,
                                Eigen::Matrix3d* gradient) noexcept {
  static const std::vector<int> all_nodes;
  u.setZero();
  if (gradient) gradient->setZero();
  evaluate_mls(x, cloud.positions, cloud.radii, all_nodes, settings, gradient ? Derivatives::gradients : Derivatives::values,
               scratch);
  if (scratch.status != MlsStatus::ok) return scratch.status;
  for (std::size_t k = 0; k < scratch.neighbours.size(); ++k) {
    const Eigen::Vector3d u_j = parameters.segment<3>(3 * scratch.neighbours[k]);
    u += scratch.value[k] * u_j;
    if (gradient) *gradient += u_j * scratch.gradient[k].transpose();
  }
  return MlsStatus::ok;
}

namespace {

double row_scale(const CollocationRow& row, double spacing, double youngs_modulus) {
  switch (row.type) {
    case CollocationRow::Type::navier: return spacing * spacing / youngs_modulus;
    case CollocationRow::Type::traction: return spacing / youngs_modulus;
    case CollocationRow::Type::dirichlet: return 1.0;
  }
  return 1.0;
}

}  // namespace

void assemble_collocation(const NodeCloud& cloud, const geometry::Material& material, const CollocationSettings& settings,
                          CollocationSystem& system) {
  const int n = static_cast<int>(cloud.size());
  const int points = n + static_cast<int>(cloud.extra_points.size());
  const double lambda = material.lame_lambda_Pa(), mu = material.shear_modulus_Pa();
  const double beta = settings.neumann_stabilization;
  system.status = AssemblyStatus{};
  system.constant_rhs.setZero(3 * points);
  system.tool_rhs.setZero(3 * points, 3);
  system.row_scale.setOnes(3 * points);

  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<std::size_t>(points) * 3 * 3 * 40);
  MlsEvaluation mls;
  static const std::vector<int> all_nodes;
  const CollocationPoint none;
  // The rows of one collocation point (a node, or an extra point when index ≥ N).
  const auto assemble_point = [&](int index, const Eigen::Vector3d& x, const Eigen::Vector3d& normal, double spacing,
                                  const Eigen::Vector3d& body_force, const std::array<CollocationRow, 3>& rows) {
    const auto is_stabilised_traction = [beta](const CollocationRow& r) {
      return beta != 0 && r.type == CollocationRow::Type::traction;
    };
    const bool needs_hessians = std::any_of(rows.begin(), rows.end(), [&](const CollocationRow& r) {
      return r.type == CollocationRow::Type::navier || is_stabilised_traction(r);
    });
    const bool needs_gradients = std::any_of(rows.begin(), rows.end(), [](const CollocationRow& r) {
      return r.type != CollocationRow::Type::dirichlet;
    });
    const Derivatives derivatives =
        needs_hessians ? Derivatives::hessians : (needs_gradients ? Derivatives::gradients : Derivatives::values);
    evaluate_mls(x, cloud.positions, cloud.radii, all_nodes, settings.mls, derivatives, mls);
    system.status.min_rcond = std::min(system.status.min_rcond, mls.rcond);
    system.status.max_support_scale = std::max(system.status.max_support_scale, mls.support_scale);
    system.status.max_neighbours = std::max(system.status.max_neighbours, static_cast<int>(mls.neighbours.size()));
    system.status.mean_neighbours += static_cast<double>(mls.neighbours.size()) / points;
    if (mls.status != MlsStatus::ok) {
      system.status.mls = mls.status;
      system.status.node = index;
      return false;
    }
    for (int r = 0; r < 3; ++r) {
      const CollocationRow& row = rows[r];
      const int row_index = 3 * index + r;
      double scale = settings.scale_rows ? row_scale(row, spacing, material.youngs_modulus_Pa) : 1.0;
      if (row.type != CollocationRow::Type::navier) scale *= settings.boundary_row_weight;
      // e·(σn − ℓ div σ) = e·t̄ + ℓ e·b with ℓ = β s: the Navier operator enters with weight −ℓ.
      const double layer = is_stabilised_traction(row) ? beta * spacing : 0.0;
      const CollocationRow navier{CollocationRow::Type::navier, row.direction, 0.0, Eigen::Vector3d::Zero()};
      system.row_scale[row_index] = scale;
      system.constant_rhs[row_index] = scale * (row.value + layer * row.direction.dot(body_force));
      system.tool_rhs.row(row_index) = scale * row.tool.transpose();
      for (std::size_t k = 0; k < mls.neighbours.size(); ++k) {
        const Eigen::Vector3d gradient = needs_gradients ? mls.gradient[k] : Eigen::Vector3d::Zero();
        const Eigen::Matrix3d hessian = needs_hessians ? mls.hessian[k] : Eigen::Matrix3d::Zero();
        Eigen::Vector3d c = row_coefficients(row, normal, lambda, mu, mls.value[k], gradient, hessian);
        if (layer != 0) c -= layer * row_coefficients(navier, normal, lambda, mu, 0.0, gradient, hessian);
        c *= scale;
        const int column = 3 * mls.neighbours[k];
        for (int d = 0; d < 3; ++d)
          if (c[d] != 0) triplets.emplace_back(row_index, column + d, c[d]);
      }
    }
    return true;
  };
  bool ok = true;
  for (int i = 0; i < n && ok; ++i)
    ok = assemble_point(i, cloud.positions[i], cloud.normals[i], cloud.spacing[i],
                        cloud.body_force.empty() ? none.body_force : cloud.body_force[i], cloud.rows[i]);
  for (int m = 0; m < static_cast<int>(cloud.extra_points.size()) && ok; ++m) {
    const CollocationPoint& p = cloud.extra_points[m];
    ok = assemble_point(n + m, p.position, p.normal, p.spacing, p.body_force, p.rows);
  }
  if (!ok) {
    system.stiffness.resize(0, 0);
    return;
  }
  system.stiffness.resize(3 * points, 3 * n);
  system.stiffness.setFromTriplets(triplets.begin(), triplets.end());
}

}  // namespace touchstone::realtime::mfs
