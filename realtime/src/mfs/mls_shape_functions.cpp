/// @file
/// MLS shape functions with values, gradients and Hessians from one Cholesky factorisation of the
/// moment matrix (paper eqs. 3–5).
///
/// Frame. The basis is centred at a frozen point c and set to c = x after differentiating: the
/// MLS approximant does not depend on the polynomial frame, so differentiating with c fixed gives
/// the exact derivatives, and p(x) = e₁, p,i = e_{1+i}, p,ij = const. Sums are built in the
/// physical frame p(y − c) and A is factorised in the scaled frame p((y − c)/ρ) = D p(y − c),
/// ρ = the largest support radius among the neighbours, D = diag(1, 1/ρ, …, 1/ρ², …): entries of
/// the scaled A are O(1), so rcond is a property of the node geometry, not of the units.
///
/// Recurrence. With t_J = p_Jᵀγ, t_J,i = p_Jᵀγ,i, t_J,ij = p_Jᵀγ,ij, the products A,i γ etc. are
/// sums over nodes (A,i γ = Σ W_J,i t_J p_J), so A,i and A,ij are never formed:
///   A γ = p,   A γ,i = p,i − Σ W_J,i t_J p_J,
///   A γ,ij = p,ij − Σ (W_J,ij t_J + W_J,i t_J,j + W_J,j t_J,i) p_J,
///   h_J = W_J t_J,   h_J,i = W_J,i t_J + W_J t_J,i,
///   h_J,ij = W_J,ij t_J + W_J,i t_J,j + W_J,j t_J,i + W_J t_J,ij.
///
/// Result sizes. On status ok, value has one entry per neighbour, gradient too unless only values
/// were requested, hessian too if Hessians were requested; what was not requested is empty. On
/// any other status value/gradient/hessian are empty, neighbours holds the nodes with W > 0 that
/// were found (empty for non_finite_input) and rcond is 0, or the value that failed the
/// min_rcond test. rcond is the exact 1-norm value 1 / (‖Â‖₁ ‖Â⁻¹‖₁), not an estimate: Â⁻¹ is
/// formed anyway. A candidate index without a position or radius counts as invalid input
/// (non_finite_input); a node with r_J ≤ 0 has no support.

