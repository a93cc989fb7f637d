#include "edge_contacts.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <tuple>

#include "box_pairs.hpp"
#include "parallel.hpp"

namespace softcontact::collide {

SurfaceEdges build_surface_edges(const World& w, const CollisionTopology& topo) {
  SurfaceEdges e;
  e.object_begin.push_back(0);
  std::vector<std::tuple<index_t, index_t, index_t>> list;  // (a, b, triangle)
  for (const ObjectInfo& o : topo.objects) {
    list.clear();
    for (index_t r : o.triangles) {
      const index_t* t = &w.triangles[3 * static_cast<std::size_t>(r)];
      for (int k = 0; k < 3; ++k) {
        const index_t p = t[k], q = t[(k + 1) % 3];
        list.emplace_back(std::min(p, q), std::max(p, q), r);
      }
    }
    std::sort(list.begin(), list.end());
    for (std::size_t i = 0; i < list.size();) {
      std::size_t j = i + 1;
      while (j < list.size() && std::get<0>(list[j]) == std::get<0>(list[i]) && std::get<1>(list[j]) == std::get<1>(list[i]))
        ++j;
      e.a.push_back(std::get<0>(list[i]));
      e.b.push_back(std::get<1>(list[i]));
      e.tri0.push_back(std::get<2>(list[i]));
      e.tri1.push_back(j > i + 1 ? std::get<2>(list[i + 1]) : -1);  // a non-manifold edge keeps its first two
      const V3 d = load(w.x.data(), e.b.back()) - load(w.x.data(), e.a.back());
      e.max_length = std::max(e.max_length, std::sqrt(norm2(d)));
      i = j;
    }
    e.object_begin.push_back(e.a.size());
  }
  return e;
}

namespace {

// Strict crossing of segment pq with triangle abc (outward order), given the endpoints'
// signed volumes sp, sq against it (orient(a, b, c, p), orient(a, b, c, q)): the endpoints
// on opposite sides of the plane and the line through p and q inside the triangle. t is
// the parameter of the crossing along p -> q; entering when p is on the outer side.
bool crosses(const V3& p, const V3& q, const V3& a, const V3& b, const V3& c, double sp, double sq, double& t,
             bool& entering) {
  if (!((sp > 0 && sq < 0) || (sp < 0 && sq > 0))) return false;
  const double v0 = orient(p, q, b, c), v1 = orient(p, q, c, a), v2 = orient(p, q, a, b);
  if (!((v0 > 0 && v1 > 0 && v2 > 0) || (v0 < 0 && v1 < 0 && v2 < 0))) return false;
  t = sp / (sp - sq);
  entering = sp > 0;
  return true;
}

// Triangle t touches the star of vertex v (v or one of its mesh neighbours).
bool touches_star(const CollisionTopology& topo, index_t v, const index_t* t) {
  const auto u = static_cast<std::size_t>(v);
  const auto nb0 = topo.edge_to.begin() + static_cast<std::ptrdiff_t>(topo.edge_begin[u]);
  const auto nb1 = topo.edge_to.begin() + static_cast<std::ptrdiff_t>(topo.edge_begin[u + 1]);
  for (int k = 0; k < 3; ++k)
    if (t[k] == v || std::binary_search(nb0, nb1, t[k])) return true;
  return false;
}

V3 unit_normal(const double* x, const index_t* t) {
  const V3 a = load(x, t[0]), b = load(x, t[1]), c = load(x, t[2]);
  return normalized(cross(b - a, c - a));
}

// The lines P + s u1 and C + u u2: their closest points' parameters (unclamped) and
// the unnormalised common normal u1 x u2. False when they are parallel or nearly so.
bool closest_line_params(const V3& P, const V3& u1, const V3& C, const V3& u2, double& s, double& u, V3& n0) {
  n0 = cross(u1, u2);
  const double a11 = dot(u1, u1), a12 = dot(u1, u2), a22 = dot(u2, u2);
  const double den = a11 * a22 - a12 * a12;
  if (!(norm2(n0) > 1e-12 * a11 * a22 && den > 0)) return false;
  const V3 w0 = P - C;
  const double b1 = dot(u1, w0), b2 = dot(u2, w0);
  s = (a12 * b2 - a22 * b1) / den;
  u = (a11 * b2 - a12 * b1) / den;
  return true;
}

// Item 6 of edge_contacts.hpp: e1 = (ia, ib) with one end (`end`, a vertex record along
// `end_dir`, unit) inside B leaves B through its surface triangle `tri`. Fills the
// record's weights, e2 and depth and returns true when e1 passes deeper under a rim edge
// of `tri` than the end lies.
bool one_end_rim_record(const World& w, const CollisionTopology& topo, const double* x, index_t ia, index_t ib,
                        index_t end, const V3& end_dir, index_t tri, Collision& rec) {
  const index_t* tt = &w.triangles[3 * static_cast<std::size_t>(tri)];
  const V3 P = load(x, ia), u1 = load(x, ib) - P, E = load(x, end);
  const V3 nt = unit_normal(x, tt);
  double depth_of_least = 0, least = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    index_t ic = tt[k], id = tt[(k + 1) % 3];
    if (w.vertex_gid[static_cast<std::size_t>(id)] < w.vertex_gid[static_cast<std::size_t>(ic)]) std::swap(ic, id);
    // T', the other surface triangle on (ic, id).
    index_t nb = -1;
    for (std::size_t m = topo.tri_begin[static_cast<std::size_t>(ic)]; m < topo.tri_begin[static_cast<std::size_t>(ic) + 1]; ++m) {
      const index_t r = topo.tri_of[m];
      const index_t* tr = &w.triangles[3 * static_cast<std::size_t>(r)];
      if (r != tri && (tr[0] == id || tr[1] == id || tr[2] == id)) nb = r;
    }
    if (nb < 0) continue;
    const V3 C = load(x, ic), u2 = load(x, id) - C;
    double s, u;
    V3 n0;
    if (!closest_line_params(P, u1, C, u2, s, u, n0)) continue;  // parallel
    if (!(s > 0 && s < 1 && u > 0 && u < 1)) continue;  // the common perpendicular within both edges
    const V3 P1 = P + s * u1;
    const V3 nn = unit_normal(x, &w.triangles[3 * static_cast<std::size_t>(nb)]);
    // A convex rim (T's third corner behind T'), not a flat or nearly flat edge
    // (|nt x nn|^2 >= 1/4: 30 degrees or more), and e1's point there behind T'.
    if (norm2(cross(nt, nn)) < 0.25 || dot(nn, load(x, tt[(k + 2) % 3]) - C) >= 0 || dot(nn, P1 - C) >= 0) continue;
    V3 n = normalized(n0);
    if (dot(n, nt + nn) < 0) n = -1.0 * n;  // B's outside
    if (dot(n, end_dir) < 0.8) continue;
    const double depth = dot(n, (C + u * u2) - P1);
    const double behind = -dot(nn, E - C);
    if (!(depth > 0) || !std::isfinite(depth) || behind < 0 || !(behind < least)) continue;
    least = behind;
    depth_of_least = depth;
    rec.point_weight = 1 - s;
    rec.triangle = {ic, id, ic};
    rec.weight = {1 - u, u, 0};
    rec.depth = {depth * n[0], depth * n[1], depth * n[2]};
  }
  return depth_of_least > least;
}

// Vertex v behind the planes of both surface triangles bordering edge e (inside the
// edge's body there, for a convex edge).
bool behind_both_triangles(const World& w, const double* x, const SurfaceEdges& E, std::size_t e, index_t v) {
  const V3 V = load(x, v);
  for (const index_t t : {E.tri0[e], E.tri1[e]}) {
    if (t < 0) return false;
    const index_t* tr = &w.triangles[3 * static_cast<std::size_t>(t)];
    if (!(dot(unit_normal(x, tr), V - load(x, tr[0])) < 0)) return false;
  }
  return true;
}

// Item 7 of edge_contacts.hpp: e1 = P Q enters B through T_in at parameter t_in and
// leaves through T_out at t_out, two triangles that share only the vertex v (not inside
// A): the chord between the two crossings lies behind the planes of v's fan, the local
// tent of B around v. The record moves the chord out by the smallest of: for each fan
// plane, the distance that puts the whole chord in front of it; and for the bisector of
// T_in and T_out, the distance that brings the chord's deepest point under both (where
// the two planes are equally far) onto their ridge. Returns the parameter s of e1 nearest
// to v (the weights 1 - s, s) and the penetration vector d.
bool under_vertex_record(const World& w, const CollisionTopology& topo, const double* x, const V3& P, const V3& Q,
                         double t_in, index_t tri_in, double t_out, index_t tri_out, index_t v, double& s, V3& d) {
  const V3 V = load(x, v), u1 = Q - P;
  const V3 c0 = P + t_in * u1, c1 = P + t_out * u1;  // the chord's ends, on T_in and T_out
  // Ties (the two triangles of a flat quad give the same move up to rounding) go to the
  // lower global triangle id, the bisector last: the same choice on any rank, whatever
  // the local order of the fan.
  double best = std::numeric_limits<double>::infinity();
  gid_t best_key = std::numeric_limits<gid_t>::max();
  V3 n{0, 0, 0};
  auto consider = [&](double dk, const V3& nk, gid_t key) {
    if (dk > 0 && std::isfinite(dk) && (dk < best || (dk == best && key < best_key))) {
      best = dk;
      best_key = key;
      n = nk;
    }
  };
  const std::size_t f0 = topo.tri_begin[static_cast<std::size_t>(v)], f1 = topo.tri_begin[static_cast<std::size_t>(v) + 1];
  for (std::size_t k = f0; k < f1; ++k) {
    const auto r = static_cast<std::size_t>(topo.tri_of[k]);
    const V3 nk = unit_normal(x, &w.triangles[3 * r]);
    consider(std::max(-dot(nk, c0 - V), -dot(nk, c1 - V)), nk, w.triangle_gid[r]);
  }
  // How far P + t u1 lies behind T_in's and T_out's planes is linear in t, and zero at
  // the chord's end on that plane: the two are equal at t*, the chord's deepest point
  // under both.
  const V3 ni = unit_normal(x, &w.triangles[3 * static_cast<std::size_t>(tri_in)]);
  const V3 no = unit_normal(x, &w.triangles[3 * static_cast<std::size_t>(tri_out)]);
  const V3 m = ni + no;
  const double gi = -dot(ni, u1), go = -dot(no, u1);
  if (norm2(m) > 0 && gi != go) {
    const double bi = -dot(ni, P - V), bo = -dot(no, P - V);
    const double ts = (bo - bi) / (gi - go);
    if (ts > std::min(t_in, t_out) && ts < std::max(t_in, t_out)) {
      const V3 nb = normalized(m);
      const double c = dot(nb, ni);  // cos of half the angle between the normals
      if (c > 0) consider((bi + gi * ts) / c, nb, std::numeric_limits<gid_t>::max() - 1);
    }
  }
  if (!std::isfinite(best)) return false;
  const double a11 = dot(u1, u1);
  s = a11 > 0 ? std::clamp(dot(V - P, u1) / a11, 0.0, 1.0) : 0.5;
  d = best * n;
  return true;
}

// The unit normal of a triangle and the unit normals of the planes through its sides,
// perpendicular to it, pointing away from it. A degenerate triangle separates nothing.
struct TrianglePlanes {
  V3 n{0, 0, 0}, side[3]{};
  V3 at[3]{};
  double size = 0;  // longest side
  bool ok = false;
  TrianglePlanes(const V3& a, const V3& b, const V3& c) {
    const V3 v[3] = {a, b, c};
    for (int k = 0; k < 3; ++k) size = std::max(size, std::sqrt(norm2(v[(k + 1) % 3] - v[k])));
    const V3 nn = cross(b - a, c - a);
    const double l = std::sqrt(norm2(nn));
    if (!(l > 1e-12 * size * size) || !std::isfinite(l)) return;
    n = (1 / l) * nn;
    for (int k = 0; k < 3; ++k) {
      const V3 s = cross(v[(k + 1) % 3] - v[k], n);  // in the plane, perpendicular to the side
      const double ls = std::sqrt(norm2(s));
      if (!(ls > 0)) return;
      side[k] = (1 / ls) * s;
      if (dot(v[(k + 2) % 3] - v[k], side[k]) > 0) side[k] = -1.0 * side[k];
      at[k] = v[k];
    }
    ok = true;
  }
  /// Both p and q farther than `reach` beyond the same plane.
  bool apart(const V3& p, const V3& q, const V3& a, double reach) const {
    if (!ok) return false;
    const double dp = dot(p - a, n), dq = dot(q - a, n);
    if ((dp > reach && dq > reach) || (dp < -reach && dq < -reach)) return true;
    for (int k = 0; k < 3; ++k)
      if (dot(p - at[k], side[k]) > reach && dot(q - at[k], side[k]) > reach) return true;
    return false;
  }
};

}  // namespace

