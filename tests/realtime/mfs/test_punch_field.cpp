// The punch fields against the closed-form oracle tests/oracles/sneddon_field.py (values below
// printed by it for a = G = 1, ν = 0.45, unit depth / unit tangential displacement), their
// boundary conditions, equilibrium and resultants, and the frame transformation. The radial and
// tilt modes have no oracle of their own: the conditions that make the half-space solution
// unique are checked instead (surface tractions and displacements, equilibrium, decay,
// resultants).
#include "support/box_quadrature.hpp"
#include "touchstone/realtime/mfs/punch_field.hpp"
#include "touchstone/realtime/mfs/quadrature_rules.hpp"

#include <Eigen/LU>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <iterator>
#include <vector>

namespace touchstone::realtime::mfs {
namespace {

constexpr double pi = 3.14159265358979323846;

struct OracleSample {
  double x[3];
  double u_normal[3];
  double stress_normal[4];  // σ_rr, σ_θθ, σ_zz, σ_rz
  double u_tangential[3];
};

// python3 -c "import sneddon_field as s; ..." with a = G = 1, ν = 0.45, δ = 1, Q = 8Ga/(2 − ν).
const OracleSample oracle[] = {
    {{0.3, 0.2, 0.5}, {0.0234757710019587, 0.0156505140013058, 0.924057500306908},
     {-0.646610420482463, -0.682646574788676, -1.37467630797889, 0.00769717057457332},
     {0.60894442897317, 0.00167211313608023, 0.0265576955754939}},
    {{1.5, -0.7, 0.2}, {0.0186295377639473, -0.00869378428984209, 0.417035404908959},
     {-0.202071606513217, -0.0602296056254952, -0.0118099756403983, -0.0506215059917506},
     {0.460589301672427, -0.067247704812082, 0.0514909821642514}},
    {{0.9, 0.1, 1e-06}, {-0.0365712183707103, -0.0040634687078567, 0.999999863588437},
     {-2.64696188656882, -2.53667750902421, -2.72823126120087, 1.37251026719401e-05},
     {0.999997996342427, -4.29510362866671e-09, 0.0259537678856688}},
    {{2.5, 1.0, 3.0}, {0.0577310905396983, 0.0230924362158793, 0.236726003724257},
     {-0.060033355812559, -0.00176305572619017, -0.0927024680813082, -0.0751333561752414},
     {0.142596595112003, 0.0134667681743947, 0.0479306388806419}},
    {{-0.4, 0.6, -0.02}, {0.0133840344634865, -0.0200760516952298, 1.00169373563079},
     {-1.59287613872684, -1.56726726543704, -1.67430834033263, -0.0496113136839385},
     {1.02424038049811, -9.4140844034222e-05, -0.00989202065699222}},
    {{0.05, 0.02, 0.8}, {0.00600770962182017, 0.00240308384872807, 0.852346245476695},
     {-0.394247269254054, -0.39458383203068, -1.25693270873761, -0.0104619901048725},
     {0.470092489024511, 4.46983772876341e-05, 0.00551542725616645}},
};

/// ν = 0.45 and G = 1 Pa.
geometry::Material unit_material() {
  geometry::Material m;
  m.poisson_ratio = 0.45;
  m.youngs_modulus_Pa = 2 * (1 + m.poisson_ratio);
  return m;
}

TEST(PunchField, NormalModeMatchesTheOracle) {
  const geometry::Material material = unit_material();
  for (const OracleSample& s : oracle) {
    const Eigen::Vector3d x(s.x[0], s.x[1], s.x[2]);
    const PunchFieldSample f = punch_field(PunchMode::normal, PunchFrame{}, 1.0, material, x);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(f.displacement[i], s.u_normal[i], 1e-12) << "u_" << i << " at " << x.transpose();
    const double r = std::hypot(x.x(), x.y());
    const Eigen::Vector3d er(x.x() / r, x.y() / r, 0), et(-x.y() / r, x.x() / r, 0), ez = Eigen::Vector3d::UnitZ();
    const Eigen::Matrix3d& t = f.stress_Pa_per_m;
    const double expected[4] = {er.dot(t * er), et.dot(t * et), ez.dot(t * ez), er.dot(t * ez)};
    for (int i = 0; i < 4; ++i)
      EXPECT_NEAR(expected[i], s.stress_normal[i], 1e-10 * (1 + std::abs(s.stress_normal[i]))) << "stress " << i;
  }
}

TEST(PunchField, TangentialModeMatchesTheOracle) {
  const geometry::Material material = unit_material();
  for (const OracleSample& s : oracle) {
    const Eigen::Vector3d x(s.x[0], s.x[1], s.x[2]);
    const PunchFieldSample f = punch_field(PunchMode::tangential_1, PunchFrame{}, 1.0, material, x);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(f.displacement[i], s.u_tangential[i], 1e-12) << "u_" << i << " at " << x.transpose();
  }
}

TEST(PunchField, NearTheAxisTheSeriesContinueTheClosedForms) {
  const geometry::Material material = unit_material();
  // The near-axis value against the line through two closed-form values farther out (the tilt
  // mode's field vanishes linearly on the axis, so a plain difference would measure its slope).
  for (const PunchMode mode : {PunchMode::normal, PunchMode::tangential_1, PunchMode::radial, PunchMode::tilt_1}) {
    const PunchFieldSample on = punch_field(mode, PunchFrame{}, 1.0, material, {2e-4, 1e-4, 0.4});
    const PunchFieldSample off = punch_field(mode, PunchFrame{}, 1.0, material, {2e-3, 1e-3, 0.4});
    const PunchFieldSample farther = punch_field(mode, PunchFrame{}, 1.0, material, {4e-3, 2e-3, 0.4});
    const Eigen::Vector3d line = off.displacement + (off.displacement - farther.displacement) * 0.9;  // at 1/10 of off
    EXPECT_LT((on.displacement - line).norm(), 1e-3 * off.displacement.norm()) << "mode " << int(mode);
    EXPECT_LT((on.stress_Pa_per_m - off.stress_Pa_per_m).norm(), 1e-2 * off.stress_Pa_per_m.norm()) << "mode " << int(mode);
    EXPECT_TRUE(punch_field(mode, PunchFrame{}, 1.0, material, {0, 0, 0.4}).stress_Pa_per_m.allFinite());
  }
}

/// ∫_disk σ(ψ) e_z dA by Gauss–Legendre in t with r = sin t (the rim's (1 − r²)^(−½) absorbed).
Eigen::Vector3d disk_traction_resultant(PunchMode mode, const geometry::Material& material) {
  std::vector<double> x, w;
  gauss_legendre(24, x, w);
  Eigen::Vector3d total = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double t = 0.5 * pi * x[i], r = std::sin(t), weight = w[i] * 0.5 * pi * r * std::cos(t);
    for (int k = 0; k < 64; ++k) {
      const double phi = 2 * pi * (k + 0.5) / 64;
      const Eigen::Vector3d p(r * std::cos(phi), r * std::sin(phi), 1e-9);
      total += weight * (2 * pi / 64) * punch_field(mode, PunchFrame{}, 1.0, material, p).stress_Pa_per_m.col(2);
    }
  }
  return total;
}

TEST(PunchField, ResultantsAreTheHalfSpaceStiffnesses) {
  const geometry::Material material = unit_material();
  // The tissue pulls the punch back: σ·e_z on the face = −(force on the tissue).
  const Eigen::Vector3d normal = disk_traction_resultant(PunchMode::normal, material);
  EXPECT_NEAR(-normal.z() / punch_half_space_stiffness_N_per_m(PunchMode::normal, 1.0, material), 1.0, 1e-6);
  const Eigen::Vector3d tangential = disk_traction_resultant(PunchMode::tangential_1, material);
  EXPECT_NEAR(-tangential.x() / punch_half_space_stiffness_N_per_m(PunchMode::tangential_1, 1.0, material), 1.0, 1e-4);
  EXPECT_LT(std::abs(tangential.y()), 1e-6);
}

/// The radial mode is the half-space under the self-equilibrated shear τ_r = 4G/(πa(1 − ν)) ·
/// r/√(a² − r²) on the disk, plus k = 2(1 − 2ν)/(π(1 − ν)) times the frictionless punch whose
/// face takes the dome √(1 − r²/a²): the shear alone lifts the face by −k√(1 − r²/a²), and the dome
/// flattens it, so a bonded face can take the mode without bulging. On the disk: the shear
/// traction is τ_r, u_z = 0 and u_r = r/a + k times the dome's own radial slip. Closed forms fix
/// the dome's share: its force is 2Ga/(1 − ν) (by reciprocity with Sneddon's field: the flat punch's
/// pressure against the dome) and its energy 4Ga(1/3 + π²/36)/(1 − ν) (the Abel transform of the dome,
/// (2/π)(1 − τ artanh τ), squared and integrated), so the mode's energy is
/// 16Ga/(3(1 − ν)) − k² 4Ga(1/3 + π²/36)/(1 − ν).
TEST(PunchField, RadialModeShearsTheDiskAndKeepsItFlat) {
  const geometry::Material material = unit_material();
  const double nu = material.poisson_ratio, G = material.shear_modulus_Pa();
  for (const double r : {0.05, 0.3, 0.7, 0.95})
    for (const double phi : {0.3, 2.0}) {
      const Eigen::Vector3d radial(std::cos(phi), std::sin(phi), 0);
      const PunchFieldSample f = punch_field(PunchMode::radial, PunchFrame{}, 1.0, material, {r * radial.x(), r * radial.y(), 1e-9});
      const double shear = 4 * G / (pi * (1 - nu)) * r / std::sqrt(1 - r * r);
      const Eigen::Vector3d traction_on_tissue = -f.stress_Pa_per_m.col(2);
      EXPECT_LT((traction_on_tissue.head<2>() - shear * radial.head<2>()).norm(), 1e-5 * shear + 1e-7) << "r = " << r;
      EXPECT_NEAR(f.displacement.z(), 0.0, 1e-6) << "r = " << r;
      EXPECT_NEAR(f.displacement.dot(radial), r, 0.05 * r) << "r = " << r;  // plus the dome's slip, a few % of r
    }
  // Far away it is Boussinesq's point force P = k 2Ga/(1 − ν): the shear's dipole is a share a/R
  // of it (1 % at R = 10³ a, 0.1 % at 10⁴ a).
  const double k = 2 * (1 - 2 * nu) / (pi * (1 - nu)), force = k * 2 * G / (1 - nu);
  for (const Eigen::Vector3d& x : {Eigen::Vector3d(6000, 0, 8000), Eigen::Vector3d(0, 3000, 9500)}) {
    const double R = x.norm(), rr = std::hypot(x.x(), x.y()), z = x.z();
    const double u_z = force / (4 * pi * G * R) * (2 * (1 - nu) + z * z / (R * R));
    const double u_r = force / (4 * pi * G * R) * (rr * z / (R * R) - (1 - 2 * nu) * rr / (R + z));
    const Eigen::Vector3d boussinesq(u_r * x.x() / rr, u_r * x.y() / rr, u_z);
    EXPECT_LT((punch_field(PunchMode::radial, PunchFrame{}, 1.0, material, x).displacement - boussinesq).norm(),
              0.003 * boussinesq.norm()) << x.transpose();
  }
}

// A bonded patch on a convex organ bulges above the rim plane (z < 0 over the disk), where the
// dome is extrapolated from the plane and the shear part continued through the disk: the mode
// stays continuous across the plane and smooth through it, its second difference across the
// plane shrinking as h² (a field frozen at its plane value above it would leave an O(h) kink).
TEST(PunchField, RadialModeContinuesAboveTheDisk) {
  const geometry::Material material = unit_material();
  for (const double r : {0.1, 0.5, 0.9}) {
    const Eigen::Vector3d below(r, 0, 1e-7), above(r, 0, -1e-7);
    const PunchFieldSample b = punch_field(PunchMode::radial, PunchFrame{}, 1.0, material, below);
    const PunchFieldSample u = punch_field(PunchMode::radial, PunchFrame{}, 1.0, material, above);
    EXPECT_LT((b.displacement - u.displacement).norm(), 1e-5) << "r = " << r;
    EXPECT_LT((b.stress_Pa_per_m - u.stress_Pa_per_m).norm(), 1e-4 * b.stress_Pa_per_m.norm()) << "r = " << r;
    const auto at = [&](double z) { return punch_field(PunchMode::radial, PunchFrame{}, 1.0, material, {r, 0, z}).displacement; };
    const auto second_difference = [&](double h) { return (at(-h) + at(h) - 2 * at(1e-12)).norm(); };
    // B3's cap rises a/40 above the rim plane at its centre; at half and a quarter of that the
    // ratio is 3.98–4.00, and 2.6–3.6 with the field frozen at its plane value above the disk.
    const double h = 0.0125;
    EXPECT_GT(second_difference(h) / second_difference(h / 2), 3.8) << "r = " << r;
  }
}

TEST(PunchField, RadialModeResultantAndEnergyAreClosedForm) {
  const geometry::Material material = unit_material();
  const double nu = material.poisson_ratio, G = material.shear_modulus_Pa();
  std::vector<double> x, w;
  gauss_legendre(48, x, w);
  Eigen::Vector3d resultant = Eigen::Vector3d::Zero();
  double energy = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    // r = sin t graded once more toward the rim, t = (π/2)(1 − (1 − x)²): the dome's pressure is
    // log-singular there on top of the shear's (1 − r²)^(−½).
    const double t = 0.5 * pi * (1 - (1 - x[i]) * (1 - x[i])), r = std::sin(t);
    const double weight = w[i] * pi * (1 - x[i]) * r * std::cos(t);
    for (int k = 0; k < 64; ++k) {
      const double phi = 2 * pi * (k + 0.5) / 64;
      const PunchFieldSample f = punch_field(PunchMode::radial, PunchFrame{}, 1.0, material, {r * std::cos(phi), r * std::sin(phi), 1e-9});
      resultant -= weight * (2 * pi / 64) * f.stress_Pa_per_m.col(2);
      energy -= weight * (2 * pi / 64) * f.displacement.dot(f.stress_Pa_per_m.col(2));
    }
  }
  const double k = 2 * (1 - 2 * nu) / (pi * (1 - nu));
  const double closed_form = punch_half_space_stiffness_N_per_m(PunchMode::radial, 1.0, material);
  EXPECT_NEAR(closed_form, 16 * G / (3 * (1 - nu)) - k * k * 4 * G * (1.0 / 3 + pi * pi / 36) / (1 - nu), 1e-14);
  EXPECT_NEAR(energy / closed_form, 1.0, 1e-4);
  EXPECT_LT(resultant.head<2>().norm(), 1e-5 * closed_form);  // the shear is self-equilibrated
  EXPECT_NEAR(resultant.z() / (k * 2 * G / (1 - nu)), 1.0, 1e-4);
}

