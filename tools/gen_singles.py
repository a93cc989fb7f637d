#!/usr/bin/env python3
"""A scene of N x N single-copy entries: N^2 corotational boxes (0.5 m, 16^3 cells, 24,576
tets each), each its own entry (no `instances`), 2 m apart on a kinematic plate, plus the
plate. No box touches another, so each rank needs only the meshes of its own boxes (and
the plate it ghosts): the benchmark of "the meshes of single-copy entries made again where
needed" (docs/benchmarks.md).

Usage: python3 tools/gen_singles.py N OUT.yaml   (N = 8: 64 boxes, 1.57M tets)
Standard library only. Check the result with `softcontact check OUT.yaml`.
"""
import sys


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    n = int(sys.argv[1])
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
        for j in range(n):
            lines.append(f"  - {{name: b{k}, material: rubber, primitive: {{type: box, size: [0.5, 0.5, 0.5], "
                         f"cells: [16, 16, 16]}}, transform: {{translate: [{-half + 2 * i}, {-half + 2 * j}, 1.0]}}}}")
            k += 1
    with open(sys.argv[2], "w") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
