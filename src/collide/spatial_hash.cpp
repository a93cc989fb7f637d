#include "spatial_hash.hpp"

#include <algorithm>
#include <array>

#include "parallel.hpp"

namespace softcontact::collide {

namespace {
// Fibonacci hashing of a key into a table of 2^bits slots.
inline std::size_t slot_of(std::uint64_t key, int bits) {
  return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> (64 - bits));
}
}  // namespace

void radix_sort(std::vector<KeyIndex>& a, std::vector<KeyIndex>& scratch) {
  const std::size_t n = a.size();
  if (n < 2) return;
  // One pass over the data gives all eight digit histograms.
  std::array<std::array<std::size_t, 256>, 8> count{};
  for (const KeyIndex& e : a)
    for (int d = 0; d < 8; ++d) ++count[d][(e.key >> (8 * d)) & 0xff];
  scratch.resize(n);
  for (int d = 0; d < 8; ++d) {
    const std::uint64_t first = (a[0].key >> (8 * d)) & 0xff;
    if (count[d][first] == n) continue;  // every key has this digit: the pass would not move anything
    std::array<std::size_t, 256> offset{};
    std::size_t sum = 0;
    for (int b = 0; b < 256; ++b) {
      offset[b] = sum;
      sum += count[d][b];
    }
    for (const KeyIndex& e : a) scratch[offset[(e.key >> (8 * d)) & 0xff]++] = e;
    a.swap(scratch);
  }
}

void SpatialHash::set_cell_size(double h) {
  h_ = h;
  inv_h_ = 1.0 / h;
}

std::int32_t SpatialHash::find(std::uint64_t key) const {
  if (keys_.empty()) return -1;
  const std::size_t mask = table_.size() - 1;
  for (std::size_t s = slot_of(key, table_bits_);; s = (s + 1) & mask) {
    const std::int32_t c = table_[s];
    if (c < 0) return -1;
    if (keys_[static_cast<std::size_t>(c)] == key) return c;
  }
}

// Cell lengths h / (inv_x h) along x and h along y, z; the points' cell range.
void SpatialHash::cell_range(const double* x, const std::vector<index_t>& points, double inv_x) {
  inv_[0] = inv_x;
  inv_[1] = inv_[2] = inv_h_;
  for (int d = 0; d < 3; ++d) {
    lo_[d] = 0;
    hi_[d] = -1;
  }
  for (std::size_t k = 0; k < points.size(); ++k)
    for (int d = 0; d < 3; ++d) {
      const std::int64_t c = cell_coord(x[3 * static_cast<std::size_t>(points[k]) + d], inv_[d]);
      if (k == 0 || c < lo_[d]) lo_[d] = c;
      if (k == 0 || c > hi_[d]) hi_[d] = c;
    }
  for (int d = 0; d < 3; ++d) dim_[d] = hi_[d] - lo_[d] + 1;
}

void SpatialHash::insert_points(const double* x, const std::vector<index_t>& points, const std::int32_t* label) {
  const std::size_t np = points.size();
  // Dense if the points' cell range (with thin cells along x) is small enough, else
  // hashed with cubic cells.
  cell_range(x, points, kRowRefine * inv_h_);
  double cells = 1;  // counted in double: a range spanning 2^40 cells per axis must not overflow
  for (int d = 0; d < 3; ++d) cells *= static_cast<double>(std::max<std::int64_t>(dim_[d], 0));
  dense_ = np > 0 && cells <= static_cast<double>(kDenseCellsPerPoint * static_cast<std::int64_t>(np) + 4096);
  if (!dense_) cell_range(x, points, inv_h_);

  order_.resize(np);
  if (dense_) {
    // Counting sort by dense index (stable: input order within a cell).
    const auto nc = static_cast<std::size_t>(cells);
    cell_.resize(np);
    start_.assign(nc + 1, 0);
    for (std::size_t k = 0; k < np; ++k) {
      const double* p = x + 3 * static_cast<std::size_t>(points[k]);
      cell_[k] = ((cell_coord(p[2], inv_[2]) - lo_[2]) * dim_[1] + (cell_coord(p[1], inv_[1]) - lo_[1])) * dim_[0] +
                 (cell_coord(p[0], inv_[0]) - lo_[0]);
      ++start_[static_cast<std::size_t>(cell_[k]) + 1];
    }
    for (std::size_t c = 0; c < nc; ++c) start_[c + 1] += start_[c];
    for (std::size_t k = 0; k < np; ++k) order_[start_[static_cast<std::size_t>(cell_[k])]++] = static_cast<std::uint32_t>(k);
    // The scatter advanced each start to the next cell's: shift back.
    for (std::size_t c = nc; c > 0; --c) start_[c] = start_[c - 1];
    start_[0] = 0;
    keys_.clear();
  } else {
    pairs_.resize(np);
    parallel_for(np, [&](std::size_t k, int) {
      const double* p = x + 3 * static_cast<std::size_t>(points[k]);
      pairs_[k] = {cell_key(cell_coord(p[0], inv_[0]), cell_coord(p[1], inv_[1]), cell_coord(p[2], inv_[2])),
                   static_cast<std::uint32_t>(k)};
    });
    radix_sort(pairs_, scratch_);
    keys_.clear();
    start_.clear();
    for (std::size_t k = 0; k < np; ++k) {
      order_[k] = pairs_[k].index;
      if (k == 0 || pairs_[k].key != pairs_[k - 1].key) {
        keys_.push_back(pairs_[k].key);
        start_.push_back(k);
      }
    }
    start_.push_back(np);
    // Table at most half full: short probe sequences.
    table_bits_ = 4;
    while ((std::size_t{1} << table_bits_) < 2 * keys_.size()) ++table_bits_;
    table_.assign(std::size_t{1} << table_bits_, -1);
    const std::size_t mask = table_.size() - 1;
    for (std::size_t c = 0; c < keys_.size(); ++c) {
      std::size_t s = slot_of(keys_[c], table_bits_);
      while (table_[s] >= 0) s = (s + 1) & mask;
      table_[s] = static_cast<std::int32_t>(c);
    }
  }
  points_.resize(np);
  px_.resize(3 * np);
  pl_.resize(np);
  for (std::size_t k = 0; k < np; ++k) {
    const index_t v = points[order_[k]];
    points_[k] = v;
    pl_[k] = label[v];
    for (int d = 0; d < 3; ++d) px_[3 * k + d] = x[3 * static_cast<std::size_t>(v) + d];
  }
}

}  // namespace softcontact::collide
