// softcontact verify: the check of one state (verify.hpp has the definitions).
//
// Per state: two grids of cells of edge h (the median rest edge), one over the tets and
// one over the surface triangles, at the current positions. Then
//  - every vertex (surface ones, and interior ones with VerifyOptions::interior): the tets
//    of its cell, barycentric test; for each other body found, the distance to that
//    body's surface by a ring search in the triangle grid;
//  - every surface edge: the triangles of the cells its box touches, each pair tested in
//    one cell only (the first cell both boxes share), segment-triangle test;
//  - every tet: its signed volume against the sign of its rest volume;
//  - every vertex: its speed.
// Each loop writes per-item results; the counts, maxima and percentiles are taken
// afterwards in item order, so nothing depends on the thread count.
#include "softcontact/verify.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <span>

#include "cell_bins.hpp"
#include "softcontact/error.hpp"
#include "softcontact/loop_failure.hpp"
#include "softcontact/mesh.hpp"
#include "verify_geometry.hpp"

namespace softcontact {

namespace {

using verify::CellBins;

constexpr double kBarycentricTol = 1e-12;  // closed point-in-tet and crossing point in triangle
constexpr double kSurfaceTol = 1e-9;       // a vertex counts when deeper than this x h
constexpr int kMaxRing = 6;                // ring search radius in cells before brute force
constexpr double kDepthAccuracy = 1e-4;    // a crossing's depth is searched to this x h

// One OpenMP loop for all passes (style.md: pragmas in one helper). Dynamic chunks:
// vertices near contacts cost far more than the others. What a body throws (the crossing
// pass allocates) is rethrown after the loop.
template <class F>
void parallel_for(std::size_t n, F&& f) {
  LoopFailure failure;
#pragma omp parallel for schedule(dynamic, 256)
  for (std::int64_t i = 0; i < static_cast<std::int64_t>(n); ++i)
    failure.run(static_cast<std::size_t>(i), f, static_cast<std::size_t>(i));
  failure.rethrow();
}

std::string row_error(const char* what, std::size_t row, const std::string& detail) {
  return std::string(what) + " " + std::to_string(row) + ": " + detail;
}

// Vertices whose stars (the vertex and its mesh neighbours) a self check leaves out:
// none, one vertex (self depth), or an edge's two ends (self crossings).
struct Star {
  gid_t v0 = -1, v1 = -1;
  bool any() const { return v0 >= 0; }
};

// The state of one check: positions and the two grids.
class FrameCheck {
public:
  FrameCheck(const VerifyMesh& mesh, const double* x) : m_(mesh), x_(x) {
    const double h = mesh.median_edge > 0 ? mesh.median_edge : 1.0;
    tol_ = kSurfaceTol * h;
    std::vector<double> lo, hi;
    boxes(mesh.tets.data(), 4, mesh.num_tets(), lo, hi);
    tets_.build(h, mesh.num_tets(), lo.data(), hi.data());
    boxes(mesh.triangles.data(), 3, mesh.num_triangles(), lo, hi);
    tris_.build(h, mesh.num_triangles(), lo.data(), hi.data());
    // Each triangle's box in one place: the crossing pass reads it for every candidate.
    tri_box_.resize(6 * mesh.num_triangles());
    parallel_for(mesh.num_triangles(), [&](std::size_t t) {
      std::copy_n(&lo[3 * t], 3, &tri_box_[6 * t]);
      std::copy_n(&hi[3 * t], 3, &tri_box_[6 * t + 3]);
    });
  }

  const double* X(gid_t v) const { return x_ + 3 * static_cast<std::size_t>(v); }

  bool skip_pair(std::int32_t a, std::int32_t b) const {
    return a == b || (m_.object_fixed[static_cast<std::size_t>(a)] && m_.object_fixed[static_cast<std::size_t>(b)]);
  }

  bool in_tet(const double* p, std::size_t t) const {
    const gid_t* c = &m_.tets[4 * t];
    return verify::in_closed_tet(p, X(c[0]), X(c[1]), X(c[2]), X(c[3]), kBarycentricTol);
  }

  // The other bodies (not `own`, not both kinematic) with a closed tet holding p, each
  // once, in the order found (`found` has room for `cap`; returns how many).
  int bodies_holding(const double* p, std::int32_t own, std::int32_t* found, int cap) const {
    int n = 0;
    auto consider = [&](std::int32_t t) {
      const std::int32_t b = m_.tet_object[static_cast<std::size_t>(t)];
      if (skip_pair(own, b) || std::find(found, found + n, b) != found + n) return;
      if (n < cap && in_tet(p, static_cast<std::size_t>(t))) found[n++] = b;
    };
    for (std::int32_t t : tets_.at(tets_.cell_of(p))) consider(t);
    for (std::int32_t t : tets_.oversized()) consider(t);
    return n;
  }

  // p in a closed tet of body b (that touches no vertex of `star`'s stars).
  bool in_body(const double* p, std::int32_t b, const Star& star = {}) const {
    auto holds = [&](std::int32_t t) {
      const auto u = static_cast<std::size_t>(t);
      return m_.tet_object[u] == b && in_tet(p, u) && !touches(star, &m_.tets[4 * u], 4);
    };
    for (std::int32_t t : tets_.at(tets_.cell_of(p)))
      if (holds(t)) return true;
    for (std::int32_t t : tets_.oversized())
      if (holds(t)) return true;
    return false;
  }

