// softcontact verify (src/verify): analytic cases with exact depths, surface crossings
// without any vertex inside, inverted tets, the free-fall bound, and the grid-based
// search against a brute-force O(n m) loop on random overlapping scenes.
#include <gtest/gtest.h>
#include <omp.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <set>
#include <string>

#include "softcontact/error.hpp"
#include "softcontact/surface.hpp"
#include "softcontact/verify.hpp"
#include "softcontact/world.hpp"
#include "../random_objects.hpp"
#include "verify/verify_geometry.hpp"

namespace softcontact {
namespace {

using P3 = std::array<double, 3>;

// Bodies built by hand: each a single tet, positive orientation, its four faces outward.
struct TetBodies {
  VerifyMesh mesh;
  std::vector<double> x;

  void add(const P3& a, const P3& b, const P3& c, const P3& d, bool fixed = false) {
    const auto obj = static_cast<std::int32_t>(mesh.object_fixed.size());
    const gid_t base = static_cast<gid_t>(x.size() / 3);
    for (const P3& p : {a, b, c, d}) {
      x.insert(x.end(), p.begin(), p.end());
      mesh.vertex_object.push_back(obj);
    }
    const bool positive = verify::orient(a.data(), b.data(), c.data(), d.data()) > 0;
    const gid_t t[4] = {base, base + (positive ? 1 : 2), base + (positive ? 2 : 1), base + 3};
    mesh.tets.insert(mesh.tets.end(), t, t + 4);
    mesh.tet_object.push_back(obj);
    for (const auto& f : kTetFaces)
      for (int k : f) mesh.triangles.push_back(t[k]);
    mesh.triangle_object.insert(mesh.triangle_object.end(), 4, obj);
    mesh.object_fixed.push_back(fixed ? 1 : 0);
  }
  void prepare() { prepare_verify_mesh(mesh, x.data(), "test"); }
};

constexpr P3 kO{0, 0, 0}, kX{1, 0, 0}, kY{0, 1, 0}, kZ{0, 0, 1};

// A small tet with its first corner at p, the rest well outside the unit tet.
TetBodies point_in_unit_tet(const P3& p) {
  TetBodies b;
  b.add(kO, kX, kY, kZ);
  b.add(p, {-2, -2, -2}, {-2.5, -2, -2}, {-2, -2.5, -2});
  b.prepare();
  return b;
}

VerifyOptions all_checks() { return VerifyOptions{true, true, 0}; }

}  // namespace

// A point inside the unit tet: its depth is the distance to the nearest face, exactly.
TEST(Verify, PointInUnitTetHasTheDistanceToTheNearestFace) {
  // Distances to x = 0, y = 0, z = 0 and x + y + z = 1: 0.1, 0.2, 0.15, 0.55 / sqrt(3).
  TetBodies b = point_in_unit_tet({0.1, 0.2, 0.15});
  const VerifyFrame f = verify_frame(b.mesh, b.x.data(), nullptr, all_checks());
  EXPECT_EQ(f.surface.count, 1);
  EXPECT_NEAR(f.surface.max_depth, 0.1, 1e-15);
  EXPECT_NEAR(f.surface.p99_depth, 0.1, 1e-15);
  EXPECT_EQ(f.surface.vertex, 4);
  EXPECT_EQ(f.surface.object, 1);
  EXPECT_EQ(f.surface.in_object, 0);
  EXPECT_EQ(f.interior.count, 0);
  // Near the slanted face: (0.3, 0.3, 0.3) is (1 - 0.9) / sqrt(3) from it.
  b = point_in_unit_tet({0.3, 0.3, 0.3});
  EXPECT_NEAR(verify_frame(b.mesh, b.x.data(), nullptr).surface.max_depth, 0.1 / std::sqrt(3.0), 1e-15);
}

// Just outside, on a face or on a corner: not inside. A micrometre inside: counted.
TEST(Verify, PointOnOrJustOutsideTheSurfaceIsNotCounted) {
  for (const P3& p : {P3{-1e-6, 0.2, 0.15}, P3{0, 0.2, 0.15}, P3{0, 0, 0}, P3{0.5, 0.5, 0}, P3{0.4, 0.3, 0.3 + 1e-9}}) {
    const TetBodies b = point_in_unit_tet(p);
    const VerifyFrame f = verify_frame(b.mesh, b.x.data(), nullptr, all_checks());
    EXPECT_EQ(f.surface.count, 0) << p[0] << ' ' << p[1] << ' ' << p[2];
    EXPECT_EQ(f.surface.max_depth, 0);
  }
  const TetBodies b = point_in_unit_tet({1e-6, 0.2, 0.15});
  const VerifyFrame f = verify_frame(b.mesh, b.x.data(), nullptr, all_checks());
  EXPECT_EQ(f.surface.count, 1);
  EXPECT_NEAR(f.surface.max_depth, 1e-6, 1e-15);
}

// Vertices inside a kinematic body count; between two kinematic bodies nothing counts.
TEST(Verify, KinematicBodiesCountUnlessBothAre) {
  TetBodies b;
  b.add(kO, kX, kY, kZ, true);
  b.add({0.1, 0.2, 0.15}, {-2, -2, -2}, {-2.5, -2, -2}, {-2, -2.5, -2}, false);
  b.prepare();
  EXPECT_EQ(verify_frame(b.mesh, b.x.data(), nullptr).surface.count, 1);
  b.mesh.object_fixed[1] = 1;
  EXPECT_EQ(verify_frame(b.mesh, b.x.data(), nullptr).surface.count, 0);
}

namespace {

const char* kSceneHead = R"(
simulation: {dt: 0.001, steps: 1}
materials:
  - {name: m, young: 1e5, poisson: 0.3, density: 1000}
objects:
)";

struct SceneBodies {
  Scene scene;
  VerifyMesh mesh;
  std::vector<double> x;
  explicit SceneBodies(const std::string& objects)
      : scene(load_scene_from_string(std::string(kSceneHead) + objects, "test.yaml")),
        mesh(verify_mesh_of(scene)),
        x(initial_positions(scene)) {}
};

}  // namespace

