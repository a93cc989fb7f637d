// CollisionDetector: the orchestration of steps 3 and 4 of Algorithm 1 (method.md).
// The algorithms live in their own files; docs/collision.md describes the whole.
//
// detect(), per step:
//   0. positions: non-finite vertices are set aside (counted); the largest step |x~ - x^t|
//   1. object boxes at x~ and the pairs of objects whose boxes overlap (sweep and prune
//      along x): each object's "partners"
//   2. query points: surface vertices inside a partner's box (with self-collisions on:
//      every surface vertex of every object); per object the box of the foreign query
//      points inside it, and per vertex its outcode against that box
//   3. spatial hash of the points (spatial_hash.hpp)
//   4. narrow phase per tet whose box can meet a foreign point: the points of the cells
//      its box overlaps, from other objects (for self-collisions also from its own
//      object, if not incident to it), tested with point_in_tet.hpp
//   5. inside pairs (point i of A, object B, lowest tet of B holding i), grouped by (A, B)
//   6. per penetrated B: smoothed normals and the surface hierarchy at x~; per group:
//      penetration vectors, T_i and weights (penetration_depth.hpp)
//   7. records sorted by (point_gid, triangle_gid)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "box_pairs.hpp"
#include "collision_topology.hpp"
#include "edge_contacts.hpp"
#include "mutual_records.hpp"
#include "parallel.hpp"
#include "penetration_depth.hpp"
#include "point_in_tet.hpp"
#include "self_culling.hpp"
#include "smoothed_normals.hpp"
#include "spatial_hash.hpp"
#include "surface_bvh.hpp"
#include "softcontact/collision.hpp"

namespace softcontact {

using namespace collide;

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

struct Hit {
  index_t point;
  index_t tet;
  bool operator<(const Hit& o) const { return point != o.point ? point < o.point : tet < o.tet; }
};

struct PairKey {
  std::int32_t a, b;  // slots of the point's object and of the penetrated object
  InsidePoint p;
  bool operator<(const PairKey& o) const {
    if (a != o.a) return a < o.a;
    if (b != o.b) return b < o.b;
    return p.point < o.p.point;
  }
};

// Per-thread tallies, combined in thread order (integer sums and maxima: exact, so the
// totals do not depend on the thread count).
struct ThreadCounts {
  std::int64_t degenerate = 0, nonfinite = 0, large = 0;
  double max_step = 0;
};

// The query points as the narrow phase reads them: point k is vertex point[k], at
// x + 3k, of object slot label[k]. The grid's sorted points, or the kept candidates'.
struct PointView {
  const double* x;
  const std::int32_t* label;
  const index_t* point;
};

// One tet against a set of query points (the points of grid cells, or the tet's kept
// candidates), in two passes: a tight, branch-free box test that only collects the
// passing points (most fail it, at random, and the own object's points are folded into
// the same test: a tet's box always holds some of them), then the exact test on the few
// collected.
struct TetCandidate {
  const World& w;
  const CollisionTopology& topo;
  bool self;
  index_t tet;
  std::int32_t slot;
  Box box;
  PointView pts;
  std::vector<std::uint32_t>& passed;  // point indices k, reused per thread
  // A tet of a ghost object meets no point of a delegated object (per slot): those are
  // found by the owners of the bodies they enter (CollisionDetector::delegate).
  bool ghost_tet = false;
  const std::uint8_t* delegated = nullptr;

  std::size_t count = 0;                // points collected so far (passed[0 .. count))

  [[gnu::always_inline]] inline bool inside_box(std::size_t k) const {
    const double* q = pts.x + 3 * k;
    return (q[0] >= box.lo[0]) & (q[0] <= box.hi[0]) & (q[1] >= box.lo[1]) & (q[1] <= box.hi[1]) &
           (q[2] >= box.lo[2]) & (q[2] <= box.hi[2]) & (self | (pts.label[k] != slot));
  }

  // Branch-free compaction: every point is written, the count advances for those that
  // pass. Points k0 .. k1-1.
  [[gnu::always_inline]] inline void collect(std::size_t k0, std::size_t k1) {
    if (passed.size() < count + (k1 - k0)) passed.resize(2 * (count + (k1 - k0)));
    std::uint32_t* outp = passed.data();
    std::size_t n = count;
    for (std::size_t k = k0; k < k1; ++k) {
      outp[n] = static_cast<std::uint32_t>(k);
      n += inside_box(k);
    }
    count = n;
  }

  // The same over a list of point indices.
  [[gnu::always_inline]] inline void collect_list(const std::uint32_t* ks, std::size_t nk) {
    if (passed.size() < count + nk) passed.resize(2 * (count + nk));
    std::uint32_t* outp = passed.data();
    std::size_t n = count;
    for (std::size_t q = 0; q < nk; ++q) {
      outp[n] = ks[q];
      n += inside_box(ks[q]);
    }
    count = n;
  }

