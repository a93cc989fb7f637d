#!/usr/bin/env python3
"""A scene of N x N single-copy entries: N^2 corotational boxes (0.5 m, 16^3 cells, 24,576
tets each), each its own entry (no `instances`), 2 m apart on a kinematic plate, plus the
plate. No box touches another, so each rank needs only the meshes of its own boxes (and
the plate it ghosts): the benchmark of "the meshes of single-copy entries made again where
needed" (docs/benchmarks.md).

Usage: python3 tools/gen_singles.py N OUT.yaml [--files [--pairs]]   (N = 8: 64 boxes, 1.57M tets)
With --files each box is its own Gmsh 2.2 ASCII file next to OUT.yaml (singles/bK.msh, the
same mesh in each, every file named by one entry), so that loading the scene reads 64
files instead of generating 64 primitives. With --pairs (N even) the boxes go two by two:
N^2 / 2 entries, each a grid of two copies 2 m apart naming its own file, so that every
rank needs every file's mesh (the benchmark of "each file of multi-copy entries read by
one rank").
Standard library only. Check the result with `softcontact check OUT.yaml`.
"""
import itertools
import os
import sys

CELLS = 16
SIZE = 0.5


def write_box_msh(path):
    """The box as the `box` primitive's size and cells, cut into 6 tets per cell along the
    diagonal (Kuhn), every tet positively oriented, written as Gmsh 2.2 ASCII."""
    n = CELLS + 1
    h = SIZE / CELLS
    vid = lambda i, j, k: 1 + i + n * (j + n * k)
    out = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$Nodes", str(n ** 3)]
    for k in range(n):
        for j in range(n):
            for i in range(n):
                out.append(f"{vid(i, j, k)} {i * h - SIZE / 2:.17g} {j * h - SIZE / 2:.17g} {k * h - SIZE / 2:.17g}")
    out.append("$EndNodes")
    tets = []
    for k in range(CELLS):
        for j in range(CELLS):
            for i in range(CELLS):
                for perm in itertools.permutations(range(3)):
                    c = [i, j, k]
                    path_ = [tuple(c)]
                    for a in perm:
                        c[a] += 1
                        path_.append(tuple(c))
                    t = [vid(*q) for q in path_]
                    # the sign of the permutation is the tet's orientation
                    inversions = sum(1 for x in range(3) for y in range(x + 1, 3) if perm[x] > perm[y])
                    if inversions % 2 == 1:
                        t[2], t[3] = t[3], t[2]
                    tets.append(t)
    out += ["$Elements", str(len(tets))]
    out += [f"{e + 1} 4 2 0 1 {t[0]} {t[1]} {t[2]} {t[3]}" for e, t in enumerate(tets)]
    out.append("$EndElements")
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")


def main():
    args = [a for a in sys.argv[1:] if a not in ("--files", "--pairs")]
    files = "--files" in sys.argv[1:]
    pairs = "--pairs" in sys.argv[1:]
    if len(args) != 2 or (pairs and not files):
        sys.exit(__doc__)
    n = int(args[0])
    if pairs and n % 2:
        sys.exit("N must be even with --pairs")
    out_path = args[1]
    if files:
        d = os.path.join(os.path.dirname(os.path.abspath(out_path)), "singles")
        os.makedirs(d, exist_ok=True)
    if n < 1:
        sys.exit("N must be at least 1")
    half = n * 2.0 / 2
    lines = [
        "simulation:",
        "  dt: auto",
        "  steps: 10",
        "  output: {directory: output/singles, every: 5}",
        "materials:",
        "  - {name: rubber, model: corotational, young: 1.0e5, poisson: 0.3, density: 1000}",
        "objects:",
        f"  - {{name: floor, material: rubber, primitive: {{type: plate, size: [{2 * half + 4}, {2 * half + 4}], "
        "thickness: 0.1, cells: [10, 10]}, transform: {translate: [0, 0, -0.05]}, kinematic: true}",
    ]
    k = 0
    for i in range(n):
        for j in range(0, n, 2 if pairs else 1):
            shape = (f"mesh: singles/b{k}.msh" if files else
                     "primitive: {type: box, size: [0.5, 0.5, 0.5], cells: [16, 16, 16]}")
            if files:
                write_box_msh(os.path.join(d, f"b{k}.msh"))
            grid = "instances: {grid: {count: [1, 2, 1], spacing: [0, 2, 0]}}, " if pairs else ""
            lines.append(f"  - {{name: b{k}, material: rubber, {shape}, {grid}"
                         f"transform: {{translate: [{-half + 2 * i}, {-half + 2 * j}, 1.0]}}}}")
            k += 1
    with open(out_path, "w") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
