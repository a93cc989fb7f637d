// The collision detector end to end on scenes with known answers: a block pushed into a
// fixed block by a known depth (flat contact: exact up to rounding), self-collisions, the
// tunnelling diagnostic, and agreement with the brute-force reference.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <map>
#include <cstring>
#include <limits>
#include <random>
#include <set>

#include "collide_test_util.hpp"
#include "collide/self_culling.hpp"
#include "collide/triangle_queries.hpp"
#include "softcontact/stepper.hpp"
#include "../random_objects.hpp"

using namespace softcontact;
using namespace softcontact::test;

namespace {

// The same records, bitwise: keys and penetration vectors.
void expect_same_records(const std::vector<Collision>& a, const std::vector<Collision>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].point_gid, b[k].point_gid) << "record " << k;
    EXPECT_EQ(a[k].triangle_gid, b[k].triangle_gid) << "record " << k;
    for (int d = 0; d < 3; ++d) EXPECT_EQ(a[k].depth[d], b[k].depth[d]) << "record " << k;
  }
}

// Every coordinate of `w` jittered by up to `amp` (seeded): self-contact with a detector
// given `cache` finds the records of one without it, bitwise, and finds some.
void expect_cache_changes_no_record(World w, const double* rest, double amp, std::uint64_t seed, SelfGapCache cache) {
  std::mt19937_64 g(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  for (double& x : w.x) x += amp * u(g);
  CollisionSettings self;
  self.self_collisions = true;
  std::vector<Collision> a, b;
  CollisionStats sa, sb;
  CollisionDetector(w, self, rest).detect(w, nullptr, a, sa);
  CollisionDetector(w, self, rest, &cache).detect(w, nullptr, b, sb);
  EXPECT_GT(sa.self_collisions, 0);
  expect_same_records(a, b);
}

// base: z in [-0.5, 0.5], cells 0.25; block: 1 x 1 x 0.5 with cells 0.25, its bottom at
// 0.5 - depth, shifted sideways by (sx, sy) so that its footprint stays inside the
// base's top face away from the base's edges (there the smoothed normals tilt).
World pushed_blocks(double depth, double sx, double sy) {
  const double z = 0.75 - depth;
  return world_from_objects(R"(
  - name: base
    material: m
    primitive: {type: box, size: [2, 2, 1], cells: [8, 8, 4]}
    kinematic: true
  - name: block
    material: m
    primitive: {type: box, size: [1, 1, 0.5], cells: [4, 4, 2]}
    transform: {translate: [)" + std::to_string(sx) + ", " + std::to_string(sy) + ", " +
                            std::to_string(z) + "]}\n");
}

// Every surface vertex of the block below the base's top plane is found; d_i = (0, 0,
// 0.5 - z_i) within 1e-9 (the top is flat and its smoothed normals are exactly +z inside
// the face, so the weighted crossings and the propagation are exact up to rounding); T_i
// lies in the top face and its weights reproduce x~_i + d_i. The base's top vertices
// under the block are inside the block in turn: they must match the brute-force
// reference, with valid records (their crossings near the block's edges see tilted
// smoothed normals, so no exact value is expected of them).
// Vertex detection only here (edge contacts: test_edge_contacts.cpp).
CollisionSettings vertex_only() {
  CollisionSettings s;
  s.edge_contacts = false;
  return s;
}

void check_pushed_block(double depth, double sx, double sy, std::int64_t block_points, std::int64_t block_border) {
  World w = pushed_blocks(depth, sx, sy);
  CollisionDetector det(w, vertex_only());
  std::vector<Collision> c;
  CollisionStats st;
  det.detect(w, nullptr, c, st);
  const collide::CollisionTopology topo = collide::build_collision_topology(w);
  EXPECT_EQ(record_pairs(c), brute_force_pairs(w));
  ASSERT_TRUE(all_finite(c));

  std::set<index_t> expected;
  for (std::size_t v = 0; v < w.n_local(); ++v)
    if (w.vertex_object[v] == 1 && topo.surface[v] && w.x[3 * v + 2] < 0.5) expected.insert(static_cast<index_t>(v));
  std::set<index_t> found;
  std::int64_t base_points = 0;
  for (const Collision& r : c) {
    if (r.object == 1) found.insert(r.point);
    base_points += r.object == 0;
  }
  EXPECT_EQ(found, expected);
  EXPECT_EQ(static_cast<std::int64_t>(found.size()), block_points);
  EXPECT_EQ(st.colliding_points, block_points + base_points);
  EXPECT_EQ(st.collisions, block_points + base_points);
  EXPECT_GE(st.border_points, block_border);
  EXPECT_EQ(st.deep_fallbacks, 0);
  EXPECT_EQ(st.self_collisions, 0);
  EXPECT_EQ(st.degenerate_skipped, 0);
  EXPECT_EQ(st.surface_searches, 0);

  std::int64_t block_border_found = 0;
  for (std::size_t k = 0; k < c.size(); ++k) {
    const Collision& r = c[k];
    const auto i = static_cast<std::size_t>(r.point);
    EXPECT_FALSE(r.fallback);
    EXPECT_EQ(r.point_gid, w.vertex_gid[i]);
    EXPECT_EQ(r.other_object, 1 - r.object);
    if (k > 0) {
      EXPECT_LT(c[k - 1].point_gid, r.point_gid);
    }
    double sum = 0;
    for (int j = 0; j < 3; ++j) {
      EXPECT_GE(r.weight[j], 0);
      EXPECT_LE(r.weight[j], 1);
      sum += r.weight[j];
    }
    EXPECT_NEAR(sum, 1, 1e-12);
    // The triangle's gid names the row holding the same vertices.
    const auto row = static_cast<std::size_t>(r.triangle_gid - w.layout[0].triangle_begin);
    for (int j = 0; j < 3; ++j) EXPECT_EQ(w.triangles[3 * row + j], r.triangle[j]);
    if (r.object == 0) continue;
    EXPECT_NEAR(r.depth[0], 0, 1e-9);
    EXPECT_NEAR(r.depth[1], 0, 1e-9);
    EXPECT_NEAR(r.depth[2], 0.5 - w.x[3 * i + 2], 1e-9) << "vertex " << i;
    for (int j = 0; j < 3; ++j) EXPECT_EQ(w.x[3 * static_cast<std::size_t>(r.triangle[j]) + 2], 0.5);  // top face
    const auto q = weighted_point(w, r);
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(q[d], w.x[3 * i + d] + r.depth[d], 1e-9) << "vertex " << i << " axis " << d;
    // A block vertex with an edge to a vertex above the top plane is a border point.
    for (std::size_t e = topo.edge_begin[i]; e < topo.edge_begin[i + 1]; ++e)
      if (w.x[3 * static_cast<std::size_t>(topo.edge_to[e]) + 2] > 0.5) {
        ++block_border_found;
        break;
      }
  }
  EXPECT_EQ(block_border_found, block_border);
}

}  // namespace

// Depth 0.1 < one cell layer: the block's bottom face (5 x 5 vertices) is inside, every
// one of them a border point. The sideways shift puts the block's vertices off the base's
// vertex columns.
TEST(CollisionDetector, BlockPushedIntoBlockShallow) { check_pushed_block(0.1, 0.1, 0.05, 25, 25); }

// The block's vertices right above the base's vertex columns: its bottom vertices lie on
// vertical edges of the base, shared by several tets (the tie rule gives each to one).
TEST(CollisionDetector, BlockPushedIntoBlockOnGridLines) { check_pushed_block(0.1, 0, 0, 25, 25); }

// Depth 0.3 > one layer: the bottom face (25) and the 16 side vertices of the next layer
// are inside; only those 16 have border edges, the bottom face takes its depth by
// propagation (three layers: ring, inner ring, centre), exactly for a flat surface.
TEST(CollisionDetector, BlockPushedIntoBlockDeepPropagates) { check_pushed_block(0.3, 0.1, 0.05, 41, 16); }

// The detector finds exactly the (point, other object) pairs of the brute-force
// reference (every surface vertex against every tet of every other object, with the
// same point-in-tet test), on random scenes with deformed and inverted tets.
TEST(CollisionDetector, MatchesBruteForceOnRandomScenes) {
  std::int64_t total = 0;
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    const World w = random_scene(seed, 6, seed % 2 ? 0.0 : 0.01);
    CollisionDetector det(w, vertex_only());
    std::vector<Collision> c;
    CollisionStats st;
    det.detect(w, nullptr, c, st);
    EXPECT_EQ(record_pairs(c), brute_force_pairs(w)) << "seed " << seed;
    EXPECT_TRUE(all_finite(c));
    std::set<index_t> points;
    for (const Collision& r : c) points.insert(r.point);
    EXPECT_EQ(st.colliding_points, static_cast<std::int64_t>(points.size()));
    EXPECT_EQ(st.collisions, static_cast<std::int64_t>(c.size()));
    for (std::size_t k = 1; k < c.size(); ++k)
      EXPECT_TRUE(c[k - 1].point_gid < c[k].point_gid ||
                  (c[k - 1].point_gid == c[k].point_gid && c[k - 1].triangle_gid < c[k].triangle_gid));
    for (const Collision& r : c) {
      double sum = 0;
      for (int j = 0; j < 3; ++j) {
        EXPECT_GE(r.weight[j], 0);
        sum += r.weight[j];
        EXPECT_EQ(w.vertex_object[static_cast<std::size_t>(r.triangle[j])], r.other_object);
      }
      EXPECT_NEAR(sum, 1, 1e-12);
    }
    total += st.collisions;
  }
  EXPECT_GT(total, 100);
}

