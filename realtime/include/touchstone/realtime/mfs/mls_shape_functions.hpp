#pragma once
/// @file
/// Moving-least-squares shape functions of the Method of Finite Spheres (paper eqs. 3–5):
/// h_J(x) = W_J(x) p(x)ᵀ A(x)⁻¹ p(x_J), A(x) = Σ_J W_J(x) p(x_J) p(x_J)ᵀ,
/// with values, gradients and Hessians from one factorisation of A.

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace touchstone::realtime::mfs {

/// Polynomial basis p. Always evaluated in the shifted, scaled frame p((y − x)/ρ) around the
/// evaluation point x (same functions, far better conditioned moment matrix).
enum class Basis : std::uint8_t {
  linear,     ///< [1, x, y, z]: the paper's basis (4 terms)
  quadratic,  ///< [1, x, y, z, x², y², z², xy, yz, zx] (10 terms): the convergent default
};

/// Weight W(s), s = |x − x_J| / r_J ∈ [0, 1], zero for s ≥ 1.
enum class Weight : std::uint8_t {
  quartic_spline,      ///< 1 − 6s² + 8s³ − 3s⁴ (C², default)
  cubic_spline,        ///< 2/3 − 4s² + 4s³ (s ≤ ½), 4/3 − 4s + 4s² − 4s³/3 (s > ½), scaled to W(0) = 1
  truncated_gaussian,  ///< (exp(−(s/α)²) − exp(−1/α²)) / (1 − exp(−1/α²)), α = 0.4
};

/// What one evaluation found. Never NaN: a failed evaluation says why.
enum class MlsStatus : std::uint8_t {
  ok,
  too_few_nodes,      ///< fewer nodes with W > 0 than basis terms
  singular_moments,   ///< A not invertible (e.g. all nodes coplanar, or on one sphere for the quadratic basis)
  non_finite_input,   ///< NaN/Inf coordinate or radius
};

/// Number of basis terms: 4 (linear) or 10 (quadratic).
constexpr int basis_size(Basis basis) { return basis == Basis::linear ? 4 : 10; }

/// Shape-function values and derivatives at one point, for the nodes in `neighbours`.
struct MlsEvaluation {
  MlsStatus status = MlsStatus::ok;
  double support_scale = 1;                  ///< the support growth that made A regular (1: none)
  double rcond = 0;                          ///< reciprocal 1-norm condition number 1/(‖Â‖₁‖Â⁻¹‖₁) of the scaled A (exact)
  std::vector<int> neighbours;               ///< node indices with W_J(x) > 0
  std::vector<double> value;                 ///< h_J(x)
  std::vector<Eigen::Vector3d> gradient;     ///< ∂h_J/∂x_i [1/m]
  std::vector<Eigen::Matrix3d> hessian;      ///< ∂²h_J/∂x_i∂x_k [1/m²] (symmetric)
  /// Scratch of the evaluation, kept to stay allocation-free: the basis at each neighbour
  /// (p(x_J − x), one row of the basis size each) and t_J = p_Jᵀγ.
  std::vector<double> basis_scratch, t_scratch;
};

/// What to compute: values only, + gradients, + Hessians (collocation needs all three).
enum class Derivatives : std::uint8_t { values, gradients, hessians };

struct MlsSettings {
  Basis basis = Basis::quadratic;
  Weight weight = Weight::quartic_spline;
  /// rcond(A) below this is treated as singular (A is built in the scaled frame, so this is
  /// a property of the node geometry, not of the units).
  double min_rcond = 1e-12;
  /// Adaptive support growth: when A is singular or has too few nodes at x, every support
  /// radius is multiplied by 1.2, 1.2², … up to this bound and A rebuilt. 1 disables it; the
  /// growth used is reported (MlsEvaluation::support_scale).
  double max_support_scale = 1.0;
};

/// Evaluates the shape functions at x for nodes at `positions` [m] with support radii `radii`
/// [m]. `candidates` lists the node indices to consider (e.g. from a neighbour search); empty
/// means all nodes. Nodes with |x − x_J| ≥ r_J do not contribute. Allocation-free after the first call with
/// the same capacity: `result` keeps its buffers. noexcept: failures are a status.
void evaluate_mls(const Eigen::Vector3d& x, const std::vector<Eigen::Vector3d>& positions,
                  const std::vector<double>& radii, const std::vector<int>& candidates,
                  const MlsSettings& settings, Derivatives derivatives, MlsEvaluation& result) noexcept;

/// The most points evaluate_mls_batch takes at once: one per lane of the widest vector of
/// doubles the build targets (eight with AVX-512, four with AVX2 or less).
#ifdef __AVX512F__
inline constexpr int mls_batch_size = 8;
#else
inline constexpr int mls_batch_size = 4;
#endif

/// evaluate_mls at `count` points (at most mls_batch_size) with every node a candidate, results[k] for x[k]:
/// the same neighbours, statuses and support growth, and the same values and gradients to
/// rounding. With the quartic spline (the default) and without Hessians the points share one
/// pass over the nodes, their moment sums, M × M inverses and shape functions (either basis)
/// computed side by side in the lanes of a vector; a point that needs its supports grown or
/// fails is evaluated on its own. Other settings evaluate the points one by one.
void evaluate_mls_batch(const Eigen::Vector3d* x, int count, const std::vector<Eigen::Vector3d>& positions,
                        const std::vector<double>& radii, const MlsSettings& settings, Derivatives derivatives,
                        MlsEvaluation* results) noexcept;

/// Weight function and its first two derivatives with respect to s: {W, dW/ds, d²W/ds²}.
Eigen::Vector3d weight_and_derivatives(Weight weight, double s) noexcept;

}  // namespace touchstone::realtime::mfs
