#pragma once
/// @file
/// Internal to the punch fields: the pieces that punch_field.cpp and the superposition fields
/// (punch_superposition.cpp) share. All in the punch frame: origin at the rim-circle centre, e₃ into
/// the body; per metre of punch displacement.

#include "touchstone/realtime/mfs/punch_field.hpp"

#include <Eigen/Core>

#include <complex>

namespace touchstone::realtime::mfs::detail {

/// The complex helpers of the punch solutions at (r, z) for a disk of radius a:
/// s = z − i a, q = −i √(−(r² + s²)) (so q² = r² + s²), w = s + q, χ = −arg w (principal
/// branches; χ = π/2 on the disk, and Sneddon's potentials are its derivatives). The branch
/// continues smoothly through the disk into z < 0 (r < a).
struct PunchHelpers {
  std::complex<double> s, q, w;
  double chi;
  PunchHelpers(double r, double z, double a) : s(z, -a) {
    q = std::complex<double>(0, -1) * std::sqrt(-(r * r + s * s));
    w = s + q;
    chi = -std::arg(w);
  }
};

/// Where a point may be evaluated for a disk of radius a: never above the rim plane outside the
/// rim (the branch cut); such points are lowered to z = 1e-13 a.
Eigen::Vector3d admissible(Eigen::Vector3d p, double a);

/// Sneddon's frictionless flat punch of radius a pressed by a unit depth (punch_field.cpp).
PunchFieldSample sneddon_local(const Eigen::Vector3d& p, double a, const geometry::Material& material);

/// The frictionless punch whose face takes the dome u_z = √(1 − r²/a²) per metre at the centre
/// (punch_superposition.cpp).
PunchFieldSample dome_local(const Eigen::Vector3d& p, double a, const geometry::Material& material);

}  // namespace touchstone::realtime::mfs::detail
