// GoogleTest main for tests that call deal.II: MPI (and PETSc) must be initialised first.
#include "touchstone/fem/elasticity_problem.hpp"

#include <gtest/gtest.h>

int main(int argc, char** argv) {
  touchstone::fem::MpiSession mpi(argc, argv);
  ::testing::InitGoogleTest(&argc, argv);
  // Only rank 0 prints, so a run under mpirun reads like a serial one.
  if (touchstone::fem::MpiSession::rank() != 0) {
    auto& listeners = ::testing::UnitTest::GetInstance()->listeners();
    delete listeners.Release(listeners.default_result_printer());
  }
  return RUN_ALL_TESTS();
}
