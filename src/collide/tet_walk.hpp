#pragma once
// Where a segment that starts inside a body leaves it: a walk through the body's tets
// along the segment, from the tet that contains the start, face to face, until a face
// that is a surface triangle. It answers "which surface triangle does the border edge
// (i, k) cross" and "which triangle does the ray x~_i + s r_i cross" (method.md) with the
// same tets that decided that i is inside, and costs O(tets crossed), usually 1 to 3.
//
// In tet T with barycentric coordinates lambda_j (affine in position), the segment
// p + t (q - p) has lambda_j(t) = lambda_j(p) + t (lambda_j(q) - lambda_j(p)); it leaves T
// through the face j whose lambda_j reaches 0 first among those that decrease,
// t_j = lambda_j(p) / (lambda_j(p) - lambda_j(q)) (ties: lower j), never through the face
// it came in by. If no face is reached before t = 1, q is inside T: the segment ends
// inside the body. lambda_j = V_j / V is independent of T's orientation, so an inverted
// tet is walked like any other.
//
// The walk gives up (status failed) on a flat tet (|V| <= kFlatTet L^3), an open face,
// or after max_steps tets (a tangled mesh could make it cycle); callers then search the
// surface directly (surface_bvh.hpp).
#include <array>
#include <cstdint>

#include "vec3.hpp"

namespace softcontact::collide {

struct WalkResult {
  enum Status : std::uint8_t { exited, ended_inside, failed };
  Status status = failed;
  double t = 0;                    ///< exit parameter in [0, 1] (exited)
  index_t triangle = -1;           ///< surface triangle crossed (row of World::triangles)
  std::array<double, 3> bary{};    ///< crossing's barycentric coordinates in the triangle's vertex order
  int steps = 0;                   ///< tets visited
};

/// The planes of one tet as seen from a point p: outward face normals n_j and
/// (a_j - p) . n_j. All segments from p share them, so the border edges of a point
/// prepare its tet once (prepare_walk) and start their walks from it.
struct TetPlanes {
  index_t tet = -1;
  bool flat = true;  ///< |V| <= kFlatTet L^3: not walkable
  V3 n[4];
  double num[4];
};

/// `x` (n,3) positions, `tets` (m,4); `tet` a tet containing p; face `skip` (0..3, or
/// -1 for none) is left out: its normal is zero, so it is never a way out.
TetPlanes prepare_walk(const double* x, const index_t* tets, index_t tet, const V3& p, int skip = -1);

/// `x` (n,3) positions, `tets` (m,4), `face_neighbour` (m,4) as in CollisionTopology,
/// `tri` (s,3) the World's triangles; `start` prepared for p (a tet containing p).
WalkResult walk_to_surface(const double* x, const index_t* tets, const index_t* face_neighbour, const index_t* tri,
                           const TetPlanes& start, const V3& p, const V3& q, int max_steps);

/// The same from a tet index.
inline WalkResult walk_to_surface(const double* x, const index_t* tets, const index_t* face_neighbour,
                                  const index_t* tri, index_t start, const V3& p, const V3& q, int max_steps) {
  return walk_to_surface(x, tets, face_neighbour, tri, prepare_walk(x, tets, start, p), p, q, max_steps);
}

}  // namespace softcontact::collide