// Bitwise the same records, in the same order, with 1 and 2 threads.
TEST(CollisionDetector, SameRecordsWithOneAndTwoThreads) {
  const World w = random_scene(42, 10, 0.005);
  const int before = omp_get_max_threads();
  std::vector<Collision> c1, c2;
  CollisionStats s1, s2;
  omp_set_num_threads(1);
  CollisionDetector(w, {}).detect(w, w.x_prev.data(), c1, s1);
  omp_set_num_threads(2);
  CollisionDetector(w, {}).detect(w, w.x_prev.data(), c2, s2);
  omp_set_num_threads(before);
  ASSERT_GT(c1.size(), 20u);
  ASSERT_EQ(c1.size(), c2.size());
  for (std::size_t k = 0; k < c1.size(); ++k) {
    const Collision &a = c1[k], &b = c2[k];
    EXPECT_EQ(a.point, b.point);
    EXPECT_EQ(a.triangle, b.triangle);
    EXPECT_EQ(a.point_gid, b.point_gid);
    EXPECT_EQ(a.triangle_gid, b.triangle_gid);
    EXPECT_EQ(a.object, b.object);
    EXPECT_EQ(a.other_object, b.other_object);
    EXPECT_EQ(a.fallback, b.fallback);
    EXPECT_EQ(std::memcmp(a.weight.data(), b.weight.data(), sizeof(a.weight)), 0);
    EXPECT_EQ(std::memcmp(a.depth.data(), b.depth.data(), sizeof(a.depth)), 0);
  }
  EXPECT_EQ(s1.colliding_points, s2.colliding_points);
  EXPECT_EQ(s1.border_points, s2.border_points);
  EXPECT_EQ(s1.deep_fallbacks, s2.deep_fallbacks);
  EXPECT_EQ(s1.degenerate_skipped, s2.degenerate_skipped);
  EXPECT_EQ(s1.surface_searches, s2.surface_searches);
  EXPECT_EQ(s1.max_step_over_thickness, s2.max_step_over_thickness);
}