// The pairs found at ref_x_ hold every (edge, triangle) pair whose boxes meet at x when
// no vertex has moved more than skin / 2 since (a piece's box and a triangle's box then
// moved by at most that much each), no vertex is bad (non-finite; the filters below are
// applied when the pairs are found) and neither the owned objects nor the settings changed.
bool EdgeContactFinder::pairs_valid(const EdgeSearchInput& in) const {
  const World& w = *in.world;
  const CollisionTopology& topo = *in.topo;
  const std::size_t n = w.n_local();
  if (!(in.skin > 0) || in.skin != ref_skin_ || in.cell_size != ref_cell_ || in.self != ref_self_ ||
      ref_x_.size() != 3 * n || ref_owned_.size() != topo.objects.size())
    return false;
  for (std::size_t k = 0; k < topo.objects.size(); ++k)
    if (ref_owned_[k] != (w.owns_object(topo.objects[k].object) ? 1 : 0)) return false;
  const double lim = 0.25 * in.skin * in.skin;
  const double* x = w.x.data();
  unsigned ok = 1;
  for (std::size_t v = 0; v < n; ++v) {
    const double dx = x[3 * v] - ref_x_[3 * v], dy = x[3 * v + 1] - ref_x_[3 * v + 1], dz = x[3 * v + 2] - ref_x_[3 * v + 2];
    ok &= static_cast<unsigned>(dx * dx + dy * dy + dz * dz <= lim) & static_cast<unsigned>(in.bad_vertex[v] == 0);
  }
  return ok != 0;
}

