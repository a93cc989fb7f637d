#!/usr/bin/env bash
# The test suite: set up (install, build), then ctest. Long validation runs (label
# 'long'), pictures ('render') and the shipped scenes under softcontact verify ('scenes',
# about 5 min) are left out; run them with: bash tools/test.sh -L long (or -L scenes).
# The suite includes the sanitizer tests (label 'sanitize': a libFuzzer pass and the
# tests under ASan+UBSan, about 12 min; docs/reliability.md).
# Extra arguments go to ctest.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bash "$root/tools/setup.sh"
cores=$(OMP_NUM_THREADS= nproc)   # nproc obeys OMP_NUM_THREADS, which env.sh sets
source "$root/tools/env.sh"
cd "${BUILD_DIR:-$root/build}"
if [ $# -eq 0 ]; then set -- -LE 'long|render|scenes'; fi
exec ctest --output-on-failure -j "$cores" "$@"
