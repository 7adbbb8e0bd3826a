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

#ifdef __AVX512F__
#include <immintrin.h>
#endif

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

inline double square_root(double v) noexcept { return std::sqrt(v); }
/// The lanes' square root, correctly rounded as std::sqrt is: Eigen's 512-bit packet square
/// root is an approximation (rsqrt14 and two Newton steps, under its default EIGEN_FAST_MATH),
/// which would make the lanes round differently from the one-point evaluation.
template <int Size>
inline Eigen::Array<double, Size, 1> square_root(const Eigen::Array<double, Size, 1>& v) noexcept {
#ifdef __AVX512F__
  if constexpr (Size == 8) {
    Eigen::Array<double, Size, 1> root;
    _mm512_storeu_pd(root.data(), _mm512_sqrt_pd(_mm512_loadu_pd(v.data())));
    return root;
  }
#endif
  return v.sqrt();  // 256- and 128-bit packets take the exact instruction
}
inline void set_zero(double& v) noexcept { v = 0.0; }
template <int Size>
inline void set_zero(Eigen::Array<double, Size, 1>& v) noexcept { v.setZero(); }

/// Inverse of a symmetric positive definite M × M matrix by Cholesky: A = L Lᵀ,
/// A⁻¹ = L⁻ᵀ L⁻¹. Hand-written for the fixed sizes 4 and 10: Eigen's general triangular solves
/// cost more than the whole factorisation here. T is double (one matrix) or an array of lanes (one
/// matrix per lane, each lane doing the same operations in the same order as the one
/// matrix would). `a(i, j)` gives the lower triangle (i ≥ j); `store(i, j, v)` receives A⁻¹'s
/// entries (i ≥ j, for both triangles). `accept_pivot(pivot)` sees each pivot before its square
/// root: false stops with false; it may replace the pivots of lanes it gives up.
template <int M, class T, class Entry, class Store, class AcceptPivot>
bool cholesky_inverse(Entry a, Store store, AcceptPivot accept_pivot) noexcept {
  T l[M][M];
  T l_inv[M][M];  // L⁻¹, lower triangular; its diagonal comes with the factorisation
  for (int j = 0; j < M; ++j) {
    T pivot = a(j, j);
    for (int k = 0; k < j; ++k) pivot -= l[j][k] * l[j][k];
    if (!accept_pivot(pivot)) return false;
    l[j][j] = square_root(pivot);
    const T inv_pivot = l_inv[j][j] = 1.0 / l[j][j];
    for (int i = j + 1; i < M; ++i) {
      T v = a(i, j);
      for (int k = 0; k < j; ++k) v -= l[i][k] * l[j][k];
      l[i][j] = v * inv_pivot;
    }
  }
  // Products with the diagonal's reciprocals, not a division per entry (the divider set the
  // pace of the whole evaluation).
  for (int j = 0; j < M; ++j)
    for (int i = j + 1; i < M; ++i) {
      T v;
      set_zero(v);
      for (int k = j; k < i; ++k) v -= l[i][k] * l_inv[k][j];
      l_inv[i][j] = v * l_inv[i][i];
    }
  for (int j = 0; j < M; ++j)
    for (int i = j; i < M; ++i) {
      T v;
      set_zero(v);
      for (int k = i; k < M; ++k) v += l_inv[k][i] * l_inv[k][j];
      store(i, j, v);
    }
  return true;
}

/// Inverse of the symmetric matrix whose lower triangle is in `a`. False if A is not positive
/// definite.
template <int M>
bool invert_spd(const Eigen::Matrix<double, M, M>& a, Eigen::Matrix<double, M, M>& inverse) noexcept {
  return cholesky_inverse<M, double>([&](int i, int j) { return a(i, j); },
                                     [&](int i, int j, double v) { inverse(i, j) = inverse(j, i) = v; },
                                     [](double pivot) { return pivot > 0.0; });
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
MlsStatus finish_from_inverse(const Eigen::Matrix<double, M, M>& inverse, Derivatives derivatives,
                              MlsEvaluation& result) noexcept;

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
  return finish_from_inverse<M>(inverse, derivatives, result);
}

