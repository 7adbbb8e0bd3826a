#pragma once
/// @file
/// Isotropic linear elastic material of the real-time model (SI units).

#include <cmath>
#include <stdexcept>
#include <string>

namespace touchstone::realtime::mfs {

struct Material {
  double youngs_modulus_Pa = 10.0e3;  ///< E [Pa]: stomach tissue, as in the paper
  double poisson_ratio = 0.45;        ///< ν, 0 ≤ ν < 0.5

  /// Throws std::invalid_argument naming the field (E ≤ 0, ν outside [0, 0.5), non-finite).
  void validate() const {
    if (!std::isfinite(youngs_modulus_Pa) || youngs_modulus_Pa <= 0)
      throw std::invalid_argument("Material.youngs_modulus_Pa = " + std::to_string(youngs_modulus_Pa) +
                                  " must be finite and > 0");
    if (!std::isfinite(poisson_ratio) || poisson_ratio < 0 || poisson_ratio >= 0.5)
      throw std::invalid_argument("Material.poisson_ratio = " + std::to_string(poisson_ratio) +
                                  " must be in [0, 0.5)");
  }
  /// λ = Eν/((1+ν)(1−2ν)) [Pa]
  double lambda_Pa() const { return youngs_modulus_Pa * poisson_ratio / ((1 + poisson_ratio) * (1 - 2 * poisson_ratio)); }
  /// μ = E/(2(1+ν)) [Pa]
  double mu_Pa() const { return youngs_modulus_Pa / (2 * (1 + poisson_ratio)); }
};

}  // namespace touchstone::realtime::mfs
