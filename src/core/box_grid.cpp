// boxes_within (box.hpp): the pairs of boxes within a margin of each other, found in a
// hierarchy of uniform grids.
//
// Each box is the interval [lo, hi + reach] per axis, so that two boxes are within
// `reach` (Box::within) exactly when their intervals overlap on every axis, computed with
// the same floating-point operations as Box::within. Level l is a grid of cubic cells of
// side h * 2^l; a box goes to the lowest level whose cell is at least its longest
// interval, where it covers at most 2 cells per axis. A cell index is floor((x - origin)
// / side), monotone in x, so overlapping intervals always have overlapping index ranges,
// and a pair whose index ranges overlap shares exactly one cell whose index is, on every
// axis, the larger of their two lowest indices: the pair is tested there only, so no
// pair is reported twice and none is missed. A box meets the boxes of its own level in
// the cells it covers, and those of every coarser level in the cells its interval covers
// at that level's size (again at most 2 per axis); finer boxes find it from their side.
//
// h is the median of the boxes' longest intervals, at least 2^-20 of the scene's extent
// (so that a cell index fits 21 bits), so a typical box meets the others of its size
// in 8 cells and a few large ones (a floor, a wall) sit alone on a coarse level. The cost
// is O(n log n) for the sorts plus the pairs tested, which are near pairs unless many
// boxes crowd into one cell (then they are mostly near each other anyway).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "softcontact/box.hpp"
#include "softcontact/error.hpp"

