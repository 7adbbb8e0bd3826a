#pragma once
/// @file
/// The full-domain finite element reference: linear elasticity on a gmsh tetrahedral mesh,
/// loaded by a rigid flat punch (benchmarks B1–B5). Plain structs, Eigen and the geometry core
/// (Material, ContactCondition) only: deal.II stays inside reference_fem/src.

#include "touchstone/geometry/contact_condition.hpp"
#include "touchstone/geometry/material.hpp"

#include <Eigen/Core>
#include <mpi.h>

#include <array>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace touchstone::fem {

/// A rigid flat punch whose face is the boundary named `tool_patch`, pressed by depth_m along
/// direction (normalised on use): the patch displacement is u·d = depth (frictionless) or
/// u = depth·d (bonded).
struct RigidPunch {
  double depth_m = 1.0e-4;
  Eigen::Vector3d direction{0.0, 0.0, -1.0};
  geometry::ContactCondition contact = geometry::ContactCondition::frictionless;
  void validate() const;
};

/// A vector field of position [m] → value (displacement [m], traction [Pa] or body force [N/m³]).
using VectorField = std::function<Eigen::Vector3d(const Eigen::Vector3d&)>;

/// A condition on one named boundary (a gmsh physical group name).
struct BoundaryCondition {
  enum class Kind { displacement, traction };
  std::string boundary;
  Kind kind = Kind::displacement;
  VectorField value;
};

enum class LinearSolver {
  cg_amg_trilinos,  ///< CG + Trilinos ML, translation near-null space (default)
  cg_gamg_petsc,    ///< CG + PETSc GAMG, rigid-body near-null space
  direct_mumps,     ///< PETSc + MUMPS sparse LDLᵀ (symmetric mode; small cases)
};

/// How the volumetric (pressure) part of the elastic energy is discretised (near-incompressibility).
///
/// Both write σ = 2μ dev ε(u) + p I with the bulk modulus κ = λ + 2μ/3 [Pa]; they differ in p.
enum class Formulation {
  /// Pure displacement: p = κ div u pointwise, K_e = ∫ (2μ ε(φ_i):ε(φ_j) + λ div φ_i div φ_j) dV.
  /// Locks as ν → 0.5 (the discrete divergence constraint is too rich for P2); the default, fine
  /// for ν ≤ 0.45.
  displacement,
  /// Mixed u–p with a discontinuous piecewise-constant pressure (P2–P0 on tetrahedra), condensed
  /// cell by cell: p = κ Π₀(div u), Π₀ the L2 projection onto constants on the cell, so
  /// K_e = ∫ 2μ dev ε(φ_i):dev ε(φ_j) dV + κ G_i G_j / |K| with G_j = ∫_K div φ_j dV.
  /// The system stays symmetric positive definite in u alone (same solvers, reaction and energy).
  /// Locking-free: use it for ν ≥ 0.49. Needs degree = 2. (A linear discontinuous pressure would
  /// change nothing on affine tetrahedra, where div u of P2 is already linear per cell.) The
  /// price: P0 limits smooth solutions to L2 order 2 instead of 3; the punch force, first order
  /// through its edge singularity, does not pay it.
  mixed_p0disc,
};

struct SolverParameters {
  unsigned int degree = 2;              ///< polynomial degree of the simplex element P1 or P2
  Formulation formulation = Formulation::displacement;  ///< see Formulation; mixed needs degree 2
  LinearSolver solver = LinearSolver::cg_amg_trilinos;
  double relative_tolerance = 1.0e-10;  ///< ‖r‖ ≤ tol · ‖b‖ for the iterative solvers
  unsigned int max_iterations = 5000;
  void validate() const;
};

/// The work of the solution's boundary reaction against a field g on one named boundary:
/// W = Σ r_i g(x_i) over the degrees of freedom i of that boundary, r = K u − f unconstrained and
/// x_i the support points. On a boundary where u is prescribed this is a(u, v) for every finite
/// element v with the trace g there and zero on the other prescribed boundaries, so a solve with
/// trace g_j and the work against g_k give the energy cross term a(u_j, u_k) [J per the units
/// of g] without a second solve.
struct BoundaryWork {
  std::string boundary;
  VectorField field;  ///< g [m]: the virtual displacement
};