  /// Exact tests of the collected points; false for a degenerate tet.
  bool finish(std::vector<Hit>& out) {
    if (count == 0) return true;
    const index_t* tv = &w.tets[4 * static_cast<std::size_t>(tet)];
    if (self) {
      // A self-tested tet's own corners are always in its box and never count (below):
      // dropped first, so that a tet with nothing else sets up no faces (most tets of a
      // self-tested object; chess500 spent 16 % of its step there).
      std::size_t n = 0;
      for (std::size_t q = 0; q < count; ++q) {
        const std::uint32_t k = passed[q];
        const index_t v = pts.point[k];
        passed[n] = k;
        n += (tv[0] != v) & (tv[1] != v) & (tv[2] != v) & (tv[3] != v);
      }
      count = n;
      if (count == 0) return true;
    }
    TetFaces faces;
    if (!faces.setup(w.x.data(), tv, topo.boundary_mask[static_cast<std::size_t>(tet)])) return false;
    const double* px = pts.x;
    for (std::size_t q = 0; q < count; ++q) {
      const std::uint32_t k = passed[q];
      const index_t v = pts.point[k];
      if (topo.vertex_slot[static_cast<std::size_t>(v)] == slot && (tv[0] == v || tv[1] == v || tv[2] == v || tv[3] == v))
        continue;  // own object (self-collisions only): a tet incident to v does not count
      if (ghost_tet && delegated[static_cast<std::size_t>(pts.label[k])]) continue;  // the tet's owner finds it
      if (faces.contains({px[3 * k], px[3 * k + 1], px[3 * k + 2]})) out.push_back({v, tet});
    }
    return true;
  }
};

// Outcode of a vertex with a non-finite position (the six side bits use bits 0..5).
constexpr std::uint8_t kBadVertex = 0x40;

// Distances below this fraction of the cell size count as zero in the depth weights.
constexpr double kTinyRelative = 1e-9;

}  // namespace

struct CollisionDetector::Impl {
  CollisionSettings settings;
  CollisionTopology topo;
  std::vector<SurfaceBvh> bvh;  // per slot
  SpatialHash grid;
  double thinnest = 0;          // smallest object thickness [m]

  // Step buffers, kept between steps so that a step allocates nothing once they have grown.
  std::vector<std::uint8_t> bad_vertex;
  std::vector<ThreadCounts> counts;
  std::vector<Box> object_box;
  std::vector<std::vector<std::int32_t>> partners;
  std::vector<std::int32_t> sweep;
  std::vector<std::uint8_t> object_active;
  std::vector<std::vector<index_t>> object_points;  // query points per object
  std::vector<index_t> query_points;
  std::vector<Box> point_box;                       // per object: box of its query points
  std::vector<Box> foreign_box;                     // per object
  std::vector<std::uint8_t> outcode;                // per vertex, against its object's foreign box
  std::vector<std::vector<Hit>> hit_buf;
  std::vector<std::vector<std::uint32_t>> passed_buf;
  std::vector<Hit> hits;
  std::vector<PairKey> pairs;
  std::vector<std::size_t> group_begin;
  std::vector<InsidePoint> group_points;    // pairs[q].p: each group's points as one ascending array
  std::vector<std::int32_t> penetrated;
  std::vector<double> normals;
  std::vector<double> face_normals;          // (s_local,3) work space of smoothed_vertex_normals
  std::vector<std::int64_t> normal_degenerate;
  std::vector<DepthCounters> group_counts;
  std::vector<DepthScratch> scratch;
  SurfaceEdges surface_edges;
  EdgeContactFinder edge_finder;
  SelfCulling culling;                      // with self-collisions: which objects can fold
  std::vector<std::uint8_t> self_active;    // per slot, this step
  std::vector<double> self_delta;           // per slot: distance from the best rigid motion [m]
  // Delegated objects (CollisionDetector::delegate): their points, owned or ghost, are
  // tested here against the owned objects' tets only.
  std::vector<std::int32_t> delegated_objects;  // global indices, ascending
  std::vector<std::uint8_t> delegated;      // per slot
  std::vector<std::uint8_t> owned;          // per slot: an object this rank owns
  std::vector<index_t> delegated_points;    // this call's points of delegated objects with a pair, ascending

  // Candidates kept across steps (docs/collision.md, "Candidates kept across steps"): per
  // tet, the query points that the grid found within `kept_skin` of its box at the
  // positions kept_x. While the objects have moved little relative to each other since
  // (kept_usable), they hold every point that can be in the tet's box now.
  struct KeptTet {
    index_t tet;
    std::uint32_t begin, count;  // its points: kept_k[begin .. begin + count)
  };
  bool kept_valid = false;
  double kept_skin = 0;                     // [m]
  std::vector<double> kept_x;               // (n_local, 3) at the search
  std::vector<std::uint8_t> kept_owned;     // per slot: owned at the search
  std::vector<std::vector<std::int32_t>> kept_partners;  // per slot: partners within the skin at the search
  std::vector<std::array<double, 6>> kept_move;          // per slot: centre and half-range of the moves since, per axis
  std::vector<index_t> kept_point;          // the query points, in grid order
  std::vector<std::int32_t> kept_label;     // their object slots
  std::vector<double> kept_px;              // their positions this step
  std::vector<KeptTet> kept_tets;
  std::vector<std::uint32_t> kept_k;        // indices into kept_point
  std::vector<std::vector<KeptTet>> kept_tet_buf;
  std::vector<std::vector<std::uint32_t>> kept_k_buf;
  bool any_bad = false;                     // a non-finite position this step

