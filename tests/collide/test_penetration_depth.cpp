// Consistent penetration depth against analytic distances: a sphere pushed into a plate
// (flat: exact), a torus resting on a torus (curved: within what the mesh resolves), and
// the nearest-triangle fallback of a deep intersection.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "collide_test_util.hpp"

using namespace softcontact;
using namespace softcontact::test;
using namespace softcontact::collide;

namespace {

struct Outcome {
  World w;
  std::vector<Collision> c;
  CollisionStats st;
};

Outcome detect(World w) {
  Outcome r{std::move(w), {}, {}};
  CollisionDetector det(r.w, {});
  det.detect(r.w, nullptr, r.c, r.st);
  return r;
}

double norm(const std::array<double, 3>& a) { return std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }

// Largest gap between a sphere of radius R about c and the planes of the surface
// triangles of object `obj` (their vertices lie on the sphere): how far the polyhedron
// lies inside the sphere.
double sphere_sag(const World& w, int obj, const std::array<double, 3>& c, double R) {
  double sag = 0;
  for (std::size_t t = 0; t < w.triangles.size() / 3; ++t) {
    const index_t* v = &w.triangles[3 * t];
    if (w.vertex_object[static_cast<std::size_t>(v[0])] != obj) continue;
    collide::V3 p[3];
    for (int k = 0; k < 3; ++k) p[k] = collide::load(w.x.data(), v[k]) - collide::V3{c[0], c[1], c[2]};
    const collide::V3 n = collide::normalized(collide::cross(p[1] - p[0], p[2] - p[0]));
    sag = std::max(sag, R - std::abs(collide::dot(p[0], n)));
  }
  return sag;
}

}  // namespace