/// One linear elasticity solve. Boundaries not named anywhere are traction-free.
struct ElasticityProblem {
  std::string mesh_path;                     ///< gmsh MSH 2.2 or 4.1 ASCII with named physical groups
  geometry::Material material;
  std::vector<std::string> clamped_boundaries{"base", "cut"};  ///< u = 0 where these exist
  std::optional<RigidPunch> punch;           ///< applied on the boundary named "tool_patch"
  std::vector<BoundaryCondition> conditions; ///< further conditions (manufactured solutions, tests)
  VectorField body_force;                    ///< [N/m³]; empty: none
  VectorField exact_displacement;            ///< [m]; when set, the L2 error is computed
  std::vector<Eigen::Vector3d> probes;       ///< points [m] where u is reported
  std::vector<BoundaryWork> boundary_works;  ///< reported in ElasticitySolution::boundary_work_J
  SolverParameters solver;
  std::string vtu_directory;                 ///< empty: no VTU written
  std::string vtu_basename = "solution";
  void validate() const;
};

struct ElasticitySolution {
  /// Tool force on the tissue [N]: the sum of the unconstrained residual K u − f over the
  /// degrees of freedom of the patch (the reaction the punch must supply).
  Eigen::Vector3d force_N = Eigen::Vector3d::Zero();
  /// Strain energy U = ½ uᵀ K u [J].
  double energy_J = 0;
  /// 2U/δ [N]: the force along the punch axis implied by the energy (equals F·d for a
  /// displacement-driven load with everything else fixed or free).
  double energy_force_N = 0;

  /// Per ElasticityProblem::boundary_works entry, the reaction's work against its field [J].
  std::vector<double> boundary_work_J;

  std::vector<Eigen::Vector3d> probe_displacements_m;
  std::vector<bool> probe_found;  ///< false where a probe lies outside the mesh

  double l2_error_m = -1;  ///< ‖u_h − u‖_L2 [m·m^{3/2}] when exact_displacement is set

  std::size_t dof_count = 0;
  std::size_t node_count = 0;  ///< support points of the element (dofs / 3)
  std::size_t cell_count = 0;
  unsigned int mpi_processes = 1;

  std::string solver_name;
  unsigned int solver_iterations = 0;
  double solver_residual = 0;  ///< final residual norm reported by the solver

  /// Wall times [s] of this rank's part of each phase (the runner reports rank 0's).
  double read_mesh_s = 0, setup_s = 0, assembly_s = 0, solve_s = 0, postprocess_s = 0, output_s = 0;
  std::string vtu_file;  ///< the .pvtu written, if any
};

/// Solves `problem` on `communicator` (call inside an MpiSession). Collective; every rank
/// returns the same solution summary. Throws std::runtime_error on a mesh without the
/// boundaries named, a solver failure, or any input problem, naming file and boundary.
ElasticitySolution solve_elasticity(const ElasticityProblem& problem,
                                    MPI_Comm communicator = MPI_COMM_WORLD);

/// Initialises and finalises MPI, PETSc and SLEPc (deal.II's MPI_InitFinalize) for the program.
/// Construct it first thing in main: before MPI starts it may restart the program once with
/// OpenBLAS's kernels for this CPU (restart_with_native_blas_kernels, blas_kernels.hpp).
class MpiSession {
 public:
  MpiSession(int& argc, char**& argv);
  ~MpiSession();
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
  static unsigned int rank();
  static unsigned int size();
  static void barrier();
  /// Every rank receives rank 0's `values` (sizes may differ on entry). For inputs only rank 0
  /// can compute, e.g. from files it alone writes.
  static void broadcast_from_root(std::vector<double>& values);
  /// Every rank receives the element-wise sum of all ranks' `values` (same size on every rank):
  /// how ranks that each computed their own share of a list put it together.
  static void sum_over_ranks(std::vector<double>& values);

 private:
  struct Impl;
  Impl* impl_ = nullptr;
};

std::string to_string(LinearSolver solver);
LinearSolver linear_solver_from_string(const std::string& name);  ///< throws, listing the names
std::string to_string(Formulation formulation);  ///< "displacement", "mixed_p0disc"
/// Accepts the to_string names and "mixed" (the recommended mixed formulation); throws listing them.
Formulation formulation_from_string(const std::string& name);

}  // namespace touchstone::fem