  bool from_rest = false;       // the hierarchies were built from rest positions given to the constructor

  Impl(const World& w, const CollisionSettings& s, const double* rest_x, SelfGapCache* gaps, Impl* previous);
  void detect(const World& w, const double* x_start, std::vector<Collision>& out, CollisionStats& st);

private:
  void scan_positions(const World& w, const double* x_start, CollisionStats& st);
  void object_boxes(const double* x);
  void find_partners(double grow);
  void select_points(const World& w, double grow);
  void narrow_phase(const World& w, CollisionStats& st, double skin);
  bool kept_usable(const World& w);
  void narrow_kept(const World& w, CollisionStats& st);
  void group_pairs(const World& w, CollisionStats& st);
  bool away_from_star(const World& w, index_t v, index_t t) const;
  void depth(const World& w, const double* x_start, std::vector<Collision>& out, CollisionStats& st);
};

CollisionDetector::Impl::Impl(const World& w, const CollisionSettings& s, const double* rest_x, SelfGapCache* gaps,
                              Impl* previous)
    : settings(s), topo(build_collision_topology(w, previous ? &previous->topo : nullptr)), from_rest(rest_x != nullptr) {
  if (settings.edge_contacts) surface_edges = build_surface_edges(w, topo);
  if (settings.self_collisions) culling.build(w, topo, rest_x ? rest_x : w.x.data(), gaps);
  double h = settings.cell_size > 0 ? settings.cell_size : topo.mean_edge_length;
  if (!(h > 0) || !std::isfinite(h)) h = 1;  // no edges at all: any size works
  grid.set_cell_size(h);
  bvh.resize(topo.objects.size());
  // An object the previous detector held alike keeps its tree, when both were built from
  // the rest positions (the same ones: the scene's).
  const std::vector<std::int32_t> from = previous && previous->from_rest && from_rest
                                             ? matching_slots(topo, previous->topo)
                                             : std::vector<std::int32_t>(topo.objects.size(), -1);
  for (std::size_t k = 0; k < topo.objects.size(); ++k) {
    // The tree's shape (and so the order of its search results) depends on the positions
    // it is built from: the rest positions, whenever the detector is built.
    const ObjectInfo& o = topo.objects[k];
    if (from[k] >= 0 && !o.triangles.empty()) {
      const auto j = static_cast<std::size_t>(from[k]);
      bvh[k] = std::move(previous->bvh[j]);
      bvh[k].shift_triangles(o.triangles.front() - previous->topo.objects[j].triangles.front());
    } else {
      bvh[k].build(rest_x ? rest_x : w.x.data(), w.triangles.data(), o.triangles);
    }
    const double t = topo.objects[k].thickness;
    if (t > 0 && (thinnest == 0 || t < thinnest)) thinnest = t;
  }
}

// Step 0: non-finite positions and the largest step.
void CollisionDetector::Impl::scan_positions(const World& w, const double* x_start, CollisionStats& st) {
  const std::size_t n = w.n_local();
  const double* x = w.x.data();
  bad_vertex.resize(n);
  counts.assign(static_cast<std::size_t>(max_threads()), ThreadCounts{});
  parallel_for(n, [&](std::size_t v, int t) {
    ThreadCounts& c = counts[static_cast<std::size_t>(t)];
    const V3 p = load(x, static_cast<index_t>(v));
    bad_vertex[v] = finite(p) ? 0 : 1;
    if (bad_vertex[v]) {
      ++c.nonfinite;
      return;
    }
    if (x_start) {
      const V3 q = load(x_start, static_cast<index_t>(v));
      const double step = std::sqrt(norm2(p - q));
      if (step > c.max_step) c.max_step = step;  // false for a non-finite x^t: ignored
    }
  });
  double max_step = 0;
  any_bad = false;
  for (const ThreadCounts& c : counts) {
    st.degenerate_skipped += c.nonfinite;
    any_bad = any_bad || c.nonfinite > 0;
    max_step = std::max(max_step, c.max_step);
  }
  st.max_step_over_thickness = thinnest > 0 ? max_step / thinnest : 0;
}

// Step 1: object boxes (the depth and the edge search use them too), ...
void CollisionDetector::Impl::object_boxes(const double* x) {
  const std::size_t no = topo.objects.size();
  object_box.resize(no);
  parallel_for(no, [&](std::size_t k, int) {
    Box b;
    b.reset();
    for (index_t v : topo.objects[k].vertices)
      if (!bad_vertex[static_cast<std::size_t>(v)]) b.add(load(x, v));
    object_box[k] = b;
  });
}

// ... and the pairs whose boxes come within 2 grow of each other: sort by the boxes'
// lower x, then each object meets only the objects that start before it ends.
void CollisionDetector::Impl::find_partners(double grow) {
  overlapping_boxes(
      object_box, grow, [&](std::size_t k) { return !topo.objects[k].triangles.empty(); }, partners, sweep);
}

