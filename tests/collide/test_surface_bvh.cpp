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