// A 0.2 m cube sunk 0.07 m into the top of a 1 m box: its four bottom corners and the
// box's top centre vertex (inside the cube, 0.07 below its bottom face) are 0.07 deep.
TEST(Verify, CubeSunkIntoABoxHasTheSinkingDepth) {
  const SceneBodies s(R"(
  - {material: m, primitive: {type: box, size: [1, 1, 1], cells: [2, 2, 2]}}
  - {material: m, primitive: {type: box, size: [0.2, 0.2, 0.2], cells: [1, 1, 1]}, transform: {translate: [0, 0, 0.53]}}
)");
  const VerifyFrame f = verify_frame(s.mesh, s.x.data(), nullptr, all_checks());
  EXPECT_EQ(f.surface.count, 5);
  EXPECT_NEAR(f.surface.max_depth, 0.07, 1e-12);
  EXPECT_NEAR(f.surface.p99_depth, 0.07, 1e-12);
  EXPECT_NEAR(f.surface_depth(), 0.07 / s.mesh.median_edge, 1e-12);
  EXPECT_EQ(f.interior.count, 0);
  EXPECT_GT(f.crossings.count, 0);
  EXPECT_EQ(f.crossings.without_inside_vertex, 0);
  // The cube's vertical edges enter the box's top at 0.07 from their bottom corners.
  EXPECT_NEAR(f.crossings.max_depth, 0.07, 1e-9);
  EXPECT_EQ(f.inverted, 0);
  // The median edge: the 2 x 2 x 2 box's 48 tets (144 edges of 0.5, 96 of 0.707, 48 of
  // 0.866) and the cube's 6 (18 of 0.2, 12 of 0.283, 6 of 0.346): slot 162 of 324 is 0.5.
  EXPECT_NEAR(s.mesh.median_edge, 0.5, 1e-15);
}

// An interior vertex of one box inside another: reported apart from the surface ones.
TEST(Verify, InteriorVerticesAreReportedApart) {
  const SceneBodies s(R"(
  - {material: m, primitive: {type: box, size: [1, 1, 1], cells: [2, 2, 2]}}
  - {material: m, primitive: {type: box, size: [0.4, 0.4, 0.4], cells: [2, 2, 2]}, transform: {translate: [0.1, 0.05, 0.45]}}
)");
  // The small box's centre (0.1, 0.05, 0.45) is an interior vertex 0.05 below the top.
  const VerifyFrame f = verify_frame(s.mesh, s.x.data(), nullptr, all_checks());
  EXPECT_EQ(f.interior.count, 1);
  EXPECT_NEAR(f.interior.max_depth, 0.05, 1e-12);
  EXPECT_EQ(f.interior.object, 1);
  EXPECT_EQ(f.interior.in_object, 0);
  VerifyOptions surface_only;
  surface_only.interior = surface_only.crossings = false;
  const VerifyFrame g = verify_frame(s.mesh, s.x.data(), nullptr, surface_only);
  EXPECT_EQ(g.interior.count, 0);
  EXPECT_EQ(g.crossings.count, 0);
  EXPECT_EQ(g.surface.count, f.surface.count);
  EXPECT_EQ(g.surface.max_depth, f.surface.max_depth);
}

