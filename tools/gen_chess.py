#!/usr/bin/python3
"""Tet meshes of the chess pieces of the 'chess500' scene (paper Figs. 5 and 6).

Each piece is a stack of K horizontal octagonal rings (a revolved profile sampled at K
heights, 8 points around). The octagon of every level is cut into three quadrilaterals,
(0,1,2,3), (4,5,6,7) and (0,3,4,7), so the solid between two neighbouring levels is three
hexahedral cells and there is no vertex on the axis (no degenerate axis, no wedge
cells). Every hexahedron is split into five tets: one central tet on four alternate
corners and four corner tets. Which four corners form the central tet alternates with the
parity (octagon index + level), the usual checkerboard, so the face diagonals of
neighbouring cells match and the tets form a conforming mesh whose boundary is a closed
manifold. A piece with K levels has 8 K vertices and 15 (K - 1) tets.

The knight is not carved: its base is revolved like the others; above it the rings of
the neck and head are shifted sideways along x and stretched along x (an elliptical
section), a forward-leaning head with a snout. It is a simplified silhouette.

Level counts are chosen so that the scene's 500 pieces (250 pawns, 63 rooks, 62 knights,
63 bishops, 31 queens, 31 kings) have about the paper's totals, 50.4K vertices and 88.2K
tets (101 vertices and 176 tets per piece on average): see inputs/chess500.yaml.

Every tet is written positively oriented; the script checks that every tet has positive
volume in the real geometry (not only in the reference cube), that every interior face
is shared by exactly two tets, and that every boundary edge lies on exactly two
boundary triangles.

Usage: /usr/bin/python3 tools/gen_chess.py [--out inputs/meshes/chess]
Writes pawn.msh, rook.msh, knight.msh, bishop.msh, queen.msh, king.msh (Gmsh MSH 2.2
ASCII), with the piece standing on z = 0, its axis on the z axis.
"""
import argparse
import collections
import math
import os

import numpy as np

AROUND = 8  # points per ring

# Profiles [m]: (z, r) per level, bottom to top; dimensions of a Staunton set
# (king about 0.1 m tall, pawn 0.05 m). Levels are at least 4 mm apart and radii at least
# 5.5 mm, which keeps the smallest tets, and so dt: auto, from getting small.
PROFILES = {
    "pawn": [
        (0.000, 0.0145), (0.005, 0.0140), (0.011, 0.0108), (0.019, 0.0080),
        (0.026, 0.0100),  # collar
        (0.031, 0.0078),  # neck
        (0.037, 0.0100), (0.044, 0.0097), (0.051, 0.0065),  # head
    ],
    "rook": [
        (0.000, 0.0160), (0.005, 0.0158), (0.010, 0.0128), (0.016, 0.0110),
        (0.022, 0.0102), (0.028, 0.0099), (0.034, 0.0097), (0.040, 0.0098),
        (0.045, 0.0112), (0.050, 0.0128),  # flare
        (0.054, 0.0133), (0.058, 0.0133), (0.062, 0.0128), (0.067, 0.0110),  # turret
    ],
    "bishop": [
        (0.000, 0.0160), (0.005, 0.0155), (0.010, 0.0122), (0.016, 0.0092),
        (0.023, 0.0080), (0.030, 0.0074), (0.036, 0.0072),
        (0.042, 0.0098),  # collar
        (0.047, 0.0076),
        (0.053, 0.0088), (0.059, 0.0096), (0.065, 0.0092), (0.071, 0.0080),  # mitre
        (0.076, 0.0066), (0.081, 0.0060), (0.086, 0.0056),  # the knob
    ],
    "queen": [
        (0.000, 0.0180), (0.005, 0.0175), (0.010, 0.0142), (0.016, 0.0110),
        (0.023, 0.0092), (0.030, 0.0083), (0.037, 0.0077), (0.044, 0.0074),
        (0.050, 0.0076),
        (0.056, 0.0104),  # collar
        (0.061, 0.0080),
        (0.066, 0.0090), (0.071, 0.0104), (0.076, 0.0114), (0.081, 0.0118),  # crown
        (0.086, 0.0090), (0.091, 0.0068), (0.096, 0.0066), (0.101, 0.0056),  # ball
    ],
    "king": [
        (0.000, 0.0190), (0.005, 0.0185), (0.010, 0.0152), (0.016, 0.0116),
        (0.023, 0.0097), (0.030, 0.0088), (0.037, 0.0082), (0.044, 0.0079),
        (0.051, 0.0079), (0.057, 0.0082),
        (0.063, 0.0108),  # collar
        (0.068, 0.0084),
        (0.073, 0.0094), (0.078, 0.0106), (0.083, 0.0114), (0.088, 0.0104),  # crown
        (0.093, 0.0072), (0.098, 0.0060), (0.103, 0.0060), (0.108, 0.0056),  # the cross, revolved: a short round finial (a cross is not a solid of revolution)
    ],
}