  double tri_dist2(const double* p, std::size_t t) const {
    const gid_t* c = &m_.triangles[3 * t];
    return verify::point_triangle_dist2(p, X(c[0]), X(c[1]), X(c[2]));
  }

  // Vertex v, or one of its mesh neighbours, among the k vertices c.
  bool touches_star(gid_t v, const gid_t* c, int k) const {
    const auto u = static_cast<std::size_t>(v);
    const gid_t* nb0 = m_.neighbours.data() + m_.neighbour_begin[u];
    const gid_t* nb1 = m_.neighbours.data() + m_.neighbour_begin[u + 1];
    for (int j = 0; j < k; ++j)
      if (c[j] == v || std::binary_search(nb0, nb1, c[j])) return true;
    return false;
  }

  // One of the k vertices c touches the star of star.v0 or of star.v1.
  bool touches(const Star& star, const gid_t* c, int k) const {
    return (star.v0 >= 0 && touches_star(star.v0, c, k)) || (star.v1 >= 0 && touches_star(star.v1, c, k));
  }

  // Self depth of surface vertex v of body b (verify.hpp), or -1.
  double self_depth(gid_t v, std::int32_t b) const { return depth_in(X(v), b, Star{v, -1}); }

  // Distance from p to body b's surface: rings of cells around p's cell, nearest first.
  // A triangle not met within ring r has its box outside the (2r+1)^3 block around p's
  // cell, so it is farther than r h plus p's distance to its cell's faces: stop once the
  // best distance is that or less (a shallow point then stops in its own cell). Deep points
  // (beyond kMaxRing) and points off the grid go through all of b's triangles.
  // The triangles touching `star`'s stars are left out (self checks).
  double surface_distance(const double* p, std::int32_t b, const Star& star = {}) const {
    auto counts = [&](std::size_t t) { return m_.triangle_object[t] == b && !touches(star, &m_.triangles[3 * t], 3); };
    double best2 = std::numeric_limits<double>::infinity();
    bool exact = false;
    const CellBins::Cell c0 = tris_.cell_of(p, &exact);
    for (std::int32_t t : tris_.oversized())
      if (counts(static_cast<std::size_t>(t))) best2 = std::min(best2, tri_dist2(p, static_cast<std::size_t>(t)));
    const double h = tris_.cell_size();
    // The rounding of cell_of may put p a hair outside c0: a margin of the tolerance the
    // boxes were grown by, far above that rounding.
    const double inner = std::max(0.0, tris_.inner_distance(p, c0) - tol_);
    for (int r = 0; exact && r <= kMaxRing; ++r) {
      for (std::int64_t dx = -r; dx <= r; ++dx)
        for (std::int64_t dy = -r; dy <= r; ++dy)
          for (std::int64_t dz = -r; dz <= r; ++dz) {
            if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) != r) continue;
            const CellBins::Cell c{c0[0] + dx, c0[1] + dy, c0[2] + dz};
            if (c[0] < 0 || c[1] < 0 || c[2] < 0 || c[0] >= tris_.dim(0) || c[1] >= tris_.dim(1) || c[2] >= tris_.dim(2))
              continue;
            // A triangle nearer than best has its nearest point to p in a cell listing it
            // (its box holds that point) and no farther than best from p: cells farther
            // than that (less the margin above) cannot lower best.
            const double gap = tris_.distance_to_cell(p, c) - tol_;
            if (gap > 0 && gap * gap >= best2) continue;
            for (std::int32_t t : tris_.at(c))
              if (counts(static_cast<std::size_t>(t))) best2 = std::min(best2, tri_dist2(p, static_cast<std::size_t>(t)));
          }
      const double reach = r * h + inner;
      if (best2 <= reach * reach) return std::sqrt(best2);
    }
    const auto ob = static_cast<std::size_t>(b);
    for (gid_t k = m_.object_triangle_begin[ob]; k < m_.object_triangle_begin[ob + 1]; ++k) {
      const auto t = static_cast<std::size_t>(m_.object_triangles[static_cast<std::size_t>(k)]);
      if (counts(t)) best2 = std::min(best2, tri_dist2(p, t));
    }
    return std::sqrt(best2);
  }

  // Depth of p in body b (its distance to b's surface) when p is inside b and deeper
  // than the tolerance; else -1.
  double depth_in(const double* p, std::int32_t b, const Star& star = {}) const {
    if (!in_body(p, b, star)) return -1;
    const double d = surface_distance(p, b, star);
    return d > tol_ ? d : -1;
  }

  // max(0, depth in body b) of the point a + t (b - a).
  double depth_on(const double* pa, const double* pb, double t, std::int32_t b, const Star& star) const {
    const double q[3] = {pa[0] + t * (pb[0] - pa[0]), pa[1] + t * (pb[1] - pa[1]), pa[2] + t * (pb[2] - pa[2])};
    return std::max(0.0, depth_in(q, b, star));
  }

