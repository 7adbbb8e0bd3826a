// Validation of the parameter structs and their names in configs.
#include "touchstone/fem/elasticity_problem.hpp"
#include "touchstone/geometry/invalid_value.hpp"

#include <cmath>
#include <stdexcept>

namespace touchstone::fem {
void RigidPunch::validate() const {
  if (!std::isfinite(depth_m) || depth_m <= 0) geometry::throw_invalid_value("RigidPunch.depth_m", depth_m, "must be finite and > 0");
  if (!direction.allFinite() || direction.norm() < 1e-12)
    throw std::invalid_argument("RigidPunch.direction must be a finite non-zero vector");
}

void SolverParameters::validate() const {
  if (degree < 1 || degree > 2) geometry::throw_invalid_value("SolverParameters.degree", degree, "must be 1 or 2");
  if (!(relative_tolerance > 0 && relative_tolerance < 1))
    geometry::throw_invalid_value("SolverParameters.relative_tolerance", relative_tolerance, "must be in (0, 1)");
  if (max_iterations < 1) geometry::throw_invalid_value("SolverParameters.max_iterations", max_iterations, "must be ≥ 1");
  if (formulation != Formulation::displacement && formulation != Formulation::mixed_p0disc)
    geometry::throw_invalid_value("SolverParameters.formulation", static_cast<int>(formulation), "is not a Formulation");
  // P1–P0 locks (3 displacement dofs per vertex against about 6 cell constraints): the mixed
  // option is the P2–P0 pair only.
  if (formulation == Formulation::mixed_p0disc && degree != 2)
    throw std::invalid_argument("SolverParameters.formulation = " + to_string(formulation) +
                                " needs degree = 2 (got " + std::to_string(degree) + ")");
}

void ElasticityProblem::validate() const {
  if (mesh_path.empty()) throw std::invalid_argument("ElasticityProblem.mesh_path is empty");
  material.validate();
  solver.validate();
  if (punch) punch->validate();
  for (const auto& condition : conditions)
    if (!condition.value)
      throw std::invalid_argument("ElasticityProblem: condition on '" + condition.boundary + "' has no value");
  for (const auto& work : boundary_works)
    if (!work.field || work.boundary.empty())
      throw std::invalid_argument("ElasticityProblem.boundary_works: an entry on '" + work.boundary +
                                  "' has no boundary name or no field");
  for (const auto& probe : probes)
    if (!probe.allFinite()) throw std::invalid_argument("ElasticityProblem.probes: a probe point is not finite");
}

std::string to_string(LinearSolver solver) {
  switch (solver) {
    case LinearSolver::cg_amg_trilinos: return "cg_amg_trilinos";
    case LinearSolver::cg_gamg_petsc: return "cg_gamg_petsc";
    case LinearSolver::direct_mumps: return "direct_mumps";
  }
  return "unknown";
}

LinearSolver linear_solver_from_string(const std::string& name) {
  for (auto s : {LinearSolver::cg_amg_trilinos, LinearSolver::cg_gamg_petsc, LinearSolver::direct_mumps})
    if (to_string(s) == name) return s;
  throw std::invalid_argument("unknown solver '" + name + "' (choose cg_amg_trilinos, cg_gamg_petsc, direct_mumps)");
}

std::string to_string(Formulation formulation) {
  switch (formulation) {
    case Formulation::displacement: return "displacement";
    case Formulation::mixed_p0disc: return "mixed_p0disc";
  }
  return "unknown";
}

Formulation formulation_from_string(const std::string& name) {
  if (name == "displacement") return Formulation::displacement;
  if (name == "mixed" || name == "mixed_p0disc") return Formulation::mixed_p0disc;
  throw std::invalid_argument("unknown formulation '" + name + "' (choose displacement, mixed, mixed_p0disc)");
}

}  // namespace touchstone::fem
