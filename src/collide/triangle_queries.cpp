#include "triangle_queries.hpp"

#include <algorithm>
#include <cmath>

namespace softcontact::collide {

namespace {
// Closest point of segment (a, b) to p, as the parameter s in [0, 1]; 0 for a point.
double segment_param(const V3& p, const V3& a, const V3& b) {
  const V3 ab = b - a;
  const double l2 = norm2(ab);
  if (!(l2 > 0)) return 0;
  return std::clamp(dot(p - a, ab) / l2, 0.0, 1.0);
}
}  // namespace

bool triangle_degenerate(const V3& a, const V3& b, const V3& c) {
  const double l2 = std::max({norm2(b - a), norm2(c - b), norm2(a - c)});
  const double n2 = norm2(cross(b - a, c - a));
  return !(n2 > kFlatTriangle * kFlatTriangle * l2 * l2);
}

bool segment_triangle(const V3& p, const V3& q, const V3& a, const V3& b, const V3& c, double& t,
                      std::array<double, 3>& bary) {
  if (triangle_degenerate(a, b, c)) return false;
  const V3 dir = q - p, e1 = b - a, e2 = c - a;
  const V3 pv = cross(dir, e2);
  const double det = dot(e1, pv);
  const double scale = std::sqrt(norm2(dir) * norm2(e1) * norm2(e2));
  if (!(std::abs(det) > 1e-14 * scale)) return false;
  const double inv = 1.0 / det;
  const V3 tv = p - a;
  const double u = dot(tv, pv) * inv;
  if (u < 0 || u > 1) return false;
  const V3 qv = cross(tv, e1);
  const double v = dot(dir, qv) * inv;
  if (v < 0 || u + v > 1) return false;
  const double s = dot(e2, qv) * inv;
  if (s < 0 || s > 1) return false;
  t = s;
  bary = {1 - u - v, u, v};
  return true;
}

V3 closest_point_on_triangle(const V3& p, const V3& a, const V3& b, const V3& c, std::array<double, 3>& bary) {
  if (triangle_degenerate(a, b, c)) {
    // Nearest of the three edges (each possibly a point).
    const V3* corner[3] = {&a, &b, &c};
    double best = -1;
    V3 out{};
    for (int e = 0; e < 3; ++e) {
      const V3 &u = *corner[e], &w = *corner[(e + 1) % 3];
      const double s = segment_param(p, u, w);
      const V3 x = u + s * (w - u);
      const double d2 = norm2(p - x);
      if (best < 0 || d2 < best) {
        best = d2;
        out = x;
        bary = {0, 0, 0};
        bary[e] = 1 - s;
        bary[(e + 1) % 3] = s;
      }
    }
    return out;
  }
  // Ericson's Voronoi-region walk.
  const V3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) {
    bary = {1, 0, 0};
    return a;
  }
  const V3 bp = p - b;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) {
    bary = {0, 1, 0};
    return b;
  }
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    bary = {1 - v, v, 0};
    return a + v * ab;
  }
  const V3 cp = p - c;
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) {
    bary = {0, 0, 1};
    return c;
  }
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    bary = {1 - w, 0, w};
    return a + w * ac;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    bary = {0, 1 - w, w};
    return b + w * (c - b);
  }
  const double denom = 1 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  bary = {1 - v - w, v, w};
  return a + v * ab + w * ac;
}

bool projected_weights(const V3& q, const V3& a, const V3& b, const V3& c, std::array<double, 3>& w) {
  if (triangle_degenerate(a, b, c)) return false;
  const V3 n = cross(b - a, c - a);
  const double inv = 1.0 / norm2(n);
  // Signed areas of the sub-triangles opposite each corner, measured along n: the
  // barycentric coordinates of q's projection onto the plane.
  std::array<double, 3> l = {dot(n, cross(c - b, q - b)) * inv, dot(n, cross(a - c, q - c)) * inv, 0};
  l[2] = 1 - l[0] - l[1];
  double sum = 0;
  for (double& x : l) {
    x = std::max(x, 0.0);
    sum += x;
  }
  for (int k = 0; k < 3; ++k) w[k] = l[k] / sum;  // sum >= 1: clamping only raised negatives
  return true;
}

}  // namespace softcontact::collide