// Step 2: the query points, owned surface vertices inside the box of a partner object
// (all owned surface vertices of objects with partners, with self-collisions on), and per object B
// a box holding the other objects' query points inside B's box: a tet of B whose box
// misses it cannot hold any of them. With grow > 0 (a search for kept candidates) the
// partners' boxes are grown by `grow` for the first test, and the foreign box holds the
// points within `grow` of B's box, grown by `grow`: a tet's box grown by `grow` misses
// it only when it holds none of them.
void CollisionDetector::Impl::select_points(const World& w, double grow) {
  const double* x = w.x.data();
  const std::size_t no = topo.objects.size();
  object_active.assign(no, 0);
  for (std::size_t k = 0; k < no; ++k)
    object_active[k] = (self_active[k] || !partners[k].empty()) && !object_box[k].empty() ? 1 : 0;
  object_points.resize(no);
  point_box.resize(no);
  parallel_for(no, [&](std::size_t k, int) {
    object_points[k].clear();
    point_box[k].reset();
    // Only owned points are queried: a ghost object's points are its owner's to query,
    // but for a delegated object's, which are queried against the owned objects here
    // (and its owned points only against those too).
    if (!object_active[k] || (!owned[k] && !delegated[k])) return;
    for (index_t v : topo.objects[k].surface_vertices) {
      if (bad_vertex[static_cast<std::size_t>(v)]) continue;
      const V3 p = load(x, v);
      bool take = self_active[k] != 0;
      for (std::size_t q = 0; !take && q < partners[k].size(); ++q) {
        if (delegated[k] && !owned[static_cast<std::size_t>(partners[k][q])]) continue;
        const Box& b = object_box[static_cast<std::size_t>(partners[k][q])];
        take = grow > 0 ? grown(b, grow).contains(p) : b.contains(p);
      }
      if (!take) continue;
      object_points[k].push_back(v);
      point_box[k].add(p);
    }
  });
  query_points.clear();
  for (const auto& pts : object_points) query_points.insert(query_points.end(), pts.begin(), pts.end());
  std::sort(query_points.begin(), query_points.end());  // ascending whatever the World's object order

  foreign_box.resize(no);
  outcode.resize(w.n_local());
  parallel_for(no, [&](std::size_t b, int) {
    // The union over partners A of (box of A's query points) cut to B's box: it holds
    // every foreign point that can be inside B, at O(partners) cost.
    Box fb;
    fb.reset();
    const Box reach = grown(object_box[b], grow);
    if (self_active[b]) {
      fb = reach;  // its own points may be inside it too
    } else if (object_active[b]) {
      for (std::int32_t a : partners[b]) {
        if (!owned[b] && delegated[static_cast<std::size_t>(a)]) continue;  // not tested against a ghost
        const Box& pa = point_box[static_cast<std::size_t>(a)];
        if (pa.empty() || !pa.overlaps(reach)) continue;
        fb.add(pa.intersection(reach));
      }
    }
    fb = grown(fb, grow);
    foreign_box[b] = fb;
    // Outcodes of the object's vertices against that box (bit per side, as in
    // Cohen-Sutherland clipping): a tet's box misses the box exactly when some bit is set
    // in all four of its vertices' codes, which spares computing the boxes of tets far
    // from any foreign point.
    for (index_t v : topo.objects[b].vertices) {
      const auto i = static_cast<std::size_t>(v);
      if (bad_vertex[i]) {
        outcode[i] = kBadVertex;
        continue;
      }
      const V3 p = load(x, v);
      std::uint8_t c = 0;
      for (int d = 0; d < 3; ++d) {
        c |= static_cast<std::uint8_t>((p[d] < fb.lo[d] ? 1u : 0u) << (2 * d));
        c |= static_cast<std::uint8_t>((p[d] > fb.hi[d] ? 1u : 0u) << (2 * d + 1));
      }
      outcode[i] = c;
    }
  });
}

