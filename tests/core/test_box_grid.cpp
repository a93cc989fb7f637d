// boxes_within (box.hpp, src/core/box_grid.cpp) against a brute-force test of every
// pair with Box::within: the same pairs, each once, on box sets chosen to stress the
// grid hierarchy (sizes over six orders of magnitude, boxes touching exactly at a
// margin, cell boundaries, duplicates, points, one box spanning everything).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include "softcontact/box.hpp"
#include "softcontact/error.hpp"

using namespace softcontact;

namespace {

using Pairs = std::vector<std::pair<std::int32_t, std::int32_t>>;

Box make_box(double x, double y, double z, double sx, double sy, double sz) {
  Box b;
  b.lo = {x, y, z};
  b.hi = {x + sx, y + sy, z + sz};
  return b;
}

Pairs brute(const std::vector<Box>& box, double reach) {
  Pairs out;
  const auto n = static_cast<std::int32_t>(box.size());
  for (std::int32_t i = 0; i < n; ++i)
    for (std::int32_t j = i + 1; j < n; ++j)
      if (box[static_cast<std::size_t>(i)].within(box[static_cast<std::size_t>(j)], reach)) out.emplace_back(i, j);
  return out;
}

void expect_same_pairs(const std::vector<Box>& box, double reach) {
  Pairs got = boxes_within(box, reach);
  for (const auto& [a, b] : got) ASSERT_LT(a, b);
  std::sort(got.begin(), got.end());
  const Pairs want = brute(box, reach);
  ASSERT_EQ(std::adjacent_find(got.begin(), got.end()), got.end()) << "a pair reported twice";
  ASSERT_EQ(got.size(), want.size()) << box.size() << " boxes, reach " << reach;
  EXPECT_EQ(got, want);
}

}  // namespace

TEST(BoxesWithin, RandomSizesOverSixDecadesMatchBruteForce) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> pos(-5.0, 5.0), decade(-4.0, 2.0), aspect(0.1, 1.0);
  for (double reach : {0.0, 0.01, 0.3, 2.0}) {
    std::vector<Box> box;
    for (int k = 0; k < 1500; ++k) {
      const double s = std::pow(10.0, decade(rng));
      box.push_back(make_box(pos(rng), pos(rng), pos(rng), s, s * aspect(rng), s * aspect(rng)));
    }
    expect_same_pairs(box, reach);
  }
}

TEST(BoxesWithin, ExactMarginsCellBoundariesDuplicatesAndPoints) {
  // A lattice of unit boxes at pitch 1.5 with reach 0.5: neighbours exactly at the
  // margin (gap 0.5 == reach, joined), diagonal ones too; every lo on a grid line.
  std::vector<Box> box;
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 8; ++j)
      for (int k = 0; k < 4; ++k) box.push_back(make_box(1.5 * i, 1.5 * j, 1.5 * k, 1, 1, 1));
  expect_same_pairs(box, 0.5);
  expect_same_pairs(box, 0.4999);  // now none of them
  EXPECT_TRUE(boxes_within(box, 0.4999).empty());
  // Duplicates and degenerate boxes (points), with reach 0: only coincident ones join.
  std::vector<Box> pts;
  for (int k = 0; k < 50; ++k) pts.push_back(make_box(k % 7, 0, 0, 0, 0, 0));
  expect_same_pairs(pts, 0.0);
  // Every box the same point: all pairs.
  std::vector<Box> same(40, make_box(2, 2, 2, 0, 0, 0));
  EXPECT_EQ(boxes_within(same, 0.0).size(), 40u * 39u / 2u);
}

TEST(BoxesWithin, OneBoxSpanningAllAndFlatColumns) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> pos(0.0, 100.0);
  std::vector<Box> box;
  box.push_back(make_box(-1, -1, -1, 102, 102, 0.5));  // a floor under everything
  for (int k = 0; k < 2000; ++k) box.push_back(make_box(pos(rng), pos(rng), pos(rng) * 0.02, 0.4, 0.4, 0.4));
  for (int k = 0; k < 200; ++k) box.push_back(make_box(0, 50, 0.05 * k, 100, 0.3, 0.04));  // stacked along z
  expect_same_pairs(box, 0.2);
  expect_same_pairs({}, 1.0);
  EXPECT_THROW((void)boxes_within({make_box(0, 0, 0, 1, 1, 1), Box::none()}, 1.0), RuntimeFailure);
  EXPECT_THROW((void)boxes_within({make_box(0, 0, 0, 1, 1, 1)}, -1.0), RuntimeFailure);
  EXPECT_THROW((void)boxes_within({make_box(0, 0, std::nan(""), 1, 1, 1)}, 1.0), RuntimeFailure);
  expect_same_pairs({make_box(0, 0, 0, 1, 1, 1)}, 1.0);
}
