#!/usr/bin/env bash
# One shipped scene run whole (or to END_TIME), checked by softcontact verify after every
# N-th step in the run and on every written frame afterwards, against the bounds given.
# Label 'scenes' (README: bash tools/test.sh -L scenes; CI runs it). The bounds are the
# values measured on this code (docs/validation.md, "Contact response in piles") with a
# margin, so that a change that makes contact worse fails; they are not the goals of
# docs/validation.md, which some scenes do not meet yet.
# Usage: scene_verify_test.sh EXE SCENE.yaml WORK END_TIME|whole EVERY MAX_DEPTH MAX_SPEED_RATIO MAX_INVERTED_LAST
set -u
exe=$1 scene=$2 work=$3 end=$4 every=$5 depth=$6 speed=$7 inverted=$8
rm -rf "$work" && mkdir -p "$work" || exit 1
args=(run "$scene" --output "$work/out" --overwrite --verify-every "$every" --quiet)
[ "$end" != whole ] && args+=(--end-time "$end")
echo "softcontact ${args[*]}"
if ! "$exe" "${args[@]}"; then echo "FAIL: the run did not reach its end"; exit 1; fi
# The in-run check (every N-th step) against the same bounds: transients between frames.
python_max() { grep -oE "\"$1\": \{\"value\": [-0-9.e+]+" "$work/out/verify_steps.json" | grep -oE '[-0-9.e+]+$'; }
steps_depth=$(python_max surface_depth_edges)
steps_speed=$(python_max speed_ratio)
echo "in-run check every $every steps: deepest surface vertex $steps_depth h, fastest vertex $steps_speed x v_ff"
fail=0
awk -v a="$steps_depth" -v b="$depth" 'BEGIN { exit !(a <= b) }' || { echo "FAIL: in-run surface depth $steps_depth h > $depth h"; fail=1; }
awk -v a="$steps_speed" -v b="$speed" 'BEGIN { exit !(a <= b) }' || { echo "FAIL: in-run speed ratio $steps_speed > $speed"; fail=1; }
# Every frame, independently of the run.
"$exe" verify "$work/out" --max-depth "$depth" --max-speed-ratio "$speed" --max-inverted "$inverted" \
  --json "$work/verify.json" | tail -12
rc=${PIPESTATUS[0]}
[ "$rc" = 0 ] || { echo "FAIL: softcontact verify exited $rc"; fail=1; }
[ "$fail" = 0 ] && echo "1 passed, 0 failed" || echo "0 passed, 1 failed"
exit "$fail"