// Steps 3 and 4: the points go into the grid; every tet of an active object whose box
// can meet a foreign point (outcodes) asks the grid for the points of the cells its box
// overlaps, keeps those inside its box and of another object (TetCandidate::collect),
// and tests them exactly (TetCandidate::finish). Tets are independent: each thread
// appends to its own hit buffer, and the hits are sorted afterwards.
// With skin > 0 the tets' boxes are grown by the skin and the points collected are kept
// as each tet's candidates (kept_tets, kept_k) instead of being tested: narrow_kept()
// tests them, in this step and in the following ones while they stay valid.
void CollisionDetector::Impl::narrow_phase(const World& w, CollisionStats& st, double skin) {
  const double* x = w.x.data();
  grid.insert_points(x, query_points, topo.vertex_slot.data());
  const PointView pts{grid.sorted_x(), grid.sorted_label(), grid.sorted_point()};
  reset_buffers(hit_buf);
  reset_buffers(kept_tet_buf);
  reset_buffers(kept_k_buf);
  passed_buf.resize(static_cast<std::size_t>(max_threads()));
  counts.assign(static_cast<std::size_t>(max_threads()), ThreadCounts{});
  const std::size_t m = w.tets.size() / 4;
  parallel_for(m, [&](std::size_t e, int t) {
    const std::int32_t slot = topo.tet_slot[e];
    if (!object_active[static_cast<std::size_t>(slot)]) return;
    const index_t* tv = &w.tets[4 * e];
    const std::uint8_t c0 = outcode[static_cast<std::size_t>(tv[0])], c1 = outcode[static_cast<std::size_t>(tv[1])],
                       c2 = outcode[static_cast<std::size_t>(tv[2])], c3 = outcode[static_cast<std::size_t>(tv[3])];
    if (((c0 | c1 | c2 | c3) & kBadVertex) || (c0 & c1 & c2 & c3)) return;  // non-finite, or far from foreign points
    Box box;
    box.reset();
    for (int c = 0; c < 4; ++c) box.add(load(x, tv[c]));
    if (skin > 0) box = grown(box, skin);
    const CellRange r = grid.range_of(box);
    if (r.empty()) return;
    auto& passed = passed_buf[static_cast<std::size_t>(t)];
    TetCandidate cand{w, topo, self_active[static_cast<std::size_t>(slot)] != 0, static_cast<index_t>(e), slot, box, pts,
                      passed, !owned[static_cast<std::size_t>(slot)], delegated.data()};
    if (r.count() > static_cast<double>(grid.num_points())) {
      // A box spanning more cells than there are points (a tet stretched far by a
      // blown-up simulation): cheaper to test every point than to visit the cells.
      ++counts[static_cast<std::size_t>(t)].large;
      cand.collect(0, grid.num_points());
    } else {
      grid.for_each_run(r, [&](std::size_t k0, std::size_t k1) { cand.collect(k0, k1); });
    }
    if (skin > 0) {
      if (cand.count == 0) return;
      auto& kt = kept_tet_buf[static_cast<std::size_t>(t)];
      auto& kk = kept_k_buf[static_cast<std::size_t>(t)];
      kt.push_back({static_cast<index_t>(e), static_cast<std::uint32_t>(kk.size()), static_cast<std::uint32_t>(cand.count)});
      kk.insert(kk.end(), passed.begin(), passed.begin() + static_cast<std::ptrdiff_t>(cand.count));
      return;
    }
    if (!cand.finish(hit_buf[static_cast<std::size_t>(t)])) ++counts[static_cast<std::size_t>(t)].degenerate;
  });
  for (const ThreadCounts& c : counts) {
    st.degenerate_skipped += c.degenerate;
    st.large_tets += c.large;
  }
  if (skin > 0) {
    // The candidates, as one list in thread order (tet order), with the positions and the
    // state they were found at.
    kept_tets.clear();
    kept_k.clear();
    for (std::size_t t = 0; t < kept_tet_buf.size(); ++t) {
      const auto base = static_cast<std::uint32_t>(kept_k.size());
      for (KeptTet k : kept_tet_buf[t]) kept_tets.push_back({k.tet, k.begin + base, k.count});
      kept_k.insert(kept_k.end(), kept_k_buf[t].begin(), kept_k_buf[t].end());
    }
    kept_point.assign(grid.sorted_point(), grid.sorted_point() + grid.num_points());
    kept_label.assign(grid.sorted_label(), grid.sorted_label() + grid.num_points());
    kept_x.assign(x, x + 3 * w.n_local());
    kept_partners = partners;
    kept_owned.resize(topo.objects.size());
    for (std::size_t k = 0; k < topo.objects.size(); ++k) kept_owned[k] = w.owns_object(topo.objects[k].object) ? 1 : 0;
    kept_valid = kept_k.size() < (std::size_t{1} << 31);  // indices are 32-bit
    return;
  }
  hits.clear();
  concatenate(hit_buf, hits);
  std::sort(hits.begin(), hits.end());  // (point, tet): independent of the schedule
}

