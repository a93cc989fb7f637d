#!/usr/bin/env bash
# Issue 19's acceptance measurements that need real cores, as one script: run it on a
# node with at least as many cores as the largest rank count (8 by default), with nothing
# else running. It measures
#   1. the soft floor (inputs/soft_floor.yaml, a floor with half of the tets) on RANKS
#      ranks in three ways, in turn, PAIRS rounds: "split" (the default: the floor's
#      forces in parts over the ranks, its points inside a body found by the body's
#      owner), "forces" (split_detection: false) and "whole" (split_objects: false);
#      `bench --warmup WARMUP --steps STEPS`, one thread per rank. Done-when 2: split on
#      4 ranks faster than whole, with a compute imbalance under 1.1.
#   2. the set-up at fixed work per rank: one chess500 container per rank
#      (tools/gen_weak_chess.py), `bench --steps 1` on each of WEAK_RANKS, TRIALS rounds;
#      bench's setup_s is the Simulator's construction (the slowest rank). Done-when 3:
#      it does not grow with the rank count. As a control, in each round and for each
#      of WEAK_RANKS from 2 up to the cores, as many one-rank runs of one container at
#      once, one per core (taskset), with no MPI between them: the growth the node's
#      shared caches and memory cause by themselves, told apart from the code's;
# and writes OUT_DIR/soft_floor.csv, OUT_DIR/weak_setup.csv and OUT_DIR/weak_side.csv
# (softcontact bench --csv, with the variant as the scene file's name) and
# OUT_DIR/summary.md: medians per case, the ratios within each round, and whether each
# Done-when is met on this node.
# Runs on fewer cores are oversubscribed (a warning is printed): their times mean little.
#
# Usage: bash tools/scaling_check.sh
#   RANKS="4 8"             soft floor rank counts
#   PAIRS=3                 rounds of the three soft floor variants
#   WARMUP=600 STEPS=300    soft floor steps before and in the timing
#   WEAK_RANKS="1 2 4 8"    set-up rank counts (one chess container per rank)
#   TRIALS=3                rounds of the set-up runs
#   MPIRUN_FLAGS            default "--bind-to core --map-by core" (none when oversubscribed)
#   OUT_DIR                 default output/scaling_check
#   BUILD_DIR, JOBS as for tools/setup.sh; SKIP_BUILD=1 uses BUILD_DIR's binary as it is
# About 4 minutes on 16 cores with the defaults (docs/scaling.md, "Checking on a node").
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
export BUILD_DIR=${BUILD_DIR:-$root/build}
[ "${SKIP_BUILD:-0}" = 1 ] || BUILD_TYPE=Release bash "$root/tools/setup.sh" >/dev/null
source "$root/tools/env.sh"
export OMP_NUM_THREADS=1
exe=$BUILD_DIR/bin/softcontact
[ -x "$exe" ] || { echo "scaling_check: no $exe (build first, or unset SKIP_BUILD)" >&2; exit 2; }
out=${OUT_DIR:-$root/output/scaling_check}
ranks_list=${RANKS:-"4 8"}
pairs=${PAIRS:-3}
warmup=${WARMUP:-600}
steps=${STEPS:-300}
weak_list=${WEAK_RANKS:-"1 2 4 8"}
trials=${TRIALS:-3}
cores=$(OMP_NUM_THREADS= nproc)
for v in $pairs $warmup $steps $trials $ranks_list $weak_list; do
  [[ $v =~ ^[0-9]+$ ]] && [ "$v" -ge 1 ] ||
    { echo "scaling_check: '$v' is not a positive whole number (RANKS, PAIRS, WARMUP, STEPS, WEAK_RANKS, TRIALS)" >&2; exit 2; }
done
mkdir -p "$out"
rm -f "$out/soft_floor.csv" "$out/weak_setup.csv" "$out/weak_side.csv" "$out/summary.md"

# mpirun for R ranks: bound to cores when they fit, oversubscribed (with a warning) when not.
launch() {
  local r=$1; shift
  if [ "$r" -le "$cores" ]; then
    # shellcheck disable=SC2086
    mpirun -n "$r" ${MPIRUN_FLAGS:---bind-to core --map-by core} "$@"
  else
    echo "scaling_check: $r ranks on $cores cores: oversubscribed, the times mean little" >&2
    mpirun -n "$r" --oversubscribe --bind-to none "$@"
  fi
}

# The soft floor's variants: the shipped scene with one key added to `simulation`.
variant() {  # name, extra line
  local f="$out/soft_floor_$1.yaml"
  awk -v extra="$2" '{print} /^simulation:/ && extra != "" {print "  " extra}' "$root/inputs/soft_floor.yaml" >"$f"
  echo "$f"
}
split=$(variant split "")
forces=$(variant forces "split_detection: false")
whole=$(variant whole "split_objects: false")

for r in $ranks_list; do
  for p in $(seq "$pairs"); do
    for f in "$split" "$forces" "$whole"; do
      echo "soft floor: $r ranks, round $p, $(basename "$f" .yaml)"
      launch "$r" "$exe" bench "$f" --warmup "$warmup" --steps "$steps" --quiet --csv "$out/soft_floor.csv" >/dev/null
    done
  done
done

for r in $weak_list; do
  python3 "$root/tools/gen_weak_chess.py" "$r" "$out/weak$r.yaml" >/dev/null
done
# The control: R one-rank runs of one container at once, each on a core of its own, no MPI
# between them (sideR.yaml is weak1.yaml under another name). What their slowest set-up
# adds to one rank alone is the node's (shared caches, memory bandwidth, page faults);
# what the R-rank run adds to that is the code's.
side_counts=""
for r in $weak_list; do
  if [ "$r" -gt 1 ] && [ "$r" -le "$cores" ]; then
    side_counts="$side_counts $r"
    [ -f "$out/weak1.yaml" ] || python3 "$root/tools/gen_weak_chess.py" 1 "$out/weak1.yaml" >/dev/null
    cp "$out/weak1.yaml" "$out/side$r.yaml"
  fi
done
# R copies of bench at once (logical CPU i for copy i, as nproc counts them), their rows
# appended to weak_side.csv in copy order once all have ended.
side_by_side() {
  local r=$1 i pids=()
  for i in $(seq 0 $((r - 1))); do
    rm -f "$out/side_run$i.csv"
    taskset -c "$i" "$exe" bench "$out/side$r.yaml" --steps 1 --quiet --csv "$out/side_run$i.csv" >/dev/null &
    pids+=($!)
  done
  for i in "${pids[@]}"; do wait "$i"; done
  for i in $(seq 0 $((r - 1))); do
    [ -f "$out/weak_side.csv" ] || head -n 1 "$out/side_run$i.csv" >"$out/weak_side.csv"
    tail -n +2 "$out/side_run$i.csv" >>"$out/weak_side.csv"
    rm -f "$out/side_run$i.csv"
  done
}
for t in $(seq "$trials"); do
  for r in $weak_list; do
    echo "set-up: $r ranks, round $t"
    launch "$r" "$exe" bench "$out/weak$r.yaml" --steps 1 --quiet --csv "$out/weak_setup.csv" >/dev/null
  done
  for r in $side_counts; do
    echo "set-up: $r one-rank runs side by side, round $t"
    side_by_side "$r"
  done
done

python3 "$root/tools/scaling_summary.py" "$out/soft_floor.csv" "$out/weak_setup.csv" "$cores" "$out/weak_side.csv" | tee "$out/summary.md"