/// The tilt mode: on the disk u₃ = x₁/a and no shear (frictionless); its load has no resultant,
/// its moment about e₂ is 8Ga²/(3(1 − ν)) and its energy 8Ga/(3(1 − ν)) per unit rim displacement
/// (a tilted flat punch: M = (4/3) E* a³ θ with θ = 1/a).
TEST(PunchField, TiltModeTurnsTheDiskAndCarriesTheFlatPunchMoment) {
  const geometry::Material material = unit_material();
  const double nu = material.poisson_ratio, G = material.shear_modulus_Pa();
  for (const double r : {0.05, 0.3, 0.7, 0.95})
    for (const double phi : {0.3, 2.0}) {
      const Eigen::Vector3d x(r * std::cos(phi), r * std::sin(phi), 1e-9);
      const PunchFieldSample f = punch_field(PunchMode::tilt_1, PunchFrame{}, 1.0, material, x);
      EXPECT_NEAR(f.displacement.z(), x.x(), 1e-8) << "r = " << r;
      const double pressure = std::abs(f.stress_Pa_per_m(2, 2));
      EXPECT_LT(f.stress_Pa_per_m.col(2).head<2>().norm(), 1e-5 * pressure + 1e-7) << "r = " << r;
    }
  std::vector<double> t, w;
  gauss_legendre(24, t, w);
  Eigen::Vector3d resultant = Eigen::Vector3d::Zero();
  double moment = 0, energy = 0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    const double angle = 0.5 * pi * t[i], r = std::sin(angle), weight = w[i] * 0.5 * pi * r * std::cos(angle);
    for (int k = 0; k < 64; ++k) {
      const double phi = 2 * pi * (k + 0.5) / 64;
      const PunchFieldSample f = punch_field(PunchMode::tilt_1, PunchFrame{}, 1.0, material, {r * std::cos(phi), r * std::sin(phi), 1e-9});
      const Eigen::Vector3d traction_on_tissue = -f.stress_Pa_per_m.col(2);
      resultant += weight * (2 * pi / 64) * traction_on_tissue;
      moment += weight * (2 * pi / 64) * r * std::cos(phi) * traction_on_tissue.z();
      energy += weight * (2 * pi / 64) * f.displacement.dot(traction_on_tissue);
    }
  }
  const double closed_form = punch_half_space_stiffness_N_per_m(PunchMode::tilt_1, 1.0, material);
  EXPECT_NEAR(closed_form, 8 * G / (3 * (1 - nu)), 1e-14);
  EXPECT_NEAR(moment / closed_form, 1.0, 1e-5);  // a = 1: the moment per unit rim displacement
  EXPECT_NEAR(energy / closed_form, 1.0, 1e-5);
  EXPECT_LT(resultant.norm(), 1e-5 * closed_form);
}

