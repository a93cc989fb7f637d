#!/usr/bin/env bash
# Pictures: tools/render.sh on a tiny run. Needs ParaView (label 'render', not in the
# default suite); without pvpython it fails with the install command.
# Usage: render_test.sh EXE RENDER_SH DATA WORK
set -u
exe=$(realpath "$1") render=$(realpath "$2") data=$(realpath "$3") work=$4
rm -rf "$work" && mkdir -p "$work" && cd "$work" || exit 1
fails=0 passes=0
ok() { passes=$((passes + 1)); }
bad() { echo "FAIL: $*"; fails=$((fails + 1)); }
export SOFTCONTACT_NO_INSTALL=1  # a test installs nothing

# expect CODE PATTERN -- command...: exit status CODE and PATTERN (grep -E) in stdout+stderr
expect() {
  local code=$1 pattern=$2; shift 3
  local out rc
  out=$("$@" 2>&1); rc=$?
  if [ "$rc" != "$code" ]; then bad "'$*' exited $rc, expected $code; output:"; echo "$out" | tail -20; return 1; fi
  if ! grep -qE -- "$pattern" <<<"$out"; then bad "'$*' output lacks /$pattern/:"; echo "$out" | tail -20; return 1; fi
  ok
}

# Bad input: exit 2 and a message naming what is missing (checked before ParaView is needed)
expect 2 "output directory 'nothing' does not exist" -- bash "$render" nothing
mkdir -p empty
expect 2 "empty/frames.xdmf' is missing" -- bash "$render" empty
expect 2 "no output directory given" -- bash "$render"

# A tiny run: two cubes dropping onto a kinematic floor, frames at steps 0, 5, ..., 20
if ! "$exe" run "$data/scenes/small.yaml" --steps 20 --output run --overwrite --quiet > run.log 2>&1; then
  bad "the run failed:"; cat run.log
  echo "render: $passes passed, $fails failed"; exit 1
fi

if ! command -v pvpython > /dev/null; then
  # the wrapper says what to install; the test fails rather than pass without checking anything
  expect 2 "apt-get install paraview" -- bash "$render" run
  bad "pvpython is not installed: install ParaView (apt-get install paraview python3-paraview python3-h5py xvfb ffmpeg) to run the 'render' tests"
  echo "render: $passes passed, $fails failed"; exit 1
fi
expect 2 "frame 9 does not exist; the run has frames 0 to 4" -- bash "$render" run --frames 9 --out bad
expect 2 "this run has no 'nosuch' field|invalid choice: 'nosuch'" -- bash "$render" run --color nosuch --out bad

# check.py PNG... [--size WxH] [--min-colours N] [--warm F]: size, distinct colours and the
# fraction of warm (object) pixels; --same-grey-box: the kinematic floor's grey pixels
# cover the same box in every image (the camera does not move between frames)
cat > check.py <<'EOF'
import sys
import numpy as np
from vtkmodules.vtkIOImage import vtkPNGReader
from vtkmodules.util.numpy_support import vtk_to_numpy

import argparse
ap = argparse.ArgumentParser()
ap.add_argument("files", nargs="+")
ap.add_argument("--size")
ap.add_argument("--min-colours", type=int, default=0)
ap.add_argument("--warm", type=float, default=0.0)
ap.add_argument("--same-grey-box", action="store_true")
a = ap.parse_args()
boxes, bad = [], 0
for f in a.files:
    r = vtkPNGReader(); r.SetFileName(f); r.Update()
    img = r.GetOutput()
    w, h, _ = img.GetDimensions()
    px = vtk_to_numpy(img.GetPointData().GetScalars())[:, :3].astype(float) / 255
    if a.size and f"{w}x{h}" != a.size:
        print(f"{f}: {w}x{h}, expected {a.size}"); bad += 1
    colours = len(np.unique((px * 255).astype(np.uint32) @ np.array([65536, 256, 1])))
    if colours < a.min_colours:
        print(f"{f}: only {colours} distinct colours"); bad += 1
    warm = float(np.mean(px[:, 0] - px[:, 2] > 0.15))
    if warm < a.warm:
        print(f"{f}: {warm:.4%} warm pixels, expected at least {a.warm:.4%} (are the objects drawn?)"); bad += 1
    grey = (np.ptp(px, axis=1) < 0.03) & (px.mean(axis=1) > 0.3) & (px.mean(axis=1) < 0.8)
    yy, xx = np.divmod(np.flatnonzero(grey), w)
    boxes.append((xx.min(), xx.max(), yy.min(), yy.max()) if len(xx) else None)
    print(f"{f}: {w}x{h}, {colours} colours, {warm:.2%} warm, grey box {boxes[-1]}")
if a.same_grey_box:
    if boxes[0] is None or any(b is None or max(abs(p - q) for p, q in zip(b, boxes[0])) > 2 for b in boxes):
        print(f"the floor moved between frames (grey boxes {boxes})"); bad += 1
sys.exit(1 if bad else 0)
EOF
check() { local out; out=$(pvpython check.py "$@" 2>&1) && ok || { bad "picture check failed:"; echo "$out"; }; }

# Object colours, two frames, 320x240: files, size, not blank
if expect 0 "2 frame\(s\) of 5" -- bash "$render" run --frames 0,-1 --size 320x240 --out pics; then
  for f in pics/frame_000000.png pics/frame_000004.png; do [ -s "$f" ] && ok || bad "$f missing"; done
  check pics/frame_000000.png pics/frame_000004.png --size 320x240 --min-colours 200 --warm 0.002
fi
# Every frame with the camera of the whole run, and an animation
if expect 0 "animation .*run\.(mp4|gif)" -- bash "$render" run --size 240x180 --out anim --animation --fps 5; then
  [ "$(ls anim/frame_*.png | wc -l)" = 5 ] && ok || bad "expected 5 frames in anim/"
  f=$(ls anim/run.mp4 anim/run.gif 2>/dev/null | head -1)
  [ -s "$f" ] && ok || bad "no animation in anim/"
  check anim/frame_00000[0-4].png --size 240x180 --same-grey-box --min-colours 100
fi
# Field colours and other views
expect 0 "1 frame\(s\)" -- bash "$render" run --color velocity --view top --size 300x200 --out vel &&
  check vel/frame_000004.png --size 300x200 --min-colours 100
expect 0 "1 frame\(s\)" -- bash "$render" run --color contact_force --view front --zoom 1.5 --out cf --size 200x200 &&
  check cf/frame_000004.png --size 200x200 --min-colours 50
# hiding every object leaves only the background: the warm-pixel check must fail
bash "$render" run --hide '*' --size 160x120 --out hidden --quiet > hidden.log 2>&1
if pvpython check.py hidden/frame_000004.png --warm 0.002 > /dev/null 2>&1; then bad "a picture without objects passed the check"; else ok; fi

echo "render: $passes passed, $fails failed"
[ "$fails" = 0 ]
