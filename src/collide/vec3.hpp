#pragma once
// Fixed-size vector arithmetic for the collision kernels: positions are read from the
// World's interleaved (n,3) arrays into std::array<double,3> values, so every kernel is
// straight-line code without allocation. Private to src/collide.
#include <array>
#include <cmath>
#include <limits>

#include "softcontact/box.hpp"
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

/// Boxes are the core's (box.hpp).
using softcontact::Box;

}  // namespace softcontact::collide