TEST(PunchField, FreeSurfaceOutsideThePunchIsTractionFree) {
  const geometry::Material material = unit_material();
  for (const PunchMode mode : {PunchMode::normal, PunchMode::tangential_1, PunchMode::tangential_2})
    for (const double r : {1.2, 2.0, 4.0}) {
      const PunchFieldSample f = punch_field(mode, PunchFrame{}, 1.0, material, {r * 0.6, r * 0.8, 0.0});
      const double scale = punch_field(mode, PunchFrame{}, 1.0, material, {r * 0.6, r * 0.8, 0.5}).stress_Pa_per_m.norm();
      EXPECT_LT(f.stress_Pa_per_m.col(2).norm(), 1e-5 * scale) << "mode " << int(mode) << " r = " << r;
    }
  // The radial and tilt modes' stresses fall off fast with depth: measured against the in-plane
  // stress of the surface point itself.
  for (const PunchMode mode : {PunchMode::radial, PunchMode::tilt_1})
    for (const double r : {1.2, 2.0, 4.0}) {
      const PunchFieldSample f = punch_field(mode, PunchFrame{}, 1.0, material, {r * 0.6, r * 0.8, 0.0});
      EXPECT_LT(f.stress_Pa_per_m.col(2).norm(), 1e-5 * f.stress_Pa_per_m.norm()) << "mode " << int(mode) << ", r = " << r;
    }
}

