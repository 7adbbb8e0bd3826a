#pragma once
/// @file
/// The closed-form displacement and stress fields of a rigid flat circular punch of radius a on
/// an elastic half-space: the singular fields that enrich the local MFS model.
///
/// Normal mode (Sneddon 1946, frictionless): the punch pressed by δ along its axis. Total force
/// P = 4 G a δ / (1 − ν); pressure −P / (2πa √(a² − r²)) under the punch; u_z = δ on the disk,
/// (2δ/π) arcsin(a/r) outside it.
/// Tangential modes (stuck punch, Mindlin/Johnson): the punch moved by Δ along one of its face's
/// axes with force Q = 8 G a Δ / (2 − ν); the ≈ 1 % normal–tangential coupling at ν = 0.45 is
/// neglected (exact at ν = 0.5).
/// Radial mode (bonded face): the self-equilibrated surface shear τ_r = 4G/(πa(1 − ν)) · r / √(a² − r²)
/// on the disk, whose face bulges by −k √(1 − r²/a²), k = 2(1 − 2ν)/(π(1 − ν)), plus k times the
/// frictionless punch whose face takes the dome √(1 − r²/a²), which flattens it. Under the disk
/// u_z = 0 and u_r = r / a (1 at the rim) plus the dome's own slip (a few per cent of it). Its
/// energy ∮ u·t is 16Ga/(3(1 − ν)) − k² 4Ga(1/3 + π²/36)/(1 − ν); its load has the normal
/// resultant 2kGa/(1 − ν). Added to the normal mode it lets a bonded punch hold the radial slip
/// that Sneddon's frictionless field has under the disk, u_r = −(1 − 2ν)/(π(1 − ν)) (a − √(a² − r²)) / r
/// per metre of depth, without doming its face.
/// Tilt modes (frictionless): the punch face turned so that u₃ = x₁/a (or x₂/a) on the disk, the
/// pressure ∝ x₁/√(a² − r²); no resultant, moment 8Ga²/(3(1 − ν)) per unit rim displacement,
/// energy 8Ga/(3(1 − ν)). They hold the tilt of the patch that the tangential modes' neglected
/// coupling leaves (their u₃ is odd under the disk).
///
/// Frame: origin at the centre of the rim circle, e₃ along the push direction (into the body),
/// e₁, e₂ spanning the rim plane; z = e₃·(x − origin) ≥ 0 inside a half-space. The complex
/// branch q = −i √(−(r² + s²)), s = z − i a, continues smoothly through the contact disk into
/// z < 0 for r < a, so the field can be anchored on the rim plane of a slightly curved patch.
///
/// Every field is per metre of punch displacement (δ, Δ or the rim's radial displacement = 1 m):
/// displacements are dimensionless [m/m] and stresses are in [Pa/m]. Displacements do not depend
/// on G.

#include "touchstone/geometry/material.hpp"

#include <Eigen/Core>

#include <cstdint>

namespace touchstone::realtime::mfs {

/// The three rigid translations of the punch face, along e₃ (normal) and e₁, e₂ (tangential), the
/// radial shear of the face (radial), and its tilts (tilt_1: u₃ = x₁/a on the face, a rotation
/// about e₂; tilt_2: u₃ = x₂/a).
enum class PunchMode : std::uint8_t { normal = 0, tangential_1 = 1, tangential_2 = 2, radial = 3, tilt_1 = 4, tilt_2 = 5 };

/// Where a punch field lives: origin at the rim-circle centre, rotation columns (e₁, e₂, e₃),
/// e₃ the push direction into the body.
struct PunchFrame {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  /// A right-handed frame with e₃ = direction (normalised) and e₁ ⟂ e₃ chosen stably.
  static PunchFrame along(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction);
};

/// One sample of a punch field in global coordinates, per metre of punch displacement.
struct PunchFieldSample {
  Eigen::Vector3d displacement = Eigen::Vector3d::Zero();  ///< u [m/m]
  Eigen::Matrix3d stress_Pa_per_m = Eigen::Matrix3d::Zero();  ///< σ (symmetric, tension positive) [Pa/m]
};

/// The field of `mode` at x [m] for a punch of radius_m on `material` in `frame`. Finite
/// everywhere except on the rim circle itself (r = a, z = 0), where the stress is singular as
/// ρ^(−1/2) in the distance ρ to the rim: the caller's quadrature must not sample the rim.
/// Points above the rim plane outside the rim (z < 0, r ≥ a) are outside the body; they are
/// evaluated at z = max(z, 1e-13 a) so that the branch never flips.
PunchFieldSample punch_field(PunchMode mode, const PunchFrame& frame, double radius_m, const geometry::Material& material,
                             const Eigen::Vector3d& x) noexcept;

/// The half-space tool stiffness of each mode [N/m]: 4 G a / (1 − ν) (normal), 8 G a / (2 − ν)
/// (tangential), and for the radial and tilt modes their energy per unit rim displacement squared,
/// 16 G a / (3(1 − ν)) − k² 4Ga(1/3 + π²/36)/(1 − ν) (k above) and 8 G a / (3(1 − ν)).
double punch_half_space_stiffness_N_per_m(PunchMode mode, double radius_m, const geometry::Material& material) noexcept;

}  // namespace touchstone::realtime::mfs
