// Long validation of the collision detector (label 'long'): larger random scenes and a
// pile of tori against the brute-force reference, and thread-count independence on the
// pile. Minutes in Release (the brute force is O(surface vertices x tets)).
#include <gtest/gtest.h>
#include <omp.h>

#include <cstring>
#include <random>

#include "collide_test_util.hpp"
#include "softcontact/primitives.hpp"

using namespace softcontact;
using namespace softcontact::test;

namespace {

// n tori (R = 0.1, a = 0.04) on a lattice `spacing` apart with random orientations:
// each overlaps its neighbours where their tubes cross.
World torus_lattice(int nx, int ny, int nz, double spacing, std::uint64_t seed) {
  std::mt19937_64 g(seed);
  std::uniform_real_distribution<double> ang(0, 360);
  std::string yaml;
  for (int i = 0; i < nx; ++i)
    for (int j = 0; j < ny; ++j)
      for (int k = 0; k < nz; ++k)
        yaml += "  - material: m\n    primitive: {type: torus, major_radius: 0.1, minor_radius: 0.04, resolution: 2, "
                "around: 13}\n    transform: {rotate: [" +
                std::to_string(ang(g)) + ", " + std::to_string(ang(g)) + ", " + std::to_string(ang(g)) +
                "], translate: [" + std::to_string(i * spacing) + ", " + std::to_string(j * spacing) + ", " +
                std::to_string(k * spacing) + "]}\n";
  return world_from_objects(yaml);
}

}  // namespace

// The benchmark's pile (bench/bench_collide.cpp, other orientations): 200 tori, 78K tets.
TEST(CollisionLong, TorusPileMatchesBruteForce) {
  const World w = torus_lattice(8, 5, 5, 0.1625, 5);
  std::vector<Collision> c;
  CollisionStats st;
  CollisionDetector(w, {}).detect(w, nullptr, c, st);
  EXPECT_GT(st.colliding_points, 2000);
  EXPECT_EQ(record_pairs(c), brute_force_pairs(w));
  EXPECT_TRUE(all_finite(c));
}

TEST(CollisionLong, JitteredTorusLatticesMatchBruteForce) {
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    World w = torus_lattice(3, 3, 3, 0.15, seed);
    std::mt19937_64 g(seed);
    std::uniform_real_distribution<double> u(-0.01, 0.01);  // a third of a cell: some tets invert
    for (double& x : w.x) x += u(g);
    std::vector<Collision> c;
    CollisionStats st;
    CollisionDetector(w, {}).detect(w, nullptr, c, st);
    EXPECT_EQ(record_pairs(c), brute_force_pairs(w)) << "seed " << seed;
    EXPECT_TRUE(all_finite(c));
  }
}

TEST(CollisionLong, TorusLatticeSameRecordsWithOneAndTwoThreads) {
  const World w = torus_lattice(6, 5, 4, 0.1625, 7);
  const int before = omp_get_max_threads();
  std::vector<Collision> c1, c2;
  CollisionStats s1, s2;
  omp_set_num_threads(1);
  CollisionDetector(w, {}).detect(w, nullptr, c1, s1);
  omp_set_num_threads(2);
  CollisionDetector(w, {}).detect(w, nullptr, c2, s2);
  omp_set_num_threads(before);
  ASSERT_GT(c1.size(), 500u);
  ASSERT_EQ(c1.size(), c2.size());
  for (std::size_t k = 0; k < c1.size(); ++k) {
    EXPECT_EQ(c1[k].point_gid, c2[k].point_gid);
    EXPECT_EQ(c1[k].triangle_gid, c2[k].triangle_gid);
    EXPECT_EQ(std::memcmp(c1[k].depth.data(), c2[k].depth.data(), sizeof(c1[k].depth)), 0);
    EXPECT_EQ(std::memcmp(c1[k].weight.data(), c2[k].weight.data(), sizeof(c1[k].weight)), 0);
    EXPECT_EQ(c1[k].fallback, c2[k].fallback);
  }
}
