#!/usr/bin/env bash
# Edge-on-edge contact (issue 15): one scene of tests/data/scenes (edge_cross_drop.yaml,
# aligned_stack.yaml) run whole with softcontact verify's check after every step
# (--verify-every 1), then verify on every written frame. Fails (exit 1) when, over all
# frames or over the in-run checks (OUT/verify_steps.json), the deepest part of a surface
# edge through another body's surface (crossing_depth_edges), the deepest interior vertex
# (interior_depth_edges) or the deepest surface vertex (surface_depth_edges) exceeds its
# bound, all in median edges h; also when the run fails or verify fails its own other
# limits (fastest vertex 3 x free fall, no inverted tet at the last frame, no non-finite
# vertex; the in-run speed against the same 3). Interior vertices inside another body
# mean surfaces passed through each other, so they take the crossing bound unless a sixth
# argument gives theirs. Prints each measured maximum on one line (value, step, time).
# Usage: edge_contact_test.sh EXE SCENE.yaml WORKDIR MAX_CROSSING_DEPTH_EDGES MAX_SURFACE_DEPTH_EDGES [MAX_INTERIOR_DEPTH_EDGES]
set -u
if [ $# -lt 5 ] || [ $# -gt 6 ]; then
  echo "usage: $0 EXE SCENE.yaml WORKDIR MAX_CROSSING_DEPTH_EDGES MAX_SURFACE_DEPTH_EDGES [MAX_INTERIOR_DEPTH_EDGES]" >&2
  exit 2
fi
exe=$1 scene=$2 work=$3 cross=$4 surf=$5 interior=${6:-$4}
speed=3
rm -rf "$work" && mkdir -p "$work" || exit 1
args=(run "$scene" --output "$work/out" --overwrite --quiet --verify-every 1)
echo "softcontact ${args[*]}"
if ! "$exe" "${args[@]}"; then echo "FAIL: the run did not reach its end"; exit 1; fi
[ -f "$work/out/verify_steps.json" ] || { echo "FAIL: no $work/out/verify_steps.json"; exit 1; }
fail=0
# Every frame, independently of the run; its summary only.
"$exe" verify "$work/out" --max-depth "$surf" --max-interior-depth "$interior" --max-speed-ratio "$speed" \
  --json "$work/verify.json" | sed -n '/^summary:/,$p'
rc=${PIPESTATUS[0]}
[ "$rc" = 0 ] || { echo "FAIL: softcontact verify exited $rc"; fail=1; }
[ -f "$work/verify.json" ] || { echo "FAIL: no $work/verify.json"; exit 1; }
# One maximum of a verify JSON file: "VALUE STEP TIME" (maxima hold {"value", "step", "time"}).
maximum() {
  grep -oE "\"$2\": \{\"value\": [-0-9.e+]+, \"step\": [0-9]+, \"time\": [-0-9.e+]+" "$1" | head -1 |
    sed -E 's/.*"value": ([^,]+), "step": ([^,]+), "time": (.+)$/\1 \2 \3/'
}
# check WHERE FILE KEY LABEL UNIT BOUND: print the maximum; fail if above BOUND (none: report only).
check() {
  local m v s t
  m=$(maximum "$2" "$3")
  if [ -z "$m" ]; then echo "FAIL: $1: no '$3' in $2"; fail=1; return; fi
  read -r v s t <<<"$m"
  echo "$1: $4 $v$5 (step $s, t = $t s)"
  if [ "$6" != none ] && ! awk -v a="$v" -v b="$6" 'BEGIN { exit !((a + 0) <= (b + 0)) }'; then
    echo "FAIL: $1: $4 $v$5 > $6$5"; fail=1
  fi
}
for where in frames in-run; do
  f=$work/verify.json
  [ "$where" = in-run ] && f=$work/out/verify_steps.json
  check "$where" "$f" crossing_depth_edges "deepest crossing edge part" " h" "$cross"
  check "$where" "$f" surface_depth_edges "deepest surface vertex" " h" "$surf"
  check "$where" "$f" interior_depth_edges "deepest interior vertex" " h" "$interior"
  check "$where" "$f" crossings_without_inside_vertex "crossings without an inside vertex, at most" "" none
  check "$where" "$f" speed_ratio "fastest vertex" " x v_ff" "$speed"
done
[ "$fail" = 0 ] && echo "1 passed, 0 failed" || echo "0 passed, 1 failed"
exit "$fail"
