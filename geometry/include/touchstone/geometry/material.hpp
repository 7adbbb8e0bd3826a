#pragma once
/// @file
/// The isotropic linear elastic material of the tissue, one definition for the real-time model
/// and the finite element reference (SI units).

namespace touchstone::geometry {

/// The range of E that validate() accepts [Pa]: every solid from soft gels (about 1 Pa) to
/// diamond (about 1e12 Pa), with wide margins.
constexpr double min_youngs_modulus_Pa = 1e-6, max_youngs_modulus_Pa = 1e15;

struct Material {
  double youngs_modulus_Pa = 10.0e3;  ///< E [Pa]; the paper's stomach tissue
  double poisson_ratio = 0.45;        ///< ν [-], 0 ≤ ν < 0.5

  /// Throws std::invalid_argument naming the field and value (E outside [min_youngs_modulus_Pa,
  /// max_youngs_modulus_Pa], ν ∉ [0, 0.5), non-finite).
  void validate() const;
  /// λ = Eν / ((1+ν)(1−2ν)) [Pa]
  double lame_lambda_Pa() const {
    return youngs_modulus_Pa * poisson_ratio / ((1 + poisson_ratio) * (1 - 2 * poisson_ratio));
  }
  /// μ = G = E / (2(1+ν)) [Pa]
  double shear_modulus_Pa() const { return youngs_modulus_Pa / (2 * (1 + poisson_ratio)); }
};

}  // namespace touchstone::geometry
