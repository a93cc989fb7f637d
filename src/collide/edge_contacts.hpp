#pragma once
// Edge-edge contacts between bodies (docs/collision.md, "Edge contacts"; docs/contact.md
// gives the response). Vertex-in-tet detection sees a contact only once a vertex is
// inside another body; two surfaces that meet edge on edge cross without that. Per step,
// at x~:
//  1. candidate edges: the surface edges of owned objects whose box comes within the
//     skin s of another object's box; cut into pieces no longer than a grid cell, their
//     pieces' midpoints go into a uniform grid (the spatial hash of the vertex test,
//     spatial_hash.hpp);
//  2. every surface triangle of another object near a candidate asks the grid for the
//     pieces within half a cell plus s of its box, and keeps the (edge, triangle) pairs
//     that come within s of each other (boxes, the triangle's plane and side planes).
//     The pairs are kept over the next steps, until some vertex has moved s / 2 from
//     where they were found (a Verlet list: every pair that can cross by then is in
//     it). Every step each pair is tested exactly: a crossing is a strict sign change
//     of the edge's endpoints against the triangle's plane with the line through the
//     edge inside the triangle (three signed volumes of one sign);
//  3. per (edge e1 of A, body B), crossings in order along e1 pair up as (entering,
//     exiting); skipped when an endpoint of e1 is already a vertex collision with B (the
//     vertex response removes that overlap), except item 6;
//  4. a pair whose entry and exit triangles share an edge e2 of B is an edge-edge
//     contact (e1, e2): e1 cuts through B under e2. n is e1 x e2, turned to B's outside
//     (the sum of the two triangles' normals), P1 on e1 and P2 on e2 the closest points
//     of the two lines at parameters s and u, and the depth is n . (P2 - P1) > 0: e1
//     must move that far along n (or e2 back) for the two edges to touch instead of
//     crossing.
//  5. otherwise no record (counted as unpaired): the triangles share nothing (e1
//     passes through a fold of B's surface, or through a thin part of B), e1 and e2 are
//     parallel (aligned rims), the depth above is not positive, or item 7 finds none.
//     A rule for these that moved the middle of e1's inside part to the nearer triangle
//     was tried and made an aligned stack worse (docs/collision.md, "Edge contacts").
//  6. one end of e1 inside B (a vertex record) and one crossing, through T: where e1
//     passes under a rim edge e2 of T (T and its neighbour T' across e2 at 30 degrees or
//     more, convex), the part of e1 near e2 can be deeper than the end, which the vertex
//     response alone leaves crossing. A record as in item 4 for (e1, e2), taken only
//     when n points within 37 degrees of the end's own vertex record (else the two push
//     the end apart), and when the crossing is deeper than the end lies behind T'; of
//     T's edges, the one whose T' the end lies least far behind (at a box corner, the
//     bottom rather than a side). docs/collision.md, "Edge contacts", item 6.
//  7. the entry and exit triangles share only a vertex v of B, which is not inside A:
//     e1 passes under v, its chord between the two crossings behind the planes of v's
//     fan (the local tent of B at v). A record between e1 (weights from the point of e1
//     nearest to v) and v alone, moving the chord out by the smallest of: for each fan
//     plane, the distance that puts the whole chord in front of it; for the bisector of
//     the two crossed triangles, the distance that brings the chord's deepest point
//     under both onto their ridge. docs/collision.md, "Edge contacts", item 7.
// The record is a Collision whose point side is the edge (point a, point2 b, weights
// 1 - s and s) and whose "triangle" side is e2 (c, d, weights 1 - u and u; the third
// entry repeats c with weight 0), or for item 7 the vertex v alone ((v, v, v), weights
// (1, 0, 0)). The same interlock is usually found again from B's
// side (e2 through A's two triangles at e1), a mirror record with the same pushes on
// the same four vertices; the response's shares (docs/contact.md) split such a vertex
// two ways, so the pair is corrected once, not twice.
//
// Self-contact (EdgeSearchInput::self, with simulation.self_collisions): every surface
// edge of an owned object is a candidate against its own object's triangles too, except
// triangles that touch the star (the vertex and its mesh neighbours) of either end; an
// edge through the other side of a fold then pairs and records exactly as between two
// bodies (object == other_object), and the vertex self records skip it the same way.
//
// Keys: point_gid = gid(a), triangle_gid = global_triangles * (1 + gid(b)) + gid(T_in):
// never a real triangle's id, unique per (edge, entry triangle), independent of ranks.
#include <cstdint>
#include <tuple>
#include <vector>

#include "collision_topology.hpp"
#include "spatial_hash.hpp"
#include "softcontact/collision.hpp"

