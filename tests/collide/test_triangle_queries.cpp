// Point/segment queries against one triangle, including degenerate triangles.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "collide/triangle_queries.hpp"

using namespace softcontact::collide;

namespace {
V3 from_bary(const V3& a, const V3& b, const V3& c, const std::array<double, 3>& w) {
  return w[0] * a + w[1] * b + w[2] * c;
}
}  // namespace

// The closest point is on the triangle (barycentric coordinates in [0, 1] that reproduce
// it) and no sampled point of the triangle is closer.
TEST(CollisionTriangle, ClosestPointBeatsSampling) {
  std::mt19937_64 g(5);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 300; ++trial) {
    const V3 a = {u(g), u(g), u(g)}, b = {u(g), u(g), u(g)}, c = {u(g), u(g), u(g)}, p = {2 * u(g), 2 * u(g), 2 * u(g)};
    std::array<double, 3> w{};
    const V3 q = closest_point_on_triangle(p, a, b, c, w);
    double sum = 0;
    for (double wi : w) {
      EXPECT_GE(wi, -1e-12);
      EXPECT_LE(wi, 1 + 1e-12);
      sum += wi;
    }
    EXPECT_NEAR(sum, 1, 1e-12);
    const V3 r = from_bary(a, b, c, w);
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(q[d], r[d], 1e-12);
    const double best = norm2(p - q);
    for (int i = 0; i <= 40; ++i)
      for (int j = 0; i + j <= 40; ++j) {
        const V3 s = from_bary(a, b, c, {1 - (i + j) / 40.0, i / 40.0, j / 40.0});
        EXPECT_LE(best, norm2(p - s) + 1e-12);
      }
  }
}

// Degenerate triangles (a point, a segment) give finite answers, reported as degenerate.
TEST(CollisionTriangle, DegenerateTrianglesStayFinite) {
  const V3 a = {0, 0, 0}, b = {1, 0, 0}, p = {0.5, 1, 0};
  EXPECT_TRUE(triangle_degenerate(a, a, a));
  EXPECT_TRUE(triangle_degenerate(a, b, 0.5 * b));
  std::array<double, 3> w{};
  const V3 q = closest_point_on_triangle(p, a, b, 0.5 * b, w);
  EXPECT_NEAR(q[0], 0.5, 1e-15);
  EXPECT_NEAR(q[1], 0, 1e-15);
  EXPECT_TRUE(std::isfinite(w[0] + w[1] + w[2]));
  const V3 q0 = closest_point_on_triangle(p, a, a, a, w);
  EXPECT_EQ(q0[0], 0);
  EXPECT_FALSE(projected_weights(p, a, a, b, w));
  double t = -1;
  EXPECT_FALSE(segment_triangle(p, {0.5, -1, 0}, a, b, 0.5 * b, t, w));
}

// Crossing of a segment with the triangle z = 0, x, y >= 0, x + y <= 1.
TEST(CollisionTriangle, SegmentCrossing) {
  const V3 a = {0, 0, 0}, b = {1, 0, 0}, c = {0, 1, 0};
  double t = -1;
  std::array<double, 3> w{};
  ASSERT_TRUE(segment_triangle({0.2, 0.3, 1}, {0.2, 0.3, -3}, a, b, c, t, w));
  EXPECT_NEAR(t, 0.25, 1e-15);
  EXPECT_NEAR(w[0], 0.5, 1e-15);
  EXPECT_NEAR(w[1], 0.2, 1e-15);
  EXPECT_NEAR(w[2], 0.3, 1e-15);
  EXPECT_FALSE(segment_triangle({0.2, 0.3, 1}, {0.2, 0.3, 0.5}, a, b, c, t, w));  // stops short
  EXPECT_FALSE(segment_triangle({0.8, 0.8, 1}, {0.8, 0.8, -1}, a, b, c, t, w));   // misses
  EXPECT_FALSE(segment_triangle({0, 0, 1}, {1, 1, 1}, a, b, c, t, w));            // parallel
  ASSERT_TRUE(segment_triangle({0.5, 0.5, -1}, {0.5, 0.5, 1}, a, b, c, t, w));    // on the edge: counted
  EXPECT_NEAR(t, 0.5, 1e-15);
}

// Projection of points above the triangle: exact inside, clamped and renormalised
// outside.
TEST(CollisionTriangle, ProjectedWeights) {
  const V3 a = {0, 0, 0}, b = {2, 0, 0}, c = {0, 2, 0};
  std::array<double, 3> w{};
  ASSERT_TRUE(projected_weights({0.5, 0.5, 7}, a, b, c, w));
  EXPECT_NEAR(w[0], 0.5, 1e-15);
  EXPECT_NEAR(w[1], 0.25, 1e-15);
  EXPECT_NEAR(w[2], 0.25, 1e-15);
  ASSERT_TRUE(projected_weights({3, -1, -2}, a, b, c, w));  // barycentric (-0.5, 1.5, -0.5)
  EXPECT_EQ(w[0], 0);
  EXPECT_EQ(w[1], 1);
  EXPECT_EQ(w[2], 0);
  ASSERT_TRUE(projected_weights({1.5, 1.5, 0}, a, b, c, w));  // (-0.5, 0.75, 0.75) -> (0, 0.5, 0.5)
  EXPECT_NEAR(w[1], 0.5, 1e-15);
  EXPECT_NEAR(w[2], 0.5, 1e-15);
}
