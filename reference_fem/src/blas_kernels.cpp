#include "touchstone/fem/blas_kernels.hpp"

#include <dlfcn.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace touchstone::fem {

CpuVectorUnits this_cpu_vector_units() {
  CpuVectorUnits units;
#if defined(__x86_64__) && defined(__GNUC__)
  // libgcc's feature bits already require the operating system to save the wider registers.
  __builtin_cpu_init();
  units.avx2_fma = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  units.avx512 = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512cd") &&
                 __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw") &&
                 __builtin_cpu_supports("avx512vl");
#endif
  return units;
}

std::string better_openblas_core(const std::string& chosen_core, const CpuVectorUnits& units) {
  std::string lower = chosen_core;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
  if (lower != "prescott") return "";
  if (units.avx512) return "SkylakeX";
  if (units.avx2_fma) return "Haswell";
  return "";
}

std::string loaded_openblas_core() {
  // Looked up at run time: the BLAS Debian links in is whichever its alternatives select.
  using CoreName = char* (*)();
  const auto core_name = reinterpret_cast<CoreName>(dlsym(RTLD_DEFAULT, "openblas_get_corename"));
  if (core_name == nullptr) return "";
  const char* name = core_name();
  return name != nullptr ? name : "";
}

void restart_with_native_blas_kernels(char** argv) {
  if (argv == nullptr || argv[0] == nullptr || std::getenv("OPENBLAS_CORETYPE") != nullptr) return;
  const std::string chosen = loaded_openblas_core();
  const std::string better = better_openblas_core(chosen, this_cpu_vector_units());
  if (better.empty()) return;
  if (setenv("OPENBLAS_CORETYPE", better.c_str(), 1) != 0) return;
  std::fflush(nullptr);
  execv("/proc/self/exe", argv);
  // Still here: the restart failed, and the program goes on with the slower kernels.
  std::fprintf(stderr, "warning: OpenBLAS chose its %s kernels for this CPU; restarting with OPENBLAS_CORETYPE=%s failed (%s)\n",
               chosen.c_str(), better.c_str(), std::strerror(errno));
}

}  // namespace touchstone::fem
