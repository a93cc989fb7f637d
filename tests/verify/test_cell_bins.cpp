// CellBins (src/verify/cell_bins.hpp), the grid of softcontact verify: every cell lists
// exactly the items whose box touches it, in item order, whether the grid keeps an offset
// per cell (dense) or only its occupied cells (sparse); checked against a brute-force
// test of every box against every cell.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "verify/cell_bins.hpp"

namespace {

using softcontact::verify::CellBins;

// Boxes of size up to 2.5 cells in [0, extent)^3, plus `far` boxes shifted by `shift`.
void random_boxes(std::size_t n, double extent, std::size_t far, double shift, std::vector<double>& lo,
                  std::vector<double>& hi) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> at(0, extent), size(0, 2.5);
  lo.clear();
  hi.clear();
  for (std::size_t i = 0; i < n + far; ++i)
    for (int d = 0; d < 3; ++d) {
      const double a = at(rng) + (i >= n ? shift : 0.0);
      lo.push_back(a);
      hi.push_back(a + size(rng));
    }
}

// Each cell c of the grid lists the items whose box overlaps c's closed extent (by the
// grid's own cell_of of the box corners), nothing else, ascending.
void expect_matches_brute_force(const CellBins& bins, const std::vector<double>& lo, const std::vector<double>& hi,
                                const std::vector<CellBins::Cell>& probes) {
  const std::size_t n = lo.size() / 3;
  for (const CellBins::Cell& c : probes) {
    std::vector<std::int32_t> expected;
    for (std::size_t i = 0; i < n; ++i) {
      const CellBins::Cell a = bins.cell_of(&lo[3 * i]), b = bins.cell_of(&hi[3 * i]);
      bool in = true;
      for (int d = 0; d < 3; ++d) in = in && a[d] <= c[d] && c[d] <= b[d];
      if (in) expected.push_back(static_cast<std::int32_t>(i));
    }
    const auto got = bins.at(c);
    ASSERT_EQ(std::vector<std::int32_t>(got.begin(), got.end()), expected)
        << "cell " << c[0] << " " << c[1] << " " << c[2];
  }
}

std::vector<CellBins::Cell> every_cell(const CellBins& bins, std::int64_t limit) {
  std::vector<CellBins::Cell> cells;
  for (std::int64_t x = -1; x <= std::min(bins.dim(0), limit); ++x)
    for (std::int64_t y = -1; y <= std::min(bins.dim(1), limit); ++y)
      for (std::int64_t z = -1; z <= std::min(bins.dim(2), limit); ++z) cells.push_back({x, y, z});
  return cells;
}

}  // namespace

TEST(CellBins, DenseGridListsEveryBoxInEveryCellItTouches) {
  std::vector<double> lo, hi;
  random_boxes(400, 12.0, 0, 0.0, lo, hi);
  CellBins bins;
  bins.build(1.0, 400, lo.data(), hi.data());
  EXPECT_LE(bins.dim(0), 15);  // at most 15^3 cells for 400 boxes: the dense layout
  expect_matches_brute_force(bins, lo, hi, every_cell(bins, 20));
}

TEST(CellBins, SparseGridOfBodiesFlownApartListsTheSame) {
  // 300 boxes near the origin and 100 a thousand cells away: 10^9 cells, sparse.
  std::vector<double> lo, hi;
  random_boxes(300, 10.0, 100, 1000.0, lo, hi);
  CellBins bins;
  bins.build(1.0, 400, lo.data(), hi.data());
  EXPECT_GT(bins.dim(0), 1000);
  std::vector<CellBins::Cell> probes = every_cell(bins, 14);
  for (std::int64_t x = 995; x <= 1015; ++x)
    for (std::int64_t y = 995; y <= 1015; ++y)
      for (std::int64_t z = 995; z <= 1015; ++z) probes.push_back({x, y, z});
  expect_matches_brute_force(bins, lo, hi, probes);
}

TEST(CellBins, InnerDistanceIsTheDistanceToTheNearestFaceOfTheCell) {
  std::vector<double> lo = {0, 0, 0}, hi = {4, 4, 4};
  CellBins bins;
  bins.build(1.0, 1, lo.data(), hi.data());
  const double p[3] = {2.3, 1.9, 3.45};
  const CellBins::Cell c = bins.cell_of(p);
  ASSERT_EQ(c, (CellBins::Cell{2, 1, 3}));
  EXPECT_NEAR(bins.inner_distance(p, c), 0.1, 1e-12);   // 1.9 is 0.1 below the face at 2
  EXPECT_EQ(bins.inner_distance(p, {0, 0, 0}), 0.0);    // not in that cell
}

// Distance from a point to a cell: 0 inside, the gap along one axis beside a face, the
// Euclidean distance to the nearest corner beyond a corner (cells of edge 1 from 0).
TEST(CellBins, DistanceToACellIsTheDistanceToItsBox) {
  std::vector<double> lo = {0, 0, 0}, hi = {4, 4, 4};
  CellBins bins;
  bins.build(1.0, 1, lo.data(), hi.data());
  const double inside[3] = {2.3, 1.9, 3.45};
  EXPECT_EQ(bins.distance_to_cell(inside, {2, 1, 3}), 0.0);
  EXPECT_NEAR(bins.distance_to_cell(inside, {2, 2, 3}), 0.1, 1e-12);  // that cell spans y in [2, 3]
  const double corner[3] = {0.7, 0.6, 0.5};                     // cell {1, 1, 1}: nearest corner (1, 1, 1)
  EXPECT_NEAR(bins.distance_to_cell(corner, {1, 1, 1}), std::sqrt(0.09 + 0.16 + 0.25), 1e-12);
  const double above[3] = {3.5, 3.5, 3.5};                      // cell {0, 0, 0}: nearest corner (1, 1, 1)
  EXPECT_NEAR(bins.distance_to_cell(above, {0, 0, 0}), std::sqrt(3 * 2.5 * 2.5), 1e-12);
}
