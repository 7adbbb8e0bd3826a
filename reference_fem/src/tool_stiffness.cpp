// The tool stiffness by unit solves (see the header).
#include "touchstone/fem/tool_stiffness.hpp"

#include <chrono>
#include <stdexcept>

namespace touchstone::fem {

ToolStiffness solve_tool_stiffness(const ElasticityProblem& problem, MPI_Comm communicator) {
  if (!problem.punch) throw std::invalid_argument("solve_tool_stiffness: the problem has no punch (ElasticityProblem.punch)");
  problem.punch->validate();
  const auto start = std::chrono::steady_clock::now();
  ElasticityProblem unit = problem;
  const double depth = problem.punch->depth_m;

  ToolStiffness stiffness;
  stiffness.probe_displacement_per_displacement.assign(problem.probes.size(), Eigen::Matrix3d::Zero());
  stiffness.probe_found.assign(problem.probes.size(), true);
  const auto take_probes = [&](const ElasticitySolution& solution, const Eigen::Vector3d& row) {
    for (std::size_t p = 0; p < problem.probes.size(); ++p) {
      stiffness.probe_displacement_per_displacement[p] += (solution.probe_displacements_m[p] / depth) * row.transpose();
      stiffness.probe_found[p] = stiffness.probe_found[p] && solution.probe_found[p];
    }
  };
  stiffness.contact = problem.punch->contact;
  stiffness.axis = problem.punch->direction.normalized();
  if (stiffness.contact == geometry::ContactCondition::bonded) {
    for (int column = 0; column < 3; ++column) {
      unit.punch->direction = Eigen::Vector3d::Unit(column);
      if (!problem.vtu_directory.empty()) unit.vtu_basename = problem.vtu_basename + "_" + "xyz"[column];
      const ElasticitySolution solution = solve_elasticity(unit, communicator);
      stiffness.force_per_displacement_N_per_m.col(column) = solution.force_N / depth;
      take_probes(solution, Eigen::Vector3d::Unit(column));
      stiffness.dof_count = solution.dof_count;
      ++stiffness.solves;
    }
  } else {
    unit.punch->direction = stiffness.axis;
    const ElasticitySolution solution = solve_elasticity(unit, communicator);
    stiffness.force_per_displacement_N_per_m = (solution.force_N / depth) * stiffness.axis.transpose();
    take_probes(solution, stiffness.axis);
    stiffness.dof_count = solution.dof_count;
    stiffness.solves = 1;
  }
  stiffness.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return stiffness;
}

}  // namespace touchstone::fem
