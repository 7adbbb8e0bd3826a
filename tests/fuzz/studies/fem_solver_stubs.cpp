// The FEM solver's entry points for the study-reader harness, which is built without deal.II.
// The study files that hold the readers also hold the study runs, which call the solver; the
// harness only reads and validates, so a call here means a reader started a run: a finding.
#include "touchstone/fem/elasticity_problem.hpp"

#include <cstdio>
#include <cstdlib>

namespace touchstone::fem {

namespace {
[[noreturn]] void reader_reached_the_solver(const char* function) {
  std::fprintf(stderr, "fuzz_config_reader: a study reader called the FEM solver (%s)\n", function);
  std::abort();
}
}  // namespace

ElasticitySolution solve_elasticity(const ElasticityProblem& /*problem*/, MPI_Comm /*communicator*/) {
  reader_reached_the_solver("solve_elasticity");
}
unsigned int MpiSession::rank() { reader_reached_the_solver("MpiSession::rank"); }
void MpiSession::barrier() { reader_reached_the_solver("MpiSession::barrier"); }

}  // namespace touchstone::fem
