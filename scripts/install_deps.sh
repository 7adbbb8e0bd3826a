#!/usr/bin/env bash
# Installs the Debian 12 packages Touchstone needs. Idempotent: when every package is already
# installed it only checks (about a second) and touches nothing.
set -euo pipefail

packages=(
  # toolchain
  g++ cmake ninja-build make pkg-config git lld
  # numerics and the reference model
  libeigen3-dev libdeal.ii-dev openmpi-bin libopenblas0 libssl-dev
  # meshes
  gmsh libgmsh-dev
  # collision detection: Embree is the oracle and speed reference for the own BVH
  libembree-dev
  # surface mesh readers (STL, OBJ, VTK, VTP) and the interactive window; OpenIGTLink devices
  libvtk9-dev libopenigtlink-dev
  # a virtual display for the interactive window test (and headless screenshots)
  xvfb xauth
  # configuration, command line, JSON
  libtomlplusplus-dev libcli11-dev nlohmann-json3-dev
  # tests, benchmarks, plots
  libgtest-dev libgmock-dev libbenchmark-dev python3 python3-matplotlib python3-jsonschema python3-vtk9
  # fuzzing the parsers (scripts/fuzz.sh): clang with libFuzzer
  clang libfuzzer-14-dev
)

missing=()
for package in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$package")
  fi
done

if ((${#missing[@]} == 0)); then
  echo "install_deps: all ${#packages[@]} Debian packages present"
  exit 0
fi

sudo_cmd=()
if [[ "$(id -u)" -ne 0 ]]; then
  command -v sudo >/dev/null || { echo "install_deps: not root and no sudo; install: ${missing[*]}" >&2; exit 1; }
  sudo_cmd=(sudo)
fi
echo "install_deps: installing ${missing[*]}"
"${sudo_cmd[@]}" apt-get update -q
DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
