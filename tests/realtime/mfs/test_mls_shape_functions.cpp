// MLS shape functions: reproduction of polynomials up to the basis degree on irregular clouds,
// finite-difference checks of every derivative, the lattice Laplacian that shows the paper's
// linear basis inconsistent for collocation (the quadratic basis is exact), and the failure
// statuses on degenerate input (a clear status, never NaN).

#include "touchstone/realtime/mfs/mls_shape_functions.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <iostream>
#include <limits>
#include <random>
#include <vector>

namespace {

using touchstone::realtime::mfs::Basis;
using touchstone::realtime::mfs::basis_size;
using touchstone::realtime::mfs::Derivatives;
using touchstone::realtime::mfs::evaluate_mls;
using touchstone::realtime::mfs::MlsEvaluation;
using touchstone::realtime::mfs::MlsSettings;
using touchstone::realtime::mfs::MlsStatus;
using touchstone::realtime::mfs::Weight;
using touchstone::realtime::mfs::weight_and_derivatives;

constexpr double h = 1e-3;  // lattice spacing [m]: physical sizes so that units matter
const Eigen::Vector3d origin(0.12, -0.05, 0.3);  // far from 0 so that the frame shift matters

constexpr std::array<Basis, 2> all_bases = {Basis::linear, Basis::quadratic};
constexpr std::array<Weight, 3> all_weights = {Weight::quartic_spline, Weight::cubic_spline,
                                               Weight::truncated_gaussian};

const char* name(Basis b) { return b == Basis::linear ? "linear" : "quadratic"; }
const char* name(Weight w) {
  switch (w) {
    case Weight::quartic_spline: return "quartic_spline";
    case Weight::cubic_spline: return "cubic_spline";
    case Weight::truncated_gaussian: return "truncated_gaussian";
  }
  return "?";
}

struct Cloud {
  std::vector<Eigen::Vector3d> positions;
  std::vector<double> radii;
};

/// n³ lattice of spacing h at `origin`, each node moved by up to ±jitter·h per axis, radii
/// c·h·(1 + spread·u), u ∈ [0, 1).
Cloud jittered_lattice(int n, double jitter, double c, double spread, std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_real_distribution<double> unit01(0.0, 1.0);
  Cloud cloud;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      for (int k = 0; k < n; ++k) {
        const Eigen::Vector3d jit(unit(rng), unit(rng), unit(rng));
        cloud.positions.push_back(origin + h * (Eigen::Vector3d(i, j, k) + jitter * jit));
        cloud.radii.push_back(c * h * (1.0 + spread * unit01(rng)));
      }
    }
  }
  return cloud;
}

/// Monomial q(y) = Π (y_i − x0_i)^e_i with its gradient and Hessian.
struct Monomial {
  std::array<int, 3> e;
  Eigen::Vector3d x0;

  static double pw(double v, int k) { return k <= 0 ? 1.0 : std::pow(v, k); }
  static double dpw(double v, int k) { return k <= 0 ? 0.0 : k * pw(v, k - 1); }
  static double d2pw(double v, int k) { return k <= 1 ? 0.0 : k * (k - 1) * pw(v, k - 2); }

  double value(const Eigen::Vector3d& y) const {
    const Eigen::Vector3d d = y - x0;
    return pw(d.x(), e[0]) * pw(d.y(), e[1]) * pw(d.z(), e[2]);
  }
  // Factor i of the product, differentiated `order_i` times.
  double factor(const Eigen::Vector3d& d, int i, int order) const {
    return order == 0 ? pw(d(i), e[i]) : order == 1 ? dpw(d(i), e[i]) : d2pw(d(i), e[i]);
  }
  Eigen::Vector3d gradient(const Eigen::Vector3d& y) const {
    const Eigen::Vector3d d = y - x0;
    Eigen::Vector3d g;
    for (int a = 0; a < 3; ++a) {
      g(a) = 1.0;
      for (int i = 0; i < 3; ++i) g(a) *= factor(d, i, i == a ? 1 : 0);
    }
    return g;
  }
  Eigen::Matrix3d hessian(const Eigen::Vector3d& y) const {
    const Eigen::Vector3d d = y - x0;
    Eigen::Matrix3d hq;
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) {
        hq(a, b) = 1.0;
        for (int i = 0; i < 3; ++i) hq(a, b) *= factor(d, i, (i == a ? 1 : 0) + (i == b ? 1 : 0));
      }
    }
    return hq;
  }
};

std::vector<Monomial> monomials(int degree, const Eigen::Vector3d& x0) {
  std::vector<Monomial> out;
  for (int a = 0; a <= degree; ++a)
    for (int b = 0; a + b <= degree; ++b)
      for (int c = 0; a + b + c <= degree; ++c) out.push_back({{a, b, c}, x0});
  return out;
}

bool all_finite(const MlsEvaluation& r) {
  if (!std::isfinite(r.rcond)) return false;
  for (double v : r.value)
    if (!std::isfinite(v)) return false;
  for (const auto& g : r.gradient)
    if (!g.allFinite()) return false;
  for (const auto& hm : r.hessian)
    if (!hm.allFinite()) return false;
  return true;
}