# Knight: (z, r, centre shift along x, stretch along x) per level.
KNIGHT = [
    (0.000, 0.0160, 0.000, 1.00), (0.005, 0.0155, 0.000, 1.00), (0.010, 0.0124, 0.000, 1.00),
    (0.016, 0.0106, 0.000, 1.00), (0.022, 0.0100, 0.000, 1.00),
    (0.028, 0.0098, -0.001, 1.10), (0.034, 0.0095, -0.002, 1.20), (0.040, 0.0092, -0.002, 1.30),  # neck
    (0.045, 0.0090, -0.001, 1.45), (0.050, 0.0087, 0.002, 1.60), (0.055, 0.0083, 0.005, 1.75),   # head
    (0.060, 0.0079, 0.006, 1.80), (0.065, 0.0076, 0.004, 1.70),                                   # snout
    (0.070, 0.0072, 0.001, 1.50), (0.075, 0.0066, -0.002, 1.25), (0.080, 0.0058, -0.004, 1.10),  # ears
]

# The octagon (points at angles 2 pi (i + 1/2) / 8, counter-clockwise seen from +z) cut
# into three quadrilaterals, each listed counter-clockwise.
QUADS = [(0, 1, 2, 3), (4, 5, 6, 7), (0, 3, 4, 7)]

# Hexahedron corners: 0-3 the bottom quad (counter-clockwise from above), 4-7 the top
# quad above them. Corners 0, 2, 5, 7 share corner 0's parity, 1, 3, 4, 6 the other.
CUBE = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                 [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], dtype=float)
NEIGHBOURS = {0: (1, 3, 4), 1: (0, 2, 5), 2: (1, 3, 6), 3: (0, 2, 7),
              4: (0, 5, 7), 5: (1, 4, 6), 6: (2, 5, 7), 7: (3, 4, 6)}


def signed_volume(p):
    return np.linalg.det(np.array([p[1] - p[0], p[2] - p[0], p[3] - p[0]])) / 6.0


def oriented(tet):
    """The tet with its corners ordered so that it is positive on the unit cube."""
    tet = list(tet)
    if signed_volume(CUBE[tet]) < 0:
        tet[2], tet[3] = tet[3], tet[2]
    return tuple(tet)


def five_tets(even):
    """Five tets of a hexahedron: the central one on the corners of one parity (`even`:
    those of corner 0) and one corner tet at each corner of the other parity."""
    central = (0, 2, 5, 7) if even else (1, 3, 4, 6)
    corners = (1, 3, 4, 6) if even else (0, 2, 5, 7)
    tets = [oriented(central)]
    for c in corners:
        tets.append(oriented((c,) + NEIGHBOURS[c]))
    return tets


SPLITS = {True: five_tets(True), False: five_tets(False)}


def rings(levels):
    """Vertices (8K,3) of the rings. levels: (z, r, shift_x, stretch_x) per level."""
    pts = []
    for z, r, cx, sx in levels:
        for i in range(AROUND):
            a = 2 * math.pi * (i + 0.5) / AROUND
            pts.append((cx + sx * r * math.cos(a), r * math.sin(a), z))
    return np.array(pts)


