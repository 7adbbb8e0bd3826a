#pragma once
/// @file
/// Which OpenBLAS kernels the direct solver's dense products run on.
///
/// OpenBLAS picks its kernel set from the CPU's family and model at load time. A model it does
/// not know (CPUs newer than the library, and virtual machines that report a model of their
/// own) gets its Prescott set: SSE3 code from 2004, which runs MUMPS's frontal matrix products
/// at a fraction of the speed the CPU's AVX2 or AVX-512 units give. OpenBLAS reads the
/// environment variable OPENBLAS_CORETYPE only when it loads, so the fix is to restart the
/// program with it set; `restart_with_native_blas_kernels` does that, once, before MPI starts.

#include <string>

namespace touchstone::fem {

/// What the CPU offers to a BLAS kernel (each flag true only when the operating system saves
/// the registers too).
struct CpuVectorUnits {
  bool avx2_fma = false;  ///< AVX2 and FMA3
  bool avx512 = false;    ///< AVX-512 F, CD, DQ, BW and VL (what OpenBLAS's SkylakeX set uses)
};

/// The vector units of the CPU this process runs on.
CpuVectorUnits this_cpu_vector_units();

/// The OPENBLAS_CORETYPE to ask for when OpenBLAS chose `chosen_core`
/// (openblas_get_corename()) on a CPU with `units`, or "" to keep its choice. Only the fallback
/// of an unrecognised model ("Prescott", whatever the case) is replaced, by the widest set the
/// CPU runs: "SkylakeX" with AVX-512, "Haswell" with AVX2 and FMA. A CPU OpenBLAS recognised,
/// or a real Prescott-class CPU, keeps its choice.
std::string better_openblas_core(const std::string& chosen_core, const CpuVectorUnits& units);

/// The kernel set the loaded OpenBLAS uses ("" when the BLAS in use is not OpenBLAS).
std::string loaded_openblas_core();

/// Restarts this program (the same executable and `argv`) with OPENBLAS_CORETYPE set when
/// `better_openblas_core` says so. Returns without doing anything when OPENBLAS_CORETYPE is
/// already set (by the user, or by the restart: so it happens at most once), when the BLAS is
/// not OpenBLAS, or when OpenBLAS's choice stands; returns after a warning on stderr when the
/// restart fails. Call it before MPI starts and before anything is printed (MpiSession does).
void restart_with_native_blas_kernels(char** argv);

}  // namespace touchstone::fem
