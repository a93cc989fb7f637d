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
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "softcontact setup: installing ${missing[*]}"
  sudo=""
  if [ "$(id -u)" != 0 ]; then
    command -v sudo >/dev/null || { echo "softcontact setup: need root (or sudo) to install: ${missing[*]}" >&2; exit 1; }
    sudo=sudo
  fi
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE="$type" >/dev/null
cmake --build "$build" -j "$jobs"
