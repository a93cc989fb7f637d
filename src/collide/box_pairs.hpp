#pragma once
// Which boxes of a set meet which: sort and sweep along x.
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
  std::sort(sweep.begin(), sweep.end(), [&](std::int32_t a, std::int32_t b) {
    const double la = box[static_cast<std::size_t>(a)].lo[0], lb = box[static_cast<std::size_t>(b)].lo[0];
    return la != lb ? la < lb : a < b;
  });
  const double g2 = 2 * grow;
  for (std::size_t i = 0; i < sweep.size(); ++i) {
    const Box& a = box[static_cast<std::size_t>(sweep[i])];
    for (std::size_t j = i + 1; j < sweep.size(); ++j) {
      const Box& b = box[static_cast<std::size_t>(sweep[j])];
      if (b.lo[0] > a.hi[0] + g2) break;
      bool meet = true;
      for (int d = 0; d < 3; ++d) meet = meet && a.lo[d] <= b.hi[d] + g2 && b.lo[d] <= a.hi[d] + g2;
      if (!meet) continue;
      out[static_cast<std::size_t>(sweep[i])].push_back(sweep[j]);
      out[static_cast<std::size_t>(sweep[j])].push_back(sweep[i]);
    }
  }
  for (auto& p : out) std::sort(p.begin(), p.end());
}

}  // namespace softcontact::collide
