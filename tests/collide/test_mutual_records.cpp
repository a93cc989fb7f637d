// Item 6 of "Penetration vectors" (docs/collision.md): mutual vertex records that point
// the same way are given one axis from the two surfaces' outward normals and one length.
// The reference normals are computed here from the World's surface triangles directly
// (every triangle that has the vertex as a corner), not with the detector's topology.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "collide_test_util.hpp"

using namespace softcontact;
using namespace softcontact::test;

namespace {

// Two boxes of 2 x 2 cells per face: A's top corner region pressed into B's bottom.
World two_boxes() {
  return world_from_objects(R"(
  - name: a
    material: m
    primitive: {type: box, size: [1, 1, 1], cells: [2, 2, 2]}
  - name: b
    material: m
    primitive: {type: box, size: [1, 1, 1], cells: [2, 2, 2]}
    transform: {translate: [0.3, 0.2, 0.9], rotate: [5, 3, 0]}
)");
}

std::array<double, 3> brute_normal(const World& w, index_t v) {
  std::array<double, 3> s{0, 0, 0};
  for (std::size_t t = 0; t < w.triangles.size() / 3; ++t) {
    const index_t* c = &w.triangles[3 * t];
    if (c[0] != v && c[1] != v && c[2] != v) continue;
    const double* a = &w.x[3 * static_cast<std::size_t>(c[0])];
    const double* b = &w.x[3 * static_cast<std::size_t>(c[1])];
    const double* e = &w.x[3 * static_cast<std::size_t>(c[2])];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, q[3] = {e[0] - a[0], e[1] - a[1], e[2] - a[2]};
    s[0] += u[1] * q[2] - u[2] * q[1];
    s[1] += u[2] * q[0] - u[0] * q[2];
    s[2] += u[0] * q[1] - u[1] * q[0];
  }
  const double n = std::sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
  for (double& c : s) c /= n;
  return s;
}

// A surface triangle of `object` with corner v, and v's corner index in it.
std::pair<std::size_t, int> triangle_at(const World& w, std::int32_t object, index_t v) {
  for (std::size_t t = 0; t < w.triangles.size() / 3; ++t)
    for (int k = 0; k < 3; ++k)
      if (w.triangles[3 * t + k] == v && w.vertex_object[static_cast<std::size_t>(v)] == object) return {t, k};
  return {0, -1};
}

// A record of point i against the triangle of B at vertex j, weight `wj` on j.
Collision record(const World& w, index_t i, index_t j, double wj, std::array<double, 3> d) {
  const std::int32_t b = w.vertex_object[static_cast<std::size_t>(j)];
  const auto [t, k] = triangle_at(w, b, j);
  EXPECT_GE(k, 0);
  Collision c;
  c.point = i;
  c.point_gid = w.vertex_gid[static_cast<std::size_t>(i)];
  c.object = w.vertex_object[static_cast<std::size_t>(i)];
  c.other_object = b;
  for (int q = 0; q < 3; ++q) {
    c.triangle[static_cast<std::size_t>(q)] = w.triangles[3 * t + static_cast<std::size_t>(q)];
    c.weight[static_cast<std::size_t>(q)] = q == k ? wj : (1 - wj) / 2;
  }
  c.triangle_gid = w.triangle_gid[t];
  c.depth = d;
  return c;
}

// The corner of A nearest to B's lowest corner, and that corner of B.
std::pair<index_t, index_t> facing_corners(const World& w) {
  index_t j = -1;
  for (std::size_t v = 0; v < w.n_local(); ++v)
    if (w.vertex_object[v] == 1 && (j < 0 || w.x[3 * v + 2] < w.x[3 * static_cast<std::size_t>(j) + 2])) j = static_cast<index_t>(v);
  index_t i = -1;
  double best = 1e300;
  for (std::size_t v = 0; v < w.n_local(); ++v) {
    if (w.vertex_object[v] != 0) continue;
    double d2 = 0;
    for (int d = 0; d < 3; ++d) d2 += std::pow(w.x[3 * v + d] - w.x[3 * static_cast<std::size_t>(j) + d], 2);
    if (d2 < best) {
      best = d2;
      i = static_cast<index_t>(v);
    }
  }
  return {i, j};
}

// Contradicting pair (both depths along +z): both records take the axis
// m = normalize(n_B(j) - n_A(i)) and the length (x_j - x_i) . m clamped to
// [max(|d_i|, |d_j|), |d_i| + |d_j|],
// with opposite signs; deciding each half with only its partner's key (two ranks) gives
// the same records to the bit.
// `offset`: j is placed that far from i along -n_A(i) (into A: the two overlap by about
// that much along m) or, negative, outside A.
void check_contradicting_pair(double offset, double expected_min, double expected_max) {
  World w = two_boxes();
  const auto [i, j] = facing_corners(w);
  ASSERT_GE(i, 0);
  ASSERT_GE(j, 0);
  const auto na = brute_normal(w, i);
  for (int d = 0; d < 3; ++d) w.x[3 * static_cast<std::size_t>(j) + d] = w.x[3 * static_cast<std::size_t>(i) + d] - offset * na[d];
  const auto nb = brute_normal(w, j);
  std::vector<Collision> rec{record(w, i, j, 0.8, {0, 0, 0.004}), record(w, j, i, 0.7, {0.001, 0, 0.003})};
  const std::vector<Collision> original = rec;
  CollisionDetector det(w, CollisionSettings{});
  std::vector<RecordKey> keys;
  CollisionDetector::record_keys(w, rec, keys);
  ASSERT_EQ(keys.size(), 2u);
  EXPECT_EQ(det.settle_mutual(w, rec, keys), 2);

  std::array<double, 3> m;
  double mn = 0;
  for (int d = 0; d < 3; ++d) {
    m[static_cast<std::size_t>(d)] = nb[static_cast<std::size_t>(d)] - na[static_cast<std::size_t>(d)];
    mn += m[static_cast<std::size_t>(d)] * m[static_cast<std::size_t>(d)];
  }
  for (double& c : m) c /= std::sqrt(mn);
  double overlap = 0;
  for (int d = 0; d < 3; ++d)
    overlap += (w.x[3 * static_cast<std::size_t>(j) + d] - w.x[3 * static_cast<std::size_t>(i) + d]) * m[static_cast<std::size_t>(d)];
  const double lj = std::sqrt(0.001 * 0.001 + 0.003 * 0.003);
  const double o = std::min(std::max(overlap, std::max(0.004, lj)), 0.004 + lj);
  EXPECT_GE(o, expected_min) << "overlap " << overlap;  // which clamp the case exercises
  EXPECT_LE(o, expected_max);
  for (int d = 0; d < 3; ++d) {
    EXPECT_NEAR(rec[0].depth[static_cast<std::size_t>(d)], o * m[static_cast<std::size_t>(d)], 1e-12);
    EXPECT_EQ(rec[1].depth[static_cast<std::size_t>(d)], -rec[0].depth[static_cast<std::size_t>(d)]);
  }

  // Each half decided with only the other's key, as two ranks would.
  std::vector<Collision> r0{original[0]}, r1{original[1]};
  std::vector<RecordKey> k0, k1;
  CollisionDetector::record_keys(w, r1, k0);  // rank 0 receives the key of record 1
  CollisionDetector::record_keys(w, r0, k1);
  EXPECT_EQ(det.settle_mutual(w, r0, k0), 1);
  EXPECT_EQ(det.settle_mutual(w, r1, k1), 1);
  for (int d = 0; d < 3; ++d) {
    EXPECT_EQ(r0[0].depth[static_cast<std::size_t>(d)], rec[0].depth[static_cast<std::size_t>(d)]);
    EXPECT_EQ(r1[0].depth[static_cast<std::size_t>(d)], rec[1].depth[static_cast<std::size_t>(d)]);
  }
}

}  // namespace

