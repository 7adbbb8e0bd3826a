#pragma once
/// @file
/// The reference's tool stiffness at one contact: linear elasticity is linear in the tool's
/// displacement, so a few unit solves give the force for every displacement there. A recorded
/// palpation then needs one set of solves per distinct contact, not one per frame.
///
/// - bonded: the patch moves rigidly with the tool, u = U on the patch; the three solves
///   U = δ e_x, δ e_y, δ e_z give the columns of K, and F = K U for any U. Reciprocity
///   (Maxwell–Betti) makes K symmetric, which the solves do not impose: a check.
/// - frictionless: only the push u·d = δ is prescribed (the patch slides freely across d), so the
///   force depends on U·d alone: one solve, K = (F₁/δ) dᵀ, rank one.

#include "touchstone/fem/elasticity_problem.hpp"

#include <Eigen/Core>

#include <vector>

namespace touchstone::fem {

struct ToolStiffness {
  /// K [N/m]: the force on the tissue per tool displacement, F = K U.
  Eigen::Matrix3d force_per_displacement_N_per_m = Eigen::Matrix3d::Zero();
  geometry::ContactCondition contact = geometry::ContactCondition::frictionless;
  Eigen::Vector3d axis{0.0, 0.0, -1.0};  ///< the push axis d (unit)
  unsigned int solves = 0;               ///< 3 bonded, 1 frictionless
  std::size_t dof_count = 0;
  double seconds = 0;                    ///< wall time of the solves
  /// Per probe of the problem: the displacement there per tool displacement, u_p = D_p U
  /// (frictionless: rank one, like K); `probe_found` false where no cell holds the point.
  std::vector<Eigen::Matrix3d> probe_displacement_per_displacement;
  std::vector<bool> probe_found;

  /// F = K U [N] for the tool displacement U [m].
  Eigen::Vector3d force_N(const Eigen::Vector3d& tool_displacement_m) const {
    return force_per_displacement_N_per_m * tool_displacement_m;
  }
};

/// Solves `problem` (its punch gives the contact condition, the axis d and the unit depth δ)
/// once per unit displacement and returns K, and D_p at the problem's probes. A VTU directory
/// gets the unit fields: `<basename>` for the frictionless push δ d, `<basename>_x`, `_y`, `_z`
/// for the bonded δ e_i. Collective on `communicator`; throws what solve_elasticity throws.
ToolStiffness solve_tool_stiffness(const ElasticityProblem& problem, MPI_Comm communicator = MPI_COMM_WORLD);

}  // namespace touchstone::fem
