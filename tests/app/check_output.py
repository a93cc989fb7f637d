#!/usr/bin/python3
"""Checks a run's output directory after a kill: frames.h5 opens with h5py, every frame it
links and every dataset the XDMF names can be read with the stated shape, no referenced
file is a temporary one; with a second directory, every frame of the first is bitwise
equal to the same frame of the second (owner_rank aside). --same-count: both have the
same frames. --by-step: frames are matched by their step, not their number (a run
continued into a new directory starts at its checkpoint's step), and the first directory
must hold every frame the reference has from its first step on; its first frame, written
at the checkpoint before any step, is compared in positions and velocities only (contact
forces and penetrations are results of a step, not part of a checkpoint).

usage: check_output.py DIR [REFERENCE_DIR] [--min-frames N] [--same-count] [--by-step]"""
import re
import sys
import xml.etree.ElementTree as ET

import h5py
import numpy as np

args = [a for a in sys.argv[1:] if not a.startswith("--")]
opts = sys.argv[1:]
min_frames = int(opts[opts.index("--min-frames") + 1]) if "--min-frames" in opts else 1
if "--min-frames" in opts:
    args.remove(opts[opts.index("--min-frames") + 1])
run = args[0]
ref = args[1] if len(args) > 1 else None


def fail(msg):
    print("check_output: " + msg)
    sys.exit(1)


with h5py.File(run + "/frames.h5", "r") as f:
    frames = sorted(f["frames"])
    if len(frames) < min_frames:
        fail(f"{run}: {len(frames)} frames, expected at least {min_frames}")
    n = f["mesh/points"].shape[0]
    for k in frames:
        g = f["frames"][k]
        if g["positions"].shape != (n, 3) or not np.isfinite(g["positions"][:]).all():
            fail(f"{run}: frame {k} positions unreadable or not finite")
        int(g.attrs["step"])

# Every DataItem of the XDMF: the file exists (not a .tmp) and the dataset has the shape.
root = ET.parse(run + "/frames.xdmf").getroot()
items = 0
for item in root.iter("DataItem"):
    fname, path = item.text.strip().split(":", 1)
    if fname.endswith(".tmp"):
        fail(f"XDMF references a temporary file {fname}")
    dims = tuple(int(d) for d in item.attrib["Dimensions"].split())
    with h5py.File(run + "/" + fname, "r") as h:
        if h[path].shape != dims:
            fail(f"{fname}:{path} has shape {h[path].shape}, XDMF says {dims}")
    items += 1
if items == 0 and min_frames > 0:
    fail("the XDMF names no dataset")

if ref and "--by-step" in opts:
    with h5py.File(run + "/frames.h5", "r") as a, h5py.File(ref + "/frames.h5", "r") as b:
        sa = {int(a["frames"][k].attrs["step"]): k for k in a["frames"]}
        sb = {int(b["frames"][k].attrs["step"]): k for k in b["frames"]}
        if not sa:
            fail(f"{run} has no frame")
        want = sorted(s for s in sb if s >= min(sa))
        if sorted(sa) != want:
            fail(f"{run} has frames at steps {sorted(sa)}, {ref} from step {min(sa)} on at {want}")
        for s, k in sa.items():
            for d in a["frames"][k]:
                if d == "owner_rank" or (s == min(sa) and d not in ("positions", "velocities")):
                    continue
                if a["frames"][k][d][:].tobytes() != b["frames"][sb[s]][d][:].tobytes():
                    fail(f"step {s}: dataset {d} differs between {run} (frame {k}) and {ref} (frame {sb[s]})")
elif ref:
    with h5py.File(run + "/frames.h5", "r") as a, h5py.File(ref + "/frames.h5", "r") as b:
        fa, fb = sorted(a["frames"]), sorted(b["frames"])
        if "--same-count" in opts and fa != fb:
            fail(f"{run} has {len(fa)} frames, {ref} {len(fb)}")
        for k in fa:
            if k not in b["frames"]:
                fail(f"frame {k} of {run} is not in {ref}")
            for d in a["frames"][k]:
                if d == "owner_rank":
                    continue
                if a["frames"][k][d][:].tobytes() != b["frames"][k][d][:].tobytes():
                    fail(f"frame {k} dataset {d} differs between {run} and {ref}")
print(f"check_output: {run}: {len(frames)} frames readable, {items} XDMF items" + (f", identical to {ref}" if ref else ""))
