#pragma once
// Smoothed surface normals of a body at the current positions (Heidelberger et al. 2004,
// used by method.md "Penetration vectors" step 1): area-weighted vertex normals,
//     n_v = normalize( sum over surface triangles t incident to v of (x1 - x0) x (x2 - x0) ),
// (the cross product's length is twice the triangle's area, so the sum weights each
// face's unit normal by its area), and their interpolation at a point of a triangle with
// its barycentric coordinates b: n = normalize(b0 n_j + b1 n_k + b2 n_l).
#include <array>
#include <cstdint>

#include "collision_topology.hpp"
#include "vec3.hpp"

namespace softcontact::collide {

/// Writes n_v to normals[3v .. 3v + 2] for every surface vertex v of `object`, from the
/// incident triangles in ascending order (a fixed summation order). Where the sum
/// vanishes (all incident triangles degenerate, or cancelling) n_v is zero and counted
/// in `degenerate`. `face` (s,3), indexed by triangle row, receives the cross products
/// (x1 - x0) x (x2 - x0) of the object's triangles on the way (work space: each is
/// computed once, not once per corner).
void smoothed_vertex_normals(const double* x, const index_t* tri, const CollisionTopology& topo,
                             const ObjectInfo& object, double* face, double* normals, std::int64_t& degenerate);

/// The same n_v for one surface vertex v (zero where the sum vanishes).
V3 vertex_normal(const double* x, const index_t* tri, const CollisionTopology& topo, index_t v);

/// Vertex normals further than this from a triangle's own normal are replaced by the
/// triangle's normal when interpolating over it (sharp edges; smoothed_normals.cpp).
inline constexpr double kCreaseDegrees = 30.0;
inline constexpr double kCreaseCosine = 0.86602540378443865;  // cos(30 degrees)

/// Interpolated unit normal at the point with barycentric coordinates `bary` of surface
/// triangle `t`, with the crease rule above. Falls back to the triangle's own unit normal where the interpolation
/// vanishes (opposite vertex normals across a knife edge); zero only for a degenerate
/// triangle whose vertex normals also cancel.
V3 interpolated_normal(const double* x, const index_t* tri, const double* normals, index_t t,
                       const std::array<double, 3>& bary);

}  // namespace softcontact::collide