  // Largest depth in body b of the points a + t (b - a), t in [t0, t1], where the ends
  // t0 > 0 and t1 < 1 are crossings of b's surface (depth 0) and the ends 0 and 1 the
  // edge's vertices, in two stages. sample_segment: evenly spaced points (up to
  // kCrossingSamples intervals, about kCrossingSamples per median edge). refine_segment:
  // where they are farther apart than 2 kDepthAccuracy h, a golden-section search between
  // the neighbours of the deepest down to kDepthAccuracy h (exact where the depth is
  // unimodal there, as inside a convex part). The depth is 1-Lipschitz, so the samples
  // alone are short of it by at most half their spacing (sample_bound).
  struct Samples {
    double t0 = 0, t1 = 1, length = 0;  // the part, and its length [m]
    int k_max = 0;                      // intervals
    double best = 0;                    // the deepest sample (0: none inside) ...
    int at = -1;                        // ... and its index (-1: none)
  };
  Samples sample_segment(const double* pa, const double* pb, double t0, double t1, std::int32_t b,
                         const Star& star = {}) const {
    Samples s;
    s.t0 = t0;
    s.t1 = t1;
    s.length = std::sqrt(verify::dist2(pa, pb)) * (t1 - t0);
    const double h = m_.median_edge > 0 ? m_.median_edge : 1.0;
    s.k_max = static_cast<int>(std::clamp(std::ceil(kCrossingSamples * s.length / h), 2.0,
                                          static_cast<double>(kCrossingSamples)));
    const double step = (t1 - t0) / s.k_max;
    for (int k = t0 > 0 ? 1 : 0; k <= (t1 < 1 ? s.k_max - 1 : s.k_max); ++k) {
      const double d = depth_on(pa, pb, t0 + k * step, b, star);
      if (d > s.best) {
        s.best = d;
        s.at = k;
      }
    }
    return s;
  }

  // Above the part's deepest point (for a depth that is 1-Lipschitz along it, as the
  // distance to another body's surface is; not for self checks, whose star leaves a
  // jump): the deepest sample plus half their spacing, plus the tolerance.
  double sample_bound(const Samples& s) const { return s.best + 0.5 * s.length / s.k_max + tol_; }

  double refine_segment(const double* pa, const double* pb, const Samples& s, std::int32_t b,
                        const Star& star = {}) const {
    const double h = m_.median_edge > 0 ? m_.median_edge : 1.0, accuracy = kDepthAccuracy * h;
    double best = s.best;
    if (s.at < 0 || s.length / s.k_max <= 2 * accuracy) return best;
    auto depth_at = [&](double t) { return depth_on(pa, pb, t, b, star); };
    const double step = (s.t1 - s.t0) / s.k_max;
    constexpr double kGolden = 0.6180339887498949;
    double lo = s.t0 + std::max(s.at - 1, 0) * step, hi = s.t0 + std::min(s.at + 1, s.k_max) * step;
    double x1 = hi - kGolden * (hi - lo), x2 = lo + kGolden * (hi - lo);
    double f1 = depth_at(x1), f2 = depth_at(x2);
    const double scale = s.length / (s.t1 - s.t0);  // metres per unit of t
    for (int it = 0; it < 40 && (hi - lo) * scale > accuracy; ++it) {
      if (f1 >= f2) {
        hi = x2;
        x2 = x1;
        f2 = f1;
        x1 = hi - kGolden * (hi - lo);
        f1 = depth_at(x1);
      } else {
        lo = x1;
        x1 = x2;
        f1 = f2;
        x2 = lo + kGolden * (hi - lo);
        f2 = depth_at(x2);
      }
      best = std::max({best, f1, f2});
    }
    return best;
  }

  double tolerance() const { return tol_; }
  const CellBins& triangle_bins() const { return tris_; }
  /// Triangle t's box: lo (3), then hi (3).
  const double* tri_box(std::size_t t) const { return &tri_box_[6 * t]; }

private:
  void boxes(const gid_t* cells, int corners, std::size_t count, std::vector<double>& lo, std::vector<double>& hi) const {
    lo.assign(3 * count, 0);
    hi.assign(3 * count, 0);
    parallel_for(count, [&](std::size_t i) {
      for (int d = 0; d < 3; ++d) {
        double a = std::numeric_limits<double>::infinity(), b = -a;
        for (int k = 0; k < corners; ++k) {
          const double v = X(cells[static_cast<std::size_t>(corners) * i + static_cast<std::size_t>(k)])[d];
          if (!std::isfinite(v)) a = b = std::numeric_limits<double>::quiet_NaN();
          a = std::min(a, v);  // NaN stays (std::min keeps the first argument when unordered)
          b = std::max(b, v);
        }
        // Grown by the tolerance: the closed tests with their tolerances accept points just
        // outside the exact boxes, and the grid must offer those too.
        lo[3 * i + static_cast<std::size_t>(d)] = a - tol_;
        hi[3 * i + static_cast<std::size_t>(d)] = b + tol_;
      }
    });
  }

  const VerifyMesh& m_;
  const double* x_;
  double tol_ = 0;
  CellBins tets_, tris_;
  std::vector<double> tri_box_;
};

// Index of the q-quantile (nearest rank) of n values in ascending order.
std::size_t nearest_rank(std::size_t n, double q) {
  return static_cast<std::size_t>(std::ceil(q * static_cast<double>(n))) - 1;
}

