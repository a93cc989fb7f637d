#!/usr/bin/env bash
# Fuzzing of the input readers with libFuzzer (tests/fuzz): builds the harnesses with
# clang, -fsanitize=fuzzer,address,undefined into build-fuzz, replays the committed
# corpus (tests/fuzz/corpus/<target>, which must pass), then fuzzes every target for a
# while. Exits non-zero on any finding (crash, sanitizer report, exception other than
# InputError, timeout, oversized allocation) and prints where the reproducer is.
#
# Usage: bash tools/fuzz.sh [--replay] [--seconds N] [--target NAME]
#   --replay      only replay the corpus (no fuzzing)
#   --seconds N   fuzz each target for N seconds (default 30)
#   --target NAME only this target: scene, gmsh, tetgen, checkpoint or frames (default: all)
# Environment: FUZZ_BUILD_DIR (default build-fuzz), JOBS.
# Needs clang with libFuzzer, ASan/UBSan and OpenMP: 'bash tools/setup.sh --sanitizers'
# installs them; without them this script says so and exits with status 2.
#
# New inputs the fuzzer finds go to build-fuzz/fuzz-work/<target>, not into the committed
# corpus. To add them, minimised (the corpus should stay small):
#   build-fuzz/fuzz/fuzz_T -merge=1 tests/fuzz/corpus/T build-fuzz/fuzz-work/T
# A reproducer, once its bug is fixed, belongs in the corpus too (replayed on every run).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${FUZZ_BUILD_DIR:-$root/build-fuzz}
jobs=${JOBS:-$(OMP_NUM_THREADS= nproc)}
all_targets=(scene gmsh tetgen checkpoint frames)

replay_only=0 seconds=30 targets=("${all_targets[@]}")
while [ $# -gt 0 ]; do
  case $1 in
    --replay) replay_only=1 ;;
    --seconds) [ $# -ge 2 ] || { echo "fuzz.sh: --seconds expects a number" >&2; exit 2; }
               seconds=$2; shift ;;
    --seconds=*) seconds=${1#*=} ;;
    --target) [ $# -ge 2 ] || { echo "fuzz.sh: --target expects one of: ${all_targets[*]}" >&2; exit 2; }
              targets=("$2"); shift ;;
    --target=*) targets=("${1#*=}") ;;
    -h|--help) sed -n '2,19p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "fuzz.sh: unknown option '$1' (expected --replay, --seconds N, --target NAME)" >&2; exit 2 ;;
  esac
  shift
done
[[ $seconds =~ ^[0-9]+$ ]] && [ "$seconds" -gt 0 ] || { echo "fuzz.sh: --seconds expects a positive integer, got '$seconds'" >&2; exit 2; }
for t in "${targets[@]}"; do
  [[ " ${all_targets[*]} " == *" $t "* ]] || { echo "fuzz.sh: unknown target '$t' (expected one of: ${all_targets[*]})" >&2; exit 2; }
done

# The toolchain (clang with libFuzzer and the sanitizer runtimes, clang's OpenMP) is
# installed by 'bash tools/setup.sh --sanitizers', never here: a test installs nothing.
# One small program built as the harnesses are tells whether it is all there.
probe=$(mktemp -d)
trap 'rm -rf "$probe"' EXIT
printf '%s\n' '#include <omp.h>' '#include <cstddef>' '#include <cstdint>' \
  'extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t*, std::size_t) { return omp_get_max_threads() > 0 ? 0 : 1; }' \
  >"$probe/probe.cpp"
if ! command -v clang++ >/dev/null ||
   ! clang++ -fsanitize=fuzzer,address,undefined -fopenmp "$probe/probe.cpp" -o "$probe/probe" >"$probe/log" 2>&1; then
  echo "fuzz.sh: the fuzzing toolchain is missing: clang++ with libFuzzer, ASan/UBSan and OpenMP" >&2
  echo "  (Debian packages clang, libclang-rt-14-dev, libomp-14-dev)." >&2
  echo "  Install it with:  bash tools/setup.sh --sanitizers" >&2
  if command -v clang++ >/dev/null; then sed 's/^/  clang++: /' "$probe/log" | head -5 >&2; fi
  exit 2