/// Failed evaluations carry no shape-function data at all (the documented choice).
void expect_failed_cleanly(const MlsEvaluation& r, MlsStatus expected) {
  EXPECT_EQ(r.status, expected);
  EXPECT_TRUE(r.value.empty());
  EXPECT_TRUE(r.gradient.empty());
  EXPECT_TRUE(r.hessian.empty());
  EXPECT_TRUE(all_finite(r));
}

/// True if no node sits within 1e-3 of a kink of the weights in s (0, ½ for the cubic spline, 1),
/// where finite differences of the derivatives would straddle a jump in a higher derivative.
bool away_from_weight_kinks(const Cloud& cloud, const Eigen::Vector3d& x) {
  for (std::size_t j = 0; j < cloud.positions.size(); ++j) {
    const double s = (cloud.positions[j] - x).norm() / cloud.radii[j];
    if (std::abs(s - 1.0) < 1e-3 || std::abs(s - 0.5) < 1e-3 || s < 1e-3) return false;
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// Weight functions

TEST(MlsWeight, EndpointValuesAndZeroOutsideSupport) {
  for (Weight w : all_weights) {
    SCOPED_TRACE(name(w));
    const Eigen::Vector3d at0 = weight_and_derivatives(w, 0.0);
    EXPECT_NEAR(at0(0), 1.0, 1e-15);
    EXPECT_NEAR(at0(1), 0.0, 1e-15);
    EXPECT_LT(at0(2), 0.0);
    EXPECT_NEAR(weight_and_derivatives(w, 1.0 - 1e-12)(0), 0.0, 1e-10);
    for (double s : {1.0, 1.5, 10.0, std::numeric_limits<double>::infinity()}) {
      EXPECT_EQ(weight_and_derivatives(w, s), Eigen::Vector3d::Zero());
    }
    EXPECT_EQ(weight_and_derivatives(w, std::nan("")), Eigen::Vector3d::Zero());
  }
  // The d → 0 limit that the Hessian handles explicitly (W,ij → −12 δ_ij / r²): W''(0) = −12.
  EXPECT_DOUBLE_EQ(weight_and_derivatives(Weight::quartic_spline, 0.0)(2), -12.0);
  EXPECT_DOUBLE_EQ(weight_and_derivatives(Weight::cubic_spline, 0.0)(2), -12.0);
}

TEST(MlsWeight, DerivativesMatchFiniteDifferences) {
  constexpr double ds = 1e-6;
  for (Weight w : all_weights) {
    SCOPED_TRACE(name(w));
    for (int i = 1; i < 200; ++i) {
      const double s = i / 200.0 - 0.0013;  // off the cubic spline's knot at ½
      const Eigen::Vector3d plus = weight_and_derivatives(w, s + ds);
      const Eigen::Vector3d minus = weight_and_derivatives(w, s - ds);
      const Eigen::Vector3d at = weight_and_derivatives(w, s);
      EXPECT_GT(at(0), 0.0) << "s = " << s;
      EXPECT_NEAR((plus(0) - minus(0)) / (2 * ds), at(1), 1e-7) << "s = " << s;
      EXPECT_NEAR((plus(1) - minus(1)) / (2 * ds), at(2), 1e-7) << "s = " << s;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Polynomial reproduction up to the basis degree

TEST(MlsShapeFunctions, ReproducesPolynomialsOnIrregularClouds) {
  std::mt19937 rng(20240611);
  std::uniform_real_distribution<double> inside(1.0 * h, 7.0 * h);
  const Eigen::Vector3d centre = origin + Eigen::Vector3d::Constant(4.0 * h);
  constexpr double tol = 1e-10;
  double worst = 0.0;
  for (double c : {2.0, 2.5, 3.0}) {
    const Cloud cloud = jittered_lattice(9, 0.35, c, 0.3, rng);
    for (Basis basis : all_bases) {
      const int degree = basis == Basis::linear ? 1 : 2;
      const std::vector<Monomial> qs = monomials(degree, centre);
      for (Weight weight : all_weights) {
        SCOPED_TRACE(::testing::Message() << "c = " << c << ", " << name(basis) << ", " << name(weight));
        const MlsSettings settings{basis, weight, 1e-12};
        MlsEvaluation r;
        for (int trial = 0; trial < 40; ++trial) {
          const Eigen::Vector3d x = origin + Eigen::Vector3d(inside(rng), inside(rng), inside(rng));
          evaluate_mls(x, cloud.positions, cloud.radii, {}, settings, Derivatives::hessians, r);
          ASSERT_EQ(r.status, MlsStatus::ok);
          ASSERT_EQ(r.value.size(), r.neighbours.size());
          ASSERT_EQ(r.gradient.size(), r.neighbours.size());
          ASSERT_EQ(r.hessian.size(), r.neighbours.size());
          for (const Monomial& q : qs) {
            // Scale of each sum: Σ |h_J| |q_J| (what rounding in the sum itself is relative to).
            double value = 0.0, value_scale = 0.0;
            Eigen::Vector3d grad = Eigen::Vector3d::Zero(), grad_scale = Eigen::Vector3d::Zero();
            Eigen::Matrix3d hess = Eigen::Matrix3d::Zero(), hess_scale = Eigen::Matrix3d::Zero();
            for (std::size_t k = 0; k < r.neighbours.size(); ++k) {
              const double qj = q.value(cloud.positions[r.neighbours[k]]);
              value += r.value[k] * qj;
              value_scale += std::abs(r.value[k] * qj);
              grad += r.gradient[k] * qj;
              grad_scale += r.gradient[k].cwiseAbs() * std::abs(qj);
              hess += r.hessian[k] * qj;
              hess_scale += r.hessian[k].cwiseAbs() * std::abs(qj);
            }
            const double ev = std::abs(value - q.value(x)) / value_scale;
            const double eg = ((grad - q.gradient(x)).cwiseAbs().array() / grad_scale.array().max(1e-300)).maxCoeff();
            const double eh = ((hess - q.hessian(x)).cwiseAbs().array() / hess_scale.array().max(1e-300)).maxCoeff();
            worst = std::max({worst, ev, eg, eh});
            EXPECT_LT(ev, tol) << "value, exponents " << q.e[0] << q.e[1] << q.e[2];
            EXPECT_LT(eg, tol) << "gradient, exponents " << q.e[0] << q.e[1] << q.e[2];
            EXPECT_LT(eh, tol) << "Hessian, exponents " << q.e[0] << q.e[1] << q.e[2];
          }
        }
      }
    }
  }
  std::cout << "[ reproduction ] worst relative error " << worst << '\n';
}

TEST(MlsShapeFunctions, IndependentOfUnitsAndReportsGoodConditioning) {
  std::mt19937 rng(7);
  const Cloud cloud = jittered_lattice(7, 0.3, 2.5, 0.2, rng);
  Cloud scaled = cloud;  // the same cloud in millimetres
  for (auto& p : scaled.positions) p *= 1e3;
  for (auto& r : scaled.radii) r *= 1e3;
  const Eigen::Vector3d x = origin + Eigen::Vector3d(3.3, 2.7, 3.1) * h;
  for (Basis basis : all_bases) {
    SCOPED_TRACE(name(basis));
    const MlsSettings settings{basis, Weight::quartic_spline, 1e-12};
    MlsEvaluation in_m, in_mm;
    evaluate_mls(x, cloud.positions, cloud.radii, {}, settings, Derivatives::hessians, in_m);
    evaluate_mls(x * 1e3, scaled.positions, scaled.radii, {}, settings, Derivatives::hessians, in_mm);
    ASSERT_EQ(in_m.status, MlsStatus::ok);
    ASSERT_EQ(in_mm.status, MlsStatus::ok);
    std::cout << "[ rcond      ] " << name(basis) << ": " << in_m.rcond << '\n';
    EXPECT_GT(in_m.rcond, 1e-8);
    EXPECT_LE(in_m.rcond, 1.0);
    EXPECT_NEAR(in_m.rcond, in_mm.rcond, 1e-6 * in_m.rcond);
    ASSERT_EQ(in_m.neighbours, in_mm.neighbours);
    for (std::size_t k = 0; k < in_m.neighbours.size(); ++k) {
      EXPECT_NEAR(in_m.value[k], in_mm.value[k], 1e-11);
      EXPECT_LT((in_m.gradient[k] * 1e-3 - in_mm.gradient[k]).norm(), 1e-11 / h * 1e-3);
      EXPECT_LT((in_m.hessian[k] * 1e-6 - in_mm.hessian[k]).norm(), 1e-11 / (h * h) * 1e-6);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Every derivative against central finite differences

/// Gradients against central differences of values, Hessians against central differences of
/// gradients, at x with step dx; the error is relative to the largest analytic entry.
void check_derivatives_by_fd(const Cloud& cloud, const Eigen::Vector3d& x, const MlsSettings& settings,
                             double dx, double tol) {
  MlsEvaluation at, plus, minus;
  evaluate_mls(x, cloud.positions, cloud.radii, {}, settings, Derivatives::hessians, at);
  ASSERT_EQ(at.status, MlsStatus::ok);
  const std::size_t n = at.neighbours.size();
  std::vector<Eigen::Vector3d> fd_gradient(n, Eigen::Vector3d::Zero());
  std::vector<Eigen::Matrix3d> fd_hessian(n, Eigen::Matrix3d::Zero());
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d step = dx * Eigen::Vector3d::Unit(i);
    evaluate_mls(x + step, cloud.positions, cloud.radii, {}, settings, Derivatives::hessians, plus);
    evaluate_mls(x - step, cloud.positions, cloud.radii, {}, settings, Derivatives::hessians, minus);
    ASSERT_EQ(plus.status, MlsStatus::ok);
    ASSERT_EQ(minus.status, MlsStatus::ok);
    // Same neighbour sets: the points were chosen away from support boundaries.
    ASSERT_EQ(plus.neighbours, at.neighbours);
    ASSERT_EQ(minus.neighbours, at.neighbours);
    for (std::size_t k = 0; k < n; ++k) {
      fd_gradient[k](i) = (plus.value[k] - minus.value[k]) / (2 * dx);
      fd_hessian[k].col(i) = (plus.gradient[k] - minus.gradient[k]) / (2 * dx);
    }
  }
  double gradient_scale = 0.0, hessian_scale = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    gradient_scale = std::max(gradient_scale, at.gradient[k].cwiseAbs().maxCoeff());
    hessian_scale = std::max(hessian_scale, at.hessian[k].cwiseAbs().maxCoeff());
  }
  for (std::size_t k = 0; k < n; ++k) {
    EXPECT_LT((fd_gradient[k] - at.gradient[k]).cwiseAbs().maxCoeff(), tol * gradient_scale) << "node " << k;
    EXPECT_LT((fd_hessian[k] - at.hessian[k]).cwiseAbs().maxCoeff(), tol * hessian_scale) << "node " << k;
    EXPECT_LT((at.hessian[k] - at.hessian[k].transpose()).cwiseAbs().maxCoeff(), 1e-12 * hessian_scale);
  }
}

TEST(MlsShapeFunctions, DerivativesMatchFiniteDifferences) {
  std::mt19937 rng(99);
  std::uniform_real_distribution<double> inside(2.0 * h, 5.0 * h);
  const Cloud cloud = jittered_lattice(8, 0.35, 2.5, 0.3, rng);
  for (Basis basis : all_bases) {
    for (Weight weight : all_weights) {
      SCOPED_TRACE(::testing::Message() << name(basis) << ", " << name(weight));
      const MlsSettings settings{basis, weight, 1e-12};
      for (int trial = 0; trial < 8; ++trial) {
        Eigen::Vector3d x;
        do {
          x = origin + Eigen::Vector3d(inside(rng), inside(rng), inside(rng));
        } while (!away_from_weight_kinks(cloud, x));
        check_derivatives_by_fd(cloud, x, settings, 1e-5 * h, 1e-6);
      }
    }
  }
}

TEST(MlsShapeFunctions, DerivativesAtANodeUseTheZeroDistanceLimit) {
  // At x = x_J the weight's Hessian is the limit W''(0) δ_ij / r² (−12 δ_ij / r² for the quartic).
  std::mt19937 rng(5);
  const Cloud cloud = jittered_lattice(7, 0.3, 2.5, 0.2, rng);
  const int node = 3 * 49 + 3 * 7 + 3;
  for (Basis basis : all_bases) {
    for (Weight weight : all_weights) {
      SCOPED_TRACE(::testing::Message() << name(basis) << ", " << name(weight));
      check_derivatives_by_fd(cloud, cloud.positions[node], {basis, weight, 1e-12}, 1e-7 * h, 1e-6);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// The linear basis (the paper's) gets second derivatives wrong by O(1); the quadratic is exact.

double lattice_laplacian(Basis basis, double factor) {
  Cloud cloud;
  constexpr int half = 5;
  for (int i = -half; i <= half; ++i)
    for (int j = -half; j <= half; ++j)
      for (int k = -half; k <= half; ++k) {
        cloud.positions.push_back(origin + h * Eigen::Vector3d(i, j, k));
        cloud.radii.push_back(factor * h);
      }
  const Eigen::Vector3d x = origin;  // the centre node
  const auto u = [](const Eigen::Vector3d& y) {
    const Eigen::Vector3d d = (y - origin) / h;  // u in units where the exact ∇²u = 3
    return d.x() * d.x() + d.y() * d.y() / 2 + d.x() * d.z() / 4;
  };
  MlsEvaluation r;
  evaluate_mls(x, cloud.positions, cloud.radii, {}, {basis, Weight::quartic_spline, 1e-12},
               Derivatives::hessians, r);
  EXPECT_EQ(r.status, MlsStatus::ok);
  double laplacian = 0.0;
  for (std::size_t k = 0; k < r.neighbours.size(); ++k) {
    laplacian += r.hessian[k].trace() * h * h * u(cloud.positions[r.neighbours[k]]);
  }
  return laplacian;
}

TEST(MlsShapeFunctions, LatticeLaplacianLinearBasisIsInconsistentQuadraticIsExact) {
  const std::array<double, 4> factors = {1.5, 2.0, 2.5, 3.0};
  const std::array<double, 4> expected = {8.10, 2.82, 3.75, 2.66};  // ∇²u_h, linear basis
  for (std::size_t i = 0; i < factors.size(); ++i) {
    const double linear = lattice_laplacian(Basis::linear, factors[i]);
    const double quadratic = lattice_laplacian(Basis::quadratic, factors[i]);
    std::cout << "[ laplacian  ] r = " << factors[i] << " h: linear " << linear << ", quadratic 3 + "
              << quadratic - 3.0 << " (exact 3)\n";
    EXPECT_NEAR(linear, expected[i], 0.005) << "r = " << factors[i] << " h";
    EXPECT_GT(std::abs(linear - 3.0), 0.15);  // O(1) wrong: at least 5 % at every radius
    EXPECT_NEAR(quadratic, 3.0, 3e-10);
  }
}

// ---------------------------------------------------------------------------------------------
// Degenerate input: a clear status and no NaN

TEST(MlsShapeFunctions, CoplanarNodesAreSingular) {
  Cloud cloud;
  for (int i = 0; i < 7; ++i)
    for (int j = 0; j < 7; ++j) {
      cloud.positions.push_back(origin + h * Eigen::Vector3d(i, j, 0.0));
      cloud.radii.push_back(2.5 * h);
    }
  for (Basis basis : all_bases) {
    SCOPED_TRACE(name(basis));
    for (const Eigen::Vector3d& x : {Eigen::Vector3d(origin + h * Eigen::Vector3d(3, 3, 0)),
                                     Eigen::Vector3d(origin + h * Eigen::Vector3d(3.2, 2.9, 0.3))}) {
      MlsEvaluation r;
      evaluate_mls(x, cloud.positions, cloud.radii, {}, {basis, Weight::quartic_spline, 1e-12},
                   Derivatives::hessians, r);
      expect_failed_cleanly(r, MlsStatus::singular_moments);
      EXPECT_GE(r.neighbours.size(), static_cast<std::size_t>(basis_size(basis)));
    }
  }
}

TEST(MlsShapeFunctions, NodesOnOneSphereAreSingularForTheQuadraticBasis) {
  const Eigen::Vector3d x = origin + Eigen::Vector3d(0.3, 0.1, -0.2) * h;
  Cloud cloud;
  constexpr int count = 50;
  const double golden = 3.14159265358979323846 * (3.0 - std::sqrt(5.0));  // golden angle
  for (int i = 0; i < count; ++i) {  // Fibonacci sphere: well spread, all at distance 2h
    const double z = 1.0 - 2.0 * (i + 0.5) / count;
    const double rxy = std::sqrt(1.0 - z * z);
    cloud.positions.push_back(x + 2.0 * h * Eigen::Vector3d(rxy * std::cos(golden * i), rxy * std::sin(golden * i), z));
    cloud.radii.push_back(3.0 * h);
  }
  for (Weight weight : all_weights) {
    SCOPED_TRACE(name(weight));
    MlsEvaluation r;
    evaluate_mls(x, cloud.positions, cloud.radii, {}, {Basis::quadratic, weight, 1e-12}, Derivatives::hessians, r);
    expect_failed_cleanly(r, MlsStatus::singular_moments);
    // The same cloud is fine for the linear basis.
    evaluate_mls(x, cloud.positions, cloud.radii, {}, {Basis::linear, weight, 1e-12}, Derivatives::hessians, r);
    EXPECT_EQ(r.status, MlsStatus::ok);
    EXPECT_GT(r.rcond, 1e-3);
  }
}

TEST(MlsShapeFunctions, TooFewNodes) {
  std::mt19937 rng(3);
  const Cloud cloud = jittered_lattice(5, 0.3, 2.5, 0.0, rng);
  const Eigen::Vector3d x = origin + Eigen::Vector3d(2.1, 1.9, 2.2) * h;
  for (Basis basis : all_bases) {
    SCOPED_TRACE(name(basis));
    // The m − 1 nearest nodes as candidates.
    std::vector<int> order(cloud.positions.size());
    for (std::size_t j = 0; j < order.size(); ++j) order[j] = static_cast<int>(j);
    std::sort(order.begin(), order.end(), [&](int a, int b) {
      return (cloud.positions[a] - x).norm() < (cloud.positions[b] - x).norm();
    });
    order.resize(basis_size(basis) - 1);
    MlsEvaluation r;
    evaluate_mls(x, cloud.positions, cloud.radii, order, {basis, Weight::quartic_spline, 1e-12},
                 Derivatives::hessians, r);
    expect_failed_cleanly(r, MlsStatus::too_few_nodes);
    EXPECT_EQ(r.neighbours.size(), order.size());
    EXPECT_EQ(r.rcond, 0.0);
    // Far from every node: no support at all.
    evaluate_mls(origin + Eigen::Vector3d::Constant(1.0), cloud.positions, cloud.radii, {},
                 {basis, Weight::quartic_spline, 1e-12}, Derivatives::hessians, r);
    expect_failed_cleanly(r, MlsStatus::too_few_nodes);
    EXPECT_TRUE(r.neighbours.empty());
  }
}

TEST(MlsShapeFunctions, NonFiniteInput) {
  std::mt19937 rng(11);
  const Cloud good = jittered_lattice(6, 0.3, 2.5, 0.2, rng);
  const Eigen::Vector3d x = origin + Eigen::Vector3d(2.5, 2.5, 2.5) * h;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const MlsSettings settings;
  MlsEvaluation r;

  evaluate_mls(Eigen::Vector3d(nan, 0, 0), good.positions, good.radii, {}, settings, Derivatives::hessians, r);
  expect_failed_cleanly(r, MlsStatus::non_finite_input);
  evaluate_mls(Eigen::Vector3d(0, inf, 0), good.positions, good.radii, {}, settings, Derivatives::hessians, r);
  expect_failed_cleanly(r, MlsStatus::non_finite_input);

  Cloud bad = good;
  bad.positions[17].y() = nan;  // a node far outside the support is still checked
  evaluate_mls(x, bad.positions, bad.radii, {}, settings, Derivatives::hessians, r);
  expect_failed_cleanly(r, MlsStatus::non_finite_input);
  EXPECT_TRUE(r.neighbours.empty());

  bad = good;
  bad.radii[40] = inf;
  evaluate_mls(x, bad.positions, bad.radii, {}, settings, Derivatives::hessians, r);
  expect_failed_cleanly(r, MlsStatus::non_finite_input);

  bad = good;
  bad.radii[3] = nan;
  evaluate_mls(x, bad.positions, bad.radii, {}, settings, Derivatives::hessians, r);
  expect_failed_cleanly(r, MlsStatus::non_finite_input);

  // Only candidates are checked: a NaN node outside the candidate list is not looked at.
  std::vector<int> candidates;
  for (int j = 0; j < static_cast<int>(good.positions.size()); ++j)
    if (j != 17) candidates.push_back(j);
  bad = good;
  bad.positions[17].x() = nan;
  evaluate_mls(x, bad.positions, bad.radii, candidates, settings, Derivatives::hessians, r);
  EXPECT_EQ(r.status, MlsStatus::ok);
  EXPECT_TRUE(all_finite(r));

  // An index without a node is invalid input, not a crash.
  candidates.push_back(static_cast<int>(good.positions.size()));
  evaluate_mls(x, good.positions, good.radii, candidates, settings, Derivatives::hessians, r);
  expect_failed_cleanly(r, MlsStatus::non_finite_input);
}

TEST(MlsShapeFunctions, MinRcondIsHonoured) {
  std::mt19937 rng(13);
  const Cloud cloud = jittered_lattice(6, 0.3, 2.5, 0.2, rng);
  const Eigen::Vector3d x = origin + Eigen::Vector3d(2.5, 2.4, 2.6) * h;
  MlsEvaluation r;
  evaluate_mls(x, cloud.positions, cloud.radii, {}, {}, Derivatives::hessians, r);
  ASSERT_EQ(r.status, MlsStatus::ok);
  const double rcond = r.rcond;
  EXPECT_GT(rcond, 0.0);
  evaluate_mls(x, cloud.positions, cloud.radii, {}, {Basis::quadratic, Weight::quartic_spline, 2.0 * rcond},
               Derivatives::hessians, r);
  expect_failed_cleanly(r, MlsStatus::singular_moments);
  EXPECT_DOUBLE_EQ(r.rcond, rcond);
}

// ---------------------------------------------------------------------------------------------
// Result layout, candidate lists and buffer reuse

TEST(MlsShapeFunctions, RequestedDerivativesOnlyAndCandidatesSubset) {
  std::mt19937 rng(17);
  const Cloud cloud = jittered_lattice(7, 0.3, 2.5, 0.2, rng);
  const Eigen::Vector3d x = origin + Eigen::Vector3d(3.1, 2.8, 3.3) * h;
  const MlsSettings settings;
  MlsEvaluation full, part;
  evaluate_mls(x, cloud.positions, cloud.radii, {}, settings, Derivatives::hessians, full);
  ASSERT_EQ(full.status, MlsStatus::ok);

  evaluate_mls(x, cloud.positions, cloud.radii, {}, settings, Derivatives::values, part);
  ASSERT_EQ(part.status, MlsStatus::ok);
  EXPECT_TRUE(part.gradient.empty());
  EXPECT_TRUE(part.hessian.empty());
  ASSERT_EQ(part.value.size(), full.value.size());
  for (std::size_t k = 0; k < full.value.size(); ++k) EXPECT_DOUBLE_EQ(part.value[k], full.value[k]);

  evaluate_mls(x, cloud.positions, cloud.radii, {}, settings, Derivatives::gradients, part);
  ASSERT_EQ(part.status, MlsStatus::ok);
  EXPECT_EQ(part.gradient.size(), full.gradient.size());
  EXPECT_TRUE(part.hessian.empty());
  for (std::size_t k = 0; k < full.value.size(); ++k) EXPECT_LT((part.gradient[k] - full.gradient[k]).norm(), 1e-9 / h);

  // Candidates that include every neighbour (plus some that are out of reach) give the same result.
  std::vector<int> candidates;
  for (int j = static_cast<int>(cloud.positions.size()) - 1; j >= 0; --j)
    if ((cloud.positions[j] - x).norm() < 4.0 * h) candidates.push_back(j);
  evaluate_mls(x, cloud.positions, cloud.radii, candidates, settings, Derivatives::hessians, part);
  ASSERT_EQ(part.status, MlsStatus::ok);
  ASSERT_EQ(part.neighbours.size(), full.neighbours.size());
  for (std::size_t k = 0; k < part.neighbours.size(); ++k) {
    const auto it = std::find(full.neighbours.begin(), full.neighbours.end(), part.neighbours[k]);
    ASSERT_NE(it, full.neighbours.end());
    const std::size_t f = static_cast<std::size_t>(it - full.neighbours.begin());
    EXPECT_NEAR(part.value[k], full.value[f], 1e-12);
    EXPECT_LT((part.hessian[k] - full.hessian[f]).norm(), 1e-9 / (h * h));
  }
}

TEST(MlsShapeFunctions, ReusesTheResultBuffers) {
  std::mt19937 rng(19);
  const Cloud cloud = jittered_lattice(7, 0.3, 2.5, 0.2, rng);
  MlsEvaluation r;
  evaluate_mls(origin + Eigen::Vector3d(3, 3, 3) * h, cloud.positions, cloud.radii, {}, {},
               Derivatives::hessians, r);
  ASSERT_EQ(r.status, MlsStatus::ok);
  // Headroom for the varying neighbour count; after this no call may reallocate.
  r.neighbours.reserve(r.neighbours.size() + 200);
  r.value.reserve(r.value.size() + 200);
  r.gradient.reserve(r.gradient.size() + 200);
  r.hessian.reserve(r.hessian.size() + 200);
  const auto* neighbours = r.neighbours.data();
  const auto* values = r.value.data();
  const auto* gradients = r.gradient.data();
  const auto* hessians = r.hessian.data();
  std::uniform_real_distribution<double> inside(2.5 * h, 3.5 * h);
  for (int trial = 0; trial < 20; ++trial) {
    evaluate_mls(origin + Eigen::Vector3d(inside(rng), inside(rng), inside(rng)), cloud.positions, cloud.radii,
                 {}, {}, Derivatives::hessians, r);
    ASSERT_EQ(r.status, MlsStatus::ok);
    EXPECT_EQ(r.neighbours.data(), neighbours);
    EXPECT_EQ(r.value.data(), values);
    EXPECT_EQ(r.gradient.data(), gradients);
    EXPECT_EQ(r.hessian.data(), hessians);
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Several points at once

/// evaluate_mls_batch must give each point what evaluate_mls gives it: the same status, support
/// growth and neighbours, and the same numbers to rounding (the lanes run the same operations;
/// only where the compiler fuses a multiply and an add differently may the last bit differ).
void expect_same_evaluation(const MlsEvaluation& batch, const MlsEvaluation& one, double tolerance, double& worst) {
  ASSERT_EQ(batch.status, one.status);
  EXPECT_EQ(batch.support_scale, one.support_scale);
  ASSERT_EQ(batch.neighbours, one.neighbours);
  ASSERT_EQ(batch.value.size(), one.value.size());
  ASSERT_EQ(batch.gradient.size(), one.gradient.size());
  EXPECT_EQ(batch.hessian.size(), one.hessian.size());
  if (one.status == MlsStatus::ok) {
    EXPECT_NEAR(batch.rcond, one.rcond, 1e-12 * one.rcond);
  } else {
    EXPECT_EQ(batch.rcond, one.rcond);
  }
  double value_scale = 0, gradient_scale = 0;
  for (std::size_t k = 0; k < one.value.size(); ++k) value_scale = std::max(value_scale, std::abs(one.value[k]));
  for (const Eigen::Vector3d& g : one.gradient) gradient_scale = std::max(gradient_scale, g.cwiseAbs().maxCoeff());
  for (std::size_t k = 0; k < one.value.size(); ++k) {
    const double difference = std::abs(batch.value[k] - one.value[k]) / value_scale;
    worst = std::max(worst, difference);
    EXPECT_LE(difference, tolerance) << "value " << k;
  }
  for (std::size_t k = 0; k < one.gradient.size(); ++k) {
    const double difference = (batch.gradient[k] - one.gradient[k]).cwiseAbs().maxCoeff() / gradient_scale;
    worst = std::max(worst, difference);
    EXPECT_LE(difference, tolerance) << "gradient " << k;
  }
}

TEST(MlsShapeFunctionsBatch, EveryPointGetsWhatItsOwnEvaluationGives) {
  using touchstone::realtime::mfs::evaluate_mls_batch;
  std::mt19937 rng(23);
  const Cloud cloud = jittered_lattice(6, 0.3, 2.5, 0.2, rng);
  std::uniform_real_distribution<double> inside(0.5, 4.5);
  std::vector<Eigen::Vector3d> points;
  for (int q = 0; q < 40; ++q) points.push_back(origin + h * Eigen::Vector3d(inside(rng), inside(rng), inside(rng)));
  // Points where the supports must grow (a corner of the lattice sees few nodes), where no node
  // reaches, and one that is not a number, among ordinary ones.
  points.push_back(origin + h * Eigen::Vector3d(-1.2, -1.2, -1.2));
  points.push_back(origin + Eigen::Vector3d::Constant(1.0));
  points.push_back(Eigen::Vector3d(std::numeric_limits<double>::quiet_NaN(), 0, 0));
  points.push_back(origin + h * Eigen::Vector3d(2.2, 2.7, 1.9));
  MlsSettings growing;
  growing.max_support_scale = 2.0;
  MlsSettings linear, linear_growing = growing;
  linear.basis = linear_growing.basis = Basis::linear;
  // 1e-13 of the largest entry: rounding leaves about 1e-15; a lane that mixed up its nodes,
  // its basis or its inverse would be off by O(1).
  constexpr double tolerance = 1e-13;
  double worst = 0;
  int statuses[4] = {};
  for (const MlsSettings& settings : {MlsSettings{}, growing, linear, linear_growing})
    for (const Derivatives derivatives : {Derivatives::values, Derivatives::gradients})
      for (int count = 1; count <= touchstone::realtime::mfs::mls_batch_size; ++count)
        for (std::size_t first = 0; first + static_cast<std::size_t>(count) <= points.size(); first += static_cast<std::size_t>(count)) {
          SCOPED_TRACE(::testing::Message() << "count " << count << ", first point " << first << ", growth bound "
                                            << settings.max_support_scale << ", basis size " << basis_size(settings.basis));
          MlsEvaluation batch[touchstone::realtime::mfs::mls_batch_size], one;
          evaluate_mls_batch(points.data() + first, count, cloud.positions, cloud.radii, settings, derivatives, batch);
          for (int k = 0; k < count; ++k) {
            evaluate_mls(points[first + static_cast<std::size_t>(k)], cloud.positions, cloud.radii, {}, settings, derivatives, one);
            expect_same_evaluation(batch[k], one, tolerance, worst);
            ++statuses[static_cast<int>(one.status)];
          }
        }
  std::cout << "largest relative difference from the one-point evaluation: " << worst << "\n";
  // Every path was taken: the lanes, the growth, too few nodes and a non-finite point.
  EXPECT_GT(statuses[static_cast<int>(MlsStatus::ok)], 0);
  EXPECT_GT(statuses[static_cast<int>(MlsStatus::too_few_nodes)], 0);
  EXPECT_GT(statuses[static_cast<int>(MlsStatus::non_finite_input)], 0);
}

TEST(MlsShapeFunctionsBatch, GrowsTheSupportsWhereTheOnePointEvaluationDoes) {
  using touchstone::realtime::mfs::evaluate_mls_batch;
  std::mt19937 rng(29);
  const Cloud cloud = jittered_lattice(5, 0.3, 2.5, 0.0, rng);
  MlsSettings settings;
  settings.max_support_scale = 2.0;
  const Eigen::Vector3d points[3] = {origin + h * Eigen::Vector3d(2.1, 1.9, 2.2), origin + h * Eigen::Vector3d(-1.5, -1.5, -1.5),
                                     origin + h * Eigen::Vector3d(1.7, 2.3, 2.0)};
  MlsEvaluation batch[3];
  evaluate_mls_batch(points, 3, cloud.positions, cloud.radii, settings, Derivatives::gradients, batch);
  EXPECT_EQ(batch[0].support_scale, 1.0);
  EXPECT_GT(batch[1].support_scale, 1.0);  // the corner point needed larger supports
  EXPECT_EQ(batch[2].support_scale, 1.0);
  for (const MlsEvaluation& r : batch) EXPECT_EQ(r.status, MlsStatus::ok);
}

TEST(MlsShapeFunctionsBatch, OtherSettingsAndANonFiniteNodeGoPointByPoint) {
  using touchstone::realtime::mfs::evaluate_mls_batch;
  std::mt19937 rng(31);
  Cloud cloud = jittered_lattice(6, 0.3, 2.5, 0.2, rng);
  const Eigen::Vector3d points[4] = {origin + h * Eigen::Vector3d(2.1, 1.9, 2.2), origin + h * Eigen::Vector3d(3.1, 2.9, 2.2),
                                     origin + h * Eigen::Vector3d(2.6, 2.4, 3.3), origin + h * Eigen::Vector3d(1.7, 2.3, 2.0)};
  // Settings the lanes do not run: the result is evaluate_mls's, to the bit.
  for (const Basis basis : all_bases)
    for (const Weight weight : all_weights)
      for (const Derivatives derivatives : {Derivatives::values, Derivatives::gradients, Derivatives::hessians}) {
        if (weight == Weight::quartic_spline && derivatives != Derivatives::hessians) continue;
        const MlsSettings settings{basis, weight, 1e-12, 1.0};
        MlsEvaluation batch[4], one;
        evaluate_mls_batch(points, 4, cloud.positions, cloud.radii, settings, derivatives, batch);
        for (int k = 0; k < 4; ++k) {
          evaluate_mls(points[k], cloud.positions, cloud.radii, {}, settings, derivatives, one);
          ASSERT_EQ(batch[k].status, one.status);
          EXPECT_EQ(batch[k].value, one.value);
          EXPECT_EQ(batch[k].gradient, one.gradient);
          EXPECT_EQ(batch[k].hessian, one.hessian);
        }
      }
  // A node that is not a number makes every point's input invalid, as for one point.
  cloud.positions[17].y() = std::numeric_limits<double>::quiet_NaN();
  MlsEvaluation batch[4];
  evaluate_mls_batch(points, 4, cloud.positions, cloud.radii, MlsSettings{}, Derivatives::gradients, batch);
  for (const MlsEvaluation& r : batch) expect_failed_cleanly(r, MlsStatus::non_finite_input);
}