// Count, maximum (lowest id on a tie) and 99th percentile (nearest rank; over every
// process with a reduction) of the depths >= 0 of the vertices selected by `pick`.
template <class Pick>
InsideStats inside_stats(const VerifyMesh& m, const std::vector<double>& depth, const std::vector<std::int32_t>& in_obj,
                         const VerifyReduction* reduction, Pick pick) {
  InsideStats s;
  std::vector<double> all;
  for (std::size_t i = 0; i < depth.size(); ++i) {
    if (!pick(i) || depth[i] < 0) continue;
    ++s.count;
    all.push_back(depth[i]);
    if (s.vertex < 0 || depth[i] > s.max_depth) {
      s.max_depth = depth[i];
      s.vertex = static_cast<gid_t>(i);
      s.object = m.vertex_object[i];
      s.in_object = in_obj[i];
    }
  }
  if (reduction) {
    s.p99_depth = reduction->quantile(all, 0.99);
  } else if (!all.empty()) {
    const std::size_t k = nearest_rank(all.size(), 0.99);
    std::nth_element(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(k), all.end());
    s.p99_depth = all[k];
  }
  return s;
}

}  // namespace

void prepare_verify_mesh(VerifyMesh& m, const double* rest, const std::string& source) {
  const std::size_t n = m.vertex_object.size();
  if (m.tets.size() % 4 != 0 || m.tet_object.size() != m.tets.size() / 4)
    throw InputError(source, 0, "the tets (" + std::to_string(m.tets.size() / 4) + ") and their objects (" +
                                    std::to_string(m.tet_object.size()) + ") do not match");
  if (m.triangles.size() % 3 != 0) throw InputError(source, 0, "the surface triangles are not rows of 3");
  const std::size_t s = m.triangles.size() / 3;
  if (m.triangle_object.empty()) {
    m.triangle_object.resize(s);
    for (std::size_t t = 0; t < s; ++t) {
      const gid_t v = m.triangles[3 * t];
      m.triangle_object[t] = v >= 0 && static_cast<std::size_t>(v) < n ? m.vertex_object[static_cast<std::size_t>(v)] : -1;
    }
  }
  if (m.triangle_object.size() != s) throw InputError(source, 0, "the surface triangles and their objects do not match");
  std::int32_t top = -1;
  for (std::int32_t o : m.vertex_object) top = std::max(top, o);
  if (m.object_fixed.empty()) m.object_fixed.assign(static_cast<std::size_t>(top + 1), 0);
  const auto nobj = static_cast<std::int32_t>(m.object_fixed.size());
  auto check_object = [&](const char* what, std::size_t row, std::int32_t o) {
    if (o < 0 || o >= nobj)
      throw InputError(source, 0, row_error(what, row, "object " + std::to_string(o) + " is not in [0, " +
                                                           std::to_string(nobj) + ")"));
  };
  auto check_vertex = [&](const char* what, std::size_t row, gid_t v) {
    if (v < 0 || static_cast<std::size_t>(v) >= n)
      throw InputError(source, 0, row_error(what, row, "vertex " + std::to_string(v) + " is not in [0, " +
                                                           std::to_string(n) + ")"));
  };
  for (std::size_t i = 0; i < n; ++i) check_object("vertex", i, m.vertex_object[i]);
  for (std::size_t t = 0; t < m.num_tets(); ++t) {
    check_object("tet", t, m.tet_object[t]);
    for (int k = 0; k < 4; ++k) check_vertex("tet", t, m.tets[4 * t + static_cast<std::size_t>(k)]);
  }
  for (std::size_t t = 0; t < s; ++t) {
    check_object("surface triangle", t, m.triangle_object[t]);
    for (int k = 0; k < 3; ++k) check_vertex("surface triangle", t, m.triangles[3 * t + static_cast<std::size_t>(k)]);
  }

  auto P = [&](gid_t v) { return rest + 3 * static_cast<std::size_t>(v); };
  m.rest_sign.resize(m.num_tets());
  std::vector<double> len(6 * m.num_tets());
  for (std::size_t t = 0; t < m.num_tets(); ++t) {
    const gid_t* c = &m.tets[4 * t];
    m.rest_sign[t] = verify::orient(P(c[0]), P(c[1]), P(c[2]), P(c[3])) < 0 ? -1 : 1;
    for (int e = 0; e < 6; ++e) len[6 * t + static_cast<std::size_t>(e)] = std::sqrt(verify::dist2(P(c[kTetEdges[e][0]]), P(c[kTetEdges[e][1]])));
  }
  m.median_edge = 0;
  if (!len.empty()) {
    std::nth_element(len.begin(), len.begin() + static_cast<std::ptrdiff_t>(len.size() / 2), len.end());
    m.median_edge = len[len.size() / 2];
  }

  m.surface_vertex.assign(n, 0);
  m.edges.clear();
  m.edges.reserve(6 * s);
  std::vector<std::pair<gid_t, gid_t>> edges;
  edges.reserve(3 * s);
  for (std::size_t t = 0; t < s; ++t)
    for (int k = 0; k < 3; ++k) {
      const gid_t a = m.triangles[3 * t + static_cast<std::size_t>(k)], b = m.triangles[3 * t + static_cast<std::size_t>((k + 1) % 3)];
      m.surface_vertex[static_cast<std::size_t>(a)] = 1;
      edges.emplace_back(std::min(a, b), std::max(a, b));
    }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  for (const auto& [a, b] : edges) {
    m.edges.push_back(a);
    m.edges.push_back(b);
  }

  // Mesh neighbours from the tets' edges.
  std::vector<std::pair<gid_t, gid_t>> pairs;
  pairs.reserve(12 * m.num_tets());
  for (std::size_t t = 0; t < m.num_tets(); ++t)
    for (const auto& e : kTetEdges) {
      const gid_t a = m.tets[4 * t + static_cast<std::size_t>(e[0])], b = m.tets[4 * t + static_cast<std::size_t>(e[1])];
      pairs.emplace_back(a, b);
      pairs.emplace_back(b, a);
    }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  m.neighbour_begin.assign(n + 1, 0);
  m.neighbours.clear();
  m.neighbours.reserve(pairs.size());
  for (const auto& [a, b] : pairs) {
    ++m.neighbour_begin[static_cast<std::size_t>(a) + 1];
    m.neighbours.push_back(b);
  }
  for (std::size_t i = 0; i < n; ++i) m.neighbour_begin[i + 1] += m.neighbour_begin[i];

  m.object_triangle_begin.assign(static_cast<std::size_t>(nobj) + 1, 0);
  for (std::int32_t o : m.triangle_object) ++m.object_triangle_begin[static_cast<std::size_t>(o) + 1];
  for (std::size_t k = 0; k < static_cast<std::size_t>(nobj); ++k) m.object_triangle_begin[k + 1] += m.object_triangle_begin[k];
  m.object_triangles.assign(s, 0);
  std::vector<gid_t> at(m.object_triangle_begin.begin(), m.object_triangle_begin.end() - 1);
  for (std::size_t t = 0; t < s; ++t)
    m.object_triangles[static_cast<std::size_t>(at[static_cast<std::size_t>(m.triangle_object[t])]++)] = static_cast<gid_t>(t);
}

