#!/usr/bin/python3
"""Tet meshes of the voussoirs of the 'archway' scene (paper Fig. 4).

A semicircular arch in the xz-plane, centred on the origin, springing from z = 0 (the
scene translates it onto its piers). Voussoir k spans the polar angles
[k pi / n, (k + 1) pi / n] (k = 0 is the right springer, k = n // 2 the keystone), the
radii [r_in, r_out] and the depth y in [-b/2, b/2]. Each stone is a structured grid of
cells in (r, theta, y), every cell split into the six tets of the Kuhn triangulation
(the same diagonal in every cell, so the tets of neighbouring cells share faces); each
tet is written positively oriented. 4 x 4 x 4 cells give 384 tets per stone, close to
the paper's 375.

All stones have the same cross-section, so at every joint the two stones' rims lie
exactly on top of each other. (Until issue 15 the even stones were 2.5 mm larger on every
side, so that no rims were aligned: vertex-in-tet detection alone sees aligned rims late.)

Joint faces are exact radial planes: both stones evaluate the same angle, so they touch
without overlapping at the start.

Usage: /usr/bin/python3 tools/gen_archway.py [--out inputs/meshes/archway]
Writes voussoir_0.msh ... voussoir_{n-1}.msh (Gmsh MSH 2.2 ASCII).
"""
import argparse
import itertools
import math
import os

import numpy as np

# Geometry [m], chosen in inputs/archway.yaml's header comment.
N_STONES = 9          # odd, so that there is a keystone
R_IN = 0.12           # intrados radius
R_OUT = 0.18          # extrados radius: thickness 0.06, mean radius 0.15, t/R = 0.4
DEPTH = 0.06          # extent along y
CELLS = (4, 4, 4)     # cells along r, theta, y


def kuhn_tets():
    """The six tets of the unit cube along its main diagonal, as corner bit triples."""
    tets = []
    for perm in itertools.permutations(range(3)):
        c = [0, 0, 0]
        path = [tuple(c)]
        for axis in perm:
            c[axis] = 1
            path.append(tuple(c))
        tets.append(path)
    return tets


def voussoir(k, n=N_STONES, cells=CELLS, r_in=R_IN, r_out=R_OUT):
    """Vertices (V,3) and positively oriented tets (T,4, 0-based) of stone k."""
    nr, nt, ny = cells
    r = np.linspace(r_in, r_out, nr + 1)
    th = np.linspace(k * math.pi / n, (k + 1) * math.pi / n, nt + 1)
    y = np.linspace(-DEPTH / 2, DEPTH / 2, ny + 1)
    # Joint faces must be exactly the same plane for both neighbours: the end angles
    # are computed once, from the same expression, for every stone.
    th[0], th[-1] = k * math.pi / n, (k + 1) * math.pi / n
    cos_t, sin_t = np.cos(th), np.sin(th)
    # The springing joints lie exactly in the plane z = 0.
    if k == 0:
        sin_t[0] = 0.0
    if k == n - 1:
        sin_t[-1] = 0.0

    def vid(i, j, l):
        return (i * (nt + 1) + j) * (ny + 1) + l

    pts = np.empty(((nr + 1) * (nt + 1) * (ny + 1), 3))
    for i in range(nr + 1):
        for j in range(nt + 1):
            for l in range(ny + 1):
                pts[vid(i, j, l)] = (r[i] * cos_t[j], y[l], r[i] * sin_t[j])

    tets = []
    for i in range(nr):
        for j in range(nt):
            for l in range(ny):
                for path in kuhn_tets():
                    t = [vid(i + a, j + b, l + c) for a, b, c in path]
                    p = pts[t]
                    vol = np.dot(np.cross(p[1] - p[0], p[2] - p[0]), p[3] - p[0]) / 6.0
                    if abs(vol) < 1e-15:
                        raise RuntimeError(f"degenerate tet in stone {k}, cell {(i, j, l)}")
                    if vol < 0:
                        t[2], t[3] = t[3], t[2]
                    tets.append(t)
    return pts, np.array(tets, dtype=np.int64)


def write_msh22(path, pts, tets):
    with open(path, "w") as f:
        f.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%d\n" % len(pts))
        for i, p in enumerate(pts):
            f.write("%d %r %r %r\n" % (i + 1, float(p[0]), float(p[1]), float(p[2])))
        f.write("$EndNodes\n$Elements\n%d\n" % len(tets))
        for e, t in enumerate(tets):
            f.write("%d 4 2 1 1 %d %d %d %d\n" % (e + 1, t[0] + 1, t[1] + 1, t[2] + 1, t[3] + 1))
        f.write("$EndElements\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    here = os.path.dirname(os.path.abspath(__file__))
    ap.add_argument("--out", default=os.path.join(here, "..", "inputs", "meshes", "archway"))
    ap.add_argument("--r-in", type=float, default=R_IN, help="intrados radius [m] (default %(default)s)")
    ap.add_argument("--r-out", type=float, default=R_OUT, help="extrados radius [m] (default %(default)s)")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    total = 0
    for k in range(N_STONES):
        pts, tets = voussoir(k, r_in=a.r_in, r_out=a.r_out)
        write_msh22(os.path.join(a.out, "voussoir_%d.msh" % k), pts, tets)
        total += len(tets)
    print("wrote %d voussoirs, %d tets each, %d tets in all, to %s"
          % (N_STONES, total // N_STONES, total, os.path.normpath(a.out)))


if __name__ == "__main__":
    main()