// A surface vertex pushed into the middle of its own box: inside a tet that shares no
// vertex with its star. Nothing without self-collisions; with them one self-contact
// record. No border edge leaves the body (every neighbour is on the top face, whose
// triangles near the vertex are its own side and skipped), and there is no x^t, so the
// depth leads to the nearest surface triangle away from the star: the bottom face, 0.3
// below (the top face away from the star is farther: its nearest such point is 0.7 above
// and 0.23 aside).
TEST(CollisionDetector, SelfContactBehindTheSwitch) {
  World w = world_from_objects("  - material: m\n    primitive: {type: box, size: [1, 1, 1], cells: [4, 4, 4]}\n");
  // The top centre vertex (0, 0, 0.5) moved to (0.01, 0.02, -0.2).
  std::size_t top = w.n_local();
  for (std::size_t v = 0; v < w.n_local(); ++v)
    if (w.x[3 * v] == 0 && w.x[3 * v + 1] == 0 && w.x[3 * v + 2] == 0.5) top = v;
  ASSERT_LT(top, w.n_local());
  w.x[3 * top] = 0.01;
  w.x[3 * top + 1] = 0.02;
  w.x[3 * top + 2] = -0.2;
  std::vector<Collision> c;
  CollisionStats st;
  CollisionDetector(w, {}).detect(w, nullptr, c, st);
  EXPECT_EQ(st.self_collisions, 0);
  EXPECT_TRUE(c.empty());
  CollisionSettings self;
  self.self_collisions = true;
  CollisionDetector(w, self).detect(w, nullptr, c, st);
  EXPECT_EQ(st.self_collisions, 1);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].point, static_cast<index_t>(top));
  EXPECT_EQ(c[0].object, c[0].other_object);
  EXPECT_NEAR(c[0].depth[0], 0, 1e-12);
  EXPECT_NEAR(c[0].depth[1], 0, 1e-12);
  EXPECT_NEAR(c[0].depth[2], -0.3, 1e-12);
  for (int k = 0; k < 3; ++k) {
    const index_t v = c[0].triangle[k];
    EXPECT_NEAR(w.x[3 * static_cast<std::size_t>(v) + 2], -0.5, 1e-12);  // a bottom-face triangle
    EXPECT_NE(v, static_cast<index_t>(top));
  }
  // x~_i + d_i lies on T_i: the weights reproduce it.
  for (int d = 0; d < 3; ++d) {
    double on = 0;
    for (int k = 0; k < 3; ++k) on += c[0].weight[k] * w.x[3 * static_cast<std::size_t>(c[0].triangle[k]) + static_cast<std::size_t>(d)];
    EXPECT_NEAR(on, w.x[3 * top + static_cast<std::size_t>(d)] + c[0].depth[d], 1e-12);
  }
}

// Self-contact culling (self_culling.hpp): a box moved rigidly (rotated and translated)
// or deformed by less than half its gap is not queried for self-contact; the box with a
// vertex pushed deep inside is, and gives its record.
TEST(CollisionDetector, SelfCullingSkipsObjectsThatCannotHaveFolded) {
  World w = world_from_objects("  - material: m\n    primitive: {type: box, size: [1, 1, 1], cells: [4, 4, 4]}\n");
  const std::vector<double> rest = w.x;
  CollisionSettings self;
  self.self_collisions = true;
  CollisionDetector det(w, self, rest.data());
  std::vector<Collision> c;
  CollisionStats st;
  // Rigid: rotated 30 degrees about z and moved.
  const double cs = std::cos(0.5236), sn = std::sin(0.5236);
  for (std::size_t v = 0; v < w.n_local(); ++v) {
    const double x = rest[3 * v], y = rest[3 * v + 1];
    w.x[3 * v] = cs * x - sn * y + 3;
    w.x[3 * v + 1] = sn * x + cs * y - 1;
    w.x[3 * v + 2] = rest[3 * v + 2] + 2;
  }
  det.detect(w, nullptr, c, st);
  EXPECT_EQ(st.self_objects, 0);
  EXPECT_TRUE(c.empty());
  // A vertex 1 mm off: far below the gap (about a quarter cell).
  w.x[0] += 1e-3;
  det.detect(w, nullptr, c, st);
  EXPECT_EQ(st.self_objects, 0);
  // The top centre vertex pushed to 0.3 above the bottom (SelfContactBehindTheSwitch).
  w.x = rest;
  std::size_t top = w.n_local();
  for (std::size_t v = 0; v < w.n_local(); ++v)
    if (w.x[3 * v] == 0 && w.x[3 * v + 1] == 0 && w.x[3 * v + 2] == 0.5) top = v;
  ASSERT_LT(top, w.n_local());
  w.x[3 * top + 2] = -0.2;
  det.detect(w, nullptr, c, st);
  EXPECT_EQ(st.self_objects, 1);
  EXPECT_EQ(st.self_collisions, 1);
  EXPECT_EQ(c.size(), 1u);
}

