#pragma once
// Fixed-size vector arithmetic for the collision kernels: positions are read from the
// World's interleaved (n,3) arrays into std::array<double,3> values, so every kernel is
// straight-line code without allocation. Private to src/collide.
#include <array>
#include <cmath>
#include <limits>

#include "softcontact/mesh.hpp"

namespace softcontact::collide {

using V3 = std::array<double, 3>;

inline V3 load(const double* x, index_t i) {
  const double* p = x + 3 * static_cast<std::size_t>(i);
  return {p[0], p[1], p[2]};
}
inline V3 operator+(const V3& a, const V3& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
inline V3 operator-(const V3& a, const V3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
inline V3 operator*(double s, const V3& a) { return {s * a[0], s * a[1], s * a[2]}; }
inline double dot(const V3& a, const V3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline V3 cross(const V3& a, const V3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
inline double norm2(const V3& a) { return dot(a, a); }
inline bool finite(const V3& a) { return std::isfinite(a[0]) && std::isfinite(a[1]) && std::isfinite(a[2]); }

/// a / |a|, or the zero vector when |a| is zero or not finite (callers test for that).
inline V3 normalized(const V3& a) {
  const double n = std::sqrt(norm2(a));
  if (!(n > 0) || !std::isfinite(n)) return {0, 0, 0};
  return (1.0 / n) * a;
}

/// orient(a, b, c, d) = (d - a) . ((b - a) x (c - a)) = 6 x signed volume of (a, b, c, d).
inline double orient(const V3& a, const V3& b, const V3& c, const V3& d) { return dot(d - a, cross(b - a, c - a)); }

/// Axis-aligned box; empty() after reset().
struct Box {
  V3 lo{}, hi{};
  void reset() {
    lo = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
          std::numeric_limits<double>::infinity()};
    hi = {-lo[0], -lo[1], -lo[2]};
  }
  void add(const V3& p) {
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
  /// Closed boxes: touching counts as overlapping.
  bool overlaps(const Box& b) const {
    return lo[0] <= b.hi[0] && b.lo[0] <= hi[0] && lo[1] <= b.hi[1] && b.lo[1] <= hi[1] && lo[2] <= b.hi[2] &&
           b.lo[2] <= hi[2];
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
  bool contains(const V3& p) const {
    return p[0] >= lo[0] && p[0] <= hi[0] && p[1] >= lo[1] && p[1] <= hi[1] && p[2] >= lo[2] && p[2] <= hi[2];
  }
  double max_extent() const {
    const double a = hi[0] - lo[0], b = hi[1] - lo[1], c = hi[2] - lo[2];
    return a > b ? (a > c ? a : c) : (b > c ? b : c);
  }
};

}  // namespace softcontact::collide
