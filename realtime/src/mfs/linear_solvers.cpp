#include "touchstone/realtime/mfs/linear_solvers.hpp"

#include <Eigen/IterativeLinearSolvers>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <Eigen/LU>
#include <Eigen/SparseLU>
#include <unsupported/Eigen/IterativeSolvers>

namespace touchstone::realtime::mfs {

using RowMatrix = Eigen::SparseMatrix<double, Eigen::RowMajor>;
using ColMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor>;

struct CollocationSolver::Impl {
  Eigen::PartialPivLU<Eigen::MatrixXd> dense;
  Eigen::SparseLU<ColMatrix, Eigen::COLAMDOrdering<int>> sparse;
  Eigen::GMRES<ColMatrix, Eigen::IncompleteLUT<double>> gmres;
  ColMatrix matrix;            // the square matrix factorised (column-major: SparseLU and ILUT want it)
  ColMatrix rectangular;       // K when it has more rows than columns (matrix = KᵀK then)
  ColMatrix analysed_pattern;  // pattern of the last symbolic analysis
  bool analysed = false;
};

CollocationSolver::CollocationSolver(SolverSettings settings) : settings_(settings), impl_(std::make_unique<Impl>()) {}
CollocationSolver::~CollocationSolver() = default;
CollocationSolver::CollocationSolver(CollocationSolver&&) noexcept = default;
CollocationSolver& CollocationSolver::operator=(CollocationSolver&&) noexcept = default;

namespace {

std::string scientific(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3e", value);
  return text;
}

bool same_pattern(const ColMatrix& a, const ColMatrix& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols() || a.nonZeros() != b.nonZeros()) return false;
  for (Eigen::Index c = 0; c <= a.outerSize(); ++c)
    if (a.outerIndexPtr()[c] != b.outerIndexPtr()[c]) return false;
  return std::equal(a.innerIndexPtr(), a.innerIndexPtr() + a.nonZeros(), b.innerIndexPtr());
}

}  // namespace

SolveReport CollocationSolver::factorize(const RowMatrix& stiffness) {
  SolveReport report;
  Impl& s = *impl_;
  if (stiffness.rows() < stiffness.cols() || stiffness.cols() == 0)
    return {false, 0, 0, "K is " + std::to_string(stiffness.rows()) + " x " + std::to_string(stiffness.cols()) +
                             ": fewer equations than unknowns"};
  for (Eigen::Index k = 0; k < stiffness.nonZeros(); ++k)
    if (!std::isfinite(stiffness.valuePtr()[k])) return {false, 0, 0, "K has a non-finite entry"};
  if (stiffness.rows() > stiffness.cols()) {
    // Least-squares collocation: the normal equations KᵀK U = Kᵀf (KᵀK is SPD when K has full
    // column rank; the LU solvers do not need the symmetry).
    s.rectangular = stiffness;
    s.rectangular.makeCompressed();
    s.matrix = ColMatrix(s.rectangular.transpose()) * s.rectangular;
  } else {
    s.rectangular.resize(0, 0);
    s.matrix = stiffness;
  }
  s.matrix.makeCompressed();
  switch (settings_.kind) {
    case SolverKind::dense_lu: {
      s.dense.compute(Eigen::MatrixXd(s.matrix));
      // PartialPivLU does not report singularity: a zero pivot shows as a non-finite rcond.
      const double rcond = s.dense.rcond();
      if (!(rcond > 1e-16)) return {false, 0, 0, "K is singular (dense LU rcond " + std::to_string(rcond) + ")"};
      break;
    }
    case SolverKind::sparse_lu: {
      if (!s.analysed || !same_pattern(s.matrix, s.analysed_pattern)) {
        s.sparse.analyzePattern(s.matrix);
        s.analysed_pattern = s.matrix;
        s.analysed = true;
      } else {
        ++symbolic_reuses_;
      }
      s.sparse.factorize(s.matrix);
      if (s.sparse.info() != Eigen::Success) return {false, 0, 0, "K is singular (sparse LU: " + s.sparse.lastErrorMessage() + ")"};
      break;
    }
    case SolverKind::gmres_ilut: {
      s.gmres.preconditioner().setDroptol(settings_.ilut_drop_tolerance);
      s.gmres.preconditioner().setFillfactor(settings_.ilut_fill_factor);
      s.gmres.set_restart(settings_.gmres_restart);
      s.gmres.setTolerance(settings_.gmres_tolerance);
      s.gmres.setMaxIterations(settings_.gmres_max_iterations);
      s.gmres.compute(s.matrix);
      if (s.gmres.info() != Eigen::Success) return {false, 0, 0, "incomplete LU of K failed"};
      break;
    }
  }
  return report;
}