// The culling is exact: on random scenes where half the objects are jittered hard (their
// vertices pushed into tets away from their stars) and half barely, self-contact finds
// the same records with it as without it, and skips the barely jittered objects.
TEST(CollisionDetector, SelfCullingChangesNoRecord) {
  for (std::uint64_t seed : {11u, 12u, 13u}) {
    World w = random_scene(seed, 8, 0.0);
    const std::vector<double> rest = w.x;
    std::mt19937_64 g(seed);
    std::uniform_real_distribution<double> u(-1, 1);
    // Odd objects jittered hard (vertices pushed through their neighbours' tets), even
    // ones barely.
    for (std::size_t v = 0; v < w.n_local(); ++v) {
      const double amp = w.vertex_object[v] % 2 ? 0.2 : 1e-5;
      for (int d = 0; d < 3; ++d) w.x[3 * v + d] += amp * u(g);
    }
    CollisionSettings on, off;
    on.self_collisions = off.self_collisions = true;
    off.self_culling = false;
    std::vector<Collision> a, b;
    CollisionStats sa, sb;
    CollisionDetector(w, on, rest.data()).detect(w, nullptr, a, sa);
    CollisionDetector(w, off, rest.data()).detect(w, nullptr, b, sb);
    EXPECT_LT(sa.self_objects, sb.self_objects) << "seed " << seed;  // some were culled
    EXPECT_GT(sa.self_collisions, 0) << "seed " << seed;  // measured: 34, 21, 29
    EXPECT_EQ(sa.self_collisions, sb.self_collisions) << "seed " << seed;
    SCOPED_TRACE("seed " + std::to_string(seed));
    expect_same_records(a, b);
  }
}

// The self-contact gaps kept across detectors (SelfGapCache): a gap taken from the cache
// is bitwise the one computed afresh (it depends only on the rest mesh), a cached value is
// what the detector uses (a poisoned entry shows it is read, not recomputed), and a
// detector built with a cache filled by an earlier one finds the same records.
TEST(CollisionDetector, SelfGapCacheGivesTheComputedGaps) {
  World w = random_scene(21, 8, 0.0);
  const std::vector<double> rest = w.x;
  const collide::CollisionTopology topo = collide::build_collision_topology(w);
  collide::SelfCulling fresh, filled, cached, poisoned;
  fresh.build(w, topo, rest.data());
  SelfGapCache cache;
  filled.build(w, topo, rest.data(), &cache);
  ASSERT_EQ(cache.gap.size(), topo.objects.size());
  cached.build(w, topo, rest.data(), &cache);
  std::size_t positive = 0;
  for (std::size_t k = 0; k < topo.objects.size(); ++k) {
    EXPECT_EQ(filled.gap(k), fresh.gap(k)) << "slot " << k;
    EXPECT_EQ(cached.gap(k), fresh.gap(k)) << "slot " << k;
    positive += fresh.gap(k) > 0;
  }
  EXPECT_EQ(positive, topo.objects.size());  // every object has a gap to keep
  SelfGapCache wrong = cache;
  wrong.gap[topo.objects[0].object] = 12345.0;
  poisoned.build(w, topo, rest.data(), &wrong);
  EXPECT_EQ(poisoned.gap(0), 12345.0);
  EXPECT_EQ(poisoned.gap(1), fresh.gap(1));

  // Jittered hard (self-contact records exist): a detector with the filled cache finds
  // the records of one without it, bitwise.
  expect_cache_changes_no_record(w, rest.data(), 0.2, 21, cache);
}

// The culling's per-step look at each object (SelfCulling::update) with a mask of the
// slots to test, as the detector passes its owned objects (a ghost's self-contact is its
// owner's). Reference: the same call without a mask. A tested slot gets the same flag
// and distance to the bit; a slot left out is inactive with an infinite distance. Half
// the objects are jittered (they can fold), half only moved rigidly (they cannot), and
// both kinds are among the tested and the untested slots.
TEST(CollisionDetector, SelfCullingLooksOnlyAtTheTestedSlots) {
  World w = random_scene(22, 8, 0.0);
  const std::vector<double> rest = w.x;
  const collide::CollisionTopology topo = collide::build_collision_topology(w);
  collide::SelfCulling culling;
  culling.build(w, topo, rest.data());
  std::mt19937_64 g(5);
  std::uniform_real_distribution<double> u(-1, 1);
  const std::size_t no = topo.objects.size();
  for (std::size_t k = 0; k < no; ++k)
    for (index_t v : topo.objects[k].vertices)
      for (std::size_t d = 0; d < 3; ++d) {
        double& c = w.x[3 * static_cast<std::size_t>(v) + d];
        c += (k / 2) % 2 ? 0.2 * u(g) : 0.5;  // slots 2, 3, 6, 7 jittered; the others shifted
      }
  const std::vector<std::uint8_t> bad(w.n_local(), 0);
  std::vector<std::uint8_t> tested(no, 0), all_active, active;
  for (std::size_t k = 0; k < no; k += 2) tested[k] = 1;
  std::vector<double> all_delta, delta;
  culling.update(w.x.data(), topo, bad.data(), nullptr, all_active, all_delta);
  culling.update(w.x.data(), topo, bad.data(), tested.data(), active, delta);
  ASSERT_EQ(active.size(), no);
  int kinds[2][2] = {{0, 0}, {0, 0}};  // [tested][active without a mask]
  for (std::size_t k = 0; k < no; ++k) {
    ++kinds[tested[k]][all_active[k]];
    if (tested[k]) {
      EXPECT_EQ(active[k], all_active[k]) << "slot " << k;
      EXPECT_EQ(delta[k], all_delta[k]) << "slot " << k;
    } else {
      EXPECT_EQ(active[k], 0) << "slot " << k;
      EXPECT_EQ(delta[k], std::numeric_limits<double>::infinity()) << "slot " << k;
    }
  }
  for (int t = 0; t < 2; ++t)
    for (int a = 0; a < 2; ++a) EXPECT_GT(kinds[t][a], 0) << "tested " << t << ", active " << a;
}

