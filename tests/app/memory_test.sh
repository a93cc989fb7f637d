#!/usr/bin/env bash
# Memory known before the run (docs/reliability.md, "Memory"): check and run estimate the
# peak per rank, and the estimate is within a factor 1.5 of the measured peak (VmHWM,
# max over ranks, the run's last line) for two scenes of different size; a run whose
# estimate exceeds the address-space limit (ulimit -v) is refused before building, exit 2,
# with both figures; running out of memory anyway ends with what the run had and what to
# try, exit 1, not a bare std::bad_alloc.
# Usage: memory_test.sh SOFTCONTACT MPIEXEC DATA_DIR WORK_DIR
set -u
exe=$1 mpiexec=$2 work=$4
rm -rf "$work" && mkdir -p "$work" && cd "$work" || exit 1
source "$(dirname "$0")/expect.sh"

# Corotational boxes of N^3 cells (6 N^3 tets) side by side.
boxes() {  # file cells count
  { echo "simulation: {dt: auto, steps: 10, output: {every: 5}}"
    echo "materials: [{name: soft, model: corotational, young: 1.0e5, poisson: 0.3, density: 1000}]"
    echo "objects:"
    for k in $(seq 1 "$3"); do
      echo "  - {name: b$k, material: soft, transform: {translate: [$((2 * k)), 0, 0]},"
      echo "     primitive: {type: box, size: [1, 1, 1], cells: [$2, $2, $2]}}"
    done; } > "$1"
}
boxes small.yaml 12 1    # 10 thousand tets, near the fixed cost
boxes pair.yaml 24 2     # 166 thousand tets, on 1 and 2 ranks

expect 0 "memory: about [0-9.]+ (MiB|GiB) peak per rank on 1 rank" -- "$exe" check small.yaml
expect 0 "memory: about [0-9.]+ (MiB|GiB) peak per rank on 4 rank" -- "$exe" check pair.yaml --ranks 4

# The estimate against the measured peak.
within() {  # log
  local line peak est
  line=$(grep -E "^done: .* peak memory" "$1") || { bad "$1: no peak in the summary"; cat "$1"; return; }
  peak=$(sed -E 's/.*peak memory ([0-9.]+) MiB per rank.*/\1/' <<<"$line")
  est=$(sed -E 's/.*estimated ([0-9.]+) MiB.*/\1/' <<<"$line")
  grep -qE "memory about $est MiB per rank" "$1" || { bad "$1: the first line lacks the estimate $est MiB"; return; }
  echo "$1: estimated $est MiB, measured $peak MiB"
  awk -v e="$est" -v p="$peak" 'BEGIN { exit !(e <= 1.5 * p && p <= 1.5 * e) }' && ok ||
    bad "$1: estimate $est MiB not within a factor 1.5 of the peak $peak MiB"
}
"$exe" run small.yaml --output small --quiet > small.log 2>&1 || bad "small run failed"
within small.log
"$mpiexec" --oversubscribe -n 2 "$exe" run pair.yaml --output pair --quiet > pair.log 2>&1 || bad "pair run failed"
within pair.log

# The address space the run needs, as check says (the estimate plus what the process has
# mapped besides its resident memory: libraries, MPI's segments).
need=$("$exe" check pair.yaml | sed -nE 's/.*address space \(ulimit -v\) about ([0-9.]+) MiB.*/\1/p')
[ -n "$need" ] || bad "check does not say the address space needed"
below=$(awk -v n="${need:-0}" 'BEGIN { printf "%d", 0.9 * n * 1024 }')  # KiB
above=$(awk -v n="${need:-0}" 'BEGIN { printf "%d", 1.1 * n * 1024 }')
echo "pair.yaml on 1 rank: address space needed $need MiB; limits $below and $above KiB"
# Subshells for ulimit; their counts come back in a file.
(passes=0 fails=0
 ulimit -v "$below"
 # 10 % below: refused before building (no output directory), with both figures.
 expect 2 "pair.yaml: the run cannot fit in memory: the estimated peak of [0-9.]+ MiB per rank, plus the [0-9.]+ MiB of address space .* exceeds the rank's address-space limit of [0-9.]+ MiB \(ulimit -v" -- "$exe" run pair.yaml --output refused --quiet
 [ ! -e refused ] && ok || bad "the refused run created its output directory"
 expect 2 "the run cannot fit in memory" -- "$exe" check pair.yaml
 # Out of memory anyway (the check turned off): what the run had, exit 1, no bare bad_alloc.
 SOFTCONTACT_MEMORY_CHECK=off expect 1 "out of memory \(std::bad_alloc\) with [0-9.]+ MiB resident at the peak, estimated [0-9.]+ MiB per rank, address-space limit [0-9.]+ MiB.*Try more ranks" -- "$exe" run pair.yaml --output oom --quiet
 echo "$passes $fails" > sub.txt)
read -r p f < sub.txt; passes=$((passes + p)); fails=$((fails + f))
(passes=0 fails=0
 ulimit -v "$above"
 # 10 % above: the run goes through (the estimate is not too high to be useful).
 expect 0 "done: 10 steps" -- "$exe" run pair.yaml --output fits --quiet
 echo "$passes $fails" > sub.txt)
read -r p f < sub.txt; passes=$((passes + p)); fails=$((fails + f))

echo "memory: $passes passed, $fails failed"
[ "$fails" = 0 ]
