#!/usr/bin/env bash
# Builds the Google Benchmark kernels (Release, build-bench/) and runs them.
# Usage: bash tools/bench.sh [NAME_FILTER] [benchmark options], e.g.
#        bash tools/bench.sh bench_forces --benchmark_repetitions=5
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BUILD_DIR=${BUILD_DIR:-$root/build-bench}
bash "$root/tools/setup.sh" >/dev/null
cmake -S "$root" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DSOFTCONTACT_WITH_BENCHMARKS=ON -DSOFTCONTACT_WITH_TESTS=OFF >/dev/null
cmake --build "$BUILD_DIR" -j "$(OMP_NUM_THREADS= nproc)" >/dev/null
source "$root/tools/env.sh"
filter=${1:-bench_}
[ $# -gt 0 ] && shift
for b in "$BUILD_DIR"/bench/*; do
  case "$(basename "$b")" in *"$filter"*) echo "== $(basename "$b")"; "$b" "$@" ;; esac
done