// The smallest distance from a surface vertex of slot k to a tet of the same object that
// shares no vertex with its star, over every such pair (no grid, no cap): the true gap
// that the culling's gap must not exceed (inside a tet: 0; else the nearest face).
double brute_force_gap(const World& w, const collide::CollisionTopology& topo, std::size_t k) {
  using collide::V3;
  auto P = [&](index_t v) { return V3{w.x[3 * static_cast<std::size_t>(v)], w.x[3 * static_cast<std::size_t>(v) + 1], w.x[3 * static_cast<std::size_t>(v) + 2]}; };
  const collide::ObjectInfo& o = topo.objects[k];
  double best = std::numeric_limits<double>::infinity();
  for (index_t v : o.surface_vertices) {
    const auto u = static_cast<std::size_t>(v);
    std::set<index_t> star(topo.edge_to.begin() + static_cast<std::ptrdiff_t>(topo.edge_begin[u]),
                           topo.edge_to.begin() + static_cast<std::ptrdiff_t>(topo.edge_begin[u + 1]));
    star.insert(v);
    for (index_t t : o.tets) {
      const index_t* c = &w.tets[4 * static_cast<std::size_t>(t)];
      if (star.count(c[0]) || star.count(c[1]) || star.count(c[2]) || star.count(c[3])) continue;
      const V3 p = P(v), a = P(c[0]), b = P(c[1]), cc = P(c[2]), d = P(c[3]);
      const double vol = collide::orient(a, b, cc, d);
      const double s0 = collide::orient(p, b, cc, d), s1 = collide::orient(a, p, cc, d), s2 = collide::orient(a, b, p, d),
                   s3 = collide::orient(a, b, cc, p);
      if (s0 * vol >= 0 && s1 * vol >= 0 && s2 * vol >= 0 && s3 * vol >= 0) return 0;
      const V3 f[4][3] = {{b, cc, d}, {a, cc, d}, {a, b, d}, {a, b, cc}};
      std::array<double, 3> bary{};
      for (const auto& tri : f) {
        const V3 q = collide::closest_point_on_triangle(p, tri[0], tri[1], tri[2], bary);
        const double dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
        best = std::min(best, std::sqrt(dx * dx + dy * dy + dz * dz));
      }
    }
  }
  return best;
}

// The copies of one scene entry share its gap (SelfGapCache::entry): a scene of 6 grid
// copies and 8 randomly rotated copies of a box, and a single box. One copy per entry is
// computed; every other copy takes that gap less a rounding margin (1e-9 of it and more).
// Each gap, computed or taken, is at most the copy's true gap by brute force (no grid, no
// cap; the copies' true gaps are equal, being rigid images, up to rounding). A copy's own
// capped gap can differ from its entry's (the cap, half the largest tet extent along the
// axes, turns with the copy), so it is not the reference. Self-contact with the shared
// gaps finds the records of a detector without them.
TEST(CollisionDetector, CopiesOfAnEntryShareItsGap) {
  const Scene scene = load_scene_from_string(std::string(kMaterials) + R"(objects:
  - name: grid
    material: m
    primitive: {type: box, size: [0.3, 0.2, 0.1], cells: [3, 2, 2]}
    instances: {grid: {count: [3, 2, 1], spacing: [0.5, 0.5, 0]}}
  - name: tumbled
    material: m
    primitive: {type: box, size: [0.3, 0.2, 0.1], cells: [3, 2, 2]}
    instances: {random: {count: 8, region: {min: [0, 0, 1], max: [3, 3, 4]}, seed: 5, rotate: true}}
  - name: single
    material: m
    primitive: {type: box, size: [0.3, 0.2, 0.1], cells: [3, 2, 2]}
    transform: {translate: [5, 5, 5]}
)", "test.yaml");
  ASSERT_EQ(scene.objects.size(), 15u);
  const World w = build_world(scene, block_partition(scene, 1), 0);
  const collide::CollisionTopology topo = collide::build_collision_topology(w);
  SelfGapCache shared = self_gap_cache_for(scene);
  EXPECT_EQ(shared.entry[0], shared.entry[5]);
  EXPECT_NE(shared.entry[0], shared.entry[6]);
  EXPECT_EQ(shared.entry[6], shared.entry[13]);
  EXPECT_EQ(shared.entry[14], -1);
  collide::SelfCulling own, from_entry;
  own.build(w, topo, w.x.data());
  from_entry.build(w, topo, w.x.data(), &shared);
  EXPECT_EQ(shared.entry_gap.size(), 2u) << "one computed copy per entry";
  std::vector<double> slot_of(15, -1);
  for (std::size_t k = 0; k < topo.objects.size(); ++k) slot_of[static_cast<std::size_t>(topo.objects[k].object)] = static_cast<double>(k);
  for (std::size_t k = 0; k < topo.objects.size(); ++k) {
    const std::int32_t obj = topo.objects[k].object;
    const double truth = brute_force_gap(w, topo, k);
    ASSERT_GT(own.gap(k), 0) << "object " << obj;
    EXPECT_LE(own.gap(k), truth) << "object " << obj;
    EXPECT_LE(from_entry.gap(k), truth) << "object " << obj;
    if (obj == 0 || obj == 6 || obj == 14) {
      EXPECT_EQ(from_entry.gap(k), own.gap(k)) << "object " << obj << " is computed";
    } else {
      const double lead = from_entry.gap(static_cast<std::size_t>(slot_of[obj < 6 ? 0 : 6]));
      EXPECT_LT(from_entry.gap(k), lead) << "object " << obj;
      EXPECT_GT(from_entry.gap(k), lead * (1 - 1e-8)) << "object " << obj;
    }
  }
  // Every vertex jittered by up to 0.15 (beyond the cells, so bodies fold): records with
  // the shared gaps equal those without the cache.
  expect_cache_changes_no_record(w, w.x.data(), 0.15, 3, self_gap_cache_for(scene));
}