// The kept candidates still hold every point that can be in a tet's box (and they are
// then used) when the positions are finite, the owned objects are those of the search,
// and the objects moved little relative to each other. Per object A and axis, the moves of its vertices since the search lie in
// c_A +- r_A. A point p of A inside the box of a tet T of B now was then inside T's box
// grown by |c_B - c_A| + r_A + r_B (T's box moved by c_B +- r_B, p by c_A +- r_A), and within
// as much of B's box: covered by the search's skin s when that sum is at most s for every
// pair of partners at the search, and when every pair of
// objects whose boxes overlap now were partners then (docs/collision.md). Falling objects
// thus keep their candidates while they fall, as long as they fall together.
bool CollisionDetector::Impl::kept_usable(const World& w) {
  const std::size_t n = w.n_local(), no = topo.objects.size();
  if (!kept_valid || any_bad || kept_x.size() != 3 * n || kept_owned.size() != no) return false;
  for (std::size_t k = 0; k < no; ++k)
    if (kept_owned[k] != (w.owns_object(topo.objects[k].object) ? 1 : 0)) return false;
  const double* x = w.x.data();
  kept_move.resize(no);
  parallel_for(no, [&](std::size_t k, int) {
    constexpr double inf = std::numeric_limits<double>::infinity();
    double lo[3] = {inf, inf, inf}, hi[3] = {-inf, -inf, -inf};
    for (index_t v : topo.objects[k].vertices)
      for (int d = 0; d < 3; ++d) {
        const std::size_t i = 3 * static_cast<std::size_t>(v) + static_cast<std::size_t>(d);
        const double m = x[i] - kept_x[i];
        lo[d] = m < lo[d] ? m : lo[d];
        hi[d] = m > hi[d] ? m : hi[d];
      }
    for (int d = 0; d < 3; ++d) {
      if (topo.objects[k].vertices.empty()) lo[d] = hi[d] = 0;
      kept_move[k][static_cast<std::size_t>(d)] = 0.5 * (lo[d] + hi[d]);
      kept_move[k][3 + static_cast<std::size_t>(d)] = 0.5 * (hi[d] - lo[d]);
    }
  });
  const double s = kept_skin;
  for (std::size_t a = 0; a < no; ++a) {
    const auto& ma = kept_move[a];
    for (std::int32_t b : kept_partners[a]) {
      const auto& mb = kept_move[static_cast<std::size_t>(b)];
      for (std::size_t d = 0; d < 3; ++d)
        if (!(std::abs(mb[d] - ma[d]) + ma[3 + d] + mb[3 + d] <= s)) return false;
    }
  }
  // No new pair of overlapping objects.
  find_partners(0);
  for (std::size_t a = 0; a < no; ++a)
    for (std::int32_t b : partners[a])
      if (!std::binary_search(kept_partners[a].begin(), kept_partners[a].end(), b)) return false;
  return true;
}

// Steps 3 and 4 on the kept candidates: each tet's box at x against its candidates'
// positions at x, then the exact test, as in narrow_phase.
void CollisionDetector::Impl::narrow_kept(const World& w, CollisionStats& st) {
  const double* x = w.x.data();
  kept_px.resize(3 * kept_point.size());
  parallel_for(kept_point.size(), [&](std::size_t k, int) {
    for (int d = 0; d < 3; ++d) kept_px[3 * k + static_cast<std::size_t>(d)] = x[3 * static_cast<std::size_t>(kept_point[k]) + static_cast<std::size_t>(d)];
  });
  const PointView pts{kept_px.data(), kept_label.data(), kept_point.data()};
  reset_buffers(hit_buf);
  passed_buf.resize(static_cast<std::size_t>(max_threads()));
  counts.assign(static_cast<std::size_t>(max_threads()), ThreadCounts{});
  parallel_for(kept_tets.size(), [&](std::size_t q, int t) {
    const KeptTet& kt = kept_tets[q];
    const auto e = static_cast<std::size_t>(kt.tet);
    const std::int32_t slot = topo.tet_slot[e];
    const index_t* tv = &w.tets[4 * e];
    Box box;
    box.reset();
    for (int c = 0; c < 4; ++c) box.add(load(x, tv[c]));
    TetCandidate cand{w, topo, self_active[static_cast<std::size_t>(slot)] != 0, kt.tet, slot, box, pts,
                      passed_buf[static_cast<std::size_t>(t)], !owned[static_cast<std::size_t>(slot)], delegated.data()};
    cand.collect_list(kept_k.data() + kt.begin, kt.count);
    if (!cand.finish(hit_buf[static_cast<std::size_t>(t)])) ++counts[static_cast<std::size_t>(t)].degenerate;
  });
  for (const ThreadCounts& c : counts) st.degenerate_skipped += c.degenerate;
  hits.clear();
  concatenate(hit_buf, hits);
  std::sort(hits.begin(), hits.end());  // (point, tet): independent of the schedule
}

// Tet `t` shares no vertex with v or v's mesh neighbours.
bool CollisionDetector::Impl::away_from_star(const World& w, index_t v, index_t t) const {
  const auto u = static_cast<std::size_t>(v);
  const auto nb0 = topo.edge_to.begin() + static_cast<std::ptrdiff_t>(topo.edge_begin[u]);
  const auto nb1 = topo.edge_to.begin() + static_cast<std::ptrdiff_t>(topo.edge_begin[u + 1]);
  for (int c = 0; c < 4; ++c) {
    const index_t q = w.tets[4 * static_cast<std::size_t>(t) + static_cast<std::size_t>(c)];
    if (q == v || std::binary_search(nb0, nb1, q)) return false;
  }
  return true;
}