// Self-contact: the top centre vertex of a 1 m box (4 x 4 x 4 cells) moved to 0.3 above
// the bottom face, inside tets far from its star. Its self depth is the distance to the
// nearest surface triangle that touches no vertex of its star: the bottom face, 0.3.
// Moved only 0.3 down, just past the vertex below it (into tets that touch its star, as
// inverted elements put it), it is not counted. Another body's checks are unchanged, and with
// VerifyOptions::self off nothing is counted.
TEST(Verify, SurfaceVertexInsideItsOwnBodyAwayFromItsStar) {
  SceneBodies s(R"(
  - {material: m, primitive: {type: box, size: [1, 1, 1], cells: [4, 4, 4]}}
)");
  std::size_t top = s.x.size();
  for (std::size_t v = 0; 3 * v < s.x.size(); ++v)
    if (s.x[3 * v] == 0 && s.x[3 * v + 1] == 0 && s.x[3 * v + 2] == 0.5) top = v;
  ASSERT_LT(top, s.x.size());
  s.x[3 * top] = 0.01;
  s.x[3 * top + 1] = 0.02;
  s.x[3 * top + 2] = -0.2;
  VerifyFrame f = verify_frame(s.mesh, s.x.data(), nullptr, all_checks());
  EXPECT_EQ(f.self.count, 1);
  EXPECT_EQ(f.self.vertex, static_cast<gid_t>(top));
  EXPECT_NEAR(f.self.max_depth, 0.3, 1e-12);
  EXPECT_NEAR(f.self_depth(), 0.3 / s.mesh.median_edge, 1e-12);
  EXPECT_EQ(f.surface.count, 0);
  VerifyOptions no_self = all_checks();
  no_self.self = false;
  EXPECT_EQ(verify_frame(s.mesh, s.x.data(), nullptr, no_self).self.count, 0);
  s.x[3 * top + 2] = 0.2;  // through the vertex below it, into tets of its star: inverted, not a fold
  f = verify_frame(s.mesh, s.x.data(), nullptr, all_checks());
  EXPECT_EQ(f.self.count, 0);
  EXPECT_GT(f.inverted, 0);
}