// Contradicting pair (both depths along +z): both records take the axis
// m = normalize(n_B(j) - n_A(i)) and the length (x_j - x_i) . m clamped to
// [max(|d_i|, |d_j|), |d_i| + |d_j|] = [0.004, 0.00716], with opposite signs; deciding
// each half with only its partner's key (two ranks) gives the same records to the bit.
// Overlapping by 0.05 along -n_A: the upper clamp; 0.01 (0.0053 along m): in between; apart: the lower.
TEST(MutualRecords, ContradictingPairTakesTheNormalsAxis) {
  check_contradicting_pair(0.05, 0.00716, 0.00717);
  check_contradicting_pair(0.01, 0.005, 0.0056);
  check_contradicting_pair(-0.05, 0.004, 0.004);
}

// Pairs that agree (opposite depths), records whose partner weighs under kMutualWeight,
// and records without a partner are left as they are.
TEST(MutualRecords, AgreeingLightAndLonelyRecordsUnchanged) {
  World w = two_boxes();
  const auto [i, j] = facing_corners(w);
  CollisionDetector det(w, CollisionSettings{});
  auto run = [&](std::vector<Collision> rec) {
    std::vector<RecordKey> keys;
    CollisionDetector::record_keys(w, rec, keys);
    const std::int64_t n = det.settle_mutual(w, rec, keys);
    return std::make_pair(n, rec);
  };
  const std::vector<Collision> agree{record(w, i, j, 0.8, {0, 0, -0.004}), record(w, j, i, 0.8, {0, 0, 0.003})};
  const std::vector<Collision> light{record(w, i, j, 0.8, {0, 0, 0.004}), record(w, j, i, 0.4, {0, 0, 0.003})};
  const std::vector<Collision> lonely{record(w, i, j, 0.8, {0, 0, 0.004})};
  for (const auto& set : {agree, light, lonely}) {
    const auto [n, out] = run(set);
    EXPECT_EQ(n, 0);
    for (std::size_t q = 0; q < set.size(); ++q)
      for (int d = 0; d < 3; ++d) EXPECT_EQ(out[q].depth[static_cast<std::size_t>(d)], set[q].depth[static_cast<std::size_t>(d)]);
  }
}
