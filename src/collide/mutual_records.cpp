#include "mutual_records.hpp"

#include <algorithm>
#include <cmath>

#include "smoothed_normals.hpp"
#include "vec3.hpp"

namespace softcontact::collide {

namespace {

// The vertex of the record's triangle with the largest weight (the lowest corner on a
// tie), or -1 when that weight is under min_weight or the record is no vertex record
// between two bodies.
int heavy_corner(const Collision& c, double min_weight) {
  if (c.point2 >= 0 || c.object == c.other_object || c.triangle_gid < 0) return -1;
  int k = 0;
  for (int a = 1; a < 3; ++a)
    if (c.weight[static_cast<std::size_t>(a)] > c.weight[static_cast<std::size_t>(k)]) k = a;
  return c.weight[static_cast<std::size_t>(k)] >= min_weight ? k : -1;
}

bool key_less(const RecordKey& a, const RecordKey& b) {
  if (a.point_gid != b.point_gid) return a.point_gid < b.point_gid;
  return a.other_object < b.other_object;
}

}  // namespace

void mutual_record_keys(const World& w, const std::vector<Collision>& records, double min_weight,
                        std::vector<RecordKey>& keys) {
  for (const Collision& c : records) {
    const int k = heavy_corner(c, min_weight);
    if (k < 0) continue;
    RecordKey key;
    key.point_gid = c.point_gid;
    key.heavy_gid = w.vertex_gid[static_cast<std::size_t>(c.triangle[static_cast<std::size_t>(k)])];
    key.other_object = c.other_object;
    for (int d = 0; d < 3; ++d) key.depth[d] = c.depth[static_cast<std::size_t>(d)];
    keys.push_back(key);
  }
}

std::int64_t settle_mutual_pairs(const World& w, const CollisionTopology& topo, std::vector<Collision>& records,
                                 std::vector<RecordKey>& keys, double min_weight) {
  // A vertex has at most one record per other body, so (point, other body) is a key, and
  // each rank sends only its own records' keys: no key should come twice; unique() keeps
  // the lookup well defined if one did.
  std::sort(keys.begin(), keys.end(), key_less);
  keys.erase(std::unique(keys.begin(), keys.end(),
                         [](const RecordKey& a, const RecordKey& b) { return !key_less(a, b) && !key_less(b, a); }),
             keys.end());
  const double* x = w.x.data();
  const index_t* tri = w.triangles.data();
  std::int64_t changed = 0;
  // Each record is decided from the records as detected (the keys hold their depths), so
  // the order of the loop cannot matter, and both halves of a pair, on one rank or two,
  // compute the same axis and length with opposite signs: m and -m are exact negatives,
  // and (x_j - x_i) . m = (x_i - x_j) . (-m) to the bit.
  for (Collision& c : records) {
    const int k = heavy_corner(c, min_weight);
    if (k < 0) continue;
    const index_t j = c.triangle[static_cast<std::size_t>(k)];
    RecordKey probe;
    probe.point_gid = w.vertex_gid[static_cast<std::size_t>(j)];
    probe.other_object = c.object;
    const auto it = std::lower_bound(keys.begin(), keys.end(), probe, key_less);
    if (it == keys.end() || it->point_gid != probe.point_gid || it->other_object != c.object ||
        it->heavy_gid != c.point_gid)
      continue;
    const V3 di{c.depth[0], c.depth[1], c.depth[2]};
    const V3 dj{it->depth[0], it->depth[1], it->depth[2]};
    if (!(dot(di, dj) > 0)) continue;  // opposite ways: the pair agrees
    const V3 m = normalized(vertex_normal(x, tri, topo, j) - vertex_normal(x, tri, topo, c.point));
    if (m[0] == 0 && m[1] == 0 && m[2] == 0) continue;
    const double overlap = dot(load(x, j) - load(x, c.point), m);
    const double li = std::sqrt(norm2(di)), lj = std::sqrt(norm2(dj));
    const double o = std::min(std::max(overlap, std::max(li, lj)), li + lj);
    for (int d = 0; d < 3; ++d) c.depth[static_cast<std::size_t>(d)] = o * m[d];
    ++changed;
  }
  return changed;
}

}  // namespace softcontact::collide