fi

# The whole library instrumented for coverage (fuzzer-no-link) and checked by ASan and
# UBSan; only the harnesses link libFuzzer's main (tests/fuzz/CMakeLists.txt). Line
# tables only: what a report prints (as in tools/sanitize.sh).
flags="-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
      -DCMAKE_C_FLAGS="$flags" -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" \
      -DSOFTCONTACT_WITH_TESTS=OFF -DSOFTCONTACT_FUZZ=ON >/dev/null
cmake --build "$build" -j "$jobs" --target $(printf 'fuzz_%s ' "${targets[@]}")

export ASAN_OPTIONS=${ASAN_OPTIONS:-abort_on_error=1:detect_leaks=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
export OMP_NUM_THREADS=1
# -timeout: one input; -rss_limit_mb: the whole process; -malloc_limit_mb: any single
# allocation (the readers must refuse counts their input cannot hold before reserving).
limits=(-timeout=5 -rss_limit_mb=2048 -malloc_limit_mb=256)
findings=$build/findings
status=0

report() {  # target, log: print the reproducer libFuzzer wrote, and how to replay it
  local t=$1 log=$2 repro
  repro=$(grep -aoE "Test unit written to [^ ]+" "$log" | tail -1 | sed 's/Test unit written to //') || true
  echo "fuzz.sh: FINDING in target '$t' (log: $log)"
  grep -aE "ERROR: |fuzz: |SUMMARY: |runtime error" "$log" | head -5 | sed 's/^/  /' || true
  if [ -n "$repro" ]; then
    echo "  reproducer: $repro"
    echo "  replay:     $build/fuzz/fuzz_$t $repro"
  fi
  status=1
}

for t in "${targets[@]}"; do
  exe=$build/fuzz/fuzz_$t
  corpus=$root/tests/fuzz/corpus/$t
  mkdir -p "$findings/$t"
  log=$findings/$t/replay.log
  n=$(find "$corpus" -type f | wc -l)
  start=$(date +%s)
  # -runs=0: run every corpus file once, mutate nothing.
  if "$exe" "${limits[@]}" -runs=0 -artifact_prefix="$findings/$t/" "$corpus" >"$log" 2>&1; then
    echo "fuzz.sh: $t: replayed $n corpus files, no finding ($(( $(date +%s) - start )) s)"
  else
    report "$t" "$log"
  fi
done

if [ "$replay_only" = 0 ] && [ "$status" = 0 ]; then
  # The targets side by side, `jobs` at a time (each libFuzzer process uses one core): on
  # 2 cores the five take 3 x N s instead of 5 x N s. Each leaves its exit status in
  # fuzz.rc; the results are printed in target order.
  fuzz_one() {
    local t=$1 exe=$build/fuzz/fuzz_$1 work=$build/fuzz-work/$1 rc=0
    mkdir -p "$work" "$findings/$t"
    # New inputs go to the work directory; the committed corpus is only read.
    "$exe" "${limits[@]}" -max_total_time="$seconds" -print_final_stats=1 -artifact_prefix="$findings/$t/" \
      "$work" "$root/tests/fuzz/corpus/$t" >"$findings/$t/fuzz.log" 2>&1 || rc=$?
    echo "$rc" >"$findings/$t/fuzz.rc"
  }
  for t in "${targets[@]}"; do
    rm -f "$findings/$t/fuzz.rc"
    while [ "$(jobs -rp | wc -l)" -ge "$jobs" ]; do wait -n || true; done
    fuzz_one "$t" &
  done
  wait
  for t in "${targets[@]}"; do
    log=$findings/$t/fuzz.log
    if [ "$(cat "$findings/$t/fuzz.rc" 2>/dev/null)" = 0 ]; then
      echo "fuzz.sh: $t: fuzzed $seconds s, $(grep -oE 'stat::number_of_executed_units: *[0-9]+' "$log" | grep -oE '[0-9]+$' || echo '?') inputs, no finding"
    else
      report "$t" "$log"
    fi
  done
fi
exit "$status"