/// Everything after A⁻¹ (physical frame): γ, its derivatives, and the shape functions. On entry
/// `result` holds pass 1's neighbours, their weights in `value`, the weights' gradients in
/// `gradient` (and Hessians in `hessian`) and the basis at each neighbour in `basis_scratch`.
template <int M>
MlsStatus finish_from_inverse(const Eigen::Matrix<double, M, M>& inverse, Derivatives derivatives,
                              MlsEvaluation& result) noexcept {
  const bool want_gradients = derivatives != Derivatives::values;
  const bool want_hessians = derivatives == Derivatives::hessians;
  const std::size_t n = result.neighbours.size();
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

/// mls_batch_size points side by side, one per lane of a vector: either basis with the quartic spline
/// weight at support scale 1, every node a candidate. The moment sums and the M × M inverses
/// are those of evaluate_fixed<M> lane by lane (the same operations in the same order per
/// entry; only the exact condition number's column sums may round differently); the finish
/// (γ, γ,i, the shape functions) runs in the lanes too, with its sums in its own order, so the
/// values and gradients agree with the one-point evaluation to rounding. Whatever
/// evaluate_fixed would not finish at scale 1 (too few nodes, a singular or ill-conditioned A,
/// a non-finite input) goes back to the one-point evaluation, which then grows the supports as
/// it always does.
constexpr int lane_count = mls_batch_size;
using Lanes = Eigen::Array<double, lane_count, 1>;

/// invert_spd<M> on lane_count matrices at once (entry [i][j], i ≥ j, of the lower triangle; lane k
/// of each entry belongs to matrix k). ok[k] is false where matrix k is not positive definite.
template <int M>
void invert_spd_lanes(const Lanes (&a)[M][M], Lanes (&inverse)[M][M], bool (&ok)[lane_count]) noexcept {
  cholesky_inverse<M, Lanes>([&](int i, int j) { return a[i][j]; },
                             [&](int i, int j, const Lanes& v) { inverse[i][j] = inverse[j][i] = v; },
                             [&](Lanes& pivot) {
                               for (int k = 0; k < lane_count; ++k)
                                 if (!(pivot[k] > 0.0)) {
                                   ok[k] = false;
                                   pivot[k] = 1.0;  // keeps the other lanes finite; this lane is dropped
                                 }
                               return true;
                             });
}

/// Largest column sum of |S| for the symmetric matrices whose lower triangles are in s.
template <int M>
Lanes norm_1_lanes(const Lanes (&s)[M][M]) noexcept {
  Lanes largest = Lanes::Zero();
  for (int j = 0; j < M; ++j) {
    Lanes sum = Lanes::Zero();
    for (int i = 0; i < M; ++i) sum += (i >= j ? s[i][j] : s[j][i]).abs();
    largest = largest.max(sum);
  }
  return largest;
}

/// basis_at<M> in the lanes: 1, x, y, z, then (quadratic) x², y², z², xy, yz, zx.
template <int M>
void basis_lanes(const Lanes& dx, const Lanes& dy, const Lanes& dz, Lanes (&p)[M]) noexcept {
  p[0] = Lanes::Ones(), p[1] = dx, p[2] = dy, p[3] = dz;
  if constexpr (M == 10) {
    p[4] = dx * dx, p[5] = dy * dy, p[6] = dz * dz, p[7] = dx * dy, p[8] = dy * dz, p[9] = dz * dx;
  }
}

/// A node that some lane keeps, as pass 1 of the lanes leaves it for the finish: its weight and
/// the weight's gradient (zero in the lanes that do not keep it) and its offset x_J − x, from
/// which the basis is rebuilt (six products, cheaper to redo than to store); then t_J = p_Jᵀγ,
/// once the finish has γ.
struct KeptNode {
  Lanes w, gx, gy, gz, dx, dy, dz, t;
  int node;
  unsigned lanes;  ///< bit k set: lane k keeps the node
};

/// Columns First … Last − 1 of the moments' lower triangle, Σ_J W_J p_J p_Jᵀ over the kept nodes
/// in their order, each entry (W_J p_b) p_i as the one-point evaluation sums it. A few columns
/// at a time, so that their sums stay in registers while the nodes stream past (all 55 sums of
/// the quadratic basis do not fit, and summing them in memory stalls on every node).
template <int M, int First, int Last>
[[gnu::always_inline]] inline void moment_columns(const KeptNode* kept, std::size_t count, Lanes (&moments)[M][M]) noexcept {
  constexpr int entries = (Last - First) * M - ((Last - 1) * Last - (First - 1) * First) / 2;
  Lanes sum[entries];
  for (int e = 0; e < entries; ++e) sum[e] = Lanes::Zero();
  for (std::size_t c = 0; c < count; ++c) {
    Lanes p[M];
    basis_lanes<M>(kept[c].dx, kept[c].dy, kept[c].dz, p);
    int e = 0;
    for (int b = First; b < Last; ++b) {
      const Lanes wp = kept[c].w * p[b];
      for (int i = b; i < M; ++i) sum[e++] += wp * p[i];
    }
  }
  int e = 0;
  for (int b = First; b < Last; ++b)
    for (int i = b; i < M; ++i) moments[i][b] = sum[e++];
}

template <int M>
void moment_sums(const KeptNode* kept, std::size_t count, Lanes (&moments)[M][M]) noexcept {
  if constexpr (M == 10) {
    moment_columns<M, 0, 1>(kept, count, moments);
    moment_columns<M, 1, 3>(kept, count, moments);
    moment_columns<M, 3, 6>(kept, count, moments);
    moment_columns<M, 6, 10>(kept, count, moments);
  } else {
    moment_columns<M, 0, M>(kept, count, moments);
  }
}

template <int M>
void evaluate_lanes(const Eigen::Vector3d* x, int count, const std::vector<Eigen::Vector3d>& positions,
                    const std::vector<double>& radii, const MlsSettings& settings, Derivatives derivatives,
                    MlsEvaluation* results) noexcept {
  const bool want_gradients = derivatives != Derivatives::values;
  const std::size_t node_count = std::min(positions.size(), radii.size());
  // Per thread and never shrunk, so that later calls allocate nothing.
  thread_local std::vector<KeptNode> kept;
  if (kept.size() < node_count) kept.resize(node_count);
  bool vector_path[lane_count] = {};
  Lanes px, py, pz;
  for (int k = 0; k < lane_count; ++k) {
    const Eigen::Vector3d& xk = x[std::min(k, count - 1)];  // spare lanes repeat the last point
    px[k] = xk.x(), py[k] = xk.y(), pz[k] = xk.z();
    if (k >= count) continue;
    vector_path[k] = xk.allFinite();
    MlsEvaluation& r = results[k];
    r.rcond = 0.0;
    r.support_scale = 1.0;
    r.status = MlsStatus::ok;
    clear_outputs(r);
    r.neighbours.clear();
  }
  // Pass 1: every node's distance test and weight in the lanes; the nodes that any lane keeps
  // are recorded, and the moment sums run over the records.
  std::size_t found[lane_count] = {};
  std::size_t kept_count = 0;
  Lanes moments[M][M];
  Lanes rho = Lanes::Zero();
  bool inputs_finite = true;
  for (std::size_t j = 0; j < node_count && inputs_finite; ++j) {
    const Eigen::Vector3d& node = positions[j];
    if (!node.allFinite() || !std::isfinite(radii[j])) {
      inputs_finite = false;
      break;
    }
    const double r = radii[j];
    const Lanes dx = node.x() - px, dy = node.y() - py, dz = node.z() - pz;
    const Lanes d_squared = dx * dx + dy * dy + dz * dz;
    const auto near = d_squared < r * r;
    if (!near.any()) continue;
    // weight_terms(quartic_spline, s), lane by lane.
    const Lanes s = square_root(d_squared) / r;
    const Lanes t = 1.0 - s;
    const Lanes w = t * t * t * (1.0 + 3.0 * s);
    const Lanes dw_over_s = -12.0 * t * t;
    const auto keep = near && s < 1.0 && w > 0.0;
    if (!keep.any()) continue;
    const Lanes kept_w = keep.select(w, Lanes::Zero());
    KeptNode& record = kept[kept_count++];
    record.node = static_cast<int>(j);
    record.lanes = 0;
    for (int k = 0; k < count; ++k)
      if (keep[k]) {
        record.lanes |= 1u << k;
        ++found[k];
      }
    // W,i = −(W'/s) Δ_i / r², Δ = x_J − x, as the one-point evaluation forms it.
    const Lanes gradient_factor = keep.select(-dw_over_s * (1.0 / (r * r)), Lanes::Zero());
    record.w = kept_w;
    record.gx = gradient_factor * dx, record.gy = gradient_factor * dy, record.gz = gradient_factor * dz;
    record.dx = dx, record.dy = dy, record.dz = dz;
    rho = keep.select(rho.max(Lanes::Constant(r)), rho);
  }
  moment_sums<M>(kept.data(), kept_count, moments);
  // Â = D A D per lane, its inverse, the exact condition number.
  Lanes frame[M];
  frame[0] = Lanes::Ones();
  for (int i = 1; i < 4; ++i) frame[i] = 1.0 / rho;
  for (int i = 4; i < M; ++i) frame[i] = 1.0 / (rho * rho);
  Lanes scaled[M][M], inverse[M][M];
  for (int i = 0; i < M; ++i)
    for (int j = 0; j <= i; ++j) scaled[i][j] = frame[i] * moments[i][j] * frame[j];
  bool positive_definite[lane_count];
  std::fill(std::begin(positive_definite), std::end(positive_definite), true);
  invert_spd_lanes<M>(scaled, inverse, positive_definite);
  const Lanes rcond = 1.0 / (norm_1_lanes<M>(scaled) * norm_1_lanes<M>(inverse));
  bool finished[lane_count] = {};
  bool any_finished = false;
  for (int k = 0; k < count; ++k) {
    MlsEvaluation& out = results[k];
    finished[k] = vector_path[k] && inputs_finite && found[k] >= static_cast<std::size_t>(M) && positive_definite[k];
    if (finished[k]) {
      out.rcond = std::isfinite(rcond[k]) ? rcond[k] : 0.0;
      finished[k] = rcond[k] >= settings.min_rcond;
    }
    any_finished = any_finished || finished[k];
  }
  if (any_finished) {
    // A⁻¹ = D Â⁻¹ D in the physical frame; γ is its first column.
    for (int i = 0; i < M; ++i)
      for (int j = 0; j < M; ++j) inverse[i][j] = frame[i] * inverse[i][j] * frame[j];
    // Pass 2 (gradients): t_J = p_Jᵀγ, and A γ,i = p,i − Σ W_J,i t_J p_J.
    Lanes rhs[M][3];
    for (int b = 0; b < M; ++b)
      for (int i = 0; i < 3; ++i) rhs[b][i] = (b == i + 1) ? Lanes::Ones() : Lanes::Zero();
    for (std::size_t c = 0; c < kept_count; ++c) {
      KeptNode& record = kept[c];
      Lanes p[M];
      basis_lanes<M>(record.dx, record.dy, record.dz, p);
      Lanes t = p[0] * inverse[0][0];
      for (int b = 1; b < M; ++b) t += p[b] * inverse[b][0];
      record.t = t;
      if (!want_gradients) continue;
      const Lanes tgx = t * record.gx, tgy = t * record.gy, tgz = t * record.gz;
      for (int b = 0; b < M; ++b) {
        rhs[b][0] -= p[b] * tgx;
        rhs[b][1] -= p[b] * tgy;
        rhs[b][2] -= p[b] * tgz;
      }
    }
    Lanes gamma_1[M][3];
    if (want_gradients)
      for (int b = 0; b < M; ++b)
        for (int i = 0; i < 3; ++i) {
          Lanes v = inverse[b][0] * rhs[0][i];
          for (int c = 1; c < M; ++c) v += inverse[b][c] * rhs[c][i];
          gamma_1[b][i] = v;
        }
    // Pass 3: h_J = W_J t_J and h_J,i = W_J,i t_J + W_J t_J,i, handed to the lanes that keep J;
    // a running sum per lane catches any overflow so that no Inf/NaN escapes.
    for (int k = 0; k < count; ++k)
      if (finished[k]) {
        results[k].neighbours.resize(found[k]);
        results[k].value.resize(found[k]);
        if (want_gradients) results[k].gradient.resize(found[k]);
        found[k] = 0;
      }
    Lanes check = Lanes::Zero();
    for (std::size_t c = 0; c < kept_count; ++c) {
      const KeptNode& record = kept[c];
      const Lanes value = record.w * record.t;
      Lanes gradient[3];
      check += value;
      if (want_gradients) {
        Lanes p[M];
        basis_lanes<M>(record.dx, record.dy, record.dz, p);
        const Lanes* own[3] = {&record.gx, &record.gy, &record.gz};
        for (int i = 0; i < 3; ++i) {
          Lanes t_i = p[0] * gamma_1[0][i];
          for (int b = 1; b < M; ++b) t_i += p[b] * gamma_1[b][i];
          gradient[i] = record.t * *own[i] + record.w * t_i;
          check += gradient[i];
        }
      }
      for (int k = 0; k < count; ++k) {
        if (!finished[k] || !(record.lanes & (1u << k))) continue;
        MlsEvaluation& out = results[k];
        const std::size_t at = found[k]++;
        out.neighbours[at] = record.node;
        out.value[at] = value[k];
        if (want_gradients) out.gradient[at] = Eigen::Vector3d(gradient[0][k], gradient[1][k], gradient[2][k]);
      }
    }
    for (int k = 0; k < count; ++k) {
      if (!finished[k]) continue;
      bool finite = std::isfinite(check[k]);
      for (int b = 0; b < M && finite; ++b) {
        finite = std::isfinite(inverse[b][0][k]);
        for (int i = 0; i < 3 && finite && want_gradients; ++i) finite = std::isfinite(gamma_1[b][i][k]);
      }
      finished[k] = finite;
    }
  }
  for (int k = 0; k < count; ++k)
    if (!finished[k]) evaluate_mls(x[k], positions, radii, {}, settings, derivatives, results[k]);
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

void evaluate_mls_batch(const Eigen::Vector3d* x, int count, const std::vector<Eigen::Vector3d>& positions,
                        const std::vector<double>& radii, const MlsSettings& settings, Derivatives derivatives,
                        MlsEvaluation* results) noexcept {
  if (count <= 0) return;
  if (count > lane_count || settings.weight != Weight::quartic_spline || derivatives == Derivatives::hessians) {
    for (int k = 0; k < count; ++k) evaluate_mls(x[k], positions, radii, {}, settings, derivatives, results[k]);
    return;
  }
  if (settings.basis == Basis::linear)
    evaluate_lanes<4>(x, count, positions, radii, settings, derivatives, results);
  else
    evaluate_lanes<10>(x, count, positions, radii, settings, derivatives, results);
}

Eigen::Vector3d weight_and_derivatives(Weight weight, double s) noexcept {
  const WeightTerms wt = weight_terms(weight, s);
  return {wt.w, wt.dw, wt.d2w};
}

}  // namespace touchstone::realtime::mfs
