#pragma once
// Which boxes of a set meet which: the core's sort and sweep (box.hpp) along x.
#include <algorithm>
#include <cstdint>
#include <vector>

#include "vec3.hpp"

namespace softcontact::collide {

/// out[k]: the indices of the boxes that meet box k (ascending) when every box is grown
/// by `grow` on each side. Boxes that are empty or not `eligible(k)` meet none. `sweep`
/// is scratch.
template <class Eligible>
void overlapping_boxes(const std::vector<Box>& box, double grow, Eligible&& eligible,
                       std::vector<std::vector<std::int32_t>>& out, std::vector<std::int32_t>& sweep) {
  const std::size_t n = box.size();
  out.resize(n);
  for (auto& p : out) p.clear();
  sweep.clear();
  for (std::size_t k = 0; k < n; ++k)
    if (!box[k].empty() && eligible(k)) sweep.push_back(static_cast<std::int32_t>(k));
  sort_for_sweep(box, sweep, 0);
  sweep_pairs(box, sweep, 0, 2 * grow, [&](std::int32_t a, std::int32_t b) {
    out[static_cast<std::size_t>(a)].push_back(b);
    out[static_cast<std::size_t>(b)].push_back(a);
  });
  for (auto& p : out) std::sort(p.begin(), p.end());
}

}  // namespace softcontact::collide