namespace softcontact::collide {

/// The surface edges of every object, built once: each edge of a surface triangle,
/// once, with the (one or two) surface triangles it borders.
struct SurfaceEdges {
  std::vector<index_t> a, b;               ///< endpoints (local), a < b
  std::vector<index_t> tri0, tri1;         ///< bordering surface triangles (rows of World::triangles); tri1 -1 if none
  std::vector<std::size_t> object_begin;   ///< edges of slot k: [object_begin[k], object_begin[k + 1])
  double max_length = 0;                   ///< longest edge at construction [m] (diagnostic)
};

SurfaceEdges build_surface_edges(const World& w, const CollisionTopology& topo);

struct EdgeCounters {
  std::int64_t crossings = 0;   ///< surface edge / surface triangle crossings between bodies
  std::int64_t contacts = 0;    ///< edge-edge records
  std::int64_t unpaired = 0;    ///< crossing pairs left without a record
};

/// What the vertex detector already computed this step (collision_detector.cpp).
struct EdgeSearchInput {
  const World* world = nullptr;
  const CollisionTopology* topo = nullptr;
  const SurfaceEdges* edges = nullptr;
  const std::uint8_t* bad_vertex = nullptr;                         ///< (n_local)
  const std::vector<Box>* object_box = nullptr;                     ///< per slot
  double cell_size = 0;
  /// Verlet skin [m] of the candidate pairs (docs/collision.md, "Edge contacts", item 2):
  /// the (edge, triangle) pairs whose boxes come within `skin` of each other are kept
  /// and only re-found once some vertex has moved skin / 2 from where they were found.
  /// 0: found again every step. The crossings are the same either way.
  double skin = 0;
  bool self = false;  ///< also edges through their own body's surface away from their ends' stars (self-contact)
};

class EdgeContactFinder {
public:
  /// Appends the edge-edge records to `out` (which holds this step's vertex records:
  /// edges with an endpoint among them, against the same body, are skipped). `out` is not
  /// re-sorted here.
  void find(const EdgeSearchInput& in, std::vector<Collision>& out, EdgeCounters& counters);

  /// Times the candidate pairs were found (the first call, and each time a vertex had
  /// moved half the skin, or the owned objects, the vertices or the settings changed).
  std::int64_t pair_searches() const { return pair_searches_; }
  /// Candidate (edge, triangle) pairs held now.
  std::size_t pair_count() const { return pairs_.size(); }

private:
  struct Pair {
    std::uint32_t edge;  // candidate index
    std::int32_t slot;   // object slot of the triangle
    index_t tri;         // row of World::triangles
  };
  bool pairs_valid(const EdgeSearchInput& in) const;
  void find_pairs(const EdgeSearchInput& in);

  struct Crossing {
    std::uint32_t edge;   // candidate index
    std::int32_t slot;    // object slot of the triangle
    index_t tri;          // row of World::triangles
    double t;             // parameter along the edge, a -> b
    bool entering;        // a on the triangle's outer side
  };
  SpatialHash grid_;
  std::vector<std::size_t> cand_;          // candidate edges (indices into SurfaceEdges)
  std::vector<std::int32_t> cand_slot_;
  std::vector<double> cand_pq_;            // candidates' endpoints (candidates, 6): contiguous for the tests
  std::vector<index_t> cand_index_;        // 0 .. pieces - 1
  std::vector<double> mid_;                // midpoints of the candidates' pieces (pieces, 3)
  std::vector<std::uint32_t> seg_edge_;    // candidate of each piece
  std::vector<std::int32_t> seg_slot_;     // object slot of each piece
  std::vector<double> piece_box_;          // box of each piece (pieces, 6: lo, hi)
  std::vector<double> sorted_box_;         // the same in the grid's order
  std::vector<std::uint32_t> sorted_edge_; // candidate of each piece, in the grid's order
  std::vector<Box> cand_box_;              // per slot: box of its candidate edges
  std::vector<Box> tri_box_;               // per slot: where its triangles can meet a candidate
  std::vector<std::vector<std::int32_t>> near_;  // per slot: the slots whose boxes come within the skin
  std::vector<std::int32_t> sweep_;
  std::vector<Pair> pairs_;                // candidate pairs, found at ref_x_, a run per triangle
  std::vector<std::size_t> run_begin_;     // the runs: [run_begin_[k], run_begin_[k + 1])
  std::vector<std::vector<Pair>> pair_buf_;
  std::vector<std::vector<std::uint32_t>> hits_;  // per thread: one triangle's candidates
  std::vector<double> ref_x_;              // positions (n_local, 3) the pairs were found at
  std::vector<std::uint8_t> ref_owned_;    // per slot: owned when they were found
  double ref_skin_ = -1, ref_cell_ = 0;
  bool ref_self_ = false;
  std::int64_t pair_searches_ = 0;
  std::vector<std::vector<Crossing>> buf_;
  std::vector<std::vector<std::uint32_t>> passed_;  // per thread: pieces that passed the box test, or pairs the plane test
  std::vector<std::vector<double>> volumes_;        // per thread: the pairs' signed volumes (one triangle's)
  std::vector<Crossing> crossings_;
  /// (point, other object, index in `out`) of the vertex records, sorted.
  std::vector<std::tuple<index_t, std::int32_t, std::size_t>> vertex_records_;
};

}  // namespace softcontact::collide
