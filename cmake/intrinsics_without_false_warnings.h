/* Forced into every C++ file (-include) when GCC before 13 compiles for the build machine.
 *
 * GCC 12's AVX-512 intrinsics pass a deliberately undefined vector (_mm256_undefined_pd and
 * kin) as the merge source of fully masked builtins. Inlined into Eigen's packet code, each such
 * use is reported as "may be used uninitialized" (or, for 512-bit packets, "is used
 * uninitialized"), and the warnings-as-errors build fails although
 * no value is ever read. Including the intrinsics here first, with those warnings off, silences
 * them inside the compiler's own headers only: the include guard keeps later includes (through
 * Eigen) from re-reading them, and the project's code keeps the warnings. */
#ifndef TOUCHSTONE_INTRINSICS_WITHOUT_FALSE_WARNINGS_H
#define TOUCHSTONE_INTRINSICS_WITHOUT_FALSE_WARNINGS_H
#if defined(__GNUC__) && !defined(__clang__) && defined(__AVX512F__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
#include <immintrin.h>
#pragma GCC diagnostic pop
#endif
#endif
