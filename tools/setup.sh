#!/usr/bin/env bash
# Installs what is missing (Debian packages) and builds softcontact in Release into
# build/. Safe to run again: installs nothing and rebuilds only what changed.
#
# Usage: bash tools/setup.sh [--sanitizers]     (environment: BUILD_DIR, BUILD_TYPE, JOBS)
#   --sanitizers  also install the toolchain of the 'sanitize' tests: clang with libFuzzer
#                 and its sanitizer runtimes (clang, libclang-rt-14-dev) and clang's
#                 OpenMP (libomp-14-dev) for tools/fuzz.sh; g++ brings the ASan/UBSan
#                 runtimes of tools/sanitize.sh. The tests install nothing themselves.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${BUILD_DIR:-$root/build}
type=${BUILD_TYPE:-Release}
jobs=${JOBS:-$(nproc)}

packages=(g++ make cmake pkg-config libopenmpi-dev openmpi-bin petsc-dev libmetis-dev libhdf5-openmpi-dev
          libeigen3-dev libyaml-cpp-dev libgtest-dev libbenchmark-dev python3-h5py python3-numpy)
sanitizer_packages=(clang libclang-rt-14-dev libomp-14-dev)
while [ $# -gt 0 ]; do
  case $1 in
    --sanitizers) packages+=("${sanitizer_packages[@]}") ;;
    -h|--help) sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "setup.sh: unknown option '$1' (expected --sanitizers)" >&2; exit 2 ;;
  esac
  shift
done
source "$root/tools/packages.sh"
install_missing "softcontact setup" "${packages[@]}"

cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE="$type" >/dev/null
cmake --build "$build" -j "$jobs"
