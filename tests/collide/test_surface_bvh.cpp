// The surface hierarchy against brute force over all triangles, after deformation.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>

#include "collide/surface_bvh.hpp"
#include "collide/triangle_queries.hpp"
#include "softcontact/primitives.hpp"
#include "softcontact/surface.hpp"

using namespace softcontact;
using namespace softcontact::collide;

namespace {
struct Fixture {
  TetMesh mesh = make_torus(1, 0.4, 16, 4);
  Surface surf = extract_surface(mesh);
  std::vector<index_t> rows;
  SurfaceBvh bvh;
  Fixture() {
    for (std::size_t t = 0; t < surf.num_triangles(); ++t) rows.push_back(static_cast<index_t>(t));
    bvh.build(mesh.points.data(), surf.triangles.data(), rows);
    // Deform after the build (the tree's topology stays, refit moves the boxes).
    std::mt19937_64 g(9);
    std::uniform_real_distribution<double> u(-0.05, 0.05);
    for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
      mesh.points[3 * v] += 0.3 * mesh.points[3 * v + 2] + u(g);
      mesh.points[3 * v + 1] += u(g);
    }
    bvh.refit(mesh.points.data(), surf.triangles.data());
  }
};
}  // namespace

TEST(CollisionSurfaceBvh, NearestMatchesBruteForce) {
  Fixture f;
  std::mt19937_64 g(1);
  std::uniform_real_distribution<double> u(-2, 2);
  for (int trial = 0; trial < 300; ++trial) {
    const V3 p = {u(g), u(g), 0.5 * u(g)};
    std::int64_t deg = 0;
    const SurfaceBvh::Nearest nr = f.bvh.nearest(f.mesh.points.data(), f.surf.triangles.data(), p, deg);
    double best = -1;
    index_t best_t = -1;
    for (index_t t : f.rows) {
      const index_t* v = &f.surf.triangles[3 * static_cast<std::size_t>(t)];
      std::array<double, 3> w{};
      const V3 q = closest_point_on_triangle(p, load(f.mesh.points.data(), v[0]), load(f.mesh.points.data(), v[1]),
                                             load(f.mesh.points.data(), v[2]), w);
      const double d2 = norm2(p - q);
      if (best < 0 || d2 < best) {
        best = d2;
        best_t = t;
      }
    }
    EXPECT_EQ(nr.dist2, best);
    EXPECT_EQ(nr.triangle, best_t);
    EXPECT_EQ(deg, 0);
  }
}

TEST(CollisionSurfaceBvh, SegmentHitsMatchBruteForce) {
  Fixture f;
  std::mt19937_64 g(2);
  std::uniform_real_distribution<double> u(-2, 2);
  int total = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const V3 p = {u(g), u(g), 0.5 * u(g)}, q = {u(g), u(g), 0.5 * u(g)};
    std::vector<SurfaceBvh::Hit> hits;
    std::int64_t deg = 0;
    f.bvh.segment_hits(f.mesh.points.data(), f.surf.triangles.data(), p, q, hits, deg);
    std::set<index_t> got, want;
    for (const auto& h : hits) got.insert(h.triangle);
    for (index_t t : f.rows) {
      const index_t* v = &f.surf.triangles[3 * static_cast<std::size_t>(t)];
      double s = 0;
      std::array<double, 3> w{};
      if (segment_triangle(p, q, load(f.mesh.points.data(), v[0]), load(f.mesh.points.data(), v[1]),
                           load(f.mesh.points.data(), v[2]), s, w))
        want.insert(t);
    }
    EXPECT_EQ(got, want);
    EXPECT_EQ(got.size(), hits.size());
    total += static_cast<int>(hits.size());
  }
  EXPECT_GT(total, 100);
}

// A detector rebuilt for a new World takes the hierarchy of an object that stayed and
// moves its triangle rows (shift_triangles). Reference: the tree built from the same rest
// positions at the new rows. The torus is symmetric, so many centroids tie along an axis
// and the split falls back on the rows' order. The two trees must list the triangles in
// the same leaf order and, refitted to the same deformed positions, answer every search
// alike: the same nearest triangle and distance, the same crossings in the same order.
TEST(CollisionSurfaceBvh, AShiftedTreeIsTheTreeBuiltAtTheNewRows) {
  TetMesh mesh = make_torus(1, 0.4, 16, 4);
  const Surface surf = extract_surface(mesh);
  const std::size_t s = surf.num_triangles();
  constexpr index_t kShift = 37;  // 37 rows of another object before this one's
  std::vector<index_t> moved(surf.triangles.begin(), surf.triangles.begin() + 3 * kShift);
  moved.insert(moved.end(), surf.triangles.begin(), surf.triangles.end());
  std::vector<index_t> rows, moved_rows;
  for (std::size_t t = 0; t < s; ++t) {
    rows.push_back(static_cast<index_t>(t));
    moved_rows.push_back(static_cast<index_t>(t) + kShift);
  }
  SurfaceBvh shifted, built;
  shifted.build(mesh.points.data(), surf.triangles.data(), rows);
  shifted.shift_triangles(kShift);
  built.build(mesh.points.data(), moved.data(), moved_rows);
  EXPECT_EQ(shifted.leaf_order(), built.leaf_order());
  std::vector<index_t> sorted = built.leaf_order();
  std::sort(sorted.begin(), sorted.end());
  EXPECT_EQ(sorted, moved_rows);
  EXPECT_NE(built.leaf_order(), moved_rows);  // the order is the tree's, not the rows'

  std::mt19937_64 g(10);
  std::uniform_real_distribution<double> u(-0.05, 0.05), w(-2, 2);
  for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
    mesh.points[3 * v] += 0.3 * mesh.points[3 * v + 2] + u(g);
    mesh.points[3 * v + 2] += u(g);
  }
  shifted.refit(mesh.points.data(), moved.data());
  built.refit(mesh.points.data(), moved.data());
  int hits_seen = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const V3 p = {w(g), w(g), 0.5 * w(g)}, q = {w(g), w(g), 0.5 * w(g)};
    std::int64_t d1 = 0, d2 = 0;
    const SurfaceBvh::Nearest a = shifted.nearest(mesh.points.data(), moved.data(), p, d1);
    const SurfaceBvh::Nearest b = built.nearest(mesh.points.data(), moved.data(), p, d2);
    EXPECT_EQ(a.triangle, b.triangle);
    EXPECT_EQ(a.dist2, b.dist2);
    EXPECT_GE(a.triangle, kShift);
    std::vector<SurfaceBvh::Hit> ha, hb;
    shifted.segment_hits(mesh.points.data(), moved.data(), p, q, ha, d1);
    built.segment_hits(mesh.points.data(), moved.data(), p, q, hb, d2);
    ASSERT_EQ(ha.size(), hb.size());
    for (std::size_t k = 0; k < ha.size(); ++k) {
      EXPECT_EQ(ha[k].triangle, hb[k].triangle);
      EXPECT_EQ(ha[k].t, hb[k].t);
    }
    hits_seen += static_cast<int>(ha.size());
  }
  EXPECT_GT(hits_seen, 50);
}
