#pragma once
/// @file
/// Point collocation of linear elasticity with MLS shape functions: K U = f (paper eq. 6).
/// Three rows per node (CollocationRow), 3N unknowns u_J (nodal parameters, not displacements:
/// MLS does not interpolate).

#include "touchstone/geometry/material.hpp"
#include "touchstone/realtime/mfs/node_cloud.hpp"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <vector>

namespace touchstone::realtime::mfs {

struct CollocationSettings {
  /// Shape functions; supports may grow up to 1.5× where a collocation point (extra points
  /// sit between nodes) has too few neighbours.
  MlsSettings mls{Basis::quadratic, Weight::quartic_spline, 1e-12, 1.5};
  /// Scale rows to displacement units before solving: Navier rows by s²/E, traction rows by
  /// s/E (s = the node's spacing), Dirichlet rows by 1. Iterative solvers need it; LU does not
  /// care, and the solution is the same.
  bool scale_rows = true;
  /// Finite-increment-calculus stabilisation of the traction (Neumann) rows (Oñate, Perazzo &
  /// Miquel 2001): each traction row becomes e·(σn − β s (div σ + b)) = e·t̄, the balance of a
  /// boundary layer of thickness β s (s = the node's spacing) instead of a point. Consistent
  /// (the exact solution satisfies it for any β); β = 0 is plain collocation.
  double neumann_stabilization = 0.0;
  /// Weight of the boundary rows (traction and Dirichlet, after scaling) relative to the Navier
  /// rows. Only matters for least-squares collocation (extra points); a square system satisfies
  /// every row exactly whatever its weight.
  double boundary_row_weight = 1.0;
};

/// Why an assembly failed, with the node.
struct AssemblyStatus {
  MlsStatus mls = MlsStatus::ok;
  int node = -1;       ///< first collocation point whose shape functions failed (N + m: extra point m)
  double min_rcond = 1;  ///< smallest rcond(A) over all collocation points
  double max_support_scale = 1;  ///< largest adaptive support growth used (1: none)
  /// Nodes in the support of a collocation point: the MLS fit averages over these. Hundreds
  /// mean coarse nodes' supports cover the point and the fit is smoothed (a sprinkling problem).
  int max_neighbours = 0;
  double mean_neighbours = 0;
  bool ok() const { return mls == MlsStatus::ok; }
};

/// K (3(N + M) × 3N, row-major sparse; square without extra points) and the right-hand side
/// f = f₀ + G U_tool. Rows 3I…3I+2 belong to node I, rows 3(N + m)… to extra point m.
struct CollocationSystem {
  Eigen::SparseMatrix<double, Eigen::RowMajor> stiffness;
  Eigen::VectorXd constant_rhs;          ///< f₀
  Eigen::Matrix<double, Eigen::Dynamic, 3> tool_rhs;  ///< G
  Eigen::VectorXd row_scale;             ///< the scaling applied to each row (1 when off)
  AssemblyStatus status;
};

/// Assembles the collocation system of `cloud` for `material`. Nodes J contribute at x_I when
/// |x_I − x_J| < r_J. Does not throw: a failed shape-function evaluation is reported in
/// `status` (and the system is left empty).
void assemble_collocation(const NodeCloud& cloud, const geometry::Material& material,
                          const CollocationSettings& settings, CollocationSystem& system);

/// u_h(x) = Σ_J h_J(x) u_J [m] from the nodal parameters U (3N), and ∇u_h (∂u_i/∂x_k) when
/// `gradient` is given. Returns the MLS status; u is zero unless ok.
MlsStatus evaluate_displacement(const NodeCloud& cloud, const Eigen::VectorXd& parameters,
                                const Eigen::Vector3d& x, const MlsSettings& settings,
                                MlsEvaluation& scratch, Eigen::Vector3d& u,
                                Eigen::Matrix3d* gradient = nullptr) noexcept;

/// Coefficients of one row with respect to u_J (3 numbers) given h_J, ∇h_J, ∇∇h_J at x_I.
Eigen::Vector3d row_coefficients(const CollocationRow& row, const Eigen::Vector3d& normal,
                                 double lambda, double mu, double shape_value,
                                 const Eigen::Vector3d& gradient, const Eigen::Matrix3d& hessian) noexcept;

}  // namespace touchstone::realtime::mfs
