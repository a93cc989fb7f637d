#!/usr/bin/python3
"""Quick still of one output frame with matplotlib (no ParaView needed).

Draws the outward surface triangles of every object, shaded by a fixed light and
coloured by object, from the HDF5 file of a run.

Usage: /usr/bin/python3 tools/render_preview.py OUTPUT_DIR/frames.h5 OUT.png [--time T] [--elev 20 --azim -60]
Needs Debian's python3-h5py and python3-matplotlib (run it with /usr/bin/python3).
"""
import argparse
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("h5")
    ap.add_argument("png")
    ap.add_argument("--time", type=float, default=None, help="simulated time of the frame (default: last)")
    ap.add_argument("--elev", type=float, default=22)
    ap.add_argument("--azim", type=float, default=-60)
    a = ap.parse_args()
    try:
        f = h5py.File(a.h5, "r")
    except OSError as e:
        sys.exit(f"render_preview: cannot open {a.h5}: {e}")
    frames = sorted(f["/frames"].keys())
    if not frames:
        sys.exit(f"render_preview: {a.h5} has no frames")
    times = [float(f["/frames"][k].attrs["time"]) for k in frames]
    k = len(frames) - 1 if a.time is None else int(np.argmin([abs(t - a.time) for t in times]))
    x = f["/frames"][frames[k]]["positions"][...]
    tri = f["/mesh/surface_triangles"][...]
    obj = f["/mesh/vertex_object"][...][tri[:, 0]]
    p = x[tri]  # (S,3,3)
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.linalg.norm(n, axis=1)[:, None] + 1e-300
    light = np.array([0.4, -0.5, 0.8])
    light /= np.linalg.norm(light)
    shade = 0.35 + 0.65 * np.clip(n @ light, 0, 1)
    cmap = plt.get_cmap("tab10")
    colors = np.array([cmap(o % 10)[:3] for o in obj]) * shade[:, None]

    fig = plt.figure(figsize=(8, 6), dpi=110)
    ax = fig.add_subplot(111, projection="3d")
    ax.add_collection3d(Poly3DCollection(p, facecolors=colors, edgecolors="none"))
    lo, hi = x.min(axis=0), x.max(axis=0)
    c, r = (lo + hi) / 2, (hi - lo).max() / 2
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_zlim(c[2] - r, c[2] + r)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=a.elev, azim=a.azim)
    ax.set_axis_off()
    ax.set_title(f"{a.h5}   t = {times[k]:.3f} s", fontsize=9)
    fig.tight_layout()
    fig.savefig(a.png)
    print(f"render_preview: wrote {a.png} (frame {frames[k]}, t = {times[k]:.4g} s)")


if __name__ == "__main__":
    main()
