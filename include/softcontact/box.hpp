#pragma once
// The one axis-aligned box of the code (core layer): object boxes for the partition and
// the ghost set, the detector's and the hierarchies' boxes, the scene's `fixed` regions
// and the placement of instances. Closed: a point on a face is inside, boxes that touch
// overlap.
#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

namespace softcontact {

struct Box {
  std::array<double, 3> lo{}, hi{};

  /// A box holding nothing (lo = +inf, hi = -inf): empty() until a point is added.
  static Box none() {
    Box b;
    b.reset();
    return b;
  }
  void reset() {
    constexpr double inf = std::numeric_limits<double>::infinity();
    lo = {inf, inf, inf};
    hi = {-inf, -inf, -inf};
  }
  /// Grows the box to hold p. A NaN coordinate is skipped.
  void add(const std::array<double, 3>& p) { add(p.data()); }
  void add(const double* p) {
    for (int d = 0; d < 3; ++d) {
      lo[d] = p[d] < lo[d] ? p[d] : lo[d];
      hi[d] = p[d] > hi[d] ? p[d] : hi[d];
    }
  }
  void add(const Box& b) {
    for (int d = 0; d < 3; ++d) {
      lo[d] = b.lo[d] < lo[d] ? b.lo[d] : lo[d];
      hi[d] = b.hi[d] > hi[d] ? b.hi[d] : hi[d];
    }
  }
  bool empty() const { return !(lo[0] <= hi[0]); }
  bool overlaps(const Box& b) const {
    return lo[0] <= b.hi[0] && b.lo[0] <= hi[0] && lo[1] <= b.hi[1] && b.lo[1] <= hi[1] && lo[2] <= b.hi[2] &&
           b.lo[2] <= hi[2];
  }
  /// Whether the two boxes come within `margin` of each other on every axis.
  bool within(const Box& b, double margin) const {
    for (int d = 0; d < 3; ++d)
      if (lo[d] > b.hi[d] + margin || b.lo[d] > hi[d] + margin) return false;
    return true;
  }
  /// The common part of two overlapping boxes.
  Box intersection(const Box& b) const {
    Box c;
    for (int d = 0; d < 3; ++d) {
      c.lo[d] = lo[d] > b.lo[d] ? lo[d] : b.lo[d];
      c.hi[d] = hi[d] < b.hi[d] ? hi[d] : b.hi[d];
    }
    return c;
  }
  bool contains(const std::array<double, 3>& p) const { return contains(p.data()); }
  bool contains(const double* p) const {
    return p[0] >= lo[0] && p[0] <= hi[0] && p[1] >= lo[1] && p[1] <= hi[1] && p[2] >= lo[2] && p[2] <= hi[2];
  }
  /// The longest side.
  double max_extent() const {
    const double a = hi[0] - lo[0], b = hi[1] - lo[1], c = hi[2] - lo[2];
    return a > b ? (a > c ? a : c) : (b > c ? b : c);
  }
};

/// The box grown by g on every side (an empty box stays empty).
inline Box grown(Box b, double g) {
  if (b.empty()) return b;
  for (std::size_t d = 0; d < 3; ++d) {
    b.lo[d] -= g;
    b.hi[d] += g;
  }
  return b;
}

/// Sorts `ids` (indices into `box`) by (lo[axis], index): the order of a sweep along `axis`.
inline void sort_for_sweep(const std::vector<Box>& box, std::vector<std::int32_t>& ids, int axis) {
  std::sort(ids.begin(), ids.end(), [&](std::int32_t a, std::int32_t b) {
    const double la = box[static_cast<std::size_t>(a)].lo[axis], lb = box[static_cast<std::size_t>(b)].lo[axis];
    return la != lb ? la < lb : a < b;
  });
}

/// The one overlap sweep of the code (sort and sweep): calls pair(a, b) for every two
/// boxes of `ids` (sorted by sort_for_sweep along `axis`) that come within `reach` of
/// each other on every axis (Box::within), a before b in the sweep. A box is compared
/// only with those after it whose lo along the axis is within its hi + reach, so the
/// cost is O(candidates along the axis), not O(n^2) unless they all overlap along it.
template <class Pair>
void sweep_pairs(const std::vector<Box>& box, const std::vector<std::int32_t>& ids, int axis, double reach, Pair&& pair) {
  for (std::size_t i = 0; i < ids.size(); ++i) {
    const Box& a = box[static_cast<std::size_t>(ids[i])];
    for (std::size_t j = i + 1; j < ids.size(); ++j) {
      const Box& b = box[static_cast<std::size_t>(ids[j])];
      if (b.lo[axis] > a.hi[axis] + reach) break;  // lo ascending: no later box is nearer
      if (a.within(b, reach)) pair(ids[i], ids[j]);
    }
  }
}

/// Every pair (a, b), a < b, of boxes that come within `reach` of each other on every
/// axis (Box::within, the same floating-point test), each once, in no set order. Found
/// in a hierarchy of uniform grids (src/core/box_grid.cpp): O(n log n + pairs near each
/// other), whatever the boxes' sizes and arrangement, where a sweep along one axis
/// compares every box with all those whose interval along that axis meets its own.
/// Throws RuntimeFailure for a box that is empty or not finite, or a negative or
/// non-finite reach.
std::vector<std::pair<std::int32_t, std::int32_t>> boxes_within(const std::vector<Box>& box, double reach);

/// Grows `b` to hold the point p (3 doubles). Unlike Box::add, a NaN coordinate is not
/// skipped: it replaces the bound, so that the box of an object with a non-finite
/// position can compare false (as the object boxes have always been built).
inline void add_point(Box& b, const double* p) {
  for (int d = 0; d < 3; ++d) {
    if (!(p[d] >= b.lo[d])) b.lo[d] = p[d];
    if (!(p[d] <= b.hi[d])) b.hi[d] = p[d];
  }
}

}  // namespace softcontact