std::vector<double> initial_positions(const Scene& scene) {
  std::vector<double> x;
  x.reserve(3 * scene.num_vertices());
  for (std::size_t k = 0; k < scene.objects.size(); ++k) {
    const Scene::MeshView m = scene.view_mesh(k);
    x.insert(x.end(), m.get().points.begin(), m.get().points.end());
  }
  return x;
}

VerifyMesh verify_mesh_of(const Scene& scene) {
  VerifyMesh m;
  gid_t base = 0;
  for (std::size_t k = 0; k < scene.objects.size(); ++k) {
    const SceneObject& o = scene.objects[k];
    const auto obj = static_cast<std::int32_t>(k);
    // Whole-scene: a mesh this rank dropped is made for the pass and not kept.
    const Scene::MeshView view = scene.view_mesh(k);
    const TetMesh& mesh = view.get();
    const Surface surface = o.surface ? *o.surface : extract_surface(mesh);
    m.vertex_object.insert(m.vertex_object.end(), mesh.num_vertices(), obj);
    for (index_t v : mesh.tets) m.tets.push_back(base + v);
    m.tet_object.insert(m.tet_object.end(), mesh.num_tets(), obj);
    for (index_t v : surface.triangles) m.triangles.push_back(base + v);
    m.triangle_object.insert(m.triangle_object.end(), surface.num_triangles(), obj);
    m.object_fixed.push_back(o.kinematic() ? 1 : 0);
    base += static_cast<gid_t>(mesh.num_vertices());
  }
  prepare_verify_mesh(m, initial_positions(scene).data(), scene.path);
  return m;
}

void height_range(const double* x0, std::size_t n, const Vec3& g, double& lo, double& hi) {
  const double gn = std::sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
  for (std::size_t i = 0; gn > 0 && i < n; ++i) {
    const double h = (x0[3 * i] * g[0] + x0[3 * i + 1] * g[1] + x0[3 * i + 2] * g[2]) / gn;
    if (!std::isfinite(h)) continue;
    lo = std::min(lo, h);
    hi = std::max(hi, h);
  }
}

double free_fall_speed(double lo, double hi, const Vec3& g, double v0) {
  const double gn = std::sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
  const double height = gn > 0 && hi > lo ? hi - lo : 0;
  return std::sqrt(v0 * v0 + 2 * gn * height);
}

double free_fall_speed(const double* x0, std::size_t n, const Vec3& g, double v0) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  height_range(x0, n, g, lo, hi);
  return free_fall_speed(lo, hi, g, v0);
}

namespace {

void merge_inside(InsideStats& s, const InsideStats& p) {
  s.count += p.count;
  if (p.vertex >= 0 && (s.vertex < 0 || p.max_depth > s.max_depth || (p.max_depth == s.max_depth && p.vertex < s.vertex))) {
    s.max_depth = p.max_depth;
    s.vertex = p.vertex;
    s.object = p.object;
    s.in_object = p.in_object;
  }
}

void merge_crossings(CrossingStats& s, const CrossingStats& p) {
  s.count += p.count;
  s.without_inside_vertex += p.without_inside_vertex;
  s.grazing += p.grazing;
  const bool lower_edge = p.edge[0] != s.edge[0] ? p.edge[0] < s.edge[0] : p.edge[1] < s.edge[1];
  if (p.triangle >= 0 && (s.triangle < 0 || p.max_depth > s.max_depth || (p.max_depth == s.max_depth && lower_edge))) {
    s.max_depth = p.max_depth;
    s.edge[0] = p.edge[0];
    s.edge[1] = p.edge[1];
    s.triangle = p.triangle;
    s.object = p.object;
    s.in_object = p.in_object;
  }
}

}  // namespace

void merge_verify_part(VerifyFrame& f, const VerifyFrame& p) {
  merge_inside(f.surface, p.surface);
  merge_inside(f.interior, p.interior);
  merge_inside(f.self, p.self);
  merge_crossings(f.self_crossings, p.self_crossings);
  merge_crossings(f.crossings, p.crossings);
  if (p.inverted > 0 && (f.inverted == 0 || p.first_inverted < f.first_inverted)) f.first_inverted = p.first_inverted;
  f.inverted += p.inverted;
  f.nonfinite += p.nonfinite;
  if (p.fastest >= 0 && (f.fastest < 0 || p.max_speed > f.max_speed || (p.max_speed == f.max_speed && p.fastest < f.fastest))) {
    f.max_speed = p.max_speed;
    f.fastest = p.fastest;
  }
  for (int k = 0; k < kRecordStatuses; ++k) f.deep_by_record[k] += p.deep_by_record[k];
}

