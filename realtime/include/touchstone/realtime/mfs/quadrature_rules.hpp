#pragma once
/// @file
/// One-dimensional rules the local models' quadratures are built from.

#include <vector>

namespace touchstone::realtime::mfs {

/// Gauss–Legendre nodes and weights on [0, 1] (exact for polynomials of degree 2n − 1).
void gauss_legendre(int n, std::vector<double>& x, std::vector<double>& w);

/// The largest t ∈ [0, t_max] such that inside(s) holds for all s ∈ (0, t], when inside holds
/// near 0: marching in `steps`, then bisection to ~1e-9 of t_max. 0 if it fails at once.
template <class Inside>
double first_exit(Inside inside, double t_max, int steps = 64) {
  double low = 0;
  for (int k = 1; k <= steps; ++k) {
    const double t = t_max * k / steps;
    if (inside(t)) {
      low = t;
      continue;
    }
    double high = t;
    for (int i = 0; i < 40 && high - low > 1e-9 * t_max; ++i) {
      const double mid = 0.5 * (low + high);
      (inside(mid) ? low : high) = mid;
    }
    return low;
  }
  return t_max;
}

}  // namespace touchstone::realtime::mfs
