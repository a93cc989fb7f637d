#!/usr/bin/env bash
# Self-contact (issue 15): a scene of tests/data/scenes with `self_collisions: true`
# (ring_squeeze.yaml) run whole with softcontact verify's check every step
# (--verify-every 1), then verify on every written frame. Fails (exit 1) when the deepest
# surface vertex inside its own body (self_depth_edges, in median edges h) or the deepest
# part of a surface edge through the body's own surface (self_crossing_depth_edges), over
# all frames or over the in-run checks, exceeds MAX_SELF_DEPTH_EDGES, or when verify fails its
# other limits (surface depth in other bodies MAX_SELF_DEPTH_EDGES as well, fastest vertex
# 3 x v_ff, no inverted tet at the last frame). Then the same scene with self_collisions
# off must go deeper than MIN_DEPTH_WITHOUT_EDGES: the scene does press the body into
# itself, so that the first part measures the response and not a scene without contact.
# With a sixth argument `edges`, the scene runs with `edge_contacts: true` added (edges
# through the body's own surface get records too).
# Usage: self_contact_test.sh EXE SCENE.yaml WORKDIR MAX_SELF_DEPTH_EDGES MIN_DEPTH_WITHOUT_EDGES [edges]
set -u
if [ $# -lt 5 ] || [ $# -gt 6 ]; then
  echo "usage: $0 EXE SCENE.yaml WORKDIR MAX_SELF_DEPTH_EDGES MIN_DEPTH_WITHOUT_EDGES [edges]" >&2
  exit 2
fi
exe=$1 scene=$2 work=$3 bound=$4 without=$5
rm -rf "$work" && mkdir -p "$work" || exit 1
grep -q '^  self_collisions: true' "$scene" || { echo "FAIL: $scene does not set self_collisions: true"; exit 1; }
if [ "${6:-}" = edges ]; then
  sed 's/^  self_collisions: true/  self_collisions: true\n  edge_contacts: true/' "$scene" >"$work/scene.yaml"
  scene=$work/scene.yaml
fi
fail=0
# value KEY FILE: the "value" of a maximum {"value", "step", "time"} in a verify JSON file.
value() { grep -oE "\"$1\": \{\"value\": [-0-9.e+]+" "$2" | head -1 | sed -E 's/.*"value": //'; }
above() { awk -v a="$1" -v b="$2" 'BEGIN { exit !((a + 0) > (b + 0)) }'; }

echo "softcontact run $scene --verify-every 1"
if ! "$exe" run "$scene" --output "$work/on" --overwrite --quiet --verify-every 1; then
  echo "FAIL: the run did not reach its end"; exit 1
fi
"$exe" verify "$work/on" --max-depth "$bound" --max-self-depth "$bound" --json "$work/on.json" | sed -n '/^summary:/,$p'
rc=${PIPESTATUS[0]}
[ "$rc" = 0 ] || { echo "FAIL: softcontact verify exited $rc"; fail=1; }
for f in "$work/on.json" "$work/on/verify_steps.json"; do
  for key in self_depth_edges self_crossing_depth_edges; do
    v=$(value "$key" "$f")
    [ -n "$v" ] || { echo "FAIL: no $key in $f"; fail=1; continue; }
    echo "$f: $key $v h (bound $bound)"
    if above "$v" "$bound"; then echo "FAIL: $key $v h > $bound h"; fail=1; fi
  done
done

sed 's/^  self_collisions: true/  self_collisions: false/' "$scene" >"$work/off.yaml"
echo "softcontact run (self_collisions: false)"
if ! "$exe" run "$work/off.yaml" --output "$work/off" --overwrite --quiet; then
  echo "FAIL: the run without self-contact did not reach its end"; exit 1
fi
"$exe" verify "$work/off" --max-self-depth inf --json "$work/off.json" >/dev/null
v=$(value self_depth_edges "$work/off.json")
echo "without self-contact: deepest surface vertex in its own body ${v:-?} h (must exceed $without h)"
if [ -z "$v" ] || ! above "$v" "$without"; then echo "FAIL: the scene does not press the body into itself"; fail=1; fi
[ "$fail" = 0 ] && echo "1 passed, 0 failed" || echo "0 passed, 1 failed"
exit "$fail"
