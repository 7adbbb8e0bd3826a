#include "touchstone/fem/richardson.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace touchstone::fem {

RichardsonEstimate richardson_extrapolate(const std::vector<double>& values, double ratio,
                                          double theoretical_order) {
  if (values.size() < 3) throw std::invalid_argument("Richardson extrapolation needs at least three values");
  if (!(ratio > 1)) throw std::invalid_argument("Richardson extrapolation needs a refinement ratio > 1");
  const std::size_t n = values.size();
  const double f1 = values[n - 3], f2 = values[n - 2], f3 = values[n - 1];
  const double d12 = f1 - f2, d23 = f2 - f3;

  RichardsonEstimate estimate;
  const auto extrapolate = [&](double p) { return f3 - d23 / (std::pow(ratio, p) - 1); };
  if (d12 == 0 || d23 == 0 || (d12 > 0) != (d23 > 0)) {
    estimate.extrapolated = f3;
    estimate.observed_order = std::numeric_limits<double>::quiet_NaN();
    estimate.finest_relative_error = std::abs(d23) / std::abs(f3);
    estimate.gci_finest = 1.25 * estimate.finest_relative_error;
    estimate.extrapolated_relative_uncertainty = estimate.finest_relative_error;
    return estimate;
  }
  const double p = std::log(d12 / d23) / std::log(ratio);
  estimate.observed_order = p;
  estimate.extrapolated = extrapolate(p);
  estimate.finest_relative_error = std::abs(f3 - estimate.extrapolated) / std::abs(estimate.extrapolated);
  estimate.gci_finest = 1.25 * std::abs(d23) / (std::abs(f3) * (std::pow(ratio, p) - 1));
  estimate.extrapolated_relative_uncertainty =
      std::abs(estimate.extrapolated - extrapolate(theoretical_order)) / std::abs(estimate.extrapolated);
  estimate.asymptotic = p >= 0.5 * theoretical_order && p <= 2 * theoretical_order + 1;
  return estimate;
}

}  // namespace touchstone::fem
