// The OpenBLAS kernel choice: an unrecognised CPU's fallback (Prescott, SSE3) is replaced by the
// widest set the CPU runs, a recognised choice is kept, and in a running program (whose main
// started MpiSession, which restarts it when needed) OpenBLAS runs the kernels asked for.
#include "touchstone/fem/blas_kernels.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <string>

namespace touchstone::fem {
namespace {

std::string lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return std::tolower(c); });
  return text;
}

TEST(BlasKernels, OnlyTheUnrecognisedFallbackIsReplacedByTheWidestSetTheCpuRuns) {
  const CpuVectorUnits none, avx2{true, false}, avx512{true, true};
  EXPECT_EQ(better_openblas_core("Prescott", avx512), "SkylakeX");
  EXPECT_EQ(better_openblas_core("PRESCOTT", avx2), "Haswell");
  EXPECT_EQ(better_openblas_core("Prescott", none), "");  // a real SSE3-class CPU
  EXPECT_EQ(better_openblas_core("Haswell", avx512), "");  // OpenBLAS knew the CPU
  EXPECT_EQ(better_openblas_core("SkylakeX", avx512), "");
  EXPECT_EQ(better_openblas_core("Zen", avx2), "");
  EXPECT_EQ(better_openblas_core("", avx512), "");  // not OpenBLAS
}

TEST(BlasKernels, TheRunningProgramUsesTheKernelsItAskedFor) {
  const std::string core = loaded_openblas_core();
  if (core.empty()) GTEST_SKIP() << "the BLAS in use is not OpenBLAS";
  if (const char* asked = std::getenv("OPENBLAS_CORETYPE")) {
    EXPECT_EQ(lower(core), lower(asked));
  } else {
    EXPECT_EQ(better_openblas_core(core, this_cpu_vector_units()), "") << "OpenBLAS runs its " << core << " kernels";
  }
}

}  // namespace
}  // namespace touchstone::fem