// Sphere (R = 0.3, 12 cells across) pushed 0.08 into a fixed plate (top at z = 0.1).
//  - Sphere points in the plate: the plate's top is flat and its smoothed normals are
//    exactly +z away from its edges, so every border crossing gives (s - x) . n = 0.1 - z
//    and the propagation formula is exact for a plane: d = (0, 0, 0.1 - z) within 1e-9.
//  - Plate points in the sphere: the analytic depth R - |p - c| is measured to the round
//    sphere, the scheme to its inscribed polyhedron, which lies inside the sphere by at
//    most the sag s (largest gap between the sphere and a triangle's plane, 0.0076 m
//    here). The depth along a direction close to the normal is therefore short of the
//    analytic one by between 0 and s plus the error of the direction, which is second
//    order in its angle; the test allows 1.5 s, and checks that the direction is within
//    15 degrees of the radial one.
TEST(PenetrationDepth, SpherePushedIntoPlate) {
  const double R = 0.3, depth = 0.08;
  const std::array<double, 3> c = {0.013, -0.021, 0.1 + R - depth};
  Outcome r = detect(world_from_objects(R"(
  - name: plate
    material: m
    primitive: {type: box, size: [2, 2, 0.2], cells: [20, 20, 2]}
    kinematic: true
  - name: ball
    material: m
    primitive: {type: sphere, radius: 0.3, resolution: 12}
    transform: {translate: [0.013, -0.021, 0.32]}
)"));
  ASSERT_TRUE(all_finite(r.c));
  EXPECT_EQ(record_pairs(r.c), brute_force_pairs(r.w));
  EXPECT_EQ(r.st.deep_fallbacks, 0);
  const double sag = sphere_sag(r.w, 1, c, R);
  EXPECT_LT(sag, 0.008);
  int ball = 0, plate = 0;
  double worst = 0;
  for (const Collision& k : r.c) {
    const auto i = static_cast<std::size_t>(k.point);
    const std::array<double, 3> x = {r.w.x[3 * i], r.w.x[3 * i + 1], r.w.x[3 * i + 2]};
    if (k.object == 1) {
      ++ball;
      EXPECT_NEAR(k.depth[0], 0, 1e-9);
      EXPECT_NEAR(k.depth[1], 0, 1e-9);
      EXPECT_NEAR(k.depth[2], 0.1 - x[2], 1e-9);
      const auto q = weighted_point(r.w, k);
      for (int d = 0; d < 3; ++d) EXPECT_NEAR(q[d], x[d] + k.depth[d], 1e-9);
      continue;
    }
    ++plate;
    const std::array<double, 3> rel = {x[0] - c[0], x[1] - c[1], x[2] - c[2]};
    const double analytic = R - norm(rel);
    const double D = norm(k.depth);
    worst = std::max(worst, std::abs(D - analytic));
    EXPECT_NEAR(D, analytic, 1.5 * sag) << "plate vertex " << i;
    // Pointing out of the sphere, about radially.
    const double cosang = (k.depth[0] * rel[0] + k.depth[1] * rel[1] + k.depth[2] * rel[2]) / (D * norm(rel));
    EXPECT_GT(cosang, std::cos(15 * 3.14159265358979 / 180));
  }
  EXPECT_GT(ball, 20);
  EXPECT_GT(plate, 5);
  RecordProperty("plate_worst_depth_error_m", std::to_string(worst));
  RecordProperty("sphere_sag_m", std::to_string(sag));
}

// A torus (R = 0.3, a = 0.1, 64 cells around, 8 across the tube) resting on an equal,
// fixed torus, 0.03 lower than touching: along the whole ring the upper tube dips into
// the lower one. Analytic depth of a point p of one torus inside the other (centre
// height z0): a - sqrt((rho - R)^2 + (z - z0)^2). The meshes are inscribed polyhedra,
// inside the round torus by at most the tube sag a (1 - cos(pi / 16)) = 0.0019 plus the
// ring sag (R + a)(1 - cos(pi / 64)) = 0.0005; the depth error is allowed 1.5 times their
// sum, 0.0036 (12 % of the 0.03 overlap; halving the cell size would quarter it).
TEST(PenetrationDepth, TorusRestingOnTorus) {
  const double R = 0.3, a = 0.1, z0 = 2 * a - 0.03;
  Outcome r = detect(world_from_objects(R"(
  - name: lower
    material: m
    primitive: {type: torus, major_radius: 0.3, minor_radius: 0.1, resolution: 8, around: 64}
    kinematic: true
  - name: upper
    material: m
    primitive: {type: torus, major_radius: 0.3, minor_radius: 0.1, resolution: 8, around: 64}
    transform: {translate: [0, 0, 0.17]}
)"));
  ASSERT_TRUE(all_finite(r.c));
  EXPECT_EQ(r.st.deep_fallbacks, 0);
  const double tol = 1.5 * (a * (1 - std::cos(3.14159265358979 / 16)) + (R + a) * (1 - std::cos(3.14159265358979 / 64)));
  double worst = 0;
  int n = 0;
  for (const Collision& k : r.c) {
    const auto i = static_cast<std::size_t>(k.point);
    const double x = r.w.x[3 * i], y = r.w.x[3 * i + 1], z = r.w.x[3 * i + 2];
    const double zc = k.other_object == 0 ? 0 : z0;  // centre height of the penetrated torus
    const double rho = std::sqrt(x * x + y * y);
    const double analytic = a - std::sqrt((rho - R) * (rho - R) + (z - zc) * (z - zc));
    const double D = norm(k.depth);
    worst = std::max(worst, std::abs(D - analytic));
    EXPECT_NEAR(D, analytic, tol) << "vertex " << i;
    // Within 15 degrees of the analytic outward normal of the other torus at p: from the
    // nearest point of its centre circle to p.
    const std::array<double, 3> nrm = {x - R * x / rho, y - R * y / rho, z - zc};
    const double cosang = (k.depth[0] * nrm[0] + k.depth[1] * nrm[1] + k.depth[2] * nrm[2]) / (D * norm(nrm));
    EXPECT_GT(cosang, std::cos(15 * 3.14159265358979 / 180)) << "vertex " << i;
    ++n;
  }
  EXPECT_GT(n, 100);
  RecordProperty("torus_worst_depth_error_m", std::to_string(worst));
}

// A small box entirely inside a large one: no border edge, one region, every point
// falls back to the nearest face of the large box, exactly.
TEST(PenetrationDepth, DeepIntersectionFallsBackToNearestTriangle) {
  Outcome r = detect(world_from_objects(R"(
  - name: big
    material: m
    primitive: {type: box, size: [2, 2, 2], cells: [4, 4, 4]}
    kinematic: true
  - name: small
    material: m
    primitive: {type: box, size: [0.2, 0.2, 0.2], cells: [2, 2, 2]}
    transform: {translate: [0.55, 0.1, -0.3]}
)"));
  ASSERT_TRUE(all_finite(r.c));
  EXPECT_EQ(r.st.deep_fallbacks, 1);
  EXPECT_EQ(r.st.border_points, 0);
  EXPECT_EQ(r.st.colliding_points, 26);  // the small box's surface vertices: 27 - 1 interior
  for (const Collision& k : r.c) {
    EXPECT_TRUE(k.fallback);
    const auto i = static_cast<std::size_t>(k.point);
    // Nearest face of [-1, 1]^3: x = +1 (0.45 .. 0.35 away; the others are farther).
    EXPECT_NEAR(k.depth[0], 1 - r.w.x[3 * i], 1e-12);
    EXPECT_NEAR(k.depth[1], 0, 1e-12);
    EXPECT_NEAR(k.depth[2], 0, 1e-12);
    const auto q = weighted_point(r.w, k);
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(q[d], r.w.x[3 * i + d] + k.depth[d], 1e-12);
  }
}

// A bar that has gone right through a slab (the configuration of two chained tori whose
// tube has passed between a vertex and its mesh neighbours): its four top vertices are
// 1 mm below the slab's top face, every other vertex is below the slab. Each top
// vertex's border edges lead down to the bar's bottom vertices and leave the slab
// through its bottom face, so the consistent depth points down, 0.199 m, to the far
// side. There is no way back to compare it with (no x^t). It is more than four times
// the distance to the slab's nearest surface point (the top face, 1 mm up), so the
// record takes that point: d = (0, 0, 0.001), T_i in the top face, x~ + d on it.
TEST(PenetrationDepth, DepthThroughTheBodyTakesTheNearestSurfacePoint) {
  Outcome r = detect(world_from_objects(R"(
  - name: slab
    material: m
    primitive: {type: box, size: [1, 1, 0.2], cells: [2, 2, 1]}
    kinematic: true
  - name: bar
    material: m
    primitive: {type: box, size: [0.1, 0.1, 1.0], cells: [1, 1, 1]}
    transform: {translate: [0.13, 0.17, -0.401]}
)"));
  ASSERT_TRUE(all_finite(r.c));
  ASSERT_EQ(r.c.size(), 4u);  // the bar's top vertices; no slab vertex is in the bar
  EXPECT_EQ(r.st.nearest_records, 4);
  EXPECT_EQ(r.st.redirected_depths, 4);
  EXPECT_EQ(r.st.entry_records, 0);
  for (const Collision& k : r.c) {
    const auto i = static_cast<std::size_t>(k.point);
    EXPECT_EQ(k.object, 1);
    EXPECT_NEAR(r.w.x[3 * i + 2], 0.099, 1e-12);
    EXPECT_TRUE(k.fallback);
    EXPECT_NEAR(k.depth[0], 0, 1e-12);
    EXPECT_NEAR(k.depth[1], 0, 1e-12);
    EXPECT_NEAR(k.depth[2], 0.001, 1e-12);
    for (int q = 0; q < 3; ++q) EXPECT_NEAR(r.w.x[3 * static_cast<std::size_t>(k.triangle[q]) + 2], 0.1, 1e-12);
    const auto p = weighted_point(r.w, k);
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(p[d], r.w.x[3 * i + d] + k.depth[d], 1e-12);
  }
}

// The same bar, after a step in which it moved 49 mm down: at the start of the step
// (x^t) its top vertices were 1 mm under the slab's top face, now (x~) they are 50 mm
// under it, a quarter of the way through. x^t was inside the slab, so there is no way
// back. The consistent depth leads down through the bottom face, 0.15 m: three times
// the distance to the nearest surface point, under the nearest-point rule's 4, so that
// rule keeps it, and the point would be pushed through the slab. The triangle x^t rested
// on, the top face, gives 0.05, less than half of it: every record is d = (0, 0, 0.05)
// to the top face, taken by the resting rule.
TEST(PenetrationDepth, PointPressedInFromRestKeepsTheFaceItRestedOn) {
  World w = world_from_objects(R"(
  - name: slab
    material: m
    primitive: {type: box, size: [1, 1, 0.2], cells: [2, 2, 1]}
    kinematic: true
  - name: bar
    material: m
    primitive: {type: box, size: [0.1, 0.1, 1.0], cells: [1, 1, 1]}
    transform: {translate: [0.13, 0.17, -0.45]}
)");
  w.x_prev = w.x;
  for (std::size_t v = 0; v < w.vertex_object.size(); ++v)
    if (w.vertex_object[v] == 1) w.x_prev[3 * v + 2] += 0.049;
  std::vector<Collision> c;
  CollisionStats st;
  CollisionDetector(w, {}).detect(w, w.x_prev.data(), c, st);
  ASSERT_TRUE(all_finite(c));
  ASSERT_EQ(c.size(), 4u);
  EXPECT_EQ(st.resting_records, 4);
  EXPECT_EQ(st.nearest_records, 0);
  EXPECT_EQ(st.entry_records, 0);
  for (const Collision& k : c) {
    const auto i = static_cast<std::size_t>(k.point);
    EXPECT_EQ(k.object, 1);
    EXPECT_NEAR(w.x[3 * i + 2], 0.05, 1e-12);
    EXPECT_TRUE(k.fallback);
    EXPECT_NEAR(k.depth[0], 0, 1e-12);
    EXPECT_NEAR(k.depth[1], 0, 1e-12);
    EXPECT_NEAR(k.depth[2], 0.05, 1e-12);
    for (int q = 0; q < 3; ++q) EXPECT_NEAR(w.x[3 * static_cast<std::size_t>(k.triangle[q]) + 2], 0.1, 1e-12);
    const auto p = weighted_point(w, k);
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(p[d], w.x[3 * i + d] + k.depth[d], 1e-12);
  }
}
