#pragma once
// The geometric predicates of softcontact verify (internal). Written apart from
// src/collide on purpose: the check must not share the detector's code (verify.hpp).
// Plain doubles on interleaved xyz; tolerances are relative, so they hold at any scale.
#include <algorithm>
#include <cmath>

namespace softcontact::verify {

/// det[b-a, c-a, d-a] = 6 x the signed volume of (a,b,c,d); positive when (b-a) x (c-a)
/// points towards d. Equal to n . (d - a) with n = (b-a) x (c-a).
inline double orient(const double* a, const double* b, const double* c, const double* d) {
  const double b0 = b[0] - a[0], b1 = b[1] - a[1], b2 = b[2] - a[2];
  const double c0 = c[0] - a[0], c1 = c[1] - a[1], c2 = c[2] - a[2];
  const double d0 = d[0] - a[0], d1 = d[1] - a[1], d2 = d[2] - a[2];
  return b0 * (c1 * d2 - c2 * d1) - b1 * (c0 * d2 - c2 * d0) + b2 * (c0 * d1 - c1 * d0);
}

inline double dist2(const double* a, const double* b) {
  const double x = a[0] - b[0], y = a[1] - b[1], z = a[2] - b[2];
  return x * x + y * y + z * z;
}

/// Barycentric point-in-tet: true when every barycentric coordinate of p in (a,b,c,d),
/// lambda_a = orient(p,b,c,d) / orient(a,b,c,d) and so on, is >= -tol. Works for either
/// orientation (an inverted tet still covers its convex hull); false for a flat tet or a
/// non-finite input.
inline bool in_closed_tet(const double* p, const double* a, const double* b, const double* c, const double* d,
                          double tol) {
  const double v = orient(a, b, c, d);
  if (!(std::abs(v) > 0) || !std::isfinite(v)) return false;
  const double s = v > 0 ? 1.0 : -1.0, t = -tol * std::abs(v);
  return s * orient(p, b, c, d) >= t && s * orient(a, p, c, d) >= t && s * orient(a, b, p, d) >= t &&
         s * orient(a, b, c, p) >= t;
}

/// Squared distance from p to the segment ab.
inline double point_segment_dist2(const double* p, const double* a, const double* b) {
  const double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
  const double len2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
  double t = len2 > 0 ? (ap[0] * ab[0] + ap[1] * ab[1] + ap[2] * ab[2]) / len2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  const double q[3] = {a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]};
  return dist2(p, q);
}

/// Squared distance from p to the closed triangle abc. The closest point by the Voronoi
/// regions of the corners, edges and face (Ericson, Real-Time Collision Detection, 5.1.5);
/// a degenerate triangle (collinear corners) falls back to its three edges.
inline double point_triangle_dist2(const double* p, const double* a, const double* b, const double* c) {
  const double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double ac[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const double ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
  auto dot = [](const double* u, const double* w) { return u[0] * w[0] + u[1] * w[1] + u[2] * w[2]; };
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return dist2(p, a);
  const double bp[3] = {p[0] - b[0], p[1] - b[1], p[2] - b[2]};
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return dist2(p, b);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return point_segment_dist2(p, a, b);
  const double cp[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return dist2(p, c);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return point_segment_dist2(p, a, c);
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return point_segment_dist2(p, b, c);
  const double sum = va + vb + vc;
  if (!(sum > 0) || !std::isfinite(sum))
    return std::min({point_segment_dist2(p, a, b), point_segment_dist2(p, b, c), point_segment_dist2(p, a, c)});
  const double v = vb / sum, w = vc / sum;
  const double q[3] = {a[0] + v * ab[0] + w * ac[0], a[1] + v * ab[1] + w * ac[1], a[2] + v * ab[2] + w * ac[2]};
  return dist2(p, q);
}

/// Where the segment pq crosses the triangle abc: p and q strictly on opposite sides of
/// its plane, each farther from it than `plane_tol` [m], and the crossing point inside the
/// closed triangle (its barycentric coordinates, from the signed volumes of the line pq
/// with each edge, >= -tol). Returns the parameter t in (0, 1) of the crossing point
/// p + t (q - p), or -1. `p_outside` tells whether p lies on the triangle's outer side
/// (the side its normal (b-a) x (c-a) points to).
inline double segment_crosses_triangle(const double* p, const double* q, const double* a, const double* b,
                                       const double* c, double plane_tol, double tol, bool& p_outside) {
  const double op = orient(a, b, c, p), oq = orient(a, b, c, q);
  const double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double ac[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const double n[3] = {ab[1] * ac[2] - ab[2] * ac[1], ab[2] * ac[0] - ab[0] * ac[2], ab[0] * ac[1] - ab[1] * ac[0]};
  const double scale = plane_tol * std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  if (!((op > scale && oq < -scale) || (op < -scale && oq > scale))) return -1;
  // The line pq meets the plane inside the triangle when the three volumes of pq with
  // the triangle's edges have one sign; they are proportional to its barycentric coordinates.
  const double wc = orient(p, q, a, b), wa = orient(p, q, b, c), wb = orient(p, q, c, a);
  const double sum = wa + wb + wc;
  if (!(std::abs(sum) > 0) || !std::isfinite(sum)) return -1;
  if (wa / sum < -tol || wb / sum < -tol || wc / sum < -tol) return -1;
  p_outside = op > 0;
  return op / (op - oq);
}

}  // namespace softcontact::verify