def piece(levels):
    """Vertices (8K,3) and positively oriented tets (15(K-1),4, 0-based)."""
    x = rings(levels)
    tets = []
    for k in range(len(levels) - 1):
        for q in QUADS:
            corner = [k * AROUND + i for i in q] + [(k + 1) * AROUND + i for i in q]
            even = (q[0] + k) % 2 == 0  # parity of corner 0 (alternates around every quad)
            for t in SPLITS[even]:
                tets.append([corner[c] for c in t])
    tets = np.array(tets, dtype=np.int64)
    return x, tets


def check(name, x, tets):
    """Positive volumes; a conforming mesh with a closed manifold boundary."""
    vol = np.array([signed_volume(x[t]) for t in tets])
    if vol.min() <= 0:
        raise SystemExit(f"{name}: tet {int(vol.argmin())} has volume {vol.min():.3g}")
    faces = collections.Counter()
    for t in tets:
        for f in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)):
            faces[tuple(sorted(int(t[i]) for i in f))] += 1
    if max(faces.values()) > 2:
        raise SystemExit(f"{name}: a face is shared by more than two tets")
    boundary = [f for f, n in faces.items() if n == 1]
    edges = collections.Counter()
    for f in boundary:
        for a, b in ((0, 1), (1, 2), (0, 2)):
            edges[(f[a], f[b])] += 1
    if set(edges.values()) != {2}:
        raise SystemExit(f"{name}: the boundary is not a closed manifold")
    used = np.unique(tets)
    if len(used) != len(x):
        raise SystemExit(f"{name}: unused vertices")
    # Smallest altitude of any tet: what limits dt: auto.
    h_min = math.inf
    for t in tets:
        p = x[t]
        v = abs(signed_volume(p))
        for f in ((1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2)):
            area = 0.5 * np.linalg.norm(np.cross(p[f[1]] - p[f[0]], p[f[2]] - p[f[0]]))
            h_min = min(h_min, 3 * v / area)
    return vol.sum(), len(boundary), h_min


def write_msh(path, x, tets, title):
    with open(path, "w") as f:
        f.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n")
        f.write(f"$Comments\n{title}\n$EndComments\n")
        f.write(f"$Nodes\n{len(x)}\n")
        for i, p in enumerate(x):
            f.write(f"{i + 1} {p[0]:.6f} {p[1]:.6f} {p[2]:.6f}\n")
        f.write(f"$EndNodes\n$Elements\n{len(tets)}\n")
        for i, t in enumerate(tets):
            f.write(f"{i + 1} 4 2 1 1 {t[0] + 1} {t[1] + 1} {t[2] + 1} {t[3] + 1}\n")
        f.write("$EndElements\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "..", "inputs", "meshes", "chess"))
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    pieces = {name: [(z, r, 0.0, 1.0) for z, r in prof] for name, prof in PROFILES.items()}
    pieces["knight"] = KNIGHT
    for name in ("pawn", "rook", "knight", "bishop", "queen", "king"):
        levels = pieces[name]
        zs = [lv[0] for lv in levels]
        assert all(b > a for a, b in zip(zs, zs[1:])), name
        x, tets = piece(levels)
        volume, n_tri, h_min = check(name, x, tets)
        title = (f"softcontact chess piece '{name}' from tools/gen_chess.py: {len(levels)} octagonal rings, "
                 f"{len(x)} vertices, {len(tets)} tets")
        write_msh(os.path.join(args.out, f"{name}.msh"), x, tets, title)
        print(f"{name:7s} levels {len(levels):2d}  vertices {len(x):4d}  tets {len(tets):4d}  "
              f"surface triangles {n_tri:4d}  height {zs[-1]:.3f} m  volume {volume * 1e6:6.2f} cm^3  "
              f"smallest altitude {h_min * 1e3:.2f} mm")


if __name__ == "__main__":
    main()