#include "touchstone/realtime/mfs/mls_shape_functions.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace touchstone::realtime::mfs {
namespace {

/// W, W', W'' and W'/s (finite as s → 0 because W'(0) = 0) at s = |x − x_J| / r_J.
struct WeightTerms {
  double w = 0;
  double dw = 0;
  double d2w = 0;
  double dw_over_s = 0;
};

constexpr double gaussian_alpha = 0.4;
const double gaussian_tail = std::exp(-1.0 / (gaussian_alpha * gaussian_alpha));

[[gnu::always_inline]] inline WeightTerms weight_terms(Weight weight, double s) noexcept {
  if (!(s < 1.0)) {
    return {};
  }
  s = std::max(s, 0.0);
  switch (weight) {
    case Weight::quartic_spline: {
      // Factored forms keep W > 0 up to s → 1 (the expanded polynomial cancels to noise there).
      const double t = 1.0 - s;
      return {t * t * t * (1.0 + 3.0 * s), -12.0 * s * t * t, -12.0 * t * (1.0 - 3.0 * s),
              -12.0 * t * t};
    }
    case Weight::cubic_spline: {
      // The classic spline times 3/2 so that W(0) = 1.
      if (s <= 0.5) {
        return {1.0 - 6.0 * s * s + 6.0 * s * s * s, -12.0 * s + 18.0 * s * s, -12.0 + 36.0 * s,
                -12.0 + 18.0 * s};
      }
      const double t = 1.0 - s;
      return {2.0 * t * t * t, -6.0 * t * t, 12.0 * t, -6.0 * t * t / s};
    }
    case Weight::truncated_gaussian: {
      const double a2 = gaussian_alpha * gaussian_alpha;
      const double scale = 1.0 / (1.0 - gaussian_tail);
      const double e = std::exp(-(s * s) / a2) * scale;
      const double dw_over_s = -2.0 / a2 * e;
      return {std::max(e - gaussian_tail * scale, 0.0), dw_over_s * s,
              (-2.0 / a2 + 4.0 * s * s / (a2 * a2)) * e, dw_over_s};
    }
  }
  return {};
}

template <int M>
using Vec = Eigen::Matrix<double, M, 1>;

/// Basis in the physical frame at y − c. Built in pairs: whole 16-byte stores let the packet
/// loads that consume p be forwarded (scalar stores then packet loads stall the pipeline).
template <int M>
Vec<M> basis_at(const Eigen::Vector3d& d) noexcept {
  Vec<M> p;
  p.template segment<2>(0) = Eigen::Vector2d(1.0, d.x());
  p.template segment<2>(2) = Eigen::Vector2d(d.y(), d.z());
  if constexpr (M == 10) {
    const Eigen::Array2d xy(d.x(), d.y());
    const Eigen::Array2d zx(d.z(), d.x());
    const Eigen::Array2d yz(d.y(), d.z());
    p.template segment<2>(4) = (xy * xy).matrix();
    p.template segment<2>(6) = (zx * Eigen::Array2d(d.z(), d.y())).matrix();
    p.template segment<2>(8) = (yz * Eigen::Array2d(d.z(), d.x())).matrix();
  }
  return p;
}

/// Second-derivative pairs, ordered like the quadratic terms 4…9 of the basis.
constexpr int pair_i[6] = {0, 1, 2, 0, 1, 2};
constexpr int pair_j[6] = {0, 1, 2, 1, 2, 0};

void clear_outputs(MlsEvaluation& result) noexcept {
  result.basis_scratch.clear();
  result.value.clear();
  result.gradient.clear();
  result.hessian.clear();
}

/// Inverse of the symmetric matrix whose lower triangle is in `a`, by Cholesky: A = L Lᵀ,
/// A⁻¹ = L⁻ᵀ L⁻¹. Hand-written for the fixed sizes 4 and 10: Eigen's general triangular solves
/// cost more than the whole factorisation here. False if A is not positive definite.
template <int M>
bool invert_spd(const Eigen::Matrix<double, M, M>& a, Eigen::Matrix<double, M, M>& inverse) noexcept {
  double l[M][M] = {};
  double l_inv[M][M] = {};  // L⁻¹, lower triangular; its diagonal comes with the factorisation
  for (int j = 0; j < M; ++j) {
    double pivot = a(j, j);
    for (int k = 0; k < j; ++k) pivot -= l[j][k] * l[j][k];
    if (!(pivot > 0.0)) return false;
    l[j][j] = std::sqrt(pivot);
    const double inv_pivot = l_inv[j][j] = 1.0 / l[j][j];
    for (int i = j + 1; i < M; ++i) {
      double v = a(i, j);
      for (int k = 0; k < j; ++k) v -= l[i][k] * l[j][k];
      l[i][j] = v * inv_pivot;
    }
  }
  // Products with the diagonal's reciprocals, not a division per entry (the divider set the
  // pace of the whole evaluation).
  for (int j = 0; j < M; ++j) {
    for (int i = j + 1; i < M; ++i) {
      double v = 0.0;
      for (int k = j; k < i; ++k) v -= l[i][k] * l_inv[k][j];
      l_inv[i][j] = v * l_inv[i][i];
    }
  }
  for (int j = 0; j < M; ++j) {
    for (int i = j; i < M; ++i) {
      double v = 0.0;
      for (int k = i; k < M; ++k) v += l_inv[k][i] * l_inv[k][j];
      inverse(i, j) = v;
      inverse(j, i) = v;
    }
  }
  return true;
}

/// Lower triangle of a += w p pᵀ, column by column with fixed-size (vectorised) segments.
template <int M, int B>
[[gnu::always_inline]] inline void accumulate_lower(Eigen::Matrix<double, M, M>& a, const Vec<M>& p, double w) noexcept {
  a.template block<M - B, 1>(B, B) += (w * p(B)) * p.template tail<M - B>();
  if constexpr (B + 1 < M) {
    accumulate_lower<M, B + 1>(a, p, w);
  }
}

template <int M>
double norm_1(const Eigen::Matrix<double, M, M>& a) noexcept {
  return a.cwiseAbs().colwise().sum().maxCoeff();
}

template <int M>
MlsStatus evaluate_fixed(const Eigen::Vector3d& x, const std::vector<Eigen::Vector3d>& positions,
                         const std::vector<double>& radii, const std::vector<int>& candidates,
                         const MlsSettings& settings, double radius_scale, Derivatives derivatives,
                         MlsEvaluation& result) noexcept {
  using Mat = Eigen::Matrix<double, M, M>;
  const bool want_gradients = derivatives != Derivatives::values;
  const bool want_hessians = derivatives == Derivatives::hessians;

  // Pass 1: neighbours, their weights with x-derivatives (parked in the output buffers) and the
  // lower triangle of the moment matrix in the physical frame centred at x.
  const std::size_t node_count = std::min(positions.size(), radii.size());
  const std::size_t candidate_count = candidates.empty() ? positions.size() : candidates.size();
  // The buffers are sized for every candidate once and cut to the neighbours found at the end:
  // growing them one neighbour at a time cost more than the moment sums.
  result.neighbours.resize(candidate_count);
  result.value.resize(candidate_count);
  if (want_gradients) result.gradient.resize(candidate_count);
  if (want_hessians) result.hessian.resize(candidate_count);
  result.basis_scratch.resize(candidate_count * M);
  std::size_t found = 0;
  Mat moments = Mat::Zero();
  double rho = 0.0;
  for (std::size_t c = 0; c < candidate_count; ++c) {
    const int j = candidates.empty() ? static_cast<int>(c) : candidates[c];
    if (j < 0 || static_cast<std::size_t>(j) >= node_count || !positions[j].allFinite() ||
        !std::isfinite(radii[j])) {
      result.neighbours.clear();
      return MlsStatus::non_finite_input;
    }
    const Eigen::Vector3d delta = positions[j] - x;
    const double r = radius_scale * radii[j];
    // Most candidates outside the support are turned away on the squared distance, without a
    // square root.
    const double d_squared = delta.squaredNorm();
    if (!(d_squared < r * r)) {
      continue;
    }
    const double d = std::sqrt(d_squared);
    const WeightTerms wt = weight_terms(settings.weight, d / r);
    if (!(wt.w > 0.0)) {
      continue;
    }
    result.neighbours[found] = j;
    result.value[found] = wt.w;
    const double inv_r2 = 1.0 / (r * r);
    if (want_gradients) {
      // W,i = W'(s) (x_i − x_Ji) / (d r) = −(W'/s) Δ_i / r², Δ = x_J − x.
      result.gradient[found] = -wt.dw_over_s * inv_r2 * delta;
    }
    if (want_hessians) {
      // W,ij = (W'' − W'/s) n_i n_j / r² + (W'/s) δ_ij / r²; the first factor vanishes at d = 0.
      const Eigen::Vector3d n = d > 0.0 ? Eigen::Vector3d(delta / d) : Eigen::Vector3d::Zero();
      const double radial = (wt.d2w - wt.dw_over_s) * inv_r2;
      Eigen::Matrix3d& hw = result.hessian[found];
      for (int b = 0; b < 3; ++b) {
        for (int a = 0; a < 3; ++a) {
          hw(a, b) = radial * n(a) * n(b);
        }
        hw(b, b) += wt.dw_over_s * inv_r2;
      }
    }
    const Vec<M> p = basis_at<M>(delta);
    Eigen::Map<Vec<M>>(result.basis_scratch.data() + found * M) = p;
    accumulate_lower<M, 0>(moments, p, wt.w);
    rho = std::max(rho, r);
    ++found;
  }
  result.neighbours.resize(found);
  result.value.resize(found);
  if (want_gradients) result.gradient.resize(found);
  if (want_hessians) result.hessian.resize(found);
  result.basis_scratch.resize(found * M);

  const std::size_t n = result.neighbours.size();
  if (n < static_cast<std::size_t>(M)) {
    return MlsStatus::too_few_nodes;
  }

  // One factorisation, in the scaled frame Â = D A D; then A⁻¹ = D Â⁻¹ D.
  Vec<M> frame;
  frame(0) = 1.0;
  frame.template segment<3>(1).setConstant(1.0 / rho);
  if constexpr (M == 10) {
    frame.template tail<6>().setConstant(1.0 / (rho * rho));
  }
  Mat scaled = moments.template selfadjointView<Eigen::Lower>();
  scaled = frame.asDiagonal() * scaled * frame.asDiagonal();
  Mat inverse;
  if (!invert_spd<M>(scaled, inverse)) {
    return MlsStatus::singular_moments;
  }
  // Exact 1-norm condition of Â: with Â⁻¹ at hand it is cheaper than an estimate.
  const double rcond = 1.0 / (norm_1<M>(scaled) * norm_1<M>(inverse));
  result.rcond = std::isfinite(rcond) ? rcond : 0.0;
  if (!(rcond >= settings.min_rcond)) {
    return MlsStatus::singular_moments;
  }
  inverse = frame.asDiagonal() * inverse * frame.asDiagonal();
  // The basis at each neighbour, as pass 1 computed it, and t_J = p_Jᵀγ, computed once.
  const auto basis_of = [&](std::size_t k) { return Eigen::Map<const Vec<M>>(result.basis_scratch.data() + k * M); };

  const Vec<M> gamma = inverse.col(0);
  bool finite = gamma.allFinite();
  std::vector<double>& t_of = result.t_scratch;
  t_of.resize(n);
  for (std::size_t k = 0; k < n; ++k) t_of[k] = basis_of(k).dot(gamma);

  // Each pass finalises what no later pass needs; a running sum of the outputs catches any
  // overflow so that no Inf/NaN escapes.
  double check = 0.0;
  if (!want_gradients) {
    for (std::size_t k = 0; k < n; ++k) {
      result.value[k] *= t_of[k];
      check += result.value[k];
    }
    return finite && std::isfinite(check) ? MlsStatus::ok : MlsStatus::singular_moments;
  }

  // Pass 2: γ,i from A γ,i = p,i − Σ W_J,i t_J p_J.
  Eigen::Matrix<double, M, 3> rhs_1 = Eigen::Matrix<double, M, 3>::Zero();
  rhs_1.template block<3, 3>(1, 0).setIdentity();
  for (std::size_t k = 0; k < n; ++k) rhs_1.noalias() -= basis_of(k) * (t_of[k] * result.gradient[k]).transpose();
  const Eigen::Matrix<double, M, 3> gamma_1 = inverse.lazyProduct(rhs_1);
  finite = finite && gamma_1.allFinite();

  if (!want_hessians) {
    for (std::size_t k = 0; k < n; ++k) {
      const double w = result.value[k];
      const double t = t_of[k];
      result.value[k] = w * t;
      result.gradient[k] = t * result.gradient[k] + w * (gamma_1.transpose() * basis_of(k));
      check += result.value[k] + result.gradient[k].sum();
    }
    return finite && std::isfinite(check) ? MlsStatus::ok : MlsStatus::singular_moments;
  }

  // Pass 3: γ,ij from A γ,ij = p,ij − Σ C_J,ij p_J with C_J,ij = W_J,ij t_J + W_J,i t_J,j +
  // W_J,j t_J,i, which is also h_J,ij without its last term: park C_J in the Hessian slot.
  // Gradients are final here.
  Eigen::Matrix<double, M, 6> rhs_2 = Eigen::Matrix<double, M, 6>::Zero();
  if constexpr (M == 10) {
    rhs_2.template block<6, 6>(4, 0).diagonal() << 2.0, 2.0, 2.0, 1.0, 1.0, 1.0;
  }
  for (std::size_t k = 0; k < n; ++k) {
    const Vec<M> p = basis_of(k);
    const double w = result.value[k];
    const double t = t_of[k];
    const Eigen::Vector3d t1 = gamma_1.transpose() * p;
    const Eigen::Vector3d gw = result.gradient[k];
    Eigen::Matrix3d& h = result.hessian[k];
    Eigen::Matrix<double, 6, 1> coupling;
    for (int q = 0; q < 6; ++q) {
      const int i = pair_i[q];
      const int j = pair_j[q];
      coupling(q) = t * h(i, j) + gw(i) * t1(j) + gw(j) * t1(i);
      h(i, j) = coupling(q);
      h(j, i) = coupling(q);
    }
    rhs_2.noalias() -= p * coupling.transpose();
    result.gradient[k] = t * gw + w * t1;
    check += result.gradient[k].sum();
  }
  const Eigen::Matrix<double, M, 6> gamma_2 = inverse.lazyProduct(rhs_2);
  finite = finite && gamma_2.allFinite();

  // Pass 4: values and the W_J t_J,ij term of the Hessians.
  for (std::size_t k = 0; k < n; ++k) {
    const Vec<M> p = basis_of(k);
    const double w = result.value[k];
    result.value[k] = w * t_of[k];
    const Eigen::Matrix<double, 6, 1> w_t2 = w * (gamma_2.transpose() * p);
    Eigen::Matrix3d& h = result.hessian[k];
    for (int q = 0; q < 3; ++q) {
      h(q, q) += w_t2(q);
    }
    for (int q = 3; q < 6; ++q) {
      h(pair_i[q], pair_j[q]) += w_t2(q);
      h(pair_j[q], pair_i[q]) += w_t2(q);
    }
    check += result.value[k] + h.sum();
  }
  if (!finite || !std::isfinite(check)) {
    return MlsStatus::singular_moments;
  }
  return MlsStatus::ok;
}

}  // namespace

