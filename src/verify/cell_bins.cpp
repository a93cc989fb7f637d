#include "cell_bins.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace softcontact::verify {

void CellBins::build(double cell, std::size_t count, const double* lo, const double* hi) {
  h_ = cell > 0 && std::isfinite(cell) ? cell : 1.0;
  inv_h_ = 1.0 / h_;
  double mn[3], mx[3];
  for (int d = 0; d < 3; ++d) {
    mn[d] = std::numeric_limits<double>::infinity();
    mx[d] = -std::numeric_limits<double>::infinity();
  }
  std::vector<char> finite(count, 0);
  for (std::size_t i = 0; i < count; ++i) {
    bool ok = true;
    for (int d = 0; d < 3; ++d) ok = ok && std::isfinite(lo[3 * i + d]) && std::isfinite(hi[3 * i + d]);
    if (!ok) continue;
    finite[i] = 1;
    for (int d = 0; d < 3; ++d) {
      mn[d] = std::min(mn[d], lo[3 * i + d]);
      mx[d] = std::max(mx[d], hi[3 * i + d]);
    }
  }
  for (std::size_t d = 0; d < 3; ++d) {
    const bool any = mn[d] <= mx[d];
    origin_[d] = any ? mn[d] : 0.0;
    const double cells = any ? std::floor((mx[d] - mn[d]) * inv_h_) + 1 : 1.0;
    dims_[d] = static_cast<std::int64_t>(std::clamp(cells, 1.0, static_cast<double>(kMaxCells)));
  }

  first_.assign(count, Cell{0, 0, 0});
  binned_.assign(count, 0);
  std::vector<std::int64_t> offset(count + 1, 0);
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < static_cast<std::int64_t>(count); ++i) {
    const auto u = static_cast<std::size_t>(i);
    if (!finite[u]) continue;
    const Cell a = cell_of(lo + 3 * u), b = cell_of(hi + 3 * u);
    const std::int64_t n = (b[0] - a[0] + 1) * (b[1] - a[1] + 1) * (b[2] - a[2] + 1);
    first_[u] = a;
    if (n <= kMaxCellsPerItem) {
      binned_[u] = 1;
      offset[u + 1] = n;
    }
  }
  oversized_.clear();
  for (std::size_t i = 0; i < count; ++i) {
    if (finite[i] && !binned_[i]) oversized_.push_back(static_cast<std::int32_t>(i));
    offset[i + 1] += offset[i];
  }

  // Dense: a grid that is not much larger than its entries gets an offset per cell, filled
  // by a counting sort (two passes over the items in order, so each list is sorted by
  // item and nothing depends on the threads). Sparse (objects flown apart): sorted keys.
  const auto entries_count = static_cast<std::size_t>(offset[count]);
  const double cells = static_cast<double>(dims_[0]) * static_cast<double>(dims_[1]) * static_cast<double>(dims_[2]);
  dense_ = cells <= std::max(4.0 * static_cast<double>(entries_count), 65536.0);
  keys_.clear();
  begin_.clear();
  items_.resize(entries_count);
  if (dense_) {
    begin_.assign(static_cast<std::size_t>(cells) + 1, 0);
    auto each_cell = [&](std::size_t u, auto&& f) {
      const Cell a = first_[u], b = cell_of(hi + 3 * u);
      for (std::int64_t x = a[0]; x <= b[0]; ++x)
        for (std::int64_t y = a[1]; y <= b[1]; ++y)
          for (std::int64_t z = a[2]; z <= b[2]; ++z) f(static_cast<std::size_t>(linear({x, y, z})));
    };
    for (std::size_t u = 0; u < count; ++u)
      if (binned_[u]) each_cell(u, [&](std::size_t c) { ++begin_[c + 1]; });
    for (std::size_t c = 1; c < begin_.size(); ++c) begin_[c] += begin_[c - 1];
    std::vector<std::int64_t> fill(begin_.begin(), begin_.end() - 1);
    for (std::size_t u = 0; u < count; ++u)
      if (binned_[u])
        each_cell(u, [&](std::size_t c) { items_[static_cast<std::size_t>(fill[c]++)] = static_cast<std::int32_t>(u); });
    return;
  }
  std::vector<std::pair<std::uint64_t, std::int32_t>> entries(entries_count);
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < static_cast<std::int64_t>(count); ++i) {
    const auto u = static_cast<std::size_t>(i);
    if (!binned_[u]) continue;
    const Cell a = first_[u], b = cell_of(hi + 3 * u);
    auto at = static_cast<std::size_t>(offset[u]);
    for (std::int64_t x = a[0]; x <= b[0]; ++x)
      for (std::int64_t y = a[1]; y <= b[1]; ++y)
        for (std::int64_t z = a[2]; z <= b[2]; ++z) entries[at++] = {key({x, y, z}), static_cast<std::int32_t>(i)};
  }
  std::sort(entries.begin(), entries.end());
  for (std::size_t e = 0; e < entries.size(); ++e) {
    if (e == 0 || entries[e].first != entries[e - 1].first) {
      keys_.push_back(entries[e].first);
      begin_.push_back(static_cast<std::int64_t>(e));
    }
    items_[e] = entries[e].second;
  }
  begin_.push_back(static_cast<std::int64_t>(entries.size()));
}

CellBins::Cell CellBins::cell_of(const double* p, bool* exact) const {
  Cell c{0, 0, 0};
  bool inside = true;
  for (std::size_t d = 0; d < 3; ++d) {
    const double f = std::floor((p[d] - origin_[d]) * inv_h_);
    const double top = static_cast<double>(dims_[d] - 1);
    if (!(f >= 0 && f <= top)) inside = false;  // also NaN
    c[d] = f >= 0 ? static_cast<std::int64_t>(std::min(f, top)) : 0;
  }
  if (exact) *exact = inside;
  return c;
}

double CellBins::inner_distance(const double* p, const Cell& c) const {
  double d = h_;
  for (std::size_t a = 0; a < 3; ++a) {
    const double lo = origin_[a] + static_cast<double>(c[a]) * h_;
    d = std::min({d, p[a] - lo, lo + h_ - p[a]});
  }
  return d > 0 ? d : 0.0;  // also NaN
}

double CellBins::distance_to_cell(const double* p, const Cell& c) const {
  double d2 = 0;
  for (std::size_t a = 0; a < 3; ++a) {
    const double lo = origin_[a] + static_cast<double>(c[a]) * h_;
    const double out = std::max({lo - p[a], p[a] - (lo + h_), 0.0});
    d2 += out * out;
  }
  return std::sqrt(d2);
}

std::span<const std::int32_t> CellBins::at(const Cell& c) const {
  if (dense_) {
    for (std::size_t a = 0; a < 3; ++a)
      if (c[a] < 0 || c[a] >= dims_[a]) return {};
    const auto j = static_cast<std::size_t>(linear(c));
    return {items_.data() + begin_[j], static_cast<std::size_t>(begin_[j + 1] - begin_[j])};
  }
  const std::uint64_t k = key(c);
  const auto it = std::lower_bound(keys_.begin(), keys_.end(), k);
  if (it == keys_.end() || *it != k) return {};
  const auto j = static_cast<std::size_t>(it - keys_.begin());
  return {items_.data() + begin_[j], static_cast<std::size_t>(begin_[j + 1] - begin_[j])};
}

}  // namespace softcontact::verify
