#!/usr/bin/env bash
# The scene benchmark: builds softcontact (Release) and runs `softcontact bench` on every
# paper scene in inputs/, for each thread count in THREADS, on RANKS ranks. Writes
#   output/bench/scenes.csv          one row per run (softcontact bench --csv)
#   output/bench/scenes.md           the same as a markdown table (docs/benchmarks.md)
#   output/bench/fig6_chess500.csv   one row per step of the chess500 run with the last
#                                    thread count (--per-step; 1 by default): Fig. 6
# and plots Fig. 6 (tools/plot_fig6.py -> docs/images/fig6_chess500.png) when
# /usr/bin/python3 has matplotlib. Scenes missing from inputs/ are skipped with a message.
#
# Usage: bash tools/bench_scenes.sh [SCENE_NAME ...]      (default: every scene below)
#   THREADS="2 1"  OpenMP threads per rank, one run each (default: all cores, then 1)
#   RANKS=1        MPI ranks (until the halo exchange exists every object is on rank 0)
#   APPEND=1       append to scenes.csv instead of starting it afresh
#   OMP_WAIT_POLICY (default passive, see below)
#   BUILD_DIR, JOBS as for tools/setup.sh; OUT_DIR (default output/bench)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cores=$(OMP_NUM_THREADS= nproc)
export BUILD_DIR=${BUILD_DIR:-$root/build}
BUILD_TYPE=Release bash "$root/tools/setup.sh" >/dev/null
source "$root/tools/env.sh"
exe=$BUILD_DIR/bin/softcontact
out=${OUT_DIR:-$root/output/bench}
threads=${THREADS:-"$cores 1"}
fig6_threads=${threads##* }   # one thread by default: no barrier waits in the per-step times
ranks=${RANKS:-1}
# Idle OpenMP threads sleep instead of spinning. On a shared, oversubscribed machine a
# spinning thread burns the time slice its partner needs, and every parallel loop then
# waits whole scheduler ticks at its barrier: measured on chess500 with 2 threads at a
# load of 6 on 2 cores, 132 ms per step with the default policy against 8 ms passive
# (docs/benchmarks.md). On a dedicated machine pass OMP_WAIT_POLICY=active.
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}
mkdir -p "$out"

# scene, warm-up steps, timed steps. The warm-up lets the objects fall into contact:
# default's first bodies land after about 0.24 s (1060 steps); tori200's chains reach the
# membrane after about 200 steps and hold about 2,000 colliding points from t = 0.45 s
# (1650 steps) on. chess500 is timed from t = 0 over the pile-up and the settling (4000
# steps = 0.74 s; the pieces are poured in over 0.3 s), which makes Fig. 6. torus_drop
# (issue 18's comparison with Bullet) is timed whole: 5275 steps = 0.5 s. The whole
# script takes about 15 minutes on 2 shared cores.
scenes=(
  "default 1100 500"
  "tori200 2000 200"
  "chess500 0 4000"
  "archway 500 1000"
  "bars_squeezed 500 1000"
  "stiff_bars_soft_cube 500 1000"
  "torus_drop 0 5275"
)

selected=("$@")
# want NAME: no names were given, or NAME is one of them
want() { [ ${#selected[@]} -eq 0 ] && return 0; local w; for w in "${selected[@]}"; do [ "$w" = "$1" ] && return 0; done; return 1; }
[ "${APPEND:-0}" = 1 ] || rm -f "$out/scenes.csv"
missing=()
for entry in "${scenes[@]}"; do
  read -r name warmup steps <<<"$entry"
  want "$name" || continue
  scene=$root/inputs/$name.yaml
  if [ ! -f "$scene" ]; then
    echo "bench_scenes: skipping $name: $scene does not exist"
    missing+=("$name")
    continue
  fi
  for t in $threads; do
    extra=()
    if [ "$name" = chess500 ] && [ "$t" = "$fig6_threads" ]; then extra=(--per-step "$out/fig6_chess500.csv"); fi
    echo "== $name: $ranks rank(s) x $t thread(s), $steps steps after $warmup warm-up steps"
    OMP_NUM_THREADS=$t mpirun -n "$ranks" --bind-to none "$exe" bench "$scene" --warmup "$warmup" \
      --steps "$steps" --csv "$out/scenes.csv" --quiet "${extra[@]}"
  done
done

# The markdown table: one line per run, medians (means in parentheses) in ms per step, and
# the wall seconds per simulated second of the timed steps (their mean time over dt): the
# figure users compare simulators by.
if [ -s "$out/scenes.csv" ]; then
  awk -F, '
    NR == 1 { for (i = 1; i <= NF; ++i) col[$i] = i; next }
    function v(name) { return $(col[name]) }
    function ms(name) { return sprintf("%.2f (%.2f)", v(name "_ms_median"), v(name "_ms_mean")) }
    NR == 2 {
      print "| scene | ranks x threads | vertices | tets | dt [us] | warm-up + timed steps | colliding points (mean) | total | forces | integration | detection | depth | response | steps/s | wall s per simulated s | peak MiB per rank (max) |"
      print "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
    }
    { printf "| %s | %s x %s | %s | %s | %.1f | %s + %s | %.0f | %s | %s | %s | %s | %s | %s | %.1f | %.1f | %.0f |\n",
        v("scene"), v("ranks"), v("threads"), v("vertices"), v("tets"), 1e6 * v("dt"), v("warmup"), v("steps"),
        v("collisions_mean"), ms("total"), ms("forces"), ms("integrate"), ms("detect"), ms("depth"), ms("response"),
        v("steps_per_second"), v("total_ms_mean") / 1000 / v("dt"), v("rss_max_mib") }' "$out/scenes.csv" >"$out/scenes.md"
  echo "== $out/scenes.md (ms per step: median (mean))"
  cat "$out/scenes.md"
fi

if [ -s "$out/fig6_chess500.csv" ] && want chess500; then
  if /usr/bin/python3 -c 'import matplotlib, numpy' 2>/dev/null; then
    /usr/bin/python3 "$root/tools/plot_fig6.py" "$out/fig6_chess500.csv"
  else
    echo "bench_scenes: /usr/bin/python3 lacks matplotlib and numpy: plot $out/fig6_chess500.csv with tools/plot_fig6.py"
  fi
fi
[ ${#missing[@]} -eq 0 ] || echo "bench_scenes: missing scenes: ${missing[*]}"