void EdgeContactFinder::find_pairs(const EdgeSearchInput& in) {
  const World& w = *in.world;
  const CollisionTopology& topo = *in.topo;
  const SurfaceEdges& E = *in.edges;
  const std::vector<Box>& obox = *in.object_box;
  const double* x = w.x.data();
  const std::size_t no = topo.objects.size();
  const double skin = in.skin > 0 ? in.skin : 0, hs = 0.5 * skin;
  ++pair_searches_;
  ref_skin_ = in.skin;
  ref_cell_ = in.cell_size;
  ref_self_ = in.self;
  ref_x_.assign(x, x + 3 * w.n_local());
  ref_owned_.resize(no);
  for (std::size_t k = 0; k < no; ++k) ref_owned_[k] = w.owns_object(topo.objects[k].object) ? 1 : 0;
  pairs_.clear();
  cand_.clear();
  cand_slot_.clear();
  // Objects whose boxes come within the skin (each box moves at most skin / 2 before the
  // pairs are found again).
  overlapping_boxes(obox, hs, [&](std::size_t k) { return !topo.objects[k].triangles.empty(); }, near_, sweep_);

  // Candidates: surface edges of owned objects whose box (grown by skin / 2) meets a near
  // object's (with self-contact: every surface edge of an owned object).
  cand_box_.assign(no, Box{});
  for (Box& b : cand_box_) b.reset();
  seg_slot_.clear();
  double half = 0;
  for (std::size_t k = 0; k < no; ++k) {
    if ((near_[k].empty() && !in.self) || !ref_owned_[k]) continue;
    for (std::size_t e = E.object_begin[k]; e < E.object_begin[k + 1]; ++e) {
      const index_t a = E.a[e], b = E.b[e];
      if (in.bad_vertex[static_cast<std::size_t>(a)] || in.bad_vertex[static_cast<std::size_t>(b)]) continue;
      Box eb;
      eb.reset();
      eb.add(load(x, a));
      eb.add(load(x, b));
      eb = grown(eb, hs);
      bool take = in.self;
      for (std::size_t q = 0; !take && q < near_[k].size(); ++q)
        take = grown(obox[static_cast<std::size_t>(near_[k][q])], hs).overlaps(eb);
      if (!take) continue;
      cand_.push_back(e);
      cand_slot_.push_back(static_cast<std::int32_t>(k));
      cand_box_[k].add(eb);
    }
  }
  cand_pq_.resize(6 * cand_.size());
  if (cand_.empty()) return;
  // The grid holds points: each candidate edge goes in as the midpoints of pieces no
  // longer than a cell, so that a triangle's box grown by half a cell finds every edge
  // that can cross it (one long edge, a floor's or a wall's, would otherwise grow every
  // triangle's query box to its own length). Each piece carries its own box: a crossing
  // point lies on some piece, so a triangle needs only the pieces whose box meets its
  // own (grown by the skin), and most of the pieces its grown box finds are rejected by
  // that one test.
  const double cell = in.cell_size;
  mid_.clear();
  seg_edge_.clear();
  piece_box_.clear();
  for (std::size_t i = 0; i < cand_.size(); ++i) {
    const V3 p = load(x, E.a[cand_[i]]), q = load(x, E.b[cand_[i]]);
    for (std::size_t d = 0; d < 3; ++d) {
      cand_pq_[6 * i + d] = p[d];
      cand_pq_[6 * i + 3 + d] = q[d];
    }
    const double len = std::sqrt(norm2(q - p));
    const double pieces = std::ceil(len / cell);
    const int k = pieces > 1 && pieces < 1024 ? static_cast<int>(pieces) : 1;
    // The rounded piece ends lie within a few ulps of the exact ones: grown by 1e-9 of
    // the edge, the boxes still cover the whole edge.
    const double grow = 1e-9 * len;
    V3 from = p;
    for (int j = 0; j < k; ++j) {
      const V3 to = j + 1 == k ? q : p + (static_cast<double>(j + 1) / k) * (q - p);
      const V3 m = p + ((j + 0.5) / k) * (q - p);
      for (int d = 0; d < 3; ++d) mid_.push_back(m[static_cast<std::size_t>(d)]);
      for (std::size_t d = 0; d < 3; ++d) piece_box_.push_back(std::min(from[d], to[d]) - grow);
      for (std::size_t d = 0; d < 3; ++d) piece_box_.push_back(std::max(from[d], to[d]) + grow);
      seg_edge_.push_back(static_cast<std::uint32_t>(i));
      seg_slot_.push_back(cand_slot_[i]);
      from = to;
    }
    half = std::max(half, 0.5 * len / k);
  }
  cand_index_.resize(seg_edge_.size());
  std::iota(cand_index_.begin(), cand_index_.end(), index_t{0});
  grid_.set_cell_size(cell);
  grid_.insert_points(mid_.data(), cand_index_, seg_slot_.data());
  // The pieces' boxes and candidates in the grid's order: a run of cells is a run here.
  sorted_box_.resize(piece_box_.size());
  sorted_edge_.resize(seg_edge_.size());
  for (std::size_t k = 0; k < seg_edge_.size(); ++k) {
    const auto piece = static_cast<std::size_t>(grid_.point(k));
    for (std::size_t d = 0; d < 6; ++d) sorted_box_[6 * k + d] = piece_box_[6 * piece + d];
    sorted_edge_[k] = seg_edge_[piece];
  }

  // Per object B, where its triangles can meet a near object's candidate edge.
  tri_box_.resize(no);
  for (std::size_t b = 0; b < no; ++b) {
    Box fb;
    fb.reset();
    if (in.self && !cand_box_[b].empty()) fb = cand_box_[b];  // its own candidates (owned objects only)
    const Box ob = grown(obox[b], hs);
    for (std::int32_t a : near_[b]) {
      const Box& ca = cand_box_[static_cast<std::size_t>(a)];
      if (ca.empty() || !ca.overlaps(ob)) continue;
      fb.add(ca.intersection(ob));
    }
    tri_box_[b] = fb;
  }

  // Every surface triangle near a candidate against the pieces of other objects' edges.
  reset_buffers(pair_buf_);
  passed_.resize(static_cast<std::size_t>(max_threads()));
  hits_.resize(static_cast<std::size_t>(max_threads()));
  const std::size_t s = w.triangles.size() / 3;
  const bool self_on = in.self;
  parallel_for(s, [&](std::size_t r, int th) {
    const std::int32_t slot = topo.triangle_slot[r];
    if (slot < 0 || tri_box_[static_cast<std::size_t>(slot)].empty()) return;
    const index_t* t = &w.triangles[3 * r];
    if (in.bad_vertex[static_cast<std::size_t>(t[0])] || in.bad_vertex[static_cast<std::size_t>(t[1])] ||
        in.bad_vertex[static_cast<std::size_t>(t[2])])
      return;
    const V3 a = load(x, t[0]), b = load(x, t[1]), c = load(x, t[2]);
    Box box;
    box.reset();
    box.add(a);
    box.add(b);
    box.add(c);
    if (!grown(box, hs).overlaps(tri_box_[static_cast<std::size_t>(slot)])) return;
    const Box tight = grown(box, skin);  // a piece's box and this one each move by at most skin / 2
    // Pass 1, branch-free over the runs (contiguous): pieces of another object whose box
    // meets the triangle's. Pass 2 on the few collected: each edge once, not the edge's
    // own neighbourhood (self-contact).
    const CellRange range = grid_.range_of(grown(tight, half));
    auto& passed = passed_[static_cast<std::size_t>(th)];
    std::size_t n = 0;
    const std::int32_t* label = grid_.sorted_label();
    const double* pb = sorted_box_.data();
    auto collect = [&](std::size_t k0, std::size_t k1) {
      if (passed.size() < n + (k1 - k0)) passed.resize(2 * (n + (k1 - k0)));
      std::uint32_t* outp = passed.data();
      for (std::size_t k = k0; k < k1; ++k) {
        const double* m = pb + 6 * k;
        const bool in = (m[0] <= tight.hi[0]) & (m[3] >= tight.lo[0]) & (m[1] <= tight.hi[1]) & (m[4] >= tight.lo[1]) &
                        (m[2] <= tight.hi[2]) & (m[5] >= tight.lo[2]) & (self_on | (label[k] != slot));
        outp[n] = static_cast<std::uint32_t>(k);
        n += in;
      }
    };
    // A box spanning more cells than there are edges (a blown-up simulation, or one very
    // long edge): cheaper to test every edge than to visit the cells.
    if (range.count() > static_cast<double>(grid_.num_points())) collect(0, grid_.num_points());
    else grid_.for_each_run(range, collect);
    auto& hits = hits_[static_cast<std::size_t>(th)];
    hits.clear();
    for (std::size_t j = 0; j < n; ++j) {
      const std::uint32_t i = sorted_edge_[passed[j]];
      if (self_on && cand_slot_[i] == slot) {  // self-contact: not the edge's own neighbourhood
        const std::size_t e = cand_[i];
        if (touches_star(topo, E.a[e], t) || touches_star(topo, E.b[e], t)) continue;
      }
      hits.push_back(i);
    }
    std::sort(hits.begin(), hits.end());  // an edge cut into pieces can meet a box through several
    hits.erase(std::unique(hits.begin(), hits.end()), hits.end());
    // An edge that is to cross the triangle before the pairs are found again comes within
    // the skin of it now (each of its points and of the triangle's moves at most skin / 2):
    // not both ends farther than that in front of or behind its plane, or outside the
    // plane through one of its sides, perpendicular to it. The margin covers rounding.
    const TrianglePlanes tp(a, b, c);
    const double reach = skin + 1e-9 * tp.size;
    auto& mine = pair_buf_[static_cast<std::size_t>(th)];
    for (std::uint32_t i : hits) {
      const double* pq = &cand_pq_[6 * static_cast<std::size_t>(i)];
      if (tp.apart(V3{pq[0], pq[1], pq[2]}, V3{pq[3], pq[4], pq[5]}, a, reach)) continue;
      mine.push_back({i, slot, static_cast<index_t>(r)});
    }
  });
  concatenate(pair_buf_, pairs_);
  run_begin_.clear();
  for (std::size_t j = 0; j < pairs_.size(); ++j)
    if (j == 0 || pairs_[j].tri != pairs_[j - 1].tri) run_begin_.push_back(j);
  run_begin_.push_back(pairs_.size());
}