// Step 5: (point, other object) pairs with the lowest tet holding the point; groups of
// equal (A, B). With self-collisions on, a point inside its own object away from its
// star makes an (A, A) pair too: self-contact.
void CollisionDetector::Impl::group_pairs(const World& w, CollisionStats& st) {
  pairs.clear();
  index_t last_self = -1;
  for (const Hit& h : hits) {
    const std::int32_t a = topo.vertex_slot[static_cast<std::size_t>(h.point)];
    const std::int32_t b = topo.tet_slot[static_cast<std::size_t>(h.tet)];
    if (a == b) {
      // Self-contact: only a tet that shares no vertex with the point's star (the point
      // and its mesh neighbours) is the other side of a fold; a tet next to the star
      // holds the point only where elements around it are inverted.
      if (h.point == last_self || !away_from_star(w, h.point, h.tet)) continue;
      ++st.self_collisions;
      last_self = h.point;
    }
    // Hits of one point are sorted by tet: the first of each object is its lowest tet.
    bool seen = false;
    for (std::size_t q = pairs.size(); q-- > 0 && pairs[q].p.point == h.point;)
      if (pairs[q].b == b) seen = true;
    if (!seen) pairs.push_back({a, b, {h.point, h.tet}});
  }
  // Distinct points among the pairs (still sorted by point here); a delegated object's
  // are listed instead, for its owner to count once over the ranks that found them.
  delegated_points.clear();
  for (std::size_t q = 0; q < pairs.size(); ++q) {
    if (q > 0 && pairs[q].p.point == pairs[q - 1].p.point) continue;
    if (delegated[static_cast<std::size_t>(pairs[q].a)])
      delegated_points.push_back(pairs[q].p.point);
    else
      ++st.colliding_points;
  }
  std::sort(pairs.begin(), pairs.end());
  group_points.resize(pairs.size());
  for (std::size_t q = 0; q < pairs.size(); ++q) group_points[q] = pairs[q].p;
  group_begin.clear();
  for (std::size_t q = 0; q < pairs.size(); ++q)
    if (q == 0 || pairs[q].a != pairs[q - 1].a || pairs[q].b != pairs[q - 1].b) group_begin.push_back(q);
  group_begin.push_back(pairs.size());
}

// Step 6 and 7.
void CollisionDetector::Impl::depth(const World& w, const double* x_start, std::vector<Collision>& out,
                                    CollisionStats& st) {
  const double* x = w.x.data();
  const std::size_t ngroups = group_begin.size() - 1;
  penetrated.clear();
  for (std::size_t g = 0; g < ngroups; ++g) penetrated.push_back(pairs[group_begin[g]].b);
  std::sort(penetrated.begin(), penetrated.end());
  penetrated.erase(std::unique(penetrated.begin(), penetrated.end()), penetrated.end());

  // Normals and hierarchies of the penetrated objects at x~ (each object writes its own).
  normals.resize(3 * w.n_local());
  face_normals.resize(w.triangles.size());
  normal_degenerate.assign(penetrated.size(), 0);
  parallel_for_dynamic(penetrated.size(), [&](std::size_t k, int) {
    const auto b = static_cast<std::size_t>(penetrated[k]);
    smoothed_vertex_normals(x, w.triangles.data(), topo, topo.objects[b], face_normals.data(), normals.data(),
                            normal_degenerate[k]);
    bvh[b].refit(x, w.triangles.data());
  });
  for (std::int64_t d : normal_degenerate) st.degenerate_skipped += d;

  DepthInput in;
  in.world = &w;
  in.x = x;
  in.x_start = x_start;
  in.topo = &topo;
  in.normals = normals.data();
  in.bvh = bvh.data();
  in.object_box = object_box.data();
  in.tiny = kTinyRelative * grid.cell_size();
  in.check_depth = 0.02 * grid.cell_size();

  out.assign(pairs.size(), Collision{});
  group_counts.assign(ngroups, DepthCounters{});
  scratch.resize(static_cast<std::size_t>(max_threads()));
  // Groups have very different sizes: dynamic schedule; each writes its own records.
  parallel_for_dynamic(ngroups, [&](std::size_t g, int t) {
    const std::size_t q0 = group_begin[g], q1 = group_begin[g + 1];
    penetration_depth(in, pairs[q0].b, group_points.data() + q0, q1 - q0, out.data() + q0, group_counts[g],
                      scratch[static_cast<std::size_t>(t)]);
  });
  for (const DepthCounters& c : group_counts) {
    st.border_points += c.border_points;
    st.deep_fallbacks += c.deep_fallbacks;
    st.entry_records += c.entry_records;
    st.redirected_depths += c.redirected;
    st.nearest_records += c.nearest_records;
    st.resting_records += c.resting_records;
    st.degenerate_skipped += c.degenerate;
    st.surface_searches += c.surface_searches;
  }
  // Last line of defence: nothing non-finite leaves (every path above is finite for
  // finite input; this catches overflow from absurd but finite coordinates), and records
  // without a triangle (non-finite positions) are dropped.
  const std::size_t before = out.size();
  out.erase(std::remove_if(out.begin(), out.end(), [](const Collision& c) { return c.triangle_gid < 0; }), out.end());
  st.degenerate_skipped += static_cast<std::int64_t>(before - out.size());
  for (Collision& c : out) {
    bool ok = true;
    for (int d = 0; d < 3; ++d) ok = ok && std::isfinite(c.depth[d]) && std::isfinite(c.weight[d]);
    if (!ok) {
      c.depth = {0, 0, 0};
      c.weight = {1.0 / 3, 1.0 / 3, 1.0 / 3};
      ++st.degenerate_skipped;
    }
  }
  if (settings.edge_contacts) {
    EdgeSearchInput ein;
    ein.world = &w;
    ein.topo = &topo;
    ein.edges = &surface_edges;
    ein.bad_vertex = bad_vertex.data();
    ein.object_box = &object_box;
    ein.cell_size = grid.cell_size();
    ein.skin = settings.edge_skin * grid.cell_size();
    ein.self = settings.self_collisions;
    EdgeCounters ec;
    const std::int64_t searches = edge_finder.pair_searches();
    edge_finder.find(ein, out, ec);
    st.edge_pairs = static_cast<std::int64_t>(edge_finder.pair_count());
    st.edge_pair_searches = edge_finder.pair_searches() - searches;
    st.edge_crossings = ec.crossings;
    st.edge_contacts = ec.contacts;
    st.edge_unpaired = ec.unpaired;
  }
  std::sort(out.begin(), out.end(), record_order);
  st.collisions = static_cast<std::int64_t>(out.size());
}

