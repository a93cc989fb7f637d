#pragma once
// Consistent penetration depth (Heidelberger et al. 2004, "Consistent Penetration Depth
// Estimation for Deformable Collision Response"; method.md "Penetration vectors" and
// "The collision (i, T_i) and the mapping H") for the points of one object A found inside
// one other object B.
//
//  1. Border edges: mesh edges (i, k) of A with i inside B and k not. The segment
//     x~_i -> x~_k is walked through B's tets from the tet holding i (tet_walk.hpp) to the
//     surface triangle where it leaves B; the crossing s_k and the smoothed normal n_k
//     there (smoothed_normals.hpp). An edge along which B is not left (k is an interior
//     vertex of A that is inside B too: only surface vertices are queried) is no border
//     edge.
//  2. Border points: w_k = 1 / |s_k - x~_i|^2,
//         D_i = sum_k w_k (s_k - x~_i) . n_k / sum_k w_k,   r_i = normalize(sum_k w_k n_k).
//  3. Propagation, breadth first over A's mesh edges between points inside B, one layer
//     at a time: every point of layer L+1 is computed from its neighbours in layers <= L
//     only (never from its own layer, so the order within a layer cannot matter):
//         mu_j = 1 / |x~_j - x~_i|^2,
//         D_i = sum_j mu_j ((x~_j - x~_i) . r_j + D_j) / sum_j mu_j,   r_i = normalize(sum_j mu_j r_j).
//  4. d_i = D_i r_i with D_i at least the distance s1 to the first exit of the ray
//     x~_i + s r_i from B: a point moved by d_i leaves B along r_i (the consistent depth
//     alone can be smaller than that near a curved or sharp part of B, leaving the point
//     inside, and it can be 0 or negative where crossings cancel).
//  5. A connected set of inside points that no border point reaches (a deep
//     intersection: the scheme has nothing to propagate), and a point whose ray finds no
//     exit, are resolved towards the side the point came from: if the segment from x~_i
//     back to x^t_i crosses B's surface an odd number of times (x^t_i was outside B), the
//     crossing nearest to x~_i is the point where it entered, and d_i leads there
//     (counted as entry records). Otherwise (x^t_i was inside B too, or no x^t is given)
//     d_i leads to the nearest surface triangle of B: d_i = (closest point) - x~_i; deep
//     sets are flagged and counted once per set. The nearest triangle can be the far side
//     of a thin body, which is why the entry rule goes first.
//  T_i is the surface triangle that the ray x~_i + s r_i crosses, the crossing nearest to
//  x~_i + d_i if there are several: the ray is walked through B to its first exit s1; only
//  if D_i > s1 can a later crossing (a re-entry into and exit from B, at s2 <= 2 D_i - s1)
//  be nearer, and the surface hierarchy is searched for it. omega: barycentric
//  coordinates of x~_i + d_i projected onto T_i, clamped, renormalised.
//
// Sums run over neighbours in ascending vertex order, so values do not depend on how the
// caller schedules the groups. Distances below `tiny` count as `tiny` (a point on B's
// surface gets D = 0 and r = n; a zero-length edge of A, counted as degenerate, weighs
// 1/tiny^2). No NaN or infinity leaves: every division is by a sum of positive weights,
// every normalisation has a fallback direction.
#include <cstdint>
#include <vector>

#include "collision_topology.hpp"
#include "surface_bvh.hpp"
#include "softcontact/collision.hpp"

namespace softcontact::collide {

/// A vertex of A inside B and the tet of B that holds it (the lowest such tet).
struct InsidePoint {
  index_t point;
  index_t tet;
};

struct DepthInput {
  const World* world = nullptr;            ///< gids, objects, tets, triangles
  const double* x = nullptr;               ///< x~ (n,3) [m]
  const double* x_start = nullptr;         ///< x^t, the step's start (n,3) [m], for the entry rule; may be null
  const CollisionTopology* topo = nullptr;
  const double* normals = nullptr;         ///< (n,3) smoothed vertex normals, valid on B's surface
  const SurfaceBvh* bvh = nullptr;         ///< per slot, refitted to x~ for B
  const Box* object_box = nullptr;         ///< per slot, at x~
  double tiny = 0;                         ///< [m]
  double check_depth = 0;                  ///< [m] consistent depths longer than this are checked against the way back and the nearest surface point
  int max_walk = 1000;                     ///< tets per walk before searching the hierarchy
};

struct DepthCounters {
  std::int64_t border_points = 0;
  std::int64_t deep_fallbacks = 0;         ///< sets of points, not points
  std::int64_t entry_records = 0;          ///< records resolved towards where the point entered
  std::int64_t redirected = 0;             ///< consistent depths replaced: by the way back (entry_records), the rested-on triangle or the nearest surface point
  std::int64_t nearest_records = 0;        ///< of those, by the nearest surface point
  std::int64_t resting_records = 0;        ///< of those, by the triangle x^t rested on
  std::int64_t degenerate = 0;
  std::int64_t surface_searches = 0;       ///< walks that failed and were replaced by a search of the hierarchy
};

/// Reusable per-thread work space.
struct DepthScratch {
  std::vector<std::size_t> in_begin, out_begin;
  std::vector<index_t> in_nb, out_nb;      // neighbours inside B (positions), outside (vertices)
  std::vector<int> layer;
  std::vector<double> depth;
  std::vector<V3> dir;
  std::vector<std::size_t> frontier, next;
  std::vector<SurfaceBvh::Hit> hits;
  std::vector<index_t> skip;               // self-contact: the point and its mesh neighbours
};

/// Penetration records of the points `pts` (ascending by point; all of one object A)
/// inside object slot `b`: out[k] for pts[k].
void penetration_depth(const DepthInput& in, std::int32_t b, const InsidePoint* pts, std::size_t count,
                       Collision* out, DepthCounters& counters, DepthScratch& s);

}  // namespace softcontact::collide