// Two long square bars turned 45 degrees about their axes, one along x with an edge down,
// one along y with an edge up, crossed so that their edges overlap by 0.04 m: no vertex is
// inside the other bar, but each bar's edge runs through the other: 4 crossings (off the
// faces' diagonals). The deepest point of either edge is 0.04 below the other's ridge,
// 0.04 sin 45 = 0.0283 from its two sloped faces.
TEST(Verify, BarsCrossedEdgeOnEdgeHaveCrossingsAndNoVertexInside) {
  const double half_diagonal = 0.1 * std::sqrt(2.0);
  auto exact = [](double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    return std::string(buf);
  };
  const std::string z_high = exact(half_diagonal - 0.02), z_low = exact(0.02 - half_diagonal);
  const SceneBodies s(R"(
  - {material: m, primitive: {type: box, size: [2, 0.2, 0.2], cells: [1, 1, 1]}, transform: {rotate: [45, 0, 0], translate: [0, 0.17, )" +
                      z_high + R"(]}}
  - {material: m, primitive: {type: box, size: [0.2, 2, 0.2], cells: [1, 1, 1]}, transform: {rotate: [0, 45, 0], translate: [0.3, 0, )" +
                      z_low + R"(]}}
)");
  const VerifyFrame f = verify_frame(s.mesh, s.x.data(), nullptr, all_checks());
  EXPECT_EQ(f.surface.count, 0);
  EXPECT_EQ(f.interior.count, 0);
  EXPECT_EQ(f.crossings.count, 4);
  EXPECT_EQ(f.crossings.without_inside_vertex, 4);
  EXPECT_NEAR(f.crossings.max_depth, 0.04 * std::sqrt(0.5), 1e-9);
  // Apart by 1 mm: nothing.
  SceneBodies apart = s;
  for (std::size_t i = 0; i < apart.x.size() / 3; ++i)
    if (apart.mesh.vertex_object[i] == 0) apart.x[3 * i + 2] += 0.041;
  const VerifyFrame g = verify_frame(apart.mesh, apart.x.data(), nullptr, all_checks());
  EXPECT_EQ(g.crossings.count, 0);
}

// Inverted tets: signed volume against the rest volume's sign (flat ones count).
TEST(Verify, InvertedAndFlatTetsAreCounted) {
  TetBodies b;
  b.add(kO, kX, kY, kZ);
  b.add({3, 0, 0}, {4, 0, 0}, {3, 1, 0}, {3, 0, 1});
  b.add({6, 0, 0}, {7, 0, 0}, {6, 1, 0}, {6, 0, 1});
  b.prepare();
  b.x[3 * 7 + 2] = -1;  // the second tet's apex through its base: inverted
  b.x[3 * 11 + 2] = 0;  // the third's apex into its base plane: flat
  const VerifyFrame f = verify_frame(b.mesh, b.x.data(), nullptr);
  EXPECT_EQ(f.inverted, 2);
  EXPECT_EQ(f.first_inverted, 1);
}

// v_ff = sqrt(v0^2 + 2 |g| H), H along g over every vertex; the ratio to the fastest vertex.
TEST(Verify, SpeedRatioAgainstTheFreeFallSpeed) {
  TetBodies b;
  b.add(kO, kX, kY, {0, 0, 5});
  b.add({3, 0, -1}, {4, 0, -1}, {3, 1, -1}, {3, 0, 0});
  b.prepare();
  // Highest z 5, lowest -1: H = 6 along g = (0, 0, -9.81).
  const double vff = free_fall_speed(b.x.data(), b.x.size() / 3, {0, 0, -9.81}, 2.0);
  EXPECT_NEAR(vff, std::sqrt(4.0 + 2 * 9.81 * 6), 1e-12);
  // Sideways gravity measures heights along x: H = 4.
  EXPECT_NEAR(free_fall_speed(b.x.data(), b.x.size() / 3, {2, 0, 0}, 0), std::sqrt(2 * 2.0 * 4), 1e-12);
  std::vector<double> v(b.x.size(), 0);
  v[3 * 5 + 0] = 3;
  v[3 * 5 + 1] = 4;  // vertex 5 at 5 m/s
  v[3 * 2 + 2] = -4.9;
  VerifyOptions opt;
  opt.free_fall_speed = vff;
  const VerifyFrame f = verify_frame(b.mesh, b.x.data(), v.data(), opt);
  EXPECT_DOUBLE_EQ(f.max_speed, 5);
  EXPECT_EQ(f.fastest, 5);
  EXPECT_DOUBLE_EQ(f.speed_ratio, 5 / vff);
  v[4] = std::nan("");
  EXPECT_EQ(verify_frame(b.mesh, b.x.data(), v.data(), opt).nonfinite, 1);
}

// A scene: H from its initial positions, v0 from initial velocities and motions.
TEST(Verify, FreeFallSpeedOfAScene) {
  const SceneBodies s(R"(
  - {material: m, primitive: {type: box, size: [1, 1, 0.2], cells: [1, 1, 1]}, kinematic: true, motion: {velocity: [0.5, 0, 0]}}
  - {material: m, primitive: {type: box, size: [0.2, 0.2, 0.2], cells: [1, 1, 1]}, transform: {translate: [0, 0, 1.9]}, velocity: [0, 0, -3]}
)");
  EXPECT_NEAR(free_fall_speed(s.scene), std::sqrt(9.0 + 2 * 9.81 * 2.1), 1e-12);
}

// Bad connectivity: an InputError naming the source and the row, never a crash.
TEST(Verify, BadIdsAreInputErrors) {
  TetBodies b;
  b.add(kO, kX, kY, kZ);
  b.mesh.tets[2] = 17;
  try {
    b.prepare();
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("test: tet 0: vertex 17 is not in [0, 4)"), std::string::npos) << e.what();
  }
  TetBodies c;
  c.add(kO, kX, kY, kZ);
  c.mesh.tet_object.push_back(0);
  EXPECT_THROW(c.prepare(), InputError);
}

namespace {

// Random scenes as in the collision tests: tori, spheres and boxes overlapping in a
// small region, random orientations, every vertex jittered (some tets inverted).
SceneBodies random_bodies(std::uint64_t seed, int n, double jitter) {
  std::mt19937_64 g(seed);
  const std::string yaml = test::random_objects_yaml(g, n);
  SceneBodies s(yaml);
  std::uniform_real_distribution<double> u(-jitter, jitter);
  for (double& c : s.x) c += u(g);
  return s;
}

struct Reference {
  std::int64_t surface = 0, interior = 0, crossings = 0;
  double surface_depth = 0, interior_depth = 0;
};

// Every vertex against every tet of every other body, the depth against every triangle
// of that body, and every surface edge against every triangle of every other body: the
// same predicates (tested above), none of the grid.
Reference brute_force(const VerifyMesh& m, const std::vector<double>& x) {
  Reference r;
  const double tol = 1e-9 * m.median_edge;
  auto X = [&](gid_t v) { return &x[3 * static_cast<std::size_t>(v)]; };
  for (std::size_t i = 0; i < m.num_vertices(); ++i) {
    const std::int32_t own = m.vertex_object[i];
    std::set<std::int32_t> bodies;
    for (std::size_t t = 0; t < m.num_tets(); ++t) {
      const gid_t* c = &m.tets[4 * t];
      if (m.tet_object[t] != own &&
          verify::in_closed_tet(X(static_cast<gid_t>(i)), X(c[0]), X(c[1]), X(c[2]), X(c[3]), 1e-12))
        bodies.insert(m.tet_object[t]);
    }
    double depth = -1;
    for (std::int32_t b : bodies) {
      double d2 = INFINITY;
      for (std::size_t t = 0; t < m.num_triangles(); ++t)
        if (m.triangle_object[t] == b) {
          const gid_t* c = &m.triangles[3 * t];
          d2 = std::min(d2, verify::point_triangle_dist2(X(static_cast<gid_t>(i)), X(c[0]), X(c[1]), X(c[2])));
        }
      if (std::sqrt(d2) > tol) depth = std::max(depth, std::sqrt(d2));
    }
    if (depth < 0) continue;
    if (m.surface_vertex[i]) {
      ++r.surface;
      r.surface_depth = std::max(r.surface_depth, depth);
    } else {
      ++r.interior;
      r.interior_depth = std::max(r.interior_depth, depth);
    }
  }
  for (std::size_t e = 0; e < m.edges.size() / 2; ++e)
    for (std::size_t t = 0; t < m.num_triangles(); ++t) {
      if (m.triangle_object[t] == m.vertex_object[static_cast<std::size_t>(m.edges[2 * e])]) continue;
      const gid_t* c = &m.triangles[3 * t];
      bool outside = false;
      r.crossings += verify::segment_crosses_triangle(X(m.edges[2 * e]), X(m.edges[2 * e + 1]), X(c[0]), X(c[1]),
                                                      X(c[2]), tol, 1e-12, outside) >= 0;
    }
  return r;
}

}  // namespace

// The grids find exactly what the brute-force loops find, depths bitwise equal.
TEST(Verify, MatchesBruteForceOnRandomScenes) {
  std::int64_t surface = 0, interior = 0, crossings = 0;
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    const SceneBodies s = random_bodies(seed, 8, seed % 2 ? 0.0 : 0.01);
    const VerifyFrame f = verify_frame(s.mesh, s.x.data(), nullptr, all_checks());
    const Reference r = brute_force(s.mesh, s.x);
    EXPECT_EQ(f.surface.count, r.surface) << "seed " << seed;
    EXPECT_EQ(f.interior.count, r.interior) << "seed " << seed;
    EXPECT_EQ(f.crossings.count + f.crossings.grazing, r.crossings) << "seed " << seed;
    EXPECT_EQ(f.surface.max_depth, r.surface_depth) << "seed " << seed;
    EXPECT_EQ(f.interior.max_depth, r.interior_depth) << "seed " << seed;
    surface += r.surface;
    interior += r.interior;
    crossings += r.crossings;
  }
  std::printf("[measured] brute force: %lld surface and %lld interior vertices inside, %lld crossings\n",
              static_cast<long long>(surface), static_cast<long long>(interior), static_cast<long long>(crossings));
  EXPECT_GT(surface, 100);
  EXPECT_GT(interior, 10);
  EXPECT_GT(crossings, 100);
}

// The deepest crossing of a frame against a dense search that shares none of the grid,
// the sampling or the golden section: for every (surface edge, other body) pair with a
// crossing, the edge's deepest point in that body from 400 evenly spaced points, each
// tested against every tet and every triangle of the body. The check finds its depth to
// kDepthAccuracy (1e-4 h) where the depth is unimodal; the dense points are short of the
// true maximum by at most half their spacing (the depth is 1-Lipschitz), h / 800 for an
// edge of h. Catches a crossing whose depth the check leaves at its coarse samples
// (up to h / 16 short) while it holds the frame's deepest crossing.
TEST(Verify, DeepestCrossingMatchesADenseSearch) {
  constexpr int kDense = 400;
  double deepest_seen = 0;
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    const SceneBodies s = random_bodies(seed, 8, seed % 2 ? 0.0 : 0.01);
    const VerifyMesh& m = s.mesh;
    VerifyOptions opt = all_checks();
    opt.self = false;
    const VerifyFrame f = verify_frame(m, s.x.data(), nullptr, opt);
    const double h = m.median_edge, tol = 1e-9 * h;
    auto X = [&](gid_t v) { return &s.x[3 * static_cast<std::size_t>(v)]; };
    double ref = 0, longest = 0;
    for (std::size_t e = 0; e < m.edges.size() / 2; ++e) {
      const double *pa = X(m.edges[2 * e]), *pb = X(m.edges[2 * e + 1]);
      const std::int32_t own = m.vertex_object[static_cast<std::size_t>(m.edges[2 * e])];
      std::set<std::int32_t> crossed;
      for (std::size_t t = 0; t < m.num_triangles(); ++t) {
        if (m.triangle_object[t] == own) continue;
        const gid_t* c = &m.triangles[3 * t];
        bool outside = false;
        if (verify::segment_crosses_triangle(pa, pb, X(c[0]), X(c[1]), X(c[2]), tol, 1e-12, outside) >= 0)
          crossed.insert(m.triangle_object[t]);
      }
      if (crossed.empty()) continue;
      longest = std::max(longest, std::sqrt(verify::dist2(pa, pb)));
      for (std::int32_t b : crossed)
        for (int k = 0; k <= kDense; ++k) {
          const double u = static_cast<double>(k) / kDense;
          const double q[3] = {pa[0] + u * (pb[0] - pa[0]), pa[1] + u * (pb[1] - pa[1]), pa[2] + u * (pb[2] - pa[2])};
          bool inside = false;
          for (std::size_t t = 0; t < m.num_tets() && !inside; ++t) {
            const gid_t* c = &m.tets[4 * t];
            inside = m.tet_object[t] == b && verify::in_closed_tet(q, X(c[0]), X(c[1]), X(c[2]), X(c[3]), 1e-12);
          }
          if (!inside) continue;
          double d2 = INFINITY;
          for (std::size_t t = 0; t < m.num_triangles(); ++t)
            if (m.triangle_object[t] == b) {
              const gid_t* c = &m.triangles[3 * t];
              d2 = std::min(d2, verify::point_triangle_dist2(q, X(c[0]), X(c[1]), X(c[2])));
            }
          if (std::sqrt(d2) > tol) ref = std::max(ref, std::sqrt(d2));
        }
    }
    // The check is a search for the maximum: never above it (beyond rounding), and short
    // of the dense points' maximum by no more than its accuracy.
    EXPECT_LE(f.crossings.max_depth, ref + 0.5 * longest / kDense + 1e-12) << "seed " << seed;
    EXPECT_GE(f.crossings.max_depth, ref - 2e-4 * h) << "seed " << seed;
    deepest_seen = std::max(deepest_seen, ref / h);
  }
  std::printf("[measured] deepest crossing of the dense search: %.4f h\n", deepest_seen);
  EXPECT_GT(deepest_seen, 0.1);  // the scenes do have deep crossings
}

// The same result with 1 and 2 threads, bitwise.
TEST(Verify, SameResultWithOneAndTwoThreads) {
  const SceneBodies s = random_bodies(7, 8, 0.005);
  const int before = omp_get_max_threads();
  omp_set_num_threads(1);
  const VerifyFrame a = verify_frame(s.mesh, s.x.data(), s.x.data(), all_checks());
  omp_set_num_threads(2);
  const VerifyFrame b = verify_frame(s.mesh, s.x.data(), s.x.data(), all_checks());
  omp_set_num_threads(before);
  EXPECT_GT(a.crossings.count, 0);
  EXPECT_EQ(std::memcmp(&a, &b, sizeof a), 0);
}

// Maxima keep the worst value and where it occurred.
// Parts of a split check (Simulator::verify) merge into the whole check whatever their
// order: counts add up, each maximum is the larger, the lower global id on a tie (for a
// crossing the lower edge as (first, second) vertex), a part with nothing found leaves
// the other's, the first inverted tet is the lowest.
TEST(Verify, MergedPartsTakeTheLowerIdOnATieInAnyOrder) {
  VerifyFrame a, b, none;
  a.surface = {3, 0.25, 0.1, 7, 1, 2};
  b.surface = {2, 0.25, 0.2, 3, 0, 1};       // as deep, lower vertex: b's
  a.interior = {1, 0.5, 0.5, 11, 1, 0};
  b.interior = {1, 0.4, 0.4, 2, 0, 1};       // shallower: a's
  a.crossings.count = 4;
  a.crossings.grazing = 1;
  a.crossings.max_depth = 0.3;
  a.crossings.edge[0] = 5;
  a.crossings.edge[1] = 9;
  a.crossings.triangle = 40;
  b.crossings.count = 1;
  b.crossings.without_inside_vertex = 1;
  b.crossings.max_depth = 0.3;
  b.crossings.edge[0] = 5;
  b.crossings.edge[1] = 8;                   // as deep, lower edge: b's
  b.crossings.triangle = 12;
  a.inverted = 2;
  a.first_inverted = 30;
  b.inverted = 1;
  b.first_inverted = 17;
  a.max_speed = b.max_speed = 2.0;
  a.fastest = 4;
  b.fastest = 6;                             // as fast, higher id: a's
  a.nonfinite = 1;
  a.deep_by_record[kCapped] = 2;
  b.deep_by_record[kCapped] = 1;
  for (const bool a_first : {true, false}) {
    SCOPED_TRACE(a_first ? "a then b" : "b then a");
    VerifyFrame f = none;
    merge_verify_part(f, a_first ? a : b);
    merge_verify_part(f, none);
    merge_verify_part(f, a_first ? b : a);
    EXPECT_EQ(f.surface.count, 5);
    EXPECT_EQ(f.surface.vertex, 3);
    EXPECT_EQ(f.surface.object, 0);
    EXPECT_EQ(f.interior.count, 2);
    EXPECT_EQ(f.interior.vertex, 11);
    EXPECT_EQ(f.self.vertex, -1);
    EXPECT_EQ(f.crossings.count, 5);
    EXPECT_EQ(f.crossings.grazing, 1);
    EXPECT_EQ(f.crossings.without_inside_vertex, 1);
    EXPECT_EQ(f.crossings.edge[1], 8);
    EXPECT_EQ(f.crossings.triangle, 12);
    EXPECT_EQ(f.self_crossings.triangle, -1);
    EXPECT_EQ(f.inverted, 3);
    EXPECT_EQ(f.first_inverted, 17);
    EXPECT_EQ(f.fastest, 4);
    EXPECT_EQ(f.max_speed, 2.0);
    EXPECT_EQ(f.nonfinite, 1);
    EXPECT_EQ(f.deep_by_record[kCapped], 3);
  }
}

TEST(Verify, MaximaKeepTheWorstCheck) {
  VerifyFrame a, b;
  a.median_edge = b.median_edge = 0.1;
  a.step = 10;
  a.surface.max_depth = 0.002;
  a.crossings.count = 7;
  b.step = 20;
  b.time = 0.5;
  b.surface.max_depth = 0.001;
  b.speed_ratio = 1.5;
  a.max_speed = 1.0;
  a.fastest = 42;
  b.max_speed = 3.0;
  b.fastest = 77;
  VerifyFrame c = a;  // a later, slower check must not replace the fastest vertex
  c.step = 30;
  c.max_speed = 2.0;
  c.fastest = 5;
  VerifyMaxima m;
  m.add(a);
  m.add(b);
  EXPECT_EQ(m.fastest_vertex, 77);
  EXPECT_EQ(m.max_speed.step, 20);
  m.add(c);
  EXPECT_EQ(m.fastest_vertex, 77);
  EXPECT_NE(to_json(m).find("\"fastest_vertex\": 77"), std::string::npos) << to_json(m);
  EXPECT_EQ(m.checks, 3);
  EXPECT_NEAR(m.surface_depth.value, 0.02, 1e-15);
  EXPECT_EQ(m.surface_depth.step, 10);
  EXPECT_EQ(m.crossings.value, 7);
  EXPECT_EQ(m.speed_ratio.step, 20);
  EXPECT_EQ(m.deepest.step, 10);
  EXPECT_NE(to_json(m).find("\"surface_depth_edges\": {\"value\": 0.02, \"step\": 10"), std::string::npos) << to_json(m);
}

// The distribution over checks of the deepest surface vertex: counts over a limit and
// nearest-rank quantiles, against the depths given (in median edges).
TEST(VerifyMaxima, DistributionOfTheDeepestVertexPerCheck) {
  VerifyMaxima m;
  const double depths[] = {0.001, 0.03, 0.004, 0.012, 0.006, 0.0};
  for (double d : depths) {
    VerifyFrame f;
    f.median_edge = 0.01;
    f.surface.max_depth = d * f.median_edge;
    m.add(f);
  }
  EXPECT_EQ(m.checks_deeper_than(0.005), 3);
  EXPECT_EQ(m.checks_deeper_than(0.01), 2);
  EXPECT_EQ(m.checks_deeper_than(0.02), 1);
  // sorted: 0, 0.001, 0.004, 0.006, 0.012, 0.03; nearest rank: ceil(q n)-th
  EXPECT_NEAR(m.surface_depth_quantile(0.5), 0.004, 1e-15);
  EXPECT_NEAR(m.surface_depth_quantile(0.9), 0.03, 1e-15);
  EXPECT_NEAR(m.surface_depth_quantile(0.0), 0.0, 1e-15);
  EXPECT_NE(to_json(m).find("\"over_0.005\": 3, \"over_0.01\": 2, \"over_0.02\": 1"), std::string::npos) << to_json(m);
}

// The in-run check's count of surface vertices left inside by what the response did
// about them (VerifyOptions::record): only the vertices deeper than record_limit median
// edges, by their status; none without the per-vertex status.
TEST(Verify, VerticesLeftInsideAreCountedByTheirRecordStatus) {
  const TetBodies b = point_in_unit_tet({0.1, 0.2, 0.15});  // vertex 4, 0.1 deep
  std::vector<std::int8_t> status(8, kNoRecord);
  status[4] = kUnderClosed;
  status[5] = kClosed;  // not inside: not counted
  VerifyOptions opt = all_checks();
  opt.record = status.data();
  opt.record_limit = 0.099 / b.mesh.median_edge;
  VerifyFrame f = verify_frame(b.mesh, b.x.data(), nullptr, opt);
  EXPECT_EQ(f.deep_by_record[kUnderClosed], 1);
  EXPECT_EQ(f.deep_by_record[kNoRecord] + f.deep_by_record[kCapped] + f.deep_by_record[kClosed], 0);
  opt.record_limit = 0.101 / b.mesh.median_edge;  // shallower than the limit
  f = verify_frame(b.mesh, b.x.data(), nullptr, opt);
  EXPECT_EQ(f.deep_by_record[kUnderClosed], 0);
  status[4] = kNoRecord;
  opt.record_limit = 0;
  f = verify_frame(b.mesh, b.x.data(), nullptr, opt);
  EXPECT_EQ(f.deep_by_record[kNoRecord], 1);
  VerifyMaxima m;
  m.add(f);
  m.add(f);
  EXPECT_EQ(m.deep_by_record[kNoRecord], 2);
  EXPECT_NE(to_json(m).find("\"deep_vertices_by_record\": {\"no_record\": 2, \"capped\": 0"), std::string::npos);
  opt.record = nullptr;
  f = verify_frame(b.mesh, b.x.data(), nullptr, opt);
  EXPECT_EQ(f.deep_by_record[kNoRecord], 0);
}

}  // namespace softcontact
