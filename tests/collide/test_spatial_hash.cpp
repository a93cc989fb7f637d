// The spatial hash of the query points: radix sort, cell coordinates, and that a box's
// runs hold every point inside the box (no pair is missed) and nothing twice, in both
// layouts (dense and hashed).
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>

#include "collide/spatial_hash.hpp"

using namespace softcontact;
using namespace softcontact::collide;

TEST(SpatialHash, RadixSortIsAStableSortByKey) {
  std::mt19937_64 g(3);
  std::vector<KeyIndex> a(5000), scratch;
  for (std::size_t k = 0; k < a.size(); ++k) {
    // Few distinct keys (duplicates test stability), spread over all eight bytes.
    const std::uint64_t key = (g() % 37) * 0x0101010101010101ull ^ (g() % 3) << 60;
    a[k] = {key, static_cast<std::uint32_t>(k)};
  }
  std::vector<KeyIndex> ref = a;
  std::stable_sort(ref.begin(), ref.end(), [](const KeyIndex& x, const KeyIndex& y) { return x.key < y.key; });
  radix_sort(a, scratch);
  ASSERT_EQ(a.size(), ref.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].key, ref[k].key);
    EXPECT_EQ(a[k].index, ref[k].index);
  }
}

TEST(SpatialHash, CellCoordinateIsTheFloor) {
  EXPECT_EQ(cell_coord(0.0, 4), 0);
  EXPECT_EQ(cell_coord(0.25, 4), 1);  // on a cell boundary: the upper cell
  EXPECT_EQ(cell_coord(-0.25, 4), -1);
  EXPECT_EQ(cell_coord(-0.2, 4), -1);
  EXPECT_EQ(cell_coord(-1e-300, 4), -1);
  EXPECT_EQ(cell_coord(0.2, 4), 0);
  EXPECT_EQ(cell_coord(1e300, 4), std::int64_t{1} << 40);  // clamped
  EXPECT_EQ(cell_coord(-1e300, 4), -(std::int64_t{1} << 40));
  // Monotone across the clamp.
  EXPECT_LE(cell_coord(1e12, 1), cell_coord(1e13, 1));
}

namespace {

// Inserts random points (spread over `extent`), then checks random boxes: every point
// in the closed box is delivered exactly once, and every delivered point lies in a cell
// of the box's range.
void check_runs(double extent, bool expect_dense, std::uint64_t seed) {
  std::mt19937_64 g(seed);
  std::uniform_real_distribution<double> u(-extent, extent);
  const std::size_t n = 3000;
  std::vector<double> x(3 * n);
  for (double& c : x) c = u(g);
  // A cluster of points on cell boundaries too.
  for (std::size_t k = 0; k < 100; ++k)
    for (int d = 0; d < 3; ++d) x[3 * k + d] = 0.1 * static_cast<double>(static_cast<int>(g() % 21) - 10);
  std::vector<index_t> points;
  std::vector<std::int32_t> label(n);
  for (std::size_t k = 0; k < n; ++k) {
    if (k % 3 != 1) points.push_back(static_cast<index_t>(k));  // ascending, with gaps
    label[k] = static_cast<std::int32_t>(k % 5);
  }
  SpatialHash grid;
  grid.set_cell_size(0.1);
  grid.insert_points(x.data(), points, label.data());
  EXPECT_EQ(grid.dense(), expect_dense);
  ASSERT_EQ(grid.num_points(), points.size());
  for (std::size_t k = 0; k < grid.num_points(); ++k) {
    const index_t v = grid.point(k);
    for (int d = 0; d < 3; ++d) EXPECT_EQ(grid.sorted_x()[3 * k + d], x[3 * static_cast<std::size_t>(v) + d]);
    EXPECT_EQ(grid.sorted_label()[k], label[static_cast<std::size_t>(v)]);
  }
  std::uniform_real_distribution<double> side(0.01, 0.3);
  for (int trial = 0; trial < 200; ++trial) {
    Box b;
    const std::size_t anchor = static_cast<std::size_t>(points[g() % points.size()]);
    for (int d = 0; d < 3; ++d) {
      // Boxes around a point (so that they are not empty), sometimes with a face exactly
      // on that point.
      b.lo[d] = trial % 4 == 0 ? x[3 * anchor + d] : x[3 * anchor + d] - side(g);
      b.hi[d] = b.lo[d] + side(g);
    }
    std::multiset<index_t> got;
    const CellRange r = grid.range_of(b);
    const double inv[3] = {grid.dense() ? 10.0 * kRowRefine : 10.0, 10.0, 10.0};  // 1 / cell length per axis
    grid.for_each_run(r, [&](std::size_t k0, std::size_t k1) {
      for (std::size_t k = k0; k < k1; ++k) {
        got.insert(grid.point(k));
        const double* p = grid.sorted_x() + 3 * k;
        for (int d = 0; d < 3; ++d) {
          EXPECT_GE(cell_coord(p[d], inv[d]), r.lo[d]);
          EXPECT_LE(cell_coord(p[d], inv[d]), r.hi[d]);
        }
      }
    });
    for (index_t v : points) {
      const V3 p = load(x.data(), v);
      if (b.contains(p)) {
        EXPECT_EQ(got.count(v), 1u) << "point " << v << " trial " << trial;
      }
    }
    for (index_t v : got) EXPECT_EQ(got.count(v), 1u);
  }
}

}  // namespace

// 3000 points in a 2 m cube with 0.1 m cells (0.025 m along x): 32,000 cells, dense.
TEST(SpatialHash, DenseLayoutFindsEveryPointInABox) { check_runs(1.0, true, 11); }

// The same points spread over 2 km: far more cells than points, hashed keys.
TEST(SpatialHash, HashedLayoutFindsEveryPointInABox) { check_runs(1000.0, false, 12); }

TEST(SpatialHash, NoPoints) {
  SpatialHash grid;
  grid.set_cell_size(1);
  grid.insert_points(nullptr, {}, nullptr);
  Box b;
  b.lo = {0, 0, 0};
  b.hi = {1, 1, 1};
  int runs = 0;
  grid.for_each_run(grid.range_of(b), [&](std::size_t, std::size_t) { ++runs; });
  EXPECT_EQ(runs, 0);
}
