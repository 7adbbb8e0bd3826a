#!/usr/bin/env bash
# The main job on a fresh Debian 12 machine: install, build, run the `hemisphere` study (MFS
# against the converged deal.II reference: Table 2 replica, force error against N, displacement
# error, error against run time, speed and accuracy targets) and print where the report is.
# Extra arguments go to `touchstone study` (e.g. --only galerkin, --no-cache).
#
# The FEM references come from .cache/touchstone after the first run; finished MFS cases are
# reused from output/hemisphere. The full B2 FEM reference (both contacts, two mesh families)
# remains available on its own:
#   OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 \
#     mpirun -np 2 ./build/release/studies/touchstone fem studies/configs/b2_reference.toml --out output/b2_reference
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install_deps.sh
cmake --preset release >/dev/null
./scripts/build.sh --preset release -j "$(nproc)" --target touchstone
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
# Every process takes part in the FEM solves (the finest meshes have ~1.2M unknowns); rank 0
# alone runs the MFS cases (one core: their run times are single-core) and writes the report.
mpirun -np "$(nproc)" --oversubscribe ./build/release/studies/touchstone study studies/configs/hemisphere.toml \
  --out output/hemisphere "$@"
echo
echo "report: $(pwd)/output/hemisphere/report.md"