void evaluate_mls(const Eigen::Vector3d& x, const std::vector<Eigen::Vector3d>& positions,
                  const std::vector<double>& radii, const std::vector<int>& candidates,
                  const MlsSettings& settings, Derivatives derivatives, MlsEvaluation& result) noexcept {
  result.rcond = 0.0;
  result.support_scale = 1.0;
  result.neighbours.clear();
  clear_outputs(result);
  if (!x.allFinite()) {
    result.status = MlsStatus::non_finite_input;
    return;
  }
  // Growth factors 1, 1.2, 1.2², … within the bound; the last one tried always fits it.
  constexpr double growth = 1.2;
  const double bound = std::isfinite(settings.max_support_scale) ? std::max(1.0, settings.max_support_scale) : 1.0;
  for (double scale = 1.0;; scale = std::min(scale * growth, bound)) {
    result.support_scale = scale;
    result.rcond = 0.0;
    result.neighbours.clear();
    clear_outputs(result);
    result.status = settings.basis == Basis::linear
                        ? evaluate_fixed<4>(x, positions, radii, candidates, settings, scale, derivatives, result)
                        : evaluate_fixed<10>(x, positions, radii, candidates, settings, scale, derivatives, result);
    if (result.status == MlsStatus::ok || result.status == MlsStatus::non_finite_input || scale >= bound) break;
  }
  if (result.status != MlsStatus::ok) {
    clear_outputs(result);
  }
}

Eigen::Vector3d weight_and_derivatives(Weight weight, double s) noexcept {
  const WeightTerms wt = weight_terms(weight, s);
  return {wt.w, wt.dw, wt.d2w};
}

}  // namespace touchstone::realtime::mfs
