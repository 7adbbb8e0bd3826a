/// @file
/// Punch fields built as superpositions of Sneddon's flat punches S_t of radii t ≤ a (Copson's
/// solution of the axisymmetric mixed problem): a frictionless face that takes any axisymmetric
/// profile u_z = f(r) under the disk is (π/2) ∫₀^a g(t) ∂_t S_t dt, where g is the Abel
/// transform of the profile, f(r) = ∫₀^r g(t) / √(r² − t²) dt. Each S_t is shear-free on the
/// surface and traction-free beyond its disk, so every superposition is too.

#include "punch_superposition.hpp"

#include "touchstone/realtime/mfs/quadrature_rules.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace touchstone::realtime::mfs::detail {
namespace {

constexpr double pi = 3.14159265358979323846;

struct GaussRule {
  std::vector<double> x, w;
  explicit GaussRule(int n) { gauss_legendre(n, x, w); }
};

/// Calls add(t, dt-weight) over the nodes of a rule for ∫₀^a … dt at the point p. The integrand
/// is singular where S_t's rim passes the point (t = r on the surface) and varies on the scale of
/// the point's distance to that rim near it; it may also carry an integrable singularity at
/// t = a. Pieces halve toward the singular end until they are as short as that scale; the last
/// one, and [r, a] when the point is over the disk, are mapped by t = lo + (hi − lo)(1 − cos θ)/2,
/// which absorbs inverse-square-root and logarithmic ends, then Gauss–Legendre in θ.
template <class Add>
void integrate_over_radii(const Eigen::Vector3d& p, double a, Add add) {
  static const GaussRule smooth(6), singular(16);
  const auto piece = [&](double lo, double hi, const GaussRule& rule, bool mapped) {
    for (std::size_t i = 0; i < rule.x.size(); ++i) {
      const double theta = pi * rule.x[i];
      const double t = mapped ? lo + 0.5 * (hi - lo) * (1 - std::cos(theta)) : lo + (hi - lo) * rule.x[i];
      const double jacobian = mapped ? pi * 0.5 * (hi - lo) * std::sin(theta) : hi - lo;
      if (t > 0 && t < a) add(t, rule.w[i] * jacobian);
    }
  };
  const double r = std::hypot(p.x(), p.y());
  const bool over_the_disk = r < a * (1 - 1e-9);
  const double end = over_the_disk ? r : a;
  const double scale = over_the_disk ? std::max(a - r, std::abs(p.z())) : std::max(std::hypot(r - a, p.z()), 1e-12 * a);
  double lo = 0;
  while (end - lo > 4 * scale && end - lo > 1e-9 * a) {
    const double mid = 0.5 * (lo + end);
    piece(lo, mid, smooth, false);
    lo = mid;
  }
  piece(lo, end, singular, true);
  if (over_the_disk) piece(r, a, singular, true);
}

}  // namespace

/// The dome u_z = √(1 − r²/a²): its Abel transform is g(t) = (2/π)(1 − τ artanh τ), τ = t/a,
/// log-singular at t = a. An integration by parts (S_t − S_a vanishes there) gives
///   D = S_a + ∫₀^a w(t) (S_t − S_a) dt,   w(t) = (artanh τ + τ/(1 − τ²)) / a.
/// Its pressure is log-singular at the rim; its force is 2Ga/(1 − ν) (by reciprocity with the
/// flat punch: Sneddon's pressure against the dome) and its energy ∫ u·t dA is
/// 4Ga(1/3 + π²/36)/(1 − ν) (for a frictionless face, (π²G/(1 − ν)) ∫₀^a g² dt).
PunchFieldSample dome_local(const Eigen::Vector3d& p, double a, const geometry::Material& material) {
  // Over the disk but above the rim plane (a patch that bulges toward the tool) the punches
  // narrower than r have no continuation consistent with the wider ones (every path down crosses
  // some rim): the field is extrapolated linearly in z from the plane and the mirror point below
  // (what the other choices cost is in docs/enriched_model.md, The dome that flattens it).
  if (p.z() < 0 && std::hypot(p.x(), p.y()) < a) {
    const PunchFieldSample on_plane = dome_local({p.x(), p.y(), 0.0}, a, material);
    const PunchFieldSample mirror = dome_local({p.x(), p.y(), -p.z()}, a, material);
    return {2 * on_plane.displacement - mirror.displacement, 2 * on_plane.stress_Pa_per_m - mirror.stress_Pa_per_m};
  }
  const PunchFieldSample full = sneddon_local(admissible(p, a), a, material);
  PunchFieldSample out = full;
  integrate_over_radii(p, a, [&](double t, double dt) {
    const double tau = t / a;
    const double weight = dt * (std::atanh(tau) + tau / (1 - tau * tau)) / a;
    const PunchFieldSample s = sneddon_local(admissible(p, t), t, material);
    out.displacement += weight * (s.displacement - full.displacement);
    out.stress_Pa_per_m += weight * (s.stress_Pa_per_m - full.stress_Pa_per_m);
  });
  return out;
}

}  // namespace touchstone::realtime::mfs::detail
