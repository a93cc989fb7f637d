#pragma once
// Point/segment queries against one triangle (a, b, c) [m], with barycentric
// coordinates (w_a, w_b, w_c) summing to 1. Every function is finite for every finite
// input: a triangle whose area is below kFlatTriangle times its longest edge squared is
// *degenerate* and is reported as such instead of being divided by.
#include <array>

#include "vec3.hpp"

namespace softcontact::collide {

inline constexpr double kFlatTriangle = 1e-12;

/// |(b - a) x (c - a)| <= kFlatTriangle * (longest edge)^2.
bool triangle_degenerate(const V3& a, const V3& b, const V3& c);

/// Crossing of the segment p + t (q - p), t in [0, 1], with the triangle (either side;
/// edges and corners included, so a segment through a shared edge crosses both
/// triangles): Moeller-Trumbore. False for no crossing, for a segment parallel to the
/// triangle's plane (|det| <= 1e-14 |q - p| |b - a| |c - a|) and for a degenerate
/// triangle. On success, t and the crossing's barycentric coordinates.
bool segment_triangle(const V3& p, const V3& q, const V3& a, const V3& b, const V3& c, double& t,
                      std::array<double, 3>& bary);

/// Closest point of the triangle to p (Ericson, "Real-Time Collision Detection", 5.1.5)
/// and its barycentric coordinates. For a degenerate triangle, the closest point of its
/// three edges.
V3 closest_point_on_triangle(const V3& p, const V3& a, const V3& b, const V3& c, std::array<double, 3>& bary);

/// Barycentric coordinates of q projected onto the triangle's plane, negative ones
/// clamped to 0 and the three renormalised to sum 1 (method.md: omega of the collision).
/// False, leaving w untouched, for a degenerate triangle.
bool projected_weights(const V3& q, const V3& a, const V3& b, const V3& c, std::array<double, 3>& w);

}  // namespace softcontact::collide
