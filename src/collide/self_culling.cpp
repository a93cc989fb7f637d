#include "self_culling.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "../model/polar_decomposition.hpp"
#include "parallel.hpp"
#include "triangle_queries.hpp"

namespace softcontact::collide {

namespace {

// Distance from p to the closed tet (a, b, c, d): 0 inside, else to the nearest face.
double point_tet_distance(const V3& p, const V3& a, const V3& b, const V3& c, const V3& d) {
  const double v = orient(a, b, c, d);
  const double s0 = orient(p, b, c, d), s1 = orient(a, p, c, d), s2 = orient(a, b, p, d), s3 = orient(a, b, c, p);
  if (v != 0 && s0 * v >= 0 && s1 * v >= 0 && s2 * v >= 0 && s3 * v >= 0) return 0;
  const V3 f[4][3] = {{b, c, d}, {a, c, d}, {a, b, d}, {a, b, c}};
  double best = std::numeric_limits<double>::infinity();
  std::array<double, 3> bary{};
  for (const auto& t : f) best = std::min(best, norm2(p - closest_point_on_triangle(p, t[0], t[1], t[2], bary)));
  return std::sqrt(best);
}

}  // namespace

namespace {
// The largest |coordinate| of an object's reference positions [m]: the scale of the
// rounding in its distances.
double coordinate_scale(const ObjectInfo& o, const double* x) {
  double m = 0;
  for (index_t v : o.vertices)
    for (int d = 0; d < 3; ++d) m = std::max(m, std::abs(x[3 * static_cast<std::size_t>(v) + static_cast<std::size_t>(d)]));
  return m;
}
}  // namespace

void SelfCulling::build(const World& w, const CollisionTopology& topo, const double* x_ref, SelfGapCache* known) {
  ref_.assign(x_ref, x_ref + 3 * w.n_local());
  const std::size_t no = topo.objects.size();
  gap_.assign(no, 0);
  // have[k]: 0 compute, 1 known by object, 2 derived from its entry's gap (after the
  // leaders are computed).
  std::vector<std::uint8_t> have(no, 0);
  auto entry_of = [&](std::size_t k) {
    const auto obj = static_cast<std::size_t>(topo.objects[k].object);
    return known && obj < known->entry.size() ? known->entry[obj] : -1;
  };
  if (known) {
    std::vector<std::int32_t> led;  // entries whose gap a slot of this build computes
    for (std::size_t k = 0; k < no; ++k) {
      const auto it = known->gap.find(topo.objects[k].object);
      if (it != known->gap.end()) {
        gap_[k] = it->second;
        have[k] = 1;
        continue;
      }
      const std::int32_t e = entry_of(k);
      if (e < 0) continue;
      if (known->entry_gap.count(e) || std::find(led.begin(), led.end(), e) != led.end()) have[k] = 2;
      else led.push_back(e);  // the lowest slot of its entry leads
    }
  }
  compute(w, topo, have);
  if (!known) return;
  // Leaders (have 0, with an entry) give their entry's gap, in slot order.
  for (std::size_t k = 0; k < no; ++k) {
    const std::int32_t e = entry_of(k);
    if (have[k] == 0 && e >= 0 && !known->entry_gap.count(e))
      known->entry_gap.emplace(e, SelfGapCache::EntryGap{gap_[k], coordinate_scale(topo.objects[k], ref_.data())});
  }
  // A copy of an entry is its rigid image, so its true gap is the entry's; the computed
  // one differs by rounding, about eps times the coordinates: the copy takes the entry's
  // less 1e-9 of it and 64 eps of both coordinate scales (a smaller gap only tests more
  // objects; the records do not change).
  parallel_for_dynamic(no, [&](std::size_t k, int) {
    if (have[k] != 2) return;
    const SelfGapCache::EntryGap& eg = known->entry_gap.at(entry_of(k));
    const double eps = std::numeric_limits<double>::epsilon();
    const double g = eg.gap - 1e-9 * eg.gap - 64 * eps * (eg.scale + coordinate_scale(topo.objects[k], ref_.data()));
    gap_[k] = g > 0 ? g : 0;
  });
  for (std::size_t k = 0; k < no; ++k) known->gap.emplace(topo.objects[k].object, gap_[k]);
}

void SelfCulling::compute(const World& w, const CollisionTopology& topo, const std::vector<std::uint8_t>& have) {
  const std::size_t no = topo.objects.size();
  parallel_for_dynamic(no, [&](std::size_t k, int) {
    const ObjectInfo& o = topo.objects[k];
    if (have[k] || o.tets.empty() || o.surface_vertices.empty()) return;
    const double* x = ref_.data();
    Box box;
    box.reset();
    for (index_t v : o.vertices) box.add(load(x, v));
    double L = 0;
    std::vector<V3> centre(o.tets.size());
    for (std::size_t q = 0; q < o.tets.size(); ++q) {
      Box tb;
      tb.reset();
      for (int c = 0; c < 4; ++c) tb.add(load(x, w.tets[4 * static_cast<std::size_t>(o.tets[q]) + static_cast<std::size_t>(c)]));
      for (std::size_t d = 0; d < 3; ++d) L = std::max(L, tb.hi[d] - tb.lo[d]);
      centre[q] = 0.5 * (tb.lo + tb.hi);
    }
    if (!(L > 0) || !std::isfinite(L) || box.empty()) return;
    std::int64_t dim[3];
    for (std::size_t d = 0; d < 3; ++d) dim[d] = static_cast<std::int64_t>((box.hi[d] - box.lo[d]) / L) + 1;
    auto cell = [&](const V3& p, std::size_t d) {
      return std::clamp(static_cast<std::int64_t>((p[d] - box.lo[d]) / L), std::int64_t{0}, dim[d] - 1);
    };
    auto key = [&](std::int64_t i, std::int64_t j, std::int64_t l) { return (i * dim[1] + j) * dim[2] + l; };
    std::vector<std::pair<std::int64_t, index_t>> bins(o.tets.size());
    for (std::size_t q = 0; q < o.tets.size(); ++q)
      bins[q] = {key(cell(centre[q], 0), cell(centre[q], 1), cell(centre[q], 2)), o.tets[q]};
    std::sort(bins.begin(), bins.end());
    double gap = 0.5 * L;
    for (index_t v : o.surface_vertices) {
      const V3 p = load(x, v);
      const auto u = static_cast<std::size_t>(v);
      const auto nb0 = topo.edge_to.begin() + static_cast<std::ptrdiff_t>(topo.edge_begin[u]);
      const auto nb1 = topo.edge_to.begin() + static_cast<std::ptrdiff_t>(topo.edge_begin[u + 1]);
      const std::int64_t ci = cell(p, 0), cj = cell(p, 1), cl = cell(p, 2);
      for (std::int64_t i = std::max<std::int64_t>(ci - 1, 0); i <= std::min(ci + 1, dim[0] - 1); ++i)
        for (std::int64_t j = std::max<std::int64_t>(cj - 1, 0); j <= std::min(cj + 1, dim[1] - 1); ++j)
          for (std::int64_t l = std::max<std::int64_t>(cl - 1, 0); l <= std::min(cl + 1, dim[2] - 1); ++l) {
            const std::int64_t kk = key(i, j, l);
            auto it = std::lower_bound(bins.begin(), bins.end(), std::make_pair(kk, std::numeric_limits<index_t>::min()));
            for (; it != bins.end() && it->first == kk; ++it) {
              const index_t* tv = &w.tets[4 * static_cast<std::size_t>(it->second)];
              bool near = false;
              for (int c = 0; c < 4 && !near; ++c) near = tv[c] == v || std::binary_search(nb0, nb1, tv[c]);
              if (near) continue;
              gap = std::min(gap, point_tet_distance(p, load(x, tv[0]), load(x, tv[1]), load(x, tv[2]), load(x, tv[3])));
            }
          }
    }
    gap_[k] = gap;
  });
}

void SelfCulling::update(const double* x, const CollisionTopology& topo, const std::uint8_t* bad_vertex,
                         const std::uint8_t* tested, std::vector<std::uint8_t>& active,
                         std::vector<double>& delta) const {
  const std::size_t no = topo.objects.size();
  active.assign(no, 1);
  delta.assign(no, std::numeric_limits<double>::infinity());
  parallel_for_dynamic(no, [&](std::size_t k, int) {
    if (tested && !tested[k]) {
      active[k] = 0;
      return;
    }
    const ObjectInfo& o = topo.objects[k];
    if (o.vertices.empty() || !(gap_[k] > 0)) return;
    V3 c{0, 0, 0}, C{0, 0, 0};
    for (index_t v : o.vertices) {
      if (bad_vertex[static_cast<std::size_t>(v)]) return;
      c = c + load(x, v);
      C = C + load(ref_.data(), v);
    }
    const double inv = 1.0 / static_cast<double>(o.vertices.size());
    c = inv * c;
    C = inv * C;
    model::Mat3 A{};
    for (index_t v : o.vertices) {
      const V3 a = load(x, v) - c, b = load(ref_.data(), v) - C;
      for (std::size_t i = 0; i < 3; ++i)
        for (std::size_t j = 0; j < 3; ++j) A[3 * i + j] += a[i] * b[j];
    }
    const model::Mat3 R = model::rotation_part(A);
    double d2 = 0;
    for (index_t v : o.vertices) {
      const V3 b = load(ref_.data(), v) - C;
      const V3 rb{R[0] * b[0] + R[1] * b[1] + R[2] * b[2], R[3] * b[0] + R[4] * b[1] + R[5] * b[2],
                  R[6] * b[0] + R[7] * b[1] + R[8] * b[2]};
      d2 = std::max(d2, norm2(load(x, v) - c - rb));
    }
    const double dl = std::sqrt(d2);
    delta[k] = dl;
    active[k] = std::isfinite(dl) && 2 * dl < gap_[k] ? 0 : 1;
  });
}

}  // namespace softcontact::collide