namespace softcontact {
namespace {

constexpr int kIndexBits = 21;
constexpr std::int64_t kIndexLimit = std::int64_t{1} << kIndexBits;

struct Level {
  double side = 0;
  std::vector<std::uint64_t> key;    // the occupied cells, ascending
  std::vector<std::size_t> start;   // cell c holds ids[start[c] .. start[c + 1])
  std::vector<std::int32_t> ids;     // per cell ascending
};

std::uint64_t pack(const std::array<std::int64_t, 3>& c) {
  return (static_cast<std::uint64_t>(c[0]) << (2 * kIndexBits)) | (static_cast<std::uint64_t>(c[1]) << kIndexBits) |
         static_cast<std::uint64_t>(c[2]);
}

}  // namespace

std::vector<std::pair<std::int32_t, std::int32_t>> boxes_within(const std::vector<Box>& box, double reach) {
  std::vector<std::pair<std::int32_t, std::int32_t>> out;
  const std::size_t n = box.size();
  if (!std::isfinite(reach) || reach < 0) throw RuntimeFailure("boxes_within: reach must be finite and >= 0");
  if (n > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
    throw RuntimeFailure("boxes_within: too many boxes (" + std::to_string(n) + ")");
  for (std::size_t k = 0; k < n; ++k)
    for (int d = 0; d < 3; ++d)
      if (!std::isfinite(box[k].lo[d]) || !std::isfinite(box[k].hi[d]) || box[k].lo[d] > box[k].hi[d])
        throw RuntimeFailure("boxes_within: box " + std::to_string(k) + " is empty or not finite");
  if (n < 2) return out;

  std::array<double, 3> origin, top;
  origin.fill(std::numeric_limits<double>::infinity());
  top.fill(-std::numeric_limits<double>::infinity());
  std::vector<double> longest(n);
  for (std::size_t k = 0; k < n; ++k) {
    double e = 0;
    for (int d = 0; d < 3; ++d) {
      origin[d] = std::min(origin[d], box[k].lo[d]);
      top[d] = std::max(top[d], box[k].hi[d] + reach);
      e = std::max(e, (box[k].hi[d] + reach) - box[k].lo[d]);
    }
    longest[k] = e;
  }
  double span = 0;
  for (int d = 0; d < 3; ++d) span = std::max(span, top[d] - origin[d]);
  std::vector<double> sorted = longest;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(n / 2), sorted.end());
  double h = std::max(sorted[n / 2], span / static_cast<double>(kIndexLimit / 2));
  if (!(h > 0)) h = 1;  // every box is one and the same point

  auto index = [&](double x, int d, double side) {
    const auto i = static_cast<std::int64_t>(std::floor((x - origin[d]) / side));
    return std::clamp<std::int64_t>(i, 0, kIndexLimit - 1);
  };
  auto range = [&](std::size_t k, double side, std::array<std::int64_t, 3>& lo, std::array<std::int64_t, 3>& hi) {
    for (int d = 0; d < 3; ++d) {
      lo[d] = index(box[k].lo[d], d, side);
      hi[d] = index(box[k].hi[d] + reach, d, side);
    }
  };

  // Each box's level: the lowest whose cell holds its longest interval.
  std::vector<int> level(n, 0);
  int levels = 1;
  for (std::size_t k = 0; k < n; ++k) {
    double side = h;
    while (longest[k] > side && level[k] < 62) {
      side *= 2;
      ++level[k];
    }
    levels = std::max(levels, level[k] + 1);
  }
  std::vector<Level> grid(static_cast<std::size_t>(levels));
  for (int l = 0; l < levels; ++l) grid[static_cast<std::size_t>(l)].side = std::ldexp(h, l);

  // Fill the cells: (key, id) sorted, then grouped. low[k]: box k's lowest cell on its level.
  std::vector<std::array<std::int64_t, 3>> low(n);
  {
    std::vector<std::vector<std::pair<std::uint64_t, std::int32_t>>> entries(static_cast<std::size_t>(levels));
    std::array<std::int64_t, 3> hi{}, c{};
    for (std::size_t k = 0; k < n; ++k) {
      auto& e = entries[static_cast<std::size_t>(level[k])];
      std::array<std::int64_t, 3>& lo = low[k];
      range(k, grid[static_cast<std::size_t>(level[k])].side, lo, hi);
      for (c[0] = lo[0]; c[0] <= hi[0]; ++c[0])
        for (c[1] = lo[1]; c[1] <= hi[1]; ++c[1])
          for (c[2] = lo[2]; c[2] <= hi[2]; ++c[2]) e.emplace_back(pack(c), static_cast<std::int32_t>(k));
    }
    for (int l = 0; l < levels; ++l) {
      auto& e = entries[static_cast<std::size_t>(l)];
      std::sort(e.begin(), e.end());
      Level& g = grid[static_cast<std::size_t>(l)];
      g.ids.reserve(e.size());
      for (std::size_t i = 0; i < e.size(); ++i) {
        if (i == 0 || e[i].first != e[i - 1].first) {
          g.key.push_back(e[i].first);
          g.start.push_back(i);
        }
        g.ids.push_back(e[i].second);
      }
      g.start.push_back(e.size());
    }
  }

  auto test = [&](std::int32_t a, std::int32_t b) {
    if (box[static_cast<std::size_t>(a)].within(box[static_cast<std::size_t>(b)], reach))
      out.emplace_back(std::min(a, b), std::max(a, b));
  };
  // The cell where a pair with these lowest indices is tested.
  auto home = [](const std::array<std::int64_t, 3>& a, const std::array<std::int64_t, 3>& b) {
    return pack({std::max(a[0], b[0]), std::max(a[1], b[1]), std::max(a[2], b[2])});
  };

  auto low_of = [&](std::int32_t k) -> const std::array<std::int64_t, 3>& { return low[static_cast<std::size_t>(k)]; };

  // Pairs within a level.
  for (int l = 0; l < levels; ++l) {
    const Level& g = grid[static_cast<std::size_t>(l)];
    for (std::size_t c = 0; c < g.key.size(); ++c)
      for (std::size_t i = g.start[c]; i < g.start[c + 1]; ++i)
        for (std::size_t j = i + 1; j < g.start[c + 1]; ++j)
          if (home(low_of(g.ids[i]), low_of(g.ids[j])) == g.key[c]) test(g.ids[i], g.ids[j]);
  }
  // Pairs across levels: each box against the coarser levels' boxes.
  std::array<std::int64_t, 3> alo{}, ahi{}, c{};
  for (std::size_t k = 0; k < n; ++k)
    for (int l = level[k] + 1; l < levels; ++l) {
      const Level& g = grid[static_cast<std::size_t>(l)];
      if (g.key.empty()) continue;
      range(k, g.side, alo, ahi);
      for (c[0] = alo[0]; c[0] <= ahi[0]; ++c[0])
        for (c[1] = alo[1]; c[1] <= ahi[1]; ++c[1])
          for (c[2] = alo[2]; c[2] <= ahi[2]; ++c[2]) {
            const std::uint64_t key = pack(c);
            const auto it = std::lower_bound(g.key.begin(), g.key.end(), key);
            if (it == g.key.end() || *it != key) continue;
            const auto cell = static_cast<std::size_t>(it - g.key.begin());
            for (std::size_t j = g.start[cell]; j < g.start[cell + 1]; ++j)
              if (home(alo, low_of(g.ids[j])) == key) test(static_cast<std::int32_t>(k), g.ids[j]);
          }
    }
  return out;
}

}  // namespace softcontact