// The narrow phase's candidates kept across steps (CollisionSettings::point_skin) give
// the records of candidates found every step, bitwise, and every inside pair of the
// brute-force loop: objects of random overlapping scenes drift through each other at 0.02
// median edges a step, in different directions (each vertex also jittered by up to 0.005)
// for 60 steps. With a skin of 0.3 cells the candidates are found again about every
// 0.15 / 0.025 = 6 steps, not every step. With self-contact on, every step searches.
TEST(CollisionDetector, KeptCandidatesFindEveryHit) {
  std::int64_t hits = 0, searches = 0, steps = 0;
  for (std::uint64_t seed = 11; seed <= 13; ++seed) {
    World w = random_scene(seed, 6, 0.0);
    const double h = collide::build_collision_topology(w).mean_edge_length;
    CollisionSettings kept = vertex_only(), fresh = vertex_only(), self = vertex_only();
    fresh.point_skin = 0;
    self.self_collisions = true;
    ASSERT_GT(kept.point_skin, 0);
    CollisionDetector a_det(w, kept), b_det(w, fresh), self_det(w, self);
    Drift drift(seed, 6, 0.02 * h, 0.005 * h);
    for (int step = 0; step < 60; ++step) {
      drift.step(w);
      std::vector<Collision> a, b;
      CollisionStats sa, sb;
      a_det.detect(w, nullptr, a, sa);
      b_det.detect(w, nullptr, b, sb);
      ASSERT_EQ(record_pairs(a), brute_force_pairs(w)) << "seed " << seed << " step " << step;
      ASSERT_EQ(a.size(), b.size()) << "seed " << seed << " step " << step;
      for (std::size_t q = 0; q < a.size(); ++q) {
        EXPECT_EQ(a[q].point, b[q].point);
        EXPECT_EQ(a[q].triangle_gid, b[q].triangle_gid);
        for (int d = 0; d < 3; ++d) EXPECT_EQ(a[q].depth[d], b[q].depth[d]);
      }
      EXPECT_EQ(sa.degenerate_skipped, sb.degenerate_skipped);
      EXPECT_EQ(sb.point_searches, 0);
      if (step % 20 == 0) {
        self_det.detect(w, nullptr, b, sb);
        EXPECT_EQ(sb.point_searches, 0);
      }
      hits += static_cast<std::int64_t>(a.size());
      searches += sa.point_searches;
      ++steps;
    }
  }
  EXPECT_GT(hits, 1000);
  EXPECT_GE(searches, steps / 20);  // found again as the objects move
  EXPECT_LE(searches, steps / 3);   // but not every step
}

// max_step_over_thickness: the largest |x~ - x^t| over the thinnest object's thickness
// (smallest extent along its principal and coordinate axes: 0.2 for the plate).
TEST(CollisionDetector, TunnellingDiagnostic) {
  World w = world_from_objects(R"(
  - material: m
    primitive: {type: box, size: [2, 2, 0.2], cells: [4, 4, 1]}
    kinematic: true
  - material: m
    primitive: {type: sphere, radius: 0.3, resolution: 4}
    transform: {rotate: [10, 20, 30], translate: [0, 0, 3]}
)");
  const std::vector<double> before = w.x;
  translate_object(w, 1, {0, 0, -0.05});
  w.x[3 * (w.n_local() - 1) + 2] -= 0.05;  // one vertex moves 0.1 in all
  std::vector<Collision> c;
  CollisionStats st;
  CollisionDetector det(w, {});
  det.detect(w, before.data(), c, st);
  EXPECT_NEAR(st.max_step_over_thickness, 0.1 / 0.2, 1e-12);
  det.detect(w, nullptr, c, st);
  EXPECT_EQ(st.max_step_over_thickness, 0);
}

TEST(CollisionDetector, SeparatedAndEmptyScenes) {
  World w = world_from_objects(R"(
  - material: m
    primitive: {type: box, size: [1, 1, 1], cells: [2, 2, 2]}
  - material: m
    primitive: {type: box, size: [1, 1, 1], cells: [2, 2, 2]}
    transform: {translate: [1.0001, 0, 0]}
)");
  std::vector<Collision> c(3);
  CollisionStats st;
  CollisionDetector(w, {}).detect(w, nullptr, c, st);
  EXPECT_TRUE(c.empty());
  EXPECT_EQ(st.colliding_points, 0);
  EXPECT_EQ(st.degenerate_skipped, 0);
  World empty;
  CollisionDetector(empty, {}).detect(empty, nullptr, c, st);
  EXPECT_TRUE(c.empty());
  EXPECT_EQ(st.max_step_over_thickness, 0);
}