void EdgeContactFinder::find(const EdgeSearchInput& in, std::vector<Collision>& out, EdgeCounters& counters) {
  const World& w = *in.world;
  const CollisionTopology& topo = *in.topo;
  const SurfaceEdges& E = *in.edges;
  const double* x = w.x.data();

  // 1. and 2. Candidate pairs (found again only when the skin no longer covers the
  // motion since they were found), then the exact test of each at x.
  if (!pairs_valid(in)) find_pairs(in);
  crossings_.clear();
  if (pairs_.empty()) return;
  for (std::size_t i = 0; i < cand_.size(); ++i) {
    const V3 p = load(x, E.a[cand_[i]]), q = load(x, E.b[cand_[i]]);
    for (std::size_t d = 0; d < 3; ++d) {
      cand_pq_[6 * i + d] = p[d];
      cand_pq_[6 * i + 3 + d] = q[d];
    }
  }
  reset_buffers(buf_);
  passed_.resize(static_cast<std::size_t>(max_threads()));
  volumes_.resize(static_cast<std::size_t>(max_threads()));
  parallel_for(run_begin_.size() - 1, [&](std::size_t run, int th) {
    // The pairs of one triangle: its plane once, then each edge's two signed volumes.
    const std::size_t j0 = run_begin_[run], j1 = run_begin_[run + 1];
    const index_t tri = pairs_[j0].tri;
    const index_t* t = &w.triangles[3 * static_cast<std::size_t>(tri)];
    const V3 a = load(x, t[0]), b = load(x, t[1]), c = load(x, t[2]);
    const V3 nrm = cross(b - a, c - a);
    // Pass 1, branch-free: the ends' signed volumes, and the edges whose ends lie on
    // opposite sides of the plane. Pass 2: the exact test of those, with the same volumes.
    auto& passed = passed_[static_cast<std::size_t>(th)];
    auto& vol = volumes_[static_cast<std::size_t>(th)];
    if (passed.size() < j1 - j0) passed.resize(2 * (j1 - j0));
    if (vol.size() < 2 * (j1 - j0)) vol.resize(4 * (j1 - j0));
    std::size_t n = 0;
    for (std::size_t j = j0; j < j1; ++j) {
      const double* pq = &cand_pq_[6 * static_cast<std::size_t>(pairs_[j].edge)];
      const double sp = dot(V3{pq[0], pq[1], pq[2]} - a, nrm), sq = dot(V3{pq[3], pq[4], pq[5]} - a, nrm);
      vol[2 * (j - j0)] = sp;
      vol[2 * (j - j0) + 1] = sq;
      passed[n] = static_cast<std::uint32_t>(j);
      n += static_cast<std::size_t>((sp > 0 && sq < 0) | (sp < 0 && sq > 0));
    }
    for (std::size_t k = 0; k < n; ++k) {
      const std::size_t j = passed[k];
      const double* pq = &cand_pq_[6 * static_cast<std::size_t>(pairs_[j].edge)];
      const V3 p{pq[0], pq[1], pq[2]}, q{pq[3], pq[4], pq[5]};
      double tc;
      bool entering;
      if (crosses(p, q, a, b, c, vol[2 * (j - j0)], vol[2 * (j - j0) + 1], tc, entering))
        buf_[static_cast<std::size_t>(th)].push_back({pairs_[j].edge, pairs_[j].slot, tri, tc, entering});
    }
  });
  concatenate(buf_, crossings_);
  std::sort(crossings_.begin(), crossings_.end(), [](const Crossing& p, const Crossing& q) {
    if (p.edge != q.edge) return p.edge < q.edge;
    if (p.slot != q.slot) return p.slot < q.slot;
    if (p.t != q.t) return p.t < q.t;
    return p.tri < q.tri;
  });
  counters.crossings += static_cast<std::int64_t>(crossings_.size());

  // 3. and 4. Pairs of crossings per (edge, body) to edge-edge records.
  vertex_records_.clear();
  for (std::size_t q = 0; q < out.size(); ++q) vertex_records_.emplace_back(out[q].point, out[q].other_object, q);
  std::sort(vertex_records_.begin(), vertex_records_.end());
  auto first_record = [&](index_t v, std::int32_t object) {
    return std::lower_bound(vertex_records_.begin(), vertex_records_.end(), std::make_tuple(v, object, std::size_t{0}));
  };
  auto has_record = [&](index_t v, std::int32_t object) {
    const auto it = first_record(v, object);
    return it != vertex_records_.end() && std::get<0>(*it) == v && std::get<1>(*it) == object;
  };
  const gid_t ntri = w.global_triangles;
  for (std::size_t g0 = 0; g0 < crossings_.size();) {
    std::size_t g1 = g0 + 1;
    while (g1 < crossings_.size() && crossings_[g1].edge == crossings_[g0].edge && crossings_[g1].slot == crossings_[g0].slot)
      ++g1;
    const std::size_t e = cand_[crossings_[g0].edge];
    const index_t ia = E.a[e], ib = E.b[e];
    const std::int32_t other = topo.objects[static_cast<std::size_t>(crossings_[g0].slot)].object;
    const std::int32_t rec_object = topo.objects[static_cast<std::size_t>(cand_slot_[crossings_[g0].edge])].object;
    const bool in_a = has_record(ia, other), in_b = has_record(ib, other);
    if (in_a || in_b) {
      // Item 6: one end inside, one crossing (leaving B from the inside end).
      if (in_a != in_b && g1 - g0 == 1 && crossings_[g0].entering == in_b) {
        const index_t end = in_a ? ia : ib;
        V3 end_dir{0, 0, 0};  // the end's vertex records against B, in the order of `out`
        for (auto it = first_record(end, other);
             it != vertex_records_.end() && std::get<0>(*it) == end && std::get<1>(*it) == other; ++it) {
          const Collision& c = out[std::get<2>(*it)];
          end_dir = end_dir + V3{c.depth[0], c.depth[1], c.depth[2]};
        }
        Collision rec;
        if (norm2(end_dir) > 0 &&
            one_end_rim_record(w, topo, x, ia, ib, end, normalized(end_dir), crossings_[g0].tri, rec)) {
          rec.point = ia;
          rec.point2 = ib;
          rec.point_gid = w.vertex_gid[static_cast<std::size_t>(ia)];
          rec.triangle_gid =
              ntri * (1 + w.vertex_gid[static_cast<std::size_t>(ib)]) + w.triangle_gid[static_cast<std::size_t>(crossings_[g0].tri)];
          rec.object = rec_object;
          rec.other_object = other;
          out.push_back(rec);
          ++counters.contacts;
        }
      }
      g0 = g1;
      continue;
    }
    for (std::size_t q = g0; q + 1 < g1;) {
      const Crossing& cin = crossings_[q];
      const Crossing& cout = crossings_[q + 1];
      if (!cin.entering || cout.entering) {
        ++q;
        continue;
      }
      q += 2;
      // The edge e2 of B that the two triangles share.
      const index_t* ti = &w.triangles[3 * static_cast<std::size_t>(cin.tri)];
      const index_t* to = &w.triangles[3 * static_cast<std::size_t>(cout.tri)];
      index_t shared[3];
      int ns = 0;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          if (ti[i] == to[j]) shared[ns++] = ti[i];
      // A vertex of B that is itself inside A, behind both of A's triangles at e1: the
      // fan around it is where e1 crosses, and its own vertex record removes that
      // overlap. (Tested here, not by its record: B may be a ghost whose records are
      // made on its owner's rank.)
      if (ns == 1 && behind_both_triangles(w, x, E, e, shared[0])) continue;
      const gid_t key = ntri * (1 + w.vertex_gid[static_cast<std::size_t>(ib)]) + w.triangle_gid[static_cast<std::size_t>(cin.tri)];
      const V3 P = load(x, ia), Q = load(x, ib);
      Collision rec;
      rec.point = ia;
      rec.point2 = ib;
      rec.point_gid = w.vertex_gid[static_cast<std::size_t>(ia)];
      rec.triangle_gid = key;
      rec.object = rec_object;
      rec.other_object = other;
      bool edge_edge = false;
      if (ns == 2) {
        index_t ic = shared[0], id = shared[1];
        if (w.vertex_gid[static_cast<std::size_t>(id)] < w.vertex_gid[static_cast<std::size_t>(ic)]) std::swap(ic, id);
        const V3 C = load(x, ic), D = load(x, id);
        const V3 u1 = Q - P, u2 = D - C;
        double s, u;
        V3 n0;
        if (closest_line_params(P, u1, C, u2, s, u, n0)) {  // else parallel (aligned rims): no record
          V3 n = normalized(n0);
          const V3 outward = unit_normal(x, ti) + unit_normal(x, to);
          if (dot(n, outward) < 0) n = -1.0 * n;
          s = std::clamp(s, 0.0, 1.0);
          u = std::clamp(u, 0.0, 1.0);
          const double depth = dot(n, (C + u * u2) - (P + s * u1));
          if (depth > 0 && std::isfinite(depth)) {
            rec.point_weight = 1 - s;
            rec.triangle = {ic, id, ic};
            rec.weight = {1 - u, u, 0};
            rec.depth = {depth * n[0], depth * n[1], depth * n[2]};
            edge_edge = true;
          }
        }
      }
      if (ns == 1) {  // item 7: e1 under a vertex v of B that is not inside A
        double sv;
        V3 dv;
        if (under_vertex_record(w, topo, x, P, Q, cin.t, cin.tri, cout.t, cout.tri, shared[0], sv, dv)) {
          rec.point_weight = 1 - sv;
          rec.triangle = {shared[0], shared[0], shared[0]};
          rec.weight = {1, 0, 0};
          rec.depth = {dv[0], dv[1], dv[2]};
          edge_edge = true;
        }
      }
      if (!edge_edge) {
        ++counters.unpaired;
        continue;
      }
      out.push_back(rec);
      ++counters.contacts;
    }
    g0 = g1;
  }
}

}  // namespace softcontact::collide