SolveReport CollocationSolver::solve(const Eigen::MatrixXd& rhs, Eigen::MatrixXd& solution) const {
  SolveReport report;
  Impl& s = *impl_;
  if (!rhs.allFinite()) return {false, 0, 0, "right-hand side is not finite"};
  const bool least_squares = s.rectangular.rows() > 0;
  const Eigen::Index expected_rows = least_squares ? s.rectangular.rows() : s.matrix.rows();
  if (rhs.rows() != expected_rows || s.matrix.rows() == 0)
    return {false, 0, 0, "right-hand side has " + std::to_string(rhs.rows()) + " rows, K has " + std::to_string(expected_rows)};
  const Eigen::MatrixXd projected = least_squares ? Eigen::MatrixXd(s.rectangular.transpose() * rhs) : Eigen::MatrixXd();
  const Eigen::MatrixXd& b = least_squares ? projected : rhs;
  Eigen::MatrixXd x(s.matrix.cols(), rhs.cols());
  switch (settings_.kind) {
    case SolverKind::dense_lu: x = s.dense.solve(b); break;
    case SolverKind::sparse_lu: x = s.sparse.solve(b); break;
    case SolverKind::gmres_ilut:
      for (Eigen::Index c = 0; c < b.cols(); ++c) {
        x.col(c) = s.gmres.solve(b.col(c));
        report.iterations += static_cast<int>(s.gmres.iterations());
        if (s.gmres.info() != Eigen::Success) {
          report.ok = false;
          report.failure = "GMRES did not converge in " + std::to_string(s.gmres.iterations()) +
                           " iterations (estimated relative error " + scientific(s.gmres.error()) + ")";
        }
      }
      break;
  }
  // Iterative refinement for the direct factorisations. The normal equations square K's
  // condition number, and near incompressibility the first solve's residual reaches the
  // acceptance bound. Least squares is refined and judged on its optimality condition
  // Kᵀ(K x − f) = 0 computed through K: the formed KᵀK carries rounding of its own that a
  // residual through it cannot see. A step is kept while it at least halves the residual.
  const auto residual_of = [&](const Eigen::MatrixXd& y) -> Eigen::MatrixXd {
    if (least_squares) return s.rectangular.transpose() * (rhs - s.rectangular * y);
    return b - s.matrix * y;
  };
  Eigen::MatrixXd residual = residual_of(x);
  constexpr int max_refinement_steps = 3;
  for (int step = 0; step < max_refinement_steps && settings_.kind != SolverKind::gmres_ilut && x.allFinite(); ++step) {
    const Eigen::MatrixXd refined =
        x + (settings_.kind == SolverKind::dense_lu ? Eigen::MatrixXd(s.dense.solve(residual)) : Eigen::MatrixXd(s.sparse.solve(residual)));
    Eigen::MatrixXd refined_residual = residual_of(refined);
    if (!(refined_residual.norm() <= 0.5 * residual.norm())) break;
    x = refined;
    residual = std::move(refined_residual);
  }
  const double norm = b.norm();
  report.relative_residual = norm > 0 ? residual.norm() / norm : residual.norm();
  if (least_squares) {
    const double f_norm = rhs.norm();
    report.least_squares_residual = f_norm > 0 ? (s.rectangular * x - rhs).norm() / f_norm : 0.0;
  }
  if (!x.allFinite()) return {false, report.iterations, report.relative_residual, "solution is not finite"};
  // LU does not always see a singular K (rounding leaves tiny non-zero pivots): judge the
  // residual, so that a wrong answer is never reported as a solution.
  if (report.ok && !(report.relative_residual <= settings_.max_relative_residual)) {
    report.ok = false;
    report.failure = "K is singular or too ill-conditioned: relative residual " + scientific(report.relative_residual) +
                     " > " + scientific(settings_.max_relative_residual);
  }
  if (report.ok) solution = std::move(x);
  return report;
}

std::string to_string(SolverKind kind) {
  switch (kind) {
    case SolverKind::dense_lu: return "dense_lu";
    case SolverKind::sparse_lu: return "sparse_lu";
    case SolverKind::gmres_ilut: return "gmres_ilut";
  }
  return "unknown";
}

}  // namespace touchstone::realtime::mfs
