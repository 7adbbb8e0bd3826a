#!/usr/bin/env bash
# The main job on a fresh Debian 12 machine: install, build, run the B2 hemisphere reference
# (frictionless and bonded, three meshes, Richardson extrapolation) and print where the results
# are. Until the study runner lands this is the FEM half of the hemisphere comparison.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install_deps.sh
cmake --preset release >/dev/null
cmake --build --preset release -j "$(nproc)"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
# Both cores: the finest meshes have ~1.4M unknowns.
mpirun -np "$(nproc)" --oversubscribe ./build/release/studies/touchstone fem studies/b2_reference.toml --out output/b2_reference "$@"
