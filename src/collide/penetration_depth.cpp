#include "penetration_depth.hpp"

#include <algorithm>
#include <cmath>

#include "smoothed_normals.hpp"
#include "tet_walk.hpp"
#include "triangle_queries.hpp"

namespace softcontact::collide {

namespace {

bool is_zero(const V3& a) { return a[0] == 0 && a[1] == 0 && a[2] == 0; }

// Position of vertex v among the (ascending) points, or -1.
std::ptrdiff_t position_of(const InsidePoint* pts, std::size_t n, index_t v) {
  const InsidePoint* it = std::lower_bound(pts, pts + n, v, [](const InsidePoint& p, index_t u) { return p.point < u; });
  return it != pts + n && it->point == v ? it - pts : -1;
}

// A walk that left B through a skipped triangle (self-contact: the point's own
// neighbourhood) counts as failed: the hierarchy, which skips them, decides.
bool usable(const WalkResult& r, const index_t* tri, const SkipVertices& skip) {
  return r.status != WalkResult::failed &&
         !(r.status == WalkResult::exited && skip.touches(tri + 3 * static_cast<std::size_t>(r.triangle)));
}

// Where the border edge p -> q leaves B: the tet walk, or (walk failed) the first
// crossing with B's surface, ties to the lower triangle.
WalkResult border_crossing(const DepthInput& in, const SurfaceBvh& bvh, const TetPlanes& start, const V3& p,
                           const V3& q, DepthCounters& c, DepthScratch& s, const SkipVertices& skip) {
  const World& w = *in.world;
  WalkResult r = walk_to_surface(in.x, w.tets.data(), in.topo->face_neighbour.data(), w.triangles.data(), start, p, q,
                                 in.max_walk);
  if (usable(r, w.triangles.data(), skip)) return r;
  r = WalkResult{};
  ++c.surface_searches;
  s.hits.clear();
  bvh.segment_hits(in.x, w.triangles.data(), p, q, s.hits, c.degenerate, skip);
  for (const SurfaceBvh::Hit& h : s.hits)
    if (r.status != WalkResult::exited || h.t < r.t || (h.t == r.t && h.triangle < r.triangle)) {
      r.status = WalkResult::exited;
      r.t = h.t;
      r.triangle = h.triangle;
      r.bary = h.bary;
    }
  return r;
}

// Candidate crossing of the ray at distance s on triangle t: nearer to the target depth
// D wins; ties to the smaller s, then the lower triangle.
struct RayPick {
  double s = 0;
  index_t triangle = -1;
  void offer(double s_new, index_t t_new, double D) {
    const double e = std::abs(s_new - D), e_old = std::abs(s - D);
    if (triangle < 0 || e < e_old || (e == e_old && (s_new < s || (s_new == s && t_new < triangle)))) {
      s = s_new;
      triangle = t_new;
    }
  }
};

// A consistent depth longer than this many times the distance to B's nearest surface
// point leads through B (docs/collision.md, "Penetration vectors", item 5). Measured on
// tori200 and chess500 to 0.5 s (in-run depth, fastest vertex): 4 helps both; 2 replaced
// consistent depths that were right (tori200 frames 0.011 -> 0.019 h).
constexpr double kNearestFactor = 4.0;

// T_i: the surface triangle crossed by the ray x~_i + s r_i, nearest to s = D_i; `at`
// receives the distance s of that crossing (0 when none was found).
index_t ray_triangle(const DepthInput& in, std::int32_t b, index_t tet, const V3& xi, const V3& r, double D,
                     double& at, DepthCounters& c, DepthScratch& s, const SkipVertices& skip) {
  const World& w = *in.world;
  const SurfaceBvh& bvh = in.bvh[b];
  const Box& box = in.object_box[b];
  // Far enough to be outside B's box: the walk must leave B before the end.
  const double reach = D + 2 * std::sqrt(norm2(box.hi - box.lo)) + in.tiny;
  const WalkResult wr = walk_to_surface(in.x, w.tets.data(), in.topo->face_neighbour.data(), w.triangles.data(), tet, xi,
                                        xi + reach * r, in.max_walk);
  RayPick pick;
  if (wr.status == WalkResult::exited && usable(wr, w.triangles.data(), skip)) {
    const double s1 = wr.t * reach;
    pick.offer(s1, wr.triangle, D);
    if (D > s1 + in.tiny) {
      // A crossing after the first exit can only be nearer to D if it lies before 2D - s1.
      const double len = 2 * D - s1;
      s.hits.clear();
      bvh.segment_hits(in.x, w.triangles.data(), xi, xi + len * r, s.hits, c.degenerate, skip);
      for (const SurfaceBvh::Hit& h : s.hits)
        if (h.t * len > s1) pick.offer(h.t * len, h.triangle, D);
    }
  } else {
    ++c.surface_searches;
    s.hits.clear();
    bvh.segment_hits(in.x, w.triangles.data(), xi, xi + reach * r, s.hits, c.degenerate, skip);
    for (const SurfaceBvh::Hit& h : s.hits) pick.offer(h.t * reach, h.triangle, D);
  }
  at = pick.triangle >= 0 ? pick.s : 0;
  return pick.triangle;  // -1: no crossing at all (a tangled B)
}

// The entry rule (item 5 above): where the segment x~_i -> x^t_i crosses B's surface
// first, when it crosses an odd number of times. False when it does not apply.
bool entry_point(const DepthInput& in, std::int32_t b, index_t i, const V3& xi, DepthCounters& c, DepthScratch& s,
                 const SkipVertices& skip, index_t& triangle, V3& d, std::array<double, 3>& weight) {
  if (!in.x_start) return false;
  const V3 xp = load(in.x_start, i);
  if (norm2(xp - xi) <= in.tiny * in.tiny) return false;
  s.hits.clear();
  in.bvh[b].segment_hits(in.x, in.world->triangles.data(), xi, xp, s.hits, c.degenerate, skip);
  if (s.hits.size() % 2 == 0) return false;
  const SurfaceBvh::Hit* first = &s.hits[0];
  for (const SurfaceBvh::Hit& h : s.hits)
    if (h.t < first->t || (h.t == first->t && h.triangle < first->triangle)) first = &h;
  triangle = first->triangle;
  d = first->t * (xp - xi);
  weight = first->bary;
  return true;
}

// The way back to rest (docs/collision.md, "Penetration vectors", item 5): the triangle
// of B nearest to x^t_i is the one the point rested on at the start of the step (a
// contact closed onto T_i's plane leaves x^t_i on or just inside B's surface); d_i leads
// to that triangle's closest point to x~_i. False when it does not apply: no x^t, or
// x^t_i farther from B's surface than x~_i from that triangle (it did not rest there).
bool resting_point(const DepthInput& in, std::int32_t b, index_t i, const V3& xi, DepthCounters& c,
                   const SkipVertices& skip, index_t& triangle, V3& d, std::array<double, 3>& weight) {
  if (!in.x_start) return false;
  const V3 xp = load(in.x_start, i);
  const index_t* tri = in.world->triangles.data();
  const SurfaceBvh::Nearest nr = in.bvh[b].nearest(in.x, tri, xp, c.degenerate, skip);
  if (nr.triangle < 0) return false;
  const index_t* tv = tri + 3 * static_cast<std::size_t>(nr.triangle);
  const V3 p = closest_point_on_triangle(xi, load(in.x, tv[0]), load(in.x, tv[1]), load(in.x, tv[2]), weight);
  triangle = nr.triangle;
  d = p - xi;
  return nr.dist2 <= norm2(d);  // x^t_i nearer to B's surface than x~_i: it rested there
}

}  // namespace

void penetration_depth(const DepthInput& in, std::int32_t b, const InsidePoint* pts, std::size_t count, Collision* out,
                       DepthCounters& c, DepthScratch& s) {
  const World& w = *in.world;
  const CollisionTopology& topo = *in.topo;
  const double* x = in.x;
  const index_t* tri = w.triangles.data();
  const SurfaceBvh& bvh = in.bvh[b];
  const double tiny2 = in.tiny * in.tiny;
  // Self-contact (A == B): the searches skip the triangles that touch the point or one
  // of its mesh neighbours, its own side of the fold.
  const bool self = count > 0 && topo.vertex_slot[static_cast<std::size_t>(pts[0].point)] == b;
  auto skip_of = [&](index_t i) {
    if (!self) return SkipVertices{};
    const auto v = static_cast<std::size_t>(i);
    s.skip.assign(1, i);
    s.skip.insert(s.skip.end(), topo.edge_to.begin() + static_cast<std::ptrdiff_t>(topo.edge_begin[v]),
                  topo.edge_to.begin() + static_cast<std::ptrdiff_t>(topo.edge_begin[v + 1]));
    return SkipVertices{s.skip.data(), s.skip.size()};
  };

  // Neighbours of each point over A's mesh edges, split into those inside B (by
  // position) and those not (by vertex), both ascending.
  s.in_begin.assign(1, 0);
  s.out_begin.assign(1, 0);
  s.in_nb.clear();
  s.out_nb.clear();
  for (std::size_t k = 0; k < count; ++k) {
    const auto v = static_cast<std::size_t>(pts[k].point);
    for (std::size_t e = topo.edge_begin[v]; e < topo.edge_begin[v + 1]; ++e) {
      const index_t u = topo.edge_to[e];
      const std::ptrdiff_t p = position_of(pts, count, u);
      if (p >= 0)
        s.in_nb.push_back(static_cast<index_t>(p));
      else
        s.out_nb.push_back(u);
    }
    s.in_begin.push_back(s.in_nb.size());
    s.out_begin.push_back(s.out_nb.size());
  }
  s.layer.assign(count, -1);
  s.depth.assign(count, 0);
  s.dir.assign(count, V3{0, 0, 0});
  s.frontier.clear();

  // Border points: weighted crossings of their border edges.
  for (std::size_t k = 0; k < count; ++k) {
    const V3 xi = load(x, pts[k].point);
    double sw = 0, sd = 0, best_w = -1;
    V3 sn{0, 0, 0}, best_n{0, 0, 0};
    if (s.out_begin[k] == s.out_begin[k + 1]) continue;
    const TetPlanes start = prepare_walk(x, w.tets.data(), pts[k].tet, xi);  // shared by the point's edges
    const SkipVertices skip = skip_of(pts[k].point);
    for (std::size_t e = s.out_begin[k]; e < s.out_begin[k + 1]; ++e) {
      const V3 xk = load(x, s.out_nb[e]);
      if (norm2(xk - xi) <= tiny2) {  // zero-length edge: no direction to search along
        ++c.degenerate;
        continue;
      }
      const WalkResult wr = border_crossing(in, bvh, start, xi, xk, c, s, skip);
      if (wr.status != WalkResult::exited) continue;  // k is inside B as well: no border edge
      const V3 n = interpolated_normal(x, tri, in.normals, wr.triangle, wr.bary);
      if (is_zero(n)) {
        ++c.degenerate;
        continue;
      }
      const V3 diff = wr.t * (xk - xi);  // s_k - x~_i
      const double wk = 1.0 / std::max(norm2(diff), tiny2);
      sw += wk;
      sd += wk * dot(diff, n);
      sn = sn + wk * n;
      if (wk > best_w) {
        best_w = wk;
        best_n = n;
      }
    }
    if (!(sw > 0)) continue;
    s.layer[k] = 0;
    s.depth[k] = sd / sw;
    const V3 r = normalized(sn);
    s.dir[k] = is_zero(r) ? best_n : r;  // normals cancelling (a thin part of B): the nearest crossing's
    s.frontier.push_back(k);
    ++c.border_points;
  }

  // Propagation, layer by layer.
  for (int L = 0; !s.frontier.empty(); ++L) {
    s.next.clear();
    for (std::size_t k : s.frontier)
      for (std::size_t e = s.in_begin[k]; e < s.in_begin[k + 1]; ++e)
        if (s.layer[static_cast<std::size_t>(s.in_nb[e])] < 0) s.next.push_back(static_cast<std::size_t>(s.in_nb[e]));
    std::sort(s.next.begin(), s.next.end());
    s.next.erase(std::unique(s.next.begin(), s.next.end()), s.next.end());
    for (std::size_t k : s.next) {
      const V3 xi = load(x, pts[k].point);
      double sm = 0, sd = 0, best_m = -1;
      V3 sr{0, 0, 0}, best_r{0, 0, 0};
      double best_d = 0;
      for (std::size_t e = s.in_begin[k]; e < s.in_begin[k + 1]; ++e) {
        const auto j = static_cast<std::size_t>(s.in_nb[e]);
        if (s.layer[j] < 0) continue;  // unprocessed, or in the layer being computed (not marked yet)
        const V3 dx = load(x, pts[j].point) - xi;
        double l2 = norm2(dx);
        if (l2 <= tiny2) {
          ++c.degenerate;
          l2 = tiny2;
        }
        const double mu = 1.0 / l2;
        sm += mu;
        sd += mu * (dot(dx, s.dir[j]) + s.depth[j]);
        sr = sr + mu * s.dir[j];
        if (mu > best_m) {
          best_m = mu;
          best_r = s.dir[j];
          best_d = dot(dx, s.dir[j]) + s.depth[j];
        }
      }
      s.depth[k] = sm > 0 ? sd / sm : best_d;
      const V3 r = normalized(sr);
      s.dir[k] = is_zero(r) ? best_r : r;
    }
    for (std::size_t k : s.next) s.layer[k] = L + 1;
    s.frontier.swap(s.next);
  }

  // Sets that no border point reached: deep intersections (layer -2 marks them).
  for (std::size_t k = 0; k < count; ++k) {
    if (s.layer[k] != -1) continue;
    ++c.deep_fallbacks;
    s.next.assign(1, k);
    s.layer[k] = -2;
    while (!s.next.empty()) {
      const std::size_t q = s.next.back();
      s.next.pop_back();
      for (std::size_t e = s.in_begin[q]; e < s.in_begin[q + 1]; ++e) {
        const auto j = static_cast<std::size_t>(s.in_nb[e]);
        if (s.layer[j] == -1) {
          s.layer[j] = -2;
          s.next.push_back(j);
        }
      }
    }
  }

  // Records.
  for (std::size_t k = 0; k < count; ++k) {
    Collision& rec = out[k];
    const index_t i = pts[k].point;
    const V3 xi = load(x, i);
    const SkipVertices skip = skip_of(i);
    rec.point = i;
    rec.point_gid = w.vertex_gid[static_cast<std::size_t>(i)];
    rec.object = w.vertex_object[static_cast<std::size_t>(i)];
    rec.other_object = topo.objects[static_cast<std::size_t>(b)].object;
    index_t t = -1;
    V3 d{0, 0, 0};
    bool projected = false;  // d_i along r_i; weights from projecting x~_i + d_i onto T_i
    bool resolved = false;   // d_i and T_i chosen
    if (s.layer[k] != -2) {
      // The direction r_i and the crossing nearest to D_i are the consistent ones; the
      // magnitude is the distance to that crossing, so that x~_i + d_i lies on T_i (D_i
      // itself, an average over the border crossings, can overshoot it by a factor of
      // two or fall short of it).
      double at = 0;
      const double D = std::max(s.depth[k], 0.0);
      t = ray_triangle(in, b, pts[k].tet, xi, s.dir[k], D, at, c, s, skip);
      if (t >= 0) {
        d = at * s.dir[k];
        projected = resolved = true;
        // A long d_i that is more than twice the way back to where the point entered B
        // within this step has gone wrong: r_i, propagated from neighbours, leads
        // through B (a thin part, a tangled region), and the point would be pushed
        // through or, limited by the separation speed, deeper. The way back is taken.
        // Where there is no way back to compare with (x^t_i was inside B too) or it is
        // long as well, d_i is compared with the way back to the triangle the point
        // rested on at the start of the step (the one nearest to x^t_i): more than twice
        // that, and that triangle's closest point is taken. Else d_i is compared with
        // the distance to B's nearest surface point: more than kNearestFactor times
        // that, and the nearest point is taken.
        index_t te = -1;
        V3 de{0, 0, 0};
        std::array<double, 3> we{};
        if (at > in.check_depth && entry_point(in, b, i, xi, c, s, skip, te, de, we) && 4 * norm2(de) < at * at) {
          t = te;
          d = de;
          rec.weight = we;
          projected = false;
          ++c.redirected;
          ++c.entry_records;
        } else if (at > in.check_depth && resting_point(in, b, i, xi, c, skip, te, de, we) && 4 * norm2(de) < at * at) {
          t = te;
          d = de;
          rec.weight = we;
          projected = false;
          ++c.redirected;
          ++c.resting_records;
        } else if (at > in.check_depth) {
          const SurfaceBvh::Nearest nr = bvh.nearest(x, tri, xi, c.degenerate, skip);
          if (nr.triangle >= 0 && kNearestFactor * kNearestFactor * norm2(nr.point - xi) < at * at) {
            t = nr.triangle;
            d = nr.point - xi;
            rec.weight = nr.bary;
            projected = false;
            ++c.redirected;
            ++c.nearest_records;
          }
        }
      }
    }
    // Deep sets and rays without an exit: the entry rule, else the nearest triangle.
    if (!resolved && entry_point(in, b, i, xi, c, s, skip, t, d, rec.weight)) {
      ++c.entry_records;
    } else if (!resolved) {
      const SurfaceBvh::Nearest nr = bvh.nearest(x, tri, xi, c.degenerate, skip);
      t = nr.triangle;
      d = nr.point - xi;
      rec.weight = nr.bary;
    }
    rec.fallback = !projected;
    if (t < 0) {
      // Only non-finite positions leave no triangle to choose (every comparison fails):
      // an empty record, which the detector drops; the run's failure guard reports why.
      rec.depth = {0, 0, 0};
      rec.weight = {1.0 / 3, 1.0 / 3, 1.0 / 3};
      for (int q = 0; q < 3; ++q) rec.triangle[q] = -1;
      rec.triangle_gid = -1;
      continue;
    }
    if (projected) {
      const index_t* tv = tri + 3 * static_cast<std::size_t>(t);
      const V3 a = load(x, tv[0]), bb = load(x, tv[1]), cc = load(x, tv[2]);
      if (!projected_weights(xi + d, a, bb, cc, rec.weight)) {
        ++c.degenerate;
        closest_point_on_triangle(xi + d, a, bb, cc, rec.weight);
      }
    }
    rec.depth = d;
    for (int q = 0; q < 3; ++q) rec.triangle[q] = tri[3 * static_cast<std::size_t>(t) + q];
    rec.triangle_gid = w.triangle_gid[static_cast<std::size_t>(t)];
  }
}

}  // namespace softcontact::collide