void CollisionDetector::Impl::detect(const World& w, const double* x_start, std::vector<Collision>& out,
                                     CollisionStats& st) {
  st = CollisionStats{};
  const auto t0 = std::chrono::steady_clock::now();
  const std::size_t no = topo.objects.size();
  owned.resize(no);
  delegated.resize(no);
  for (std::size_t k = 0; k < no; ++k) {
    const std::int32_t o = topo.objects[k].object;
    owned[k] = w.owns_object(o) ? 1 : 0;
    delegated[k] = std::binary_search(delegated_objects.begin(), delegated_objects.end(), o) ? 1 : 0;
  }
  scan_positions(w, x_start, st);
  if (settings.self_collisions) {
    // A ghost's self-contact is its owner's: its points never meet its own tets here, and
    // its fit to a rigid motion is not computed.
    culling.update(w.x.data(), topo, bad_vertex.data(), owned.data(), self_active, self_delta);
    if (!settings.self_culling) self_active.assign(topo.objects.size(), 1);
    for (std::size_t k = 0; k < no; ++k) self_active[k] = owned[k] ? self_active[k] : 0;
    for (std::uint8_t a : self_active) st.self_objects += a;
  } else {
    self_active.assign(topo.objects.size(), 0);
  }
  // The query: on the kept candidates while they are valid, else a search of the grid
  // (with a skin: one that keeps its candidates for the next steps).
  object_boxes(w.x.data());
  // Self-contact: every step searches. Objects start and stop being self-tested often
  // (self culling), and a self-tested tet's own points made the kept lists long: chess500
  // poured took 17.9 ms of detection per step with kept candidates against 12.9 without
  // (docs/benchmarks.md, "Candidates kept across steps").
  const bool keep = settings.point_skin > 0 && !settings.self_collisions;
  if (keep && kept_usable(w)) {
    narrow_kept(w, st);
  } else {
    double skin = 0;
    if (keep) {
      // The skin, and a margin for the rounding of the grown boxes and of the moves
      // compared with half of it: a few ulps of the largest coordinate.
      double big = 0;
      for (double c : w.x) big = std::max(big, std::abs(c));
      kept_skin = settings.point_skin * grid.cell_size();
      skin = kept_skin + 16 * std::numeric_limits<double>::epsilon() * big;
      st.point_searches = 1;
    }
    find_partners(0.5 * skin);
    select_points(w, skin);
    narrow_phase(w, st, skin);
    if (skin > 0) narrow_kept(w, st);
  }
  group_pairs(w, st);
  st.detection_seconds = seconds_since(t0);
  const auto t1 = std::chrono::steady_clock::now();
  depth(w, x_start, out, st);
  st.depth_seconds = seconds_since(t1);
}

CollisionDetector::CollisionDetector(const World& world, const CollisionSettings& settings, const double* rest_x,
                                     SelfGapCache* gaps, CollisionDetector* previous)
    : impl_(std::make_unique<Impl>(world, settings, rest_x, gaps, previous ? previous->impl_.get() : nullptr)) {}
CollisionDetector::~CollisionDetector() = default;
CollisionDetector::CollisionDetector(CollisionDetector&&) noexcept = default;
CollisionDetector& CollisionDetector::operator=(CollisionDetector&&) noexcept = default;

void CollisionDetector::detect(const World& world, const double* x_start, std::vector<Collision>& out,
                               CollisionStats& stats) {
  impl_->detect(world, x_start, out, stats);
}

void CollisionDetector::delegate(std::vector<std::int32_t> objects) {
  std::sort(objects.begin(), objects.end());
  objects.erase(std::unique(objects.begin(), objects.end()), objects.end());
  impl_->delegated_objects = std::move(objects);
  impl_->kept_valid = false;
}

const std::vector<index_t>& CollisionDetector::delegated_points() const { return impl_->delegated_points; }

void CollisionDetector::record_keys(const World& world, const std::vector<Collision>& records,
                                    std::vector<RecordKey>& keys) {
  collide::mutual_record_keys(world, records, kMutualWeight, keys);
}

std::int64_t CollisionDetector::settle_mutual(const World& world, std::vector<Collision>& records,
                                              std::vector<RecordKey>& keys) {
  return collide::settle_mutual_pairs(world, impl_->topo, records, keys, kMutualWeight);
}

}  // namespace softcontact