// Touching faces (a box resting exactly on another, vertices on the other's surface):
// not strictly inside, so nothing is reported except, at most, points exactly on
// surface edges that the tie rule hands to an interior tet, with zero depth.
TEST(CollisionDetector, TouchingIsNotPenetrating) {
  World w = world_from_objects(R"(
  - material: m
    primitive: {type: box, size: [1, 1, 1], cells: [4, 4, 4]}
    kinematic: true
  - material: m
    primitive: {type: box, size: [0.5, 0.5, 0.5], cells: [2, 2, 2]}
    transform: {translate: [0.125, 0, 0.75]}
)");
  std::vector<Collision> c;
  CollisionStats st;
  CollisionDetector(w, {}).detect(w, nullptr, c, st);
  EXPECT_TRUE(all_finite(c));
  for (const Collision& r : c) EXPECT_LE(std::sqrt(r.depth[0] * r.depth[0] + r.depth[1] * r.depth[1] + r.depth[2] * r.depth[2]), 1e-12);
  EXPECT_EQ(record_pairs(c), brute_force_pairs(w));
}

// A vertex of a small box exactly on a face shared by two tets of a large box (and one
// exactly at the large box's centre, a vertex shared by 24 tets): one record each, and
// the brute force finds exactly one tet holding it.
TEST(CollisionDetector, VertexOnSharedFaceFoundOnce) {
  // Big box [-0.5, 0.5]^3 in 2 x 2 x 2 cells; the small box's corner at the centre.
  World w = world_from_objects(R"(
  - material: m
    primitive: {type: box, size: [1, 1, 1], cells: [2, 2, 2]}
    kinematic: true
  - material: m
    primitive: {type: box, size: [1, 1, 1], cells: [1, 1, 1]}
    transform: {translate: [0.5, 0.5, 0.5]}
)");
  const collide::CollisionTopology topo = collide::build_collision_topology(w);
  std::vector<Collision> c;
  CollisionStats st;
  CollisionDetector(w, {}).detect(w, nullptr, c, st);
  ASSERT_TRUE(all_finite(c));
  EXPECT_EQ(record_pairs(c), brute_force_pairs(w));
  int at_centre = 0;
  for (const Collision& r : c) {
    const auto i = static_cast<std::size_t>(r.point);
    if (r.object != 1 || w.x[3 * i] != 0 || w.x[3 * i + 1] != 0 || w.x[3 * i + 2] != 0) continue;
    ++at_centre;
    int holders = 0;
    for (std::size_t e = 0; e < w.tets.size() / 4; ++e)
      if (w.tet_object[e] == 0)
        holders += collide::point_in_tet(w.x.data(), &w.tets[4 * e], topo.boundary_mask[e], {0, 0, 0}) ==
                   collide::TetSide::inside;
    EXPECT_EQ(holders, 1);
  }
  EXPECT_EQ(at_centre, 1);
  // Moved onto the plane x = 0 (faces shared by tets of both cells).
  translate_object(w, 1, {0, 0.125, 0.0625});
  CollisionDetector(w, {}).detect(w, nullptr, c, st);
  EXPECT_EQ(record_pairs(c), brute_force_pairs(w));
  EXPECT_EQ(st.collisions, static_cast<std::int64_t>(record_pairs(c).size()));
}

// Degenerate inputs: a collapsed surface triangle (and the flat tets and zero-length
// edges it makes) in the penetrated body, a zero-length edge in the penetrating one,
// two coincident bodies, and a non-finite position: every record stays finite and the
// degenerate cases are counted.
TEST(CollisionDetector, DegenerateInputsStayFinite) {
  World w = world_from_objects(R"(
  - material: m
    primitive: {type: box, size: [1, 1, 1], cells: [4, 4, 4]}
    kinematic: true
  - material: m
    primitive: {type: box, size: [0.5, 0.5, 0.5], cells: [2, 2, 2]}
    transform: {translate: [0.05, 0.02, 0.6]}
  - material: m
    primitive: {type: sphere, radius: 0.2, resolution: 4}
    transform: {translate: [3, 0, 0]}
  - material: m
    primitive: {type: sphere, radius: 0.2, resolution: 4}
    transform: {translate: [3, 0, 0]}
)");
  auto find = [&](int obj, double x, double y, double z) {
    for (std::size_t v = 0; v < w.n_local(); ++v)
      if (w.vertex_object[v] == obj && std::abs(w.x[3 * v] - x) < 1e-12 && std::abs(w.x[3 * v + 1] - y) < 1e-12 &&
          std::abs(w.x[3 * v + 2] - z) < 1e-12)
        return v;
    return w.n_local();
  };
  // Collapse the big box's top vertex (0.25, 0, 0.5) onto (0, 0, 0.5).
  const std::size_t a = find(0, 0.25, 0, 0.5), b = find(0, 0, 0, 0.5);
  ASSERT_LT(a, w.n_local());
  ASSERT_LT(b, w.n_local());
  for (int d = 0; d < 3; ++d) w.x[3 * a + d] = w.x[3 * b + d];
  // A zero-length edge in the small box's bottom face: (0.05, 0.02, 0.35) onto (0.3, 0.02, 0.35).
  const std::size_t p = find(1, 0.05, 0.02, 0.35), q = find(1, 0.3, 0.02, 0.35);
  ASSERT_LT(p, w.n_local());
  ASSERT_LT(q, w.n_local());
  for (int d = 0; d < 3; ++d) w.x[3 * p + d] = w.x[3 * q + d];

  std::vector<Collision> c;
  CollisionStats st;
  CollisionDetector det(w, {});
  det.detect(w, nullptr, c, st);
  EXPECT_TRUE(all_finite(c));
  EXPECT_GT(st.collisions, 0);
  EXPECT_GT(st.degenerate_skipped, 0);
  // Coincident spheres: every vertex of each lies on the other's surface (surface
  // vertices coincide), so neither is inside the other.
  for (const Collision& r : c) EXPECT_LE(r.object, 1);

  // A non-finite position: set aside and counted, nothing non-finite comes out.
  w.x[3 * q + 1] = std::numeric_limits<double>::quiet_NaN();
  const std::int64_t before = st.degenerate_skipped;
  det.detect(w, nullptr, c, st);
  EXPECT_TRUE(all_finite(c));
  EXPECT_GT(st.degenerate_skipped, before);
  w.x[3 * q] = std::numeric_limits<double>::infinity();
  det.detect(w, w.x.data(), c, st);
  EXPECT_TRUE(all_finite(c));
  EXPECT_TRUE(std::isfinite(st.max_step_over_thickness));
}

