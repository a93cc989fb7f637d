#pragma once
// A World of n loose vertices (no tets), all owned, global id = local index: what the
// contact response needs for hand-made collision records.
#include <cmath>
#include <vector>

#include "softcontact/collision.hpp"

#include "softcontact/world.hpp"

namespace softcontact::test {

inline World loose_world(const std::vector<double>& mass, const std::vector<bool>& fixed, int objects = 2) {
  World w;
  const std::size_t n = mass.size();
  w.n_owned = n;
  w.layout.resize(static_cast<std::size_t>(objects));
  w.vertex_offset.assign(static_cast<std::size_t>(objects), 0);  // every object starts at gid 0 = local 0 here
  for (std::size_t i = 0; i < n; ++i) {
    w.vertex_gid.push_back(static_cast<gid_t>(i));
    w.vertex_object.push_back(0);
    w.mass.push_back(mass[i]);
    w.inv_mass.push_back(fixed[i] ? 0.0 : 1.0 / mass[i]);
  }
  w.x.assign(3 * n, 0.0);
  w.x_prev.assign(3 * n, 0.0);
  w.v.assign(3 * n, 0.0);
  return w;
}

// The gap a collision's step closed, as a fraction of |d|: the motion of i against the
// point of T_i under it, (x_i - x_i~) - sum_j w_j (x_j - x_j~), along n = d/|d|
// (1: the two meet).
inline double closed_along(const World& before, const World& after, const Collision& c) {
  const double D = std::sqrt(c.depth[0] * c.depth[0] + c.depth[1] * c.depth[1] + c.depth[2] * c.depth[2]);
  double moved = 0;
  for (int d = 0; d < 3; ++d) {
    double u = after.x[3 * c.point + d] - before.x[3 * c.point + d];
    for (int k = 0; k < 3; ++k) u -= c.weight[k] * (after.x[3 * c.triangle[k] + d] - before.x[3 * c.triangle[k] + d]);
    moved += u * c.depth[d] / D;
  }
  return moved / D;
}

}  // namespace softcontact::test
