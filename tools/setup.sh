#!/usr/bin/env bash
# Installs what is missing (Debian packages) and builds softcontact in Release into
# build/. Safe to run again: installs nothing and rebuilds only what changed.
# Usage: bash tools/setup.sh        (environment: BUILD_DIR, BUILD_TYPE, JOBS)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${BUILD_DIR:-$root/build}
type=${BUILD_TYPE:-Release}
jobs=${JOBS:-$(nproc)}

packages=(g++ make cmake pkg-config libopenmpi-dev openmpi-bin petsc-dev libmetis-dev libhdf5-openmpi-dev
          libeigen3-dev libyaml-cpp-dev libgtest-dev libbenchmark-dev python3-h5py python3-numpy)
source "$root/tools/packages.sh"
install_missing "softcontact setup" "${packages[@]}"

cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE="$type" >/dev/null
cmake --build "$build" -j "$jobs"
