#pragma once
// Generated primitive meshes: box, cylinder, sphere, torus, all centred at the origin,
// in SI units, ready to use without validate_mesh having to repair anything (every tet
// positively oriented, no unreferenced or duplicate vertices, conforming, closed outward
// boundary). Deterministic: the same arguments give the same mesh, bit for bit.
//
// Construction. Every mesh is a set of logically hexahedral cells, each split into the
// same 6 tets around its local (0,0,0)-(1,1,1) diagonal (Kuhn / Freudenthal split). The
// split of a quad face then depends only on which way the cell's local axes point along
// that face, so neighbouring cells agree (the mesh is conforming) as long as every
// cell's local axes point the same way along shared faces; the generators choose the
// local axes to guarantee this (tangential axes along the positive global axis, radial
// axes outward), also across the torus' periodic seam. Cells whose local frame is
// left-handed get their tets written with two vertices swapped, so every tet comes out
// with a positive volume.
//
// Round shapes use an O-grid (the disk) or a "cubed sphere" (the ball) instead of
// mapping one square/cube grid onto the disk/ball, which would flatten the corner cells
// (two faces on the boundary meeting at nearly 180 degrees) into slivers:
//  - disk: an inner n x n block of quads plus m rings of 4n quads around it;
//  - ball: an inner n x n x n block of hexes plus m shells of 6 n^2 hexes around it.
// Positions come from a parameter square/cube [-1,1]^d in which the inner block is
// [-s0,s0]^d and the rings/shells are concentric square/cube surfaces at s in (s0,1].
// A parameter point p = s q (s = max|p_i|, q on the unit square/cube surface) goes to
//     x = s ((1 - b) q + b e(q)),   e(q) = normalise(tan(pi q_i / 4)),
// e being the equal-angle ("equiangular") projection of the square/cube surface onto the
// circle/sphere. The blend b is a constant b0 inside the inner block (0.4 for the disk,
// 0.6 for the ball, measured best; this makes the map there homogeneous of degree 1: the
// inner block is a uniformly rounded square/cube whose cells are alike up to scale) and
// rises to 1 at s = 1, where x = e(q) lies exactly on the circle/sphere. Rounding the
// inner block thickens the rings/shells at its corners, which a flat block would pinch
// (most in the ball: radius sqrt(3) s0 at its corners against s0 on the axes); across the
// rings/shells b rises so that the layers are evenly spaced both along the axes and
// along the diagonals. Worst tet quality 6 sqrt(2) V / l_rms^3 (1 for a regular tet,
// 0.657 for the Kuhn tets of a cube) with about cubic cells: cylinder 0.41 (radial 4),
// 0.42 (8), tending to 0.435; sphere 0.35 (8 cells across), 0.32 (16), tending to about
// 0.28; box with cubic cells 0.657.
//
// Resolution. A disk or ball with `across` cells across its diameter gets
//     m = max(1, (across + 2) / 4) rings/shells,  n = max(1, across - 2 m),
// so n + 2m = across from across >= 4 (3 for across = 2 or 3), s0 = n / (n + 2m). The
// circle is cut into 4n equal arcs (about 2 across), the sphere into 6 n^2 equal-angle
// quads, so boundary cells are about pi/2 times longer along the surface than thick.
// Vertex and tet counts:
//  - box:      (nx+1)(ny+1)(nz+1) vertices,           6 nx ny nz tets;
//  - cylinder: ((n+1)^2 + 4 n m)(axial+1) vertices,   6 (n^2 + 4 n m) axial tets,
//              with across = 2 radial;
//  - sphere:   (n+1)^3 + (6 n^2 + 2) m vertices,      6 (n^3 + 6 n^2 m) tets,
//              with across = cells;
//  - torus:    ((n+1)^2 + 4 n m) around vertices,     6 (n^2 + 4 n m) around tets,
//              with across = tube.
// The boundary vertices lie exactly (to rounding) on the analytic surface, so the
// volume is that of an inscribed polyhedron: it converges from below, O(h^2).
//
// Invalid arguments (a non-positive or non-finite size, a >= R, a count below its
// minimum, a mesh too large for index_t) throw InputError saying what was expected.
#include "softcontact/mesh.hpp"

namespace softcontact {

/// Axis-aligned box of size (lx,ly,lz) with (nx,ny,nz) hexahedral cells, each split
/// into 6 tets. A plate or membrane is a thin box.
TetMesh make_box(double lx, double ly, double lz, int nx, int ny, int nz);

/// Solid cylinder, axis z, radius r, height h; about `radial` cells across the radius
/// (>= 1) and `axial` along z (>= 1).
TetMesh make_cylinder(double r, double h, int radial, int axial);

/// Solid sphere of radius r with about `cells` cells across the diameter (>= 2).
TetMesh make_sphere(double r, int cells);

/// Solid torus in the xy plane (axis z): major radius R (centre of the tube), minor
/// radius a < R; `around` cells around the ring (>= 3), about `tube` cells across the
/// tube diameter (>= 2). The ring is closed: the vertices at angle 0 and 2 pi are one.
TetMesh make_torus(double R, double a, int around, int tube);

}  // namespace softcontact