TEST(PunchField, StressesAreInEquilibrium) {
  // div σ = 0 by central differences of the returned stress.
  const geometry::Material material = unit_material();
  const double h = 1e-5;
  for (const PunchMode mode : {PunchMode::normal, PunchMode::tangential_1, PunchMode::radial, PunchMode::tilt_1})
    for (const Eigen::Vector3d& x : {Eigen::Vector3d(0.3, 0.4, 0.6), Eigen::Vector3d(1.6, -0.5, 0.7)}) {
      Eigen::Vector3d divergence = Eigen::Vector3d::Zero();
      for (int j = 0; j < 3; ++j) {
        const Eigen::Vector3d e = h * Eigen::Vector3d::Unit(j);
        divergence += (punch_field(mode, PunchFrame{}, 1.0, material, x + e).stress_Pa_per_m.col(j) -
                       punch_field(mode, PunchFrame{}, 1.0, material, x - e).stress_Pa_per_m.col(j)) /
                      (2 * h);
      }
      EXPECT_LT(divergence.norm(), 1e-4 * punch_field(mode, PunchFrame{}, 1.0, material, x).stress_Pa_per_m.norm())
          << "mode " << int(mode) << " at " << x.transpose();
    }
}

/// The enriched model integrates every ψ term on the boundary: ∫_V σ(ψ_m):ε(ψ_n) dV =
/// ∮_∂V ψ_n·σ(ψ_m)n dA, because div σ(ψ) = 0. Checked on a box away from the rim by tensor
/// Gauss rules (the integrands are smooth there).
TEST(PunchField, BoundaryFormEqualsVolumeIntegral) {
  const geometry::Material material = unit_material();
  const double lambda = material.lame_lambda_Pa(), mu = material.shear_modulus_Pa();
  const Eigen::Vector3d low(0.4, -0.6, 0.8), high(1.7, 0.5, 2.0);
  const auto strain_of = [&](const Eigen::Matrix3d& stress) {
    return Eigen::Matrix3d((stress - lambda / (3 * lambda + 2 * mu) * stress.trace() * Eigen::Matrix3d::Identity()) / (2 * mu));
  };
  const PunchMode modes[] = {PunchMode::normal, PunchMode::tangential_1, PunchMode::tangential_2,
                             PunchMode::radial, PunchMode::tilt_1, PunchMode::tilt_2};
  constexpr std::size_t count = std::size(modes);
  Eigen::Matrix<double, count, count> volume = Eigen::Matrix<double, count, count>::Zero(), boundary = volume;
  const auto fields_at = [&](const Eigen::Vector3d& p) {
    std::array<PunchFieldSample, count> f;
    for (std::size_t m = 0; m < count; ++m) f[m] = punch_field(modes[m], PunchFrame{}, 1.0, material, p);
    return f;
  };
  for (const touchstone::testing::BoxPoint& q : touchstone::testing::box_volume_rule(low, high, 16)) {
    const std::array<PunchFieldSample, count> f = fields_at(q.position_m);
    for (std::size_t m = 0; m < count; ++m)
      for (std::size_t n = 0; n < count; ++n)
        volume(m, n) += q.weight * (f[m].stress_Pa_per_m.cwiseProduct(strain_of(f[n].stress_Pa_per_m))).sum();
  }
  for (const touchstone::testing::BoxPoint& q : touchstone::testing::box_surface_rule(low, high, 16)) {
    const std::array<PunchFieldSample, count> f = fields_at(q.position_m);
    for (std::size_t m = 0; m < count; ++m)
      for (std::size_t n = 0; n < count; ++n) boundary(m, n) += q.weight * f[n].displacement.dot(f[m].stress_Pa_per_m * q.normal);
  }
  EXPECT_NEAR(boundary(0, 0) / volume(0, 0), 1.0, 1e-6);  // ψ_normal, closed-form stresses
  for (int m = 0; m < static_cast<int>(count); ++m)
    for (int n = 0; n < static_cast<int>(count); ++n)  // the other modes' stresses are finite differences
      EXPECT_NEAR(boundary(m, n), volume(m, n), 1e-5 * volume.diagonal().maxCoeff()) << m << n;
}

