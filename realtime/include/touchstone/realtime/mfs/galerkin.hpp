#pragma once
/// @file
/// The Method of Finite Spheres as De & Bathe define it: a Galerkin (weak-form) discretisation
/// with the MLS shape functions, K = ∫_Ω Bᵀ D B dV, the rigid tool and the clamped cut imposed
/// weakly, by a penalty α ∫ Hᵀ P H dA (default) or Nitsche's method. Unlike point
/// collocation it is symmetric, has no Neumann rows to destabilise (traction-free is natural),
/// and the tool force — the boundary flux on the patch — balances the cut's exactly
/// (Σ_J h_J = 1). The paper replaced it by point collocation for speed; both are offered.
///
/// Nitsche adds the consistency terms −∫ (σ(u)n)·P v − ∫ (σ(v)n)·P (u − ū): the exact
/// solution satisfies the weak form for any α, so α need only be large enough for coercivity.
/// On B3 the penalty and Nitsche give nearly the same force (top-level README, Measured: the
/// first MFS models) — the constraint is not what limits the accuracy (the resolution of the
/// punch edge and the volume quadrature are); and Nitsche with β = 100 can lose positive
/// definiteness on fine clouds, so the penalty stays the default.

#include "touchstone/geometry/material.hpp"
#include "touchstone/realtime/mfs/node_cloud.hpp"
#include "touchstone/realtime/mfs/node_sprinkling.hpp"
#include "touchstone/realtime/mfs/tool_force.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace touchstone::realtime::mfs {

/// How u = ū is imposed on the tool patch and the cut.
enum class Constraint : std::uint8_t {
  penalty,  ///< α ∫ P (u − ū)·v only: O(1/α) violation and, for large α, locking (default)
  nitsche,  ///< consistent (symmetric Nitsche); K loses definiteness when α is too small
};

struct GalerkinSettings {
  MlsSettings mls{Basis::quadratic, Weight::quartic_spline, 1e-12, 1.5};
  Constraint constraint = Constraint::penalty;
  /// α = β E / s_min [Pa/m] (β = penalty_factor, s_min the finest node spacing). Penalty: the
  /// constraint's strength. Nitsche: the stabilisation, which must exceed a bound of the
  /// inverse inequality ‖σ(v)n‖_Γ ≤ C ‖ε(v)‖_Ω / √h for K to be positive definite.
  double penalty_factor = 100;
  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// K (3N × 3N, dense, symmetric), the tool right-hand side G (f = G U_tool), and the linear maps
/// of the boundary forces on the tissue, ∫ P (σ(u_h)n + α (ū − u_h)) dA with Nitsche and
/// ∫ α P (ū − u_h) dA with the penalty: F_patch = A_patch U_tool − M_patch U, F_cut = −M_cut U.
struct GalerkinSystem {
  Eigen::MatrixXd stiffness;
  Eigen::Matrix<double, Eigen::Dynamic, 3> tool_rhs;
  Eigen::Matrix3d patch_tool_map = Eigen::Matrix3d::Zero();   ///< A_patch [N/m]
  Eigen::Matrix<double, 3, Eigen::Dynamic> patch_map, cut_map;  ///< M_patch, M_cut [N/m]
  /// The paper's partition force (eq. 9) in the weak form: the tool-patch nodes (ascending), their
  /// rows of the elastic K (3 per node, before the constraints), ∫_patch h_a dA [m²] and
  /// ∫_patch h_a h_b dA [m²]. Row a applied to the solution is ∫_patch h_a λ dA [N], λ the
  /// constraint's traction; local_model's paper_map weights the rows so that the weighted shape
  /// functions sum to one on the patch.
  std::vector<int> patch_nodes;
  Eigen::MatrixXd patch_node_rows;
  std::vector<double> patch_node_shape_integral_m2;
  Eigen::MatrixXd patch_node_mass_m2;  ///< ∫_patch h_a h_b dA over the patch nodes [m²]
  double penalty_Pa_per_m = 0;
  /// Over the volume quadrature points: the smallest rcond of the moment matrix and the largest
  /// support growth the shape functions needed (1: none) — how close the model came to failing.
  double min_rcond = 1, max_support_scale = 1;
  MlsStatus status = MlsStatus::ok;
  int failed_point = -1;  ///< index of the quadrature point (volume, then patch, then cut) that failed
};

std::string to_string(Constraint constraint);

/// Assembles the Galerkin system on the quadratures of Ω, the tool patch and the cut surface.
/// Frictionless: the penalty holds only the component along d (u·d = U_tool·d); bonded: all.
GalerkinSystem assemble_galerkin(const NodeCloud& cloud, const geometry::Material& material, const ToolContact& contact,
                                 const PatchQuadrature& volume, const PatchQuadrature& patch,
                                 const PatchQuadrature& cut, const GalerkinSettings& settings);

/// Load vectors (3N) for problems other than the punch, e.g. the verification tests. Each
/// returns false if a quadrature point is outside every support (`load` is then unusable).
/// ∫_Γ h_J t̄ dA: a prescribed traction t̄ [Pa] at the points of `surface`.
bool traction_load(const NodeCloud& cloud, const PatchQuadrature& surface, const std::vector<Eigen::Vector3d>& traction_Pa,
                   const GalerkinSettings& settings, Eigen::VectorXd& load);
/// The right-hand side of u = ū [m] imposed on `surface` with projection I (the cut's
/// constraint in assemble_galerkin): ∫_Γ (α h_J − T_Jᵀ) ū dA with Nitsche, α h_J ū with the
/// penalty (T_J: the traction of the shape function, α from `cloud` as in assemble_galerkin).
bool prescribed_displacement_load(const NodeCloud& cloud, const geometry::Material& material, const PatchQuadrature& surface,
                                  const std::vector<Eigen::Vector3d>& displacement_m, const GalerkinSettings& settings,
                                  Eigen::VectorXd& load);

}  // namespace touchstone::realtime::mfs