// Delegated objects (CollisionDetector::delegate, the objects split over ranks): one World
// seen as two ranks' (every object present; objects of even index rank 0's, odd rank
// 1's), each view with a detector that delegates objects 1, 2 and 5. Over the two views
// every pair (point, body) of the brute-force reference is recorded exactly once, by the
// view that owns the body when the point's object is delegated and by the point's owner
// otherwise (so a delegated point inside another rank's body, or inside a body that is a
// ghost of both, is never recorded twice); each record is bitwise the one-rank detector's;
// and the colliding points (the views' own counts plus the distinct delegated points of
// both) are the one-rank count.
TEST(CollisionDetector, DelegatedPointsAreRecordedOnceByTheBodysOwner) {
  const std::vector<std::int32_t> delegated = {1, 2, 5};
  const auto is_delegated = [&](std::int32_t o) { return std::count(delegated.begin(), delegated.end(), o) > 0; };
  std::int64_t found = 0, by_body = 0;
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    World w = random_scene(seed, 8, seed % 2 ? 0.0 : 0.01);
    std::vector<Collision> one;
    CollisionStats one_st;
    CollisionDetector(w, vertex_only()).detect(w, nullptr, one, one_st);
    ASSERT_EQ(record_pairs(one), brute_force_pairs(w)) << "seed " << seed;
    for (std::size_t k = 0; k < w.layout.size(); ++k) w.layout[k].rank = static_cast<int>(k % 2);
    std::map<std::pair<std::int64_t, std::int64_t>, const Collision*> reference;
    for (const Collision& c : one) reference[{c.point_gid, c.triangle_gid}] = &c;
    std::map<std::pair<std::int64_t, std::int64_t>, int> seen;
    std::set<std::int64_t> delegated_points;
    std::int64_t points = 0;
    for (int r = 0; r < 2; ++r) {
      World view = w;
      view.rank = r;
      CollisionDetector det(view, vertex_only());
      det.delegate(delegated);
      std::vector<Collision> c;
      CollisionStats st;
      det.detect(view, nullptr, c, st);
      points += st.colliding_points;
      for (index_t v : det.delegated_points()) {
        EXPECT_TRUE(is_delegated(view.vertex_object[static_cast<std::size_t>(v)]));
        delegated_points.insert(view.vertex_gid[static_cast<std::size_t>(v)]);
      }
      for (const Collision& rec : c) {
        const int maker = is_delegated(rec.object) ? view.layout[static_cast<std::size_t>(rec.other_object)].rank
                                                   : view.layout[static_cast<std::size_t>(rec.object)].rank;
        EXPECT_EQ(maker, r) << "seed " << seed << ": point " << rec.point_gid << " of object " << rec.object
                            << " inside object " << rec.other_object << " recorded by the wrong rank";
        ++seen[{rec.point_gid, rec.triangle_gid}];
        const auto it = reference.find({rec.point_gid, rec.triangle_gid});
        ASSERT_NE(it, reference.end()) << "seed " << seed << ": a record one rank does not make";
        EXPECT_EQ(std::memcmp(rec.depth.data(), it->second->depth.data(), sizeof(rec.depth)), 0);
        EXPECT_EQ(std::memcmp(rec.weight.data(), it->second->weight.data(), sizeof(rec.weight)), 0);
        EXPECT_EQ(rec.triangle, it->second->triangle);
        if (is_delegated(rec.object) && view.layout[static_cast<std::size_t>(rec.object)].rank != r) ++by_body;
      }
    }
    EXPECT_EQ(seen.size(), reference.size()) << "seed " << seed << ": records missing over the two ranks";
    for (const auto& [key, n] : seen) EXPECT_EQ(n, 1) << "seed " << seed << ": point " << key.first << " recorded twice";
    EXPECT_EQ(points + static_cast<std::int64_t>(delegated_points.size()), one_st.colliding_points) << "seed " << seed;
    found += static_cast<std::int64_t>(one.size());
  }
  EXPECT_GT(found, 100);
  EXPECT_GT(by_body, 10) << "too few delegated points inside another rank's body: the test proves little";
  std::cout << "[measured] " << found << " records, " << by_body << " of delegated points made by the body's owner\n";
}