TEST(PunchField, AFrameRotatesTheField) {
  const geometry::Material material = unit_material();
  const Eigen::Vector3d origin(0.1, -0.2, 0.3), direction = Eigen::Vector3d(0.3, -0.2, -1.0).normalized();
  const PunchFrame frame = PunchFrame::along(origin, direction);
  EXPECT_NEAR((frame.axes.transpose() * frame.axes - Eigen::Matrix3d::Identity()).norm(), 0, 1e-14);
  EXPECT_NEAR(frame.axes.determinant(), 1, 1e-14);
  const Eigen::Vector3d local(0.4, 0.7, 0.5), x = origin + frame.axes * local;
  for (const PunchMode mode : {PunchMode::normal, PunchMode::tangential_1, PunchMode::tangential_2, PunchMode::radial,
                               PunchMode::tilt_1, PunchMode::tilt_2}) {
    const PunchFieldSample global = punch_field(mode, frame, 1.0, material, x);
    const PunchFieldSample reference = punch_field(mode, PunchFrame{}, 1.0, material, local);
    EXPECT_LT((frame.axes.transpose() * global.displacement - reference.displacement).norm(), 1e-12);
    EXPECT_LT((frame.axes.transpose() * global.stress_Pa_per_m * frame.axes - reference.stress_Pa_per_m).norm(), 1e-9);
  }
  // tangential_2 is tangential_1 turned by 90° about e₃.
  const PunchFieldSample t2 = punch_field(PunchMode::tangential_2, PunchFrame{}, 1.0, material, {-0.7, 0.4, 0.5});
  const PunchFieldSample t1 = punch_field(PunchMode::tangential_1, PunchFrame{}, 1.0, material, {0.4, 0.7, 0.5});
  EXPECT_NEAR(t2.displacement.x(), -t1.displacement.y(), 1e-14);
  EXPECT_NEAR(t2.displacement.y(), t1.displacement.x(), 1e-14);
  EXPECT_NEAR(t2.displacement.z(), t1.displacement.z(), 1e-14);
  // and tilt_2 is tilt_1 turned the same way: u₃ = x₂/a on the disk.
  EXPECT_NEAR(punch_field(PunchMode::tilt_2, PunchFrame{}, 1.0, material, {0.2, 0.5, 1e-9}).displacement.z(), 0.5, 1e-8);
}

}  // namespace
}  // namespace touchstone::realtime::mfs
