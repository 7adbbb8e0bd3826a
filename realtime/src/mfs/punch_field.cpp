#include "touchstone/realtime/mfs/punch_field.hpp"

#include "punch_superposition.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <complex>

namespace touchstone::realtime::mfs {
namespace {

constexpr double pi = 3.14159265358979323846;
using Complex = std::complex<double>;

using Helpers = detail::PunchHelpers;

}  // namespace

namespace detail {

Eigen::Vector3d admissible(Eigen::Vector3d p, double a) {
  if (std::hypot(p.x(), p.y()) >= a) p.z() = std::max(p.z(), 1e-13 * a);
  return p;
}

PunchFieldSample sneddon_local(const Eigen::Vector3d& p, double a, const geometry::Material& material) {
  const double nu = material.poisson_ratio, G = material.shear_modulus_Pa();
  const double r = std::hypot(p.x(), p.y()), z = p.z();
  const Helpers h(r, z, a);
  const double chi_z = -(1.0 / h.q).imag();
  const double chi_zz = (h.s / (h.q * h.q * h.q)).imag();
  // χ_r/r and Φ_r/r by their axis series where r/a is small (the closed forms cancel there).
  double chi_r_over_r, phi_r_over_r;
  if (r < 1e-3 * a) {
    chi_r_over_r = -(1.0 / (2.0 * h.s * h.s)).imag();
    phi_r_over_r = a / (2 * (z * z + a * a));
  } else {
    chi_r_over_r = (h.s / h.q).imag() / (r * r);
    phi_r_over_r = (h.q - h.s).imag() / (r * r);
  }
  const double chi_r = chi_r_over_r * r, phi_r = phi_r_over_r * r;
  const double chi_rz = (r / (h.q * h.q * h.q)).imag();
  const double chi_rr = -chi_zz - chi_r_over_r;
  const double phi_rr = -chi_z - phi_r_over_r;
  const double K = 1.0 / (pi * (1 - nu)), S = 2 * G * K;
  const double ur = -K * ((1 - 2 * nu) * phi_r + z * chi_r);
  const double uz = K * (2 * (1 - nu) * h.chi - z * chi_z);
  const double srr = S * (2 * nu * chi_z - (1 - 2 * nu) * phi_rr - z * chi_rr);
  const double stt = S * (2 * nu * chi_z - (1 - 2 * nu) * phi_r_over_r - z * chi_r_over_r);
  const double szz = S * (chi_z - z * chi_zz);
  const double srz = -S * z * chi_rz;
  const double c = r > 0 ? p.x() / r : 1.0, sn = r > 0 ? p.y() / r : 0.0;
  PunchFieldSample out;
  out.displacement = {ur * c, ur * sn, uz};
  Eigen::Matrix3d& t = out.stress_Pa_per_m;
  t(0, 0) = srr * c * c + stt * sn * sn;
  t(1, 1) = srr * sn * sn + stt * c * c;
  t(2, 2) = szz;
  t(0, 1) = t(1, 0) = (srr - stt) * c * sn;
  t(0, 2) = t(2, 0) = srz * c;
  t(1, 2) = t(2, 1) = srz * sn;
  return out;
}

}  // namespace detail

namespace {

using detail::admissible;
using detail::sneddon_local;

/// The stuck punch moved by a unit displacement along local x (force Q = 8Ga/(2 − ν)):
/// the displacement only, in local coordinates. Needs r > 0.
Eigen::Vector3d tangential_displacement_off_axis(const Eigen::Vector3d& p, double a, double nu) {
  const double r = std::hypot(p.x(), p.y()), z = p.z();
  const double c = p.x() / r, sn = p.y() / r;
  const Helpers h(r, z, a);
  const Complex& s = h.s;
  const Complex& q = h.q;
  const Complex& w = h.w;
  const double chi = h.chi;
  const double chi_r = (s / q).imag() / r;
  const double phi_r = (q - s).imag() / r;
  const Complex lnw = std::log(w);
  const double th_r = 0.5 * r * ((s / w).imag() - chi);
  const double th_rr = 0.5 * ((s / w).imag() - chi) + 0.5 * r * ((-s * r / (q * w * w)).imag() - chi_r);
  const Complex i(0, 1);
  const Complex H = 0.5 * (s * q - r * r * lnw) + i * a * q;
  const Complex H_r = 0.5 * (s * r / q - 2 * r * lnw - r * r * r / (q * w)) + i * a * r / q;
  const double la_r = H.imag() / r;
  const double la_rr = -H.imag() / (r * r) + H_r.imag() / r;
  const auto xx = [&](double frr, double fr) { return frr * c * c + fr / r * sn * sn; };
  const auto xy = [&](double frr, double fr) { return (frr - fr / r) * c * sn; };
  const double C = 2.0 / (pi * (2 - nu));  // Q / (4πGa) with Q = 8Ga/(2 − ν)
  return {C * (2 * chi - xx(la_rr, la_r) - (1 - 2 * nu) * xx(th_rr, th_r)),
          C * (-xy(la_rr, la_r) - (1 - 2 * nu) * xy(th_rr, th_r)),
          C * ((1 - 2 * nu) * phi_r - z * chi_r) * c};
}

/// A closed form that divides by r, continued onto and near the axis: within 1e-3 a of it the
/// linear interpolation between the two points at ±1e-3 a across the axis, second-order accurate
/// (the fields are smooth there).
template <class OffAxis>
Eigen::Vector3d continued_to_the_axis(const Eigen::Vector3d& p, double a, OffAxis off_axis) {
  const double r = std::hypot(p.x(), p.y()), eps = 1e-3 * a;
  if (r >= eps) return off_axis(p);
  const Eigen::Vector2d dir = r > 0 ? Eigen::Vector2d(p.x() / r, p.y() / r) : Eigen::Vector2d(1, 0);
  const Eigen::Vector3d plus(dir.x() * eps, dir.y() * eps, p.z()), minus(-dir.x() * eps, -dir.y() * eps, p.z());
  const double t = (r + eps) / (2 * eps);  // linear interpolation weight of `plus`
  return t * off_axis(plus) + (1 - t) * off_axis(minus);
}

Eigen::Vector3d tangential_displacement(const Eigen::Vector3d& p, double a, double nu) {
  return continued_to_the_axis(p, a, [&](const Eigen::Vector3d& y) { return tangential_displacement_off_axis(y, a, nu); });
}

/// The radial shear mode per metre of radial displacement at the rim, in the punch frame: the
/// half-space under the self-equilibrated surface shear τ_r ∝ r / √(a² − r²) on the disk (zero
/// normal traction everywhere). Built from one harmonic potential φ₁ and φ₂ = ∂φ₁/∂z / (2(1 − ν)):
/// u = ∇φ₁ + z ∇φ₂ − (3 − 4ν) φ₂ e_z (Papkovich–Neuber), whose surface normal stress vanishes by
/// that choice of φ₂ and whose shear stress is G/(1 − ν) ∂²φ₁/∂r∂z. φ₁ is Hertz's potential in
/// oblate spheroidal coordinates (ξ, η) = (Re q, −Im q) / a:
///   φ₁ = −(a²/3) [arccot ξ + P₂(η) Q̃₂(ξ)],  f = ∂φ₁/∂z = a η (1 − ξ arccot ξ),
/// so f = √(a² − r²) on the disk and 0 beyond it. Under the disk u_r = (π/4) r before the
/// scaling to a unit rim displacement: the field carries the uniform radial strain of the patch
/// that the frictionless field lets slip and a bonded punch holds. Its face bulges by
/// u_z = −(1 − 2ν)/(2(1 − ν)) f; punch_field adds the dome that flattens it.
Eigen::Vector3d radial_displacement(const Eigen::Vector3d& p, double a, double nu) {
  const double r = std::hypot(p.x(), p.y()), z = p.z();
  const Helpers h(r, z, a);
  // ξ < 0 where the branch continues through the disk into z < 0; arccot and √(1 − η²) are
  // written so that they continue with it.
  const double xi = h.q.real() / a, eta = -h.q.imag() / a;
  const double acot = std::atan2(1.0, xi);
  const double root = std::sqrt(1 + xi * xi), sin_eta = r / (a * root);
  const double phi1_r = a * sin_eta * ((xi * xi + 1) * acot - xi) / (2 * root);
  const double f = a * eta * (1 - xi * acot);
  // z ∂f/∂r and z ∂f/∂z with z = a ξ η: bounded at the rim, where ∂f itself is singular.
  const double rho2 = xi * xi + eta * eta;
  const double z_f_r = rho2 > 0 ? -a * xi * eta * eta * sin_eta / (rho2 * root) : 0.0;
  const double z_f_z = rho2 > 0 ? a * xi * eta * (xi - rho2 * acot) / rho2 : 0.0;
  const double k = 1 / (2 * (1 - nu));
  const double ur = phi1_r + k * z_f_r, uz = f + k * z_f_z - (3 - 4 * nu) * k * f;
  const double scale = 4 / (pi * a);  // u_r = 1 at the rim
  const double c = r > 0 ? p.x() / r : 1.0, sn = r > 0 ? p.y() / r : 0.0;
  return scale * Eigen::Vector3d(ur * c, ur * sn, uz);
}

/// The dome's weight in the radial mode: the shear mode's u_z under the disk is
/// −k √(1 − r²/a²) per unit rim displacement.
double radial_mode_dome_weight(double nu) { return 2 * (1 - 2 * nu) / (pi * (1 - nu)); }

/// The frictionless punch tilted about local y per metre of rim displacement (u_z = x/a on the
/// disk), in the punch frame: Boussinesq's shear-free solution u_h = −K[(1 − 2ν)∇_hΦ + z∇_hχ],
/// u_z = K[2(1 − ν)χ − z∂_zχ], K = 1/(π(1 − ν)), with the pressure x/√(a² − r²) = −∂_x √(a² − r²):
/// its potential is the x-derivative of Hertz's, χ = (2/a) ∂_xφ₁, and Φ = (2/a) ∂_xΦ₁ with
/// ∂_zΦ₁ = φ₁. In the radial mode's oblate coordinates (AC = arccot ξ, R = √(1 + ξ²),
/// S = √(1 − η²) = r/(aR)):
///   φ₁,r = aS((1 + ξ²)AC − ξ)/(2R),  φ₁,rr = AC/2 + ξ(η² − ξ² − 2)/(2(ξ² + η²)(1 + ξ²)),
///   Φ₁,r = a²[η(1 − η²)(3ξ(1 + ξ²)AC − 3ξ²) − 2(1 − η³)]/(6RS),
///   Φ₁,rr = a[η(3ξ(1 + ξ²)AC − 3ξ² − 4)/(6(1 + ξ²)) + 1/(3(1 + η)(1 + ξ²))],
///   ∂_rf = −Sη/(R(ξ² + η²)) with f = ∂_zφ₁. Needs r > 0.
Eigen::Vector3d tilt_displacement_off_axis(const Eigen::Vector3d& p, double a, double nu) {
  const double r = std::hypot(p.x(), p.y()), z = p.z();
  const double c = p.x() / r, sn = p.y() / r;
  const Helpers h(r, z, a);
  const double xi = h.q.real() / a, eta = -h.q.imag() / a;
  const double ac = std::atan2(1.0, xi), xi2 = xi * xi, R = std::sqrt(1 + xi2), S = r / (a * R);
  const double rho2 = xi2 + eta * eta;
  const double phi_r = a * S * ((1 + xi2) * ac - xi) / (2 * R);
  // z φ₁,rr and z ∂_rf with z = aξη: bounded at the rim, where the second derivatives are not.
  const double z_phi_rr = z * ac / 2 + (rho2 > 0 ? a * xi * eta * xi * (eta * eta - xi2 - 2) / (2 * rho2 * (1 + xi2)) : 0.0);
  const double z_f_r = rho2 > 0 ? -a * xi * eta * S * eta / (R * rho2) : 0.0;
  const double bracket = 3 * xi * (1 + xi2) * ac - 3 * xi2;
  const double big_phi_r = a * a * (eta * (1 - eta * eta) * bracket - 2 * (1 - eta * eta * eta)) / (6 * R * S);
  const double big_phi_rr = a * (eta * (bracket - 4) / (6 * (1 + xi2)) + 1 / (3 * (1 + eta) * (1 + xi2)));
  const double K = 1 / (pi * (1 - nu)), scale = 2 / a;
  const double chi = scale * c * phi_r;
  const double z_chi_x = scale * (z_phi_rr * c * c + z * phi_r / r * sn * sn);
  const double z_chi_y = scale * (z_phi_rr - z * phi_r / r) * c * sn;
  const double z_chi_z = scale * c * z_f_r;
  const double big_phi_x = scale * (big_phi_rr * c * c + big_phi_r / r * sn * sn);
  const double big_phi_y = scale * (big_phi_rr - big_phi_r / r) * c * sn;
  return {-K * ((1 - 2 * nu) * big_phi_x + z_chi_x), -K * ((1 - 2 * nu) * big_phi_y + z_chi_y),
          K * (2 * (1 - nu) * chi - z_chi_z)};
}

Eigen::Vector3d tilt_displacement(const Eigen::Vector3d& p, double a, double nu) {
  return continued_to_the_axis(p, a, [&](const Eigen::Vector3d& y) { return tilt_displacement_off_axis(y, a, nu); });
}

/// A mode given by its displacement alone, with its stress from a second-order finite-difference
/// gradient (step 1e-3 of the distance to the rim, one-sided near the free surface).
template <class Displacement>
PunchFieldSample with_finite_difference_stress(const Eigen::Vector3d& p, double a, const geometry::Material& material,
                                               Displacement displacement) {
  const auto u = [&](const Eigen::Vector3d& y) { return displacement(admissible(y, a)); };
  const double r = std::hypot(p.x(), p.y());
  const double rim_distance = std::hypot(r - a, p.z());
  const double step = 1e-3 * std::clamp(rim_distance, 1e-9 * a, a);
  PunchFieldSample out;
  out.displacement = u(p);
  Eigen::Matrix3d gradient;  // ∂u_i/∂x_j
  for (int j = 0; j < 3; ++j) {
    Eigen::Vector3d e = Eigen::Vector3d::Zero();
    e[j] = step;
    const bool one_sided = j == 2 && r >= a - step && p.z() < step;
    if (one_sided)
      gradient.col(j) = (-3 * out.displacement + 4 * u(p + e) - u(p + 2 * e)) / (2 * step);
    else
      gradient.col(j) = (u(p + e) - u(p - e)) / (2 * step);
  }
  const Eigen::Matrix3d strain = 0.5 * (gradient + gradient.transpose());
  out.stress_Pa_per_m = material.lame_lambda_Pa() * strain.trace() * Eigen::Matrix3d::Identity() + 2 * material.shear_modulus_Pa() * strain;
  return out;
}

}  // namespace

PunchFrame PunchFrame::along(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) {
  PunchFrame frame;
  frame.origin = origin;
  const Eigen::Vector3d e3 = direction.normalized();
  // e₁: the global axis least aligned with e₃, made orthogonal.
  Eigen::Index least = 0;
  e3.cwiseAbs().minCoeff(&least);
  const Eigen::Vector3d e1 = (Eigen::Vector3d::Unit(least) - e3[least] * e3).normalized();
  frame.axes.col(0) = e1;
  frame.axes.col(1) = e3.cross(e1);
  frame.axes.col(2) = e3;
  return frame;
}

PunchFieldSample punch_field(PunchMode mode, const PunchFrame& frame, double radius_m, const geometry::Material& material,
                             const Eigen::Vector3d& x) noexcept {
  const Eigen::Matrix3d& R = frame.axes;
  Eigen::Vector3d local = R.transpose() * (x - frame.origin);
  // tangential_2 and tilt_2 are tangential_1 and tilt_1 turned by 90° about e₃: u₂(p) = Q u₁(Qᵀ p).
  Eigen::Matrix3d turn = Eigen::Matrix3d::Identity();
  if (mode == PunchMode::tangential_2 || mode == PunchMode::tilt_2) turn << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  local = turn.transpose() * local;
  const double a = radius_m, nu = material.poisson_ratio;
  PunchFieldSample sample;
  switch (mode) {
    case PunchMode::normal: sample = sneddon_local(admissible(local, a), a, material); break;
    case PunchMode::tangential_1:
    case PunchMode::tangential_2:
      sample = with_finite_difference_stress(local, a, material, [&](const Eigen::Vector3d& y) { return tangential_displacement(y, a, nu); });
      break;
    case PunchMode::radial: {
      // The shear mode plus the dome that flattens its face (its u_z under the disk is
      // −k √(1 − r²/a²)): a bonded face stays flat.
      sample = with_finite_difference_stress(local, a, material, [&](const Eigen::Vector3d& y) { return radial_displacement(y, a, nu); });
      const PunchFieldSample dome = detail::dome_local(local, a, material);
      const double k = radial_mode_dome_weight(nu);
      sample.displacement += k * dome.displacement;
      sample.stress_Pa_per_m += k * dome.stress_Pa_per_m;
      break;
    }
    case PunchMode::tilt_1:
    case PunchMode::tilt_2:
      sample = with_finite_difference_stress(local, a, material, [&](const Eigen::Vector3d& y) { return tilt_displacement(y, a, nu); });
      break;
  }
  const Eigen::Matrix3d to_global = R * turn;
  sample.displacement = to_global * sample.displacement;
  sample.stress_Pa_per_m = to_global * sample.stress_Pa_per_m * to_global.transpose();
  return sample;
}

double punch_half_space_stiffness_N_per_m(PunchMode mode, double radius_m, const geometry::Material& material) noexcept {
  const double G = material.shear_modulus_Pa(), nu = material.poisson_ratio;
  switch (mode) {
    case PunchMode::normal: return 4 * G * radius_m / (1 - nu);
    case PunchMode::tangential_1:
    case PunchMode::tangential_2: return 8 * G * radius_m / (2 - nu);
    case PunchMode::radial: {
      // ⟨R + kD, R + kD⟩ = E_R + 2k⟨R, D⟩ + k²E_D with ⟨R, D⟩ = −k E_D (R's u_z under the disk is
      // −k times D's, and D's traction there is normal).
      const double k = radial_mode_dome_weight(nu);
      return 16 * G * radius_m / (3 * (1 - nu)) - k * k * 4 * G * radius_m * (1.0 / 3 + pi * pi / 36) / (1 - nu);
    }
    case PunchMode::tilt_1:
    case PunchMode::tilt_2: return 8 * G * radius_m / (3 * (1 - nu));
  }
  return 0;
}

}  // namespace touchstone::realtime::mfs
