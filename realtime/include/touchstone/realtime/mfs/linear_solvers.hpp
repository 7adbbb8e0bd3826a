#pragma once
/// @file
/// Solvers for the unsymmetric collocation system K U = f: dense LU for small
/// N, sparse LU with the symbolic analysis reused while the sparsity pattern stays the same,
/// and restarted GMRES with an incomplete-LU preconditioner (the paper used LU and GMRES).

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <cstdint>
#include <memory>
#include <string>

namespace touchstone::realtime::mfs {

enum class SolverKind : std::uint8_t { dense_lu, sparse_lu, gmres_ilut };

struct SolverSettings {
  SolverKind kind = SolverKind::sparse_lu;
  double gmres_tolerance = 1e-12;   ///< relative residual
  int gmres_restart = 60;
  int gmres_max_iterations = 2000;
  /// A solve whose relative residual (of the normal equations for least squares) exceeds this is a failure.
  double max_relative_residual = 1e-6;
  double ilut_drop_tolerance = 1e-6;
  int ilut_fill_factor = 20;
};

/// What a factorisation or solve did. `ok` false: `failure` says why (singular K, GMRES not
/// converged, non-finite values); the solution is then left untouched.
struct SolveReport {
  bool ok = true;
  int iterations = 0;           ///< GMRES iterations (0 for LU)
  double relative_residual = 0; ///< ‖K x − f‖ / ‖f‖ of the last solve; for least squares ‖Kᵀ(K x − f)‖ / ‖Kᵀf‖, through K
  std::string failure;
  double least_squares_residual = 0;  ///< ‖K x − f‖ / ‖f‖ when K is rectangular (not zero: the fit's misfit)
};

class CollocationSolver {
 public:
  explicit CollocationSolver(SolverSettings settings = {});
  ~CollocationSolver();
  CollocationSolver(CollocationSolver&&) noexcept;
  CollocationSolver& operator=(CollocationSolver&&) noexcept;

  /// Factorises K (reuses the sparse symbolic analysis when the pattern is unchanged). A K with
  /// more rows than columns (least-squares collocation) is solved through its normal equations
  /// KᵀK U = Kᵀ f; fewer rows than columns is an error.
  SolveReport factorize(const Eigen::SparseMatrix<double, Eigen::RowMajor>& stiffness);
  /// x = K⁻¹ f for one or several right-hand sides (columns).
  SolveReport solve(const Eigen::MatrixXd& rhs, Eigen::MatrixXd& solution) const;

  const SolverSettings& settings() const { return settings_; }
  /// Number of factorisations that reused the previous symbolic analysis.
  int symbolic_reuses() const { return symbolic_reuses_; }

 private:
  struct Impl;
  SolverSettings settings_;
  std::unique_ptr<Impl> impl_;
  int symbolic_reuses_ = 0;
};

std::string to_string(SolverKind kind);

}  // namespace touchstone::realtime::mfs
