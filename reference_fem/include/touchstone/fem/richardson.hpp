#pragma once
/// @file
/// Richardson extrapolation of a quantity computed on a sequence of meshes whose sizes shrink by
/// a constant ratio r (here r = 2: each refinement halves every element size).

#include <vector>

namespace touchstone::fem {

struct RichardsonEstimate {
  double extrapolated = 0;     ///< f_R = f₃ + (f₃ − f₂)/(r^p − 1) from the three finest values
  double observed_order = 0;   ///< p = ln((f₁ − f₂)/(f₂ − f₃)) / ln r; NaN when not monotone
  /// |f₃ − f_R| / |f_R|: the estimated discretisation error of the finest mesh.
  double finest_relative_error = 0;
  /// Roache's grid convergence index of the finest mesh, 1.25 |f₃ − f₂| / (|f₃| (r^p − 1)).
  double gci_finest = 0;
  /// Uncertainty of f_R itself: |f_R(p) − f_R(p_theory)| / |f_R|, the change of the extrapolated
  /// value when the observed order is replaced by the order theory predicts (0 when p = p_theory).
  double extrapolated_relative_uncertainty = 0;
  /// True when the three values converge monotonically (same sign of successive differences)
  /// and the observed order is within [p_theory/2, 2 p_theory + 1]: only then is f_R trusted.
  bool asymptotic = false;
};

/// Needs ≥ 3 values, coarsest first; uses the last three. When the differences change sign or
/// vanish, extrapolated = finest and the error estimates fall back to |f₃ − f₂| / |f₃|.
/// Throws std::invalid_argument for fewer than three values or r ≤ 1.
RichardsonEstimate richardson_extrapolate(const std::vector<double>& values, double ratio,
                                          double theoretical_order);

}  // namespace touchstone::fem