double initial_speed(const Scene& scene) {
  double v0 = 0;
  auto norm = [](const Vec3& v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); };
  for (const SceneObject& o : scene.objects) v0 = std::max({v0, norm(o.velocity()), norm(o.motion().velocity)});
  return v0;
}

double free_fall_speed(const Scene& scene) {
  const std::vector<double> x0 = initial_positions(scene);
  return free_fall_speed(x0.data(), x0.size() / 3, scene.sim.gravity, initial_speed(scene));
}

VerifyFrame verify_frame(const VerifyMesh& m, const double* x, const double* v, const VerifyOptions& opt) {
  VerifyFrame f;
  f.median_edge = m.median_edge;
  const std::size_t n = m.num_vertices();
  const FrameCheck check(m, x);
  // The bodies whose vertices, edges and tets this check counts (VerifyOptions::counted).
  auto counted = [&](std::int32_t body) { return !opt.counted || opt.counted[static_cast<std::size_t>(body)] != 0; };
  const VerifyReduction* reduction = opt.counted ? opt.reduction : nullptr;

  // Non-finite vertices, and the speeds.
  std::vector<char> bad(n, 0);
  std::vector<double> speed(n, 0);
  parallel_for(n, [&](std::size_t i) {
    const double* p = x + 3 * i;
    bool ok = std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]);
    if (v) {
      const double* w = v + 3 * i;
      speed[i] = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
      ok = ok && std::isfinite(speed[i]);
    }
    bad[i] = ok ? 0 : 1;
  });
  for (std::size_t i = 0; i < n; ++i) {
    if (!counted(m.vertex_object[i])) continue;
    f.nonfinite += bad[i];
    if (!bad[i] && speed[i] > f.max_speed) {
      f.max_speed = speed[i];
      f.fastest = static_cast<gid_t>(i);
    }
  }
  if (opt.free_fall_speed > 0) f.speed_ratio = f.max_speed / opt.free_fall_speed;

  // Vertices inside other bodies.
  std::vector<double> depth(n, -1);
  std::vector<std::int32_t> in_obj(n, -1);
  std::vector<std::int8_t> in_count(n, 0);  // bodies the vertex is inside (2: two or more)
  parallel_for(n, [&](std::size_t i) {
    if (bad[i] || (!opt.interior && !m.surface_vertex[i]) || !counted(m.vertex_object[i])) return;
    const double* p = x + 3 * i;
    constexpr int kCap = 16;
    std::int32_t found[kCap];
    const int k = check.bodies_holding(p, m.vertex_object[i], found, kCap);
    for (int j = 0; j < k; ++j) {
      const double d = check.surface_distance(p, found[j]);
      if (d <= check.tolerance()) continue;
      in_count[i] = static_cast<std::int8_t>(std::min(in_count[i] + 1, 2));
      if (d > depth[i] || (d == depth[i] && found[j] < in_obj[i])) {
        depth[i] = d;
        in_obj[i] = found[j];
      }
    }
  });
  f.surface = inside_stats(m, depth, in_obj, reduction, [&](std::size_t i) { return m.surface_vertex[i] != 0; });
  if (opt.record) {
    const double limit = opt.record_limit * m.median_edge;
    for (std::size_t i = 0; i < n; ++i)
      if (m.surface_vertex[i] && depth[i] > limit) {
        const int st = opt.record[i];
        ++f.deep_by_record[st >= 0 && st < kRecordStatuses ? st : kNoRecord];
      }
  }
  if (opt.self) {
    std::vector<double> self(n, -1);
    std::vector<std::int32_t> self_obj(m.vertex_object);
    parallel_for(n, [&](std::size_t i) {
      if (bad[i] || !m.surface_vertex[i] || m.object_fixed[static_cast<std::size_t>(m.vertex_object[i])] ||
          !counted(m.vertex_object[i]))
        return;
      self[i] = check.self_depth(static_cast<gid_t>(i), m.vertex_object[i]);
    });
    f.self = inside_stats(m, self, self_obj, reduction, [](std::size_t) { return true; });
  }
  if (opt.interior)
    f.interior = inside_stats(m, depth, in_obj, reduction, [&](std::size_t i) { return m.surface_vertex[i] == 0; });

  // Surface edges through other bodies' surface triangles.
  if (opt.crossings) {
    struct EdgeResult {
      std::int32_t count = 0, without_inside = 0, grazing = 0;
      double depth = -1;
      std::int32_t triangle = -1;
      std::int32_t self_count = 0;  // through its own body's surface, away from the edge's stars
      double self_depth = -1;
      std::int32_t self_triangle = -1;
    };
    struct Hit {
      double t;                // crossing point a + t (b - a)
      std::int32_t body, triangle;
      bool entering;           // a lies on the triangle's outer side
    };
    // A crossing's part of the edge inside the crossed body (see the first pass below).
    struct Part {
      std::size_t edge = 0;
      Hit hit;
      FrameCheck::Samples s;
      std::int32_t same_as = -1;  // an exiting crossing after an entering one: that crossing's part (index in the edge's)
    };
    const std::size_t ne = m.edges.size() / 2;
    std::vector<EdgeResult> er(ne);
    // The crossing edges' parts, each thread's in its own list (memory for the crossings
    // only, not for every edge).
    std::vector<std::vector<Part>> found(static_cast<std::size_t>(omp_get_max_threads()));
    const CellBins& bins = check.triangle_bins();
    // Vertex v inside body b, from the vertex pass (surface vertices of counted bodies
    // are always checked there; the others here, as the pass would have).
    auto inside = [&](gid_t v, std::int32_t b) {
      const auto u = static_cast<std::size_t>(v);
      if (!counted(m.vertex_object[u])) return !bad[u] && check.depth_in(check.X(v), b) > 0;
      return in_count[u] > 0 && (in_obj[u] == b || (in_count[u] > 1 && check.depth_in(check.X(v), b) > 0));
    };
    parallel_for(ne, [&](std::size_t e) {
      const gid_t a = m.edges[2 * e], b = m.edges[2 * e + 1];
      const std::int32_t own = m.vertex_object[static_cast<std::size_t>(a)];
      if (bad[static_cast<std::size_t>(a)] || bad[static_cast<std::size_t>(b)] || !counted(own)) return;
      const double *pa = check.X(a), *pb = check.X(b);
      double lo[3], hi[3];
      for (int d = 0; d < 3; ++d) {
        lo[d] = std::min(pa[d], pb[d]);
        hi[d] = std::max(pa[d], pb[d]);
      }
      std::vector<Hit> hits;  // allocates only for crossing edges
      const Star star{a, b};
      auto test = [&](std::size_t t) {
        const double* box = check.tri_box(t);
        for (int d = 0; d < 3; ++d)
          if (box[3 + d] < lo[d] || box[d] > hi[d]) return;
        const std::int32_t body = m.triangle_object[t];
        const bool self = body == own;
        if (self ? !opt.self || m.object_fixed[static_cast<std::size_t>(own)] : check.skip_pair(own, body)) return;
        const gid_t* c = &m.triangles[3 * t];
        bool a_outside = false;
        const double s = verify::segment_crosses_triangle(pa, pb, check.X(c[0]), check.X(c[1]), check.X(c[2]),
                                                          check.tolerance(), kBarycentricTol, a_outside);
        if (s < 0 || (self && check.touches(star, c, 3))) return;  // none, or the edge's own neighbourhood
        hits.push_back({s, body, static_cast<std::int32_t>(t), a_outside});
      };
      const CellBins::Cell c0 = bins.cell_of(lo), c1 = bins.cell_of(hi);
      for (std::int64_t cx = c0[0]; cx <= c1[0]; ++cx)
        for (std::int64_t cy = c0[1]; cy <= c1[1]; ++cy)
          for (std::int64_t cz = c0[2]; cz <= c1[2]; ++cz)
            for (std::int32_t t : bins.at({cx, cy, cz})) {
              // Each (edge, triangle) pair in the first cell the two boxes share.
              const CellBins::Cell& tf = bins.first_cell(static_cast<std::size_t>(t));
              if (std::max(c0[0], tf[0]) == cx && std::max(c0[1], tf[1]) == cy && std::max(c0[2], tf[2]) == cz)
                test(static_cast<std::size_t>(t));
            }
      for (std::int32_t t : bins.oversized()) test(static_cast<std::size_t>(t));
      if (hits.empty()) return;
      std::sort(hits.begin(), hits.end(), [](const Hit& x, const Hit& y) {
        return x.body != y.body ? x.body < y.body : x.t != y.t ? x.t < y.t : x.triangle < y.triangle;
      });
      // Each crossing's part of the edge inside its body, sampled.
      std::vector<Part>& out = found[static_cast<std::size_t>(omp_get_thread_num())];
      const std::size_t first = out.size();
      out.resize(first + hits.size());
      for (std::size_t j = 0; j < hits.size(); ++j) {
        const Hit& h = hits[j];
        Part& p = out[first + j];
        p.edge = e;
        p.hit = h;
        // The part of the edge inside the body that this crossing bounds: towards the
        // inner side up to the edge's next crossing with the same body, or its end.
        double t0 = 0, t1 = 1;
        if (h.entering) {
          t0 = h.t;
          for (std::size_t k = j + 1; k < hits.size() && hits[k].body == h.body; ++k)
            if (hits[k].t > h.t) {
              t1 = hits[k].t;
              break;
            }
        } else {
          t1 = h.t;
          for (std::size_t k = j; k-- > 0 && hits[k].body == h.body;)
            if (hits[k].t < h.t) {
              t0 = hits[k].t;
              break;
            }
        }
        // An exiting crossing after an entering one bounds the same part: computed once.
        for (std::size_t k = j; k-- > 0 && hits[k].body == h.body && !h.entering;)
          if (hits[k].t < h.t) {
            if (hits[k].entering) p.same_as = static_cast<std::int32_t>(k);
            break;
          }
        if (p.same_as < 0) p.s = check.sample_segment(pa, pb, t0, t1, h.body, h.body == own ? star : Star{});
      }
    });
    // The deepest sample of any crossing with another body: the frame's deepest crossing
    // is at least that deep, so a part whose bound (sample_bound) lies below it cannot
    // hold it, and its samples stand for its depth without the golden-section search (an
    // edge's depth is used for the frame's deepest crossing only). Whether a crossing
    // counts (deeper than the tolerance) is decided by its samples already when they are
    // deeper. The threshold depends on the samples alone: the same on any thread count.
    // Self crossings are always searched (the star's jump breaks the bound).
    // In edge order (each edge's parts lie together, in order, in one thread's list).
    std::vector<Part> parts;
    for (std::vector<Part>& l : found) {
      parts.insert(parts.end(), l.begin(), l.end());
      std::vector<Part>().swap(l);
    }
    std::stable_sort(parts.begin(), parts.end(), [](const Part& x, const Part& y) { return x.edge < y.edge; });
    std::vector<std::size_t> edge_begin;  // where each crossing edge's parts begin, then the end
    double sampled = 0;
    for (std::size_t k = 0; k < parts.size(); ++k) {
      const Part& p = parts[k];
      if (k == 0 || p.edge != parts[k - 1].edge) edge_begin.push_back(k);
      if (p.same_as < 0 && p.hit.body != m.vertex_object[static_cast<std::size_t>(m.edges[2 * p.edge])])
        sampled = std::max(sampled, p.s.best);
    }
    edge_begin.push_back(parts.size());
    if (reduction) sampled = reduction->max(sampled);  // the whole check's (the same threshold on any process count)
    parallel_for(edge_begin.size() - 1, [&](std::size_t g) {
      const std::span<const Part> ps(parts.data() + edge_begin[g], edge_begin[g + 1] - edge_begin[g]);
      const std::size_t e = ps[0].edge;
      const gid_t a = m.edges[2 * e], b = m.edges[2 * e + 1];
      const double *pa = check.X(a), *pb = check.X(b);
      const std::int32_t own = m.vertex_object[static_cast<std::size_t>(a)];
      const Star star{a, b};
      EdgeResult& r = er[e];
      std::vector<double> depth(ps.size(), -1);
      for (std::size_t j = 0; j < ps.size(); ++j) {
        const Part& p = ps[j];
        const Hit& h = p.hit;
        const bool self = h.body == own;
        double deepest = 0;
        if (p.same_as >= 0) deepest = depth[static_cast<std::size_t>(p.same_as)];
        else if (!self && p.s.best > check.tolerance() && check.sample_bound(p.s) < sampled) deepest = p.s.best;
        else deepest = check.refine_segment(pa, pb, p.s, h.body, self ? star : Star{});
        depth[j] = deepest;
        if (deepest <= check.tolerance()) {
          r.grazing += self ? 0 : 1;  // through a triangle's rim, or touching: not inside anywhere
          continue;
        }
        if (self) {
          ++r.self_count;
          if (deepest > r.self_depth || (deepest == r.self_depth && h.triangle < r.self_triangle)) {
            r.self_depth = deepest;
            r.self_triangle = h.triangle;
          }
          continue;
        }
        const gid_t* c = &m.triangles[3 * static_cast<std::size_t>(h.triangle)];
        bool touching = inside(a, h.body) || inside(b, h.body);
        for (int k = 0; k < 3 && !touching; ++k) touching = inside(c[k], own);
        ++r.count;
        r.without_inside += touching ? 0 : 1;
        if (deepest > r.depth || (deepest == r.depth && h.triangle < r.triangle)) {
          r.depth = deepest;
          r.triangle = h.triangle;
        }
      }
    });
    for (std::size_t e = 0; e < ne; ++e) {
      const EdgeResult& r = er[e];
      if (r.self_count > 0) {
        CrossingStats& sc = f.self_crossings;
        sc.count += r.self_count;
        if (sc.triangle < 0 || r.self_depth > sc.max_depth) {
          sc.max_depth = r.self_depth;
          sc.edge[0] = m.edges[2 * e];
          sc.edge[1] = m.edges[2 * e + 1];
          sc.triangle = r.self_triangle;
          sc.object = sc.in_object = m.vertex_object[static_cast<std::size_t>(m.edges[2 * e])];
        }
      }
      f.crossings.grazing += r.grazing;
      if (r.count == 0) continue;
      f.crossings.count += r.count;
      f.crossings.without_inside_vertex += r.without_inside;
      if (f.crossings.triangle < 0 || r.depth > f.crossings.max_depth) {
        f.crossings.max_depth = r.depth;
        f.crossings.edge[0] = m.edges[2 * e];
        f.crossings.edge[1] = m.edges[2 * e + 1];
        f.crossings.triangle = r.triangle;
        f.crossings.object = m.vertex_object[static_cast<std::size_t>(m.edges[2 * e])];
        f.crossings.in_object = m.triangle_object[static_cast<std::size_t>(r.triangle)];
      }
    }
  }

  // Inverted tets.
  const std::size_t nt = m.num_tets();
  std::vector<char> inverted(nt, 0);
  parallel_for(nt, [&](std::size_t t) {
    if (!counted(m.tet_object[t])) return;
    const gid_t* c = &m.tets[4 * t];
    const double vol = verify::orient(check.X(c[0]), check.X(c[1]), check.X(c[2]), check.X(c[3]));
    inverted[t] = std::isfinite(vol) && vol * m.rest_sign[t] <= 0 ? 1 : 0;
  });
  for (std::size_t t = 0; t < nt; ++t)
    if (inverted[t]) {
      if (f.inverted == 0) f.first_inverted = static_cast<gid_t>(t);
      ++f.inverted;
    }
  return f;
}

}  // namespace softcontact
