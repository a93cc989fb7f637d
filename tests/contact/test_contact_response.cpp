// The contact response on hand-made collision records: the closed-form force pairs
// (docs/contact.md) against values computed independently here, the gap measured after
// the step, shared vertices, momentum conservation, kinematic obstacles, mass ratios,
// overlaps, friction and thread independence.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <random>

#include "loose_world.hpp"
#include "softcontact/contact.hpp"

using namespace softcontact;

namespace {

World toy_world(const std::vector<double>& mass, const std::vector<bool>& fixed, int objects = 2) {
  return test::loose_world(mass, fixed, objects);
}

Scene two_materials(double mu_s = 0, double mu_k = 0) {
  Scene s;
  s.materials.resize(2);
  s.friction.assign(2, std::vector<Friction>(2, Friction{mu_s, mu_k}));
  s.objects.resize(2);
  s.objects[0].material = 0;
  s.objects[1].material = 1;
  s.sim.separation_speed = 1e3;  // the equations alone; OldOverlapSeparates... tests the bound
  return s;
}

Collision make(index_t i, std::array<index_t, 3> t, std::array<double, 3> w, std::array<double, 3> d) {
  Collision c;
  c.point = i;
  c.triangle = t;
  c.weight = w;
  c.depth = d;
  c.point_gid = i;
  c.triangle_gid = 0;
  c.object = 0;
  c.other_object = 1;
  return c;
}

std::array<double, 3> momentum_change(const World& before, const World& after) {
  std::array<double, 3> p{0, 0, 0};
  for (std::size_t i = 0; i < after.n_owned; ++i)
    if (after.inv_mass[i] != 0)
      for (int d = 0; d < 3; ++d) p[d] += after.mass[i] * (after.v[3 * i + d] - before.v[3 * i + d]);
  return p;
}

constexpr double dt = 1e-3;

// The point i came in by d within the step (x^t = x~ + d): the whole contact is dynamic,
// and the force is the momentum it transfers over dt.
void arrived(World& w, index_t i, const std::array<double, 3>& d) {
  for (int k = 0; k < 3; ++k) w.x_prev[3 * i + k] = w.x[3 * i + k] + d[k];
}

using test::closed_along;  // the gap closed, as a fraction of |d| (loose_world.hpp)

}  // namespace

// One collision against a free triangle: the force pair of docs/contact.md, lambda =
// 1 / (dt^2 (1/m_i + sum_j w_j^2 / m_j)), f_i = lambda d, f_j = -w_j lambda d; the gap
// closes exactly and the forces sum to zero.
TEST(ContactResponse, SingleCollisionClosesExactlyAndSumsToZero) {
  const std::vector<double> m = {2.0, 1.0, 3.0, 0.5};
  World w = toy_world(m, {false, false, false, false});
  const std::array<double, 3> om = {0.2, 0.3, 0.5}, d = {0.001, -0.002, 0.01};
  arrived(w, 0, d);
  const World w0 = w;
  const Collision c = make(0, {1, 2, 3}, om, d);
  ContactResponse solver(two_materials(), w);
  ContactStats st;
  solver.respond(w, {c}, dt, st);
  double K = 1 / m[0];
  for (int k = 0; k < 3; ++k) K += om[k] * om[k] / m[k + 1];
  const auto& F = solver.force();
  for (int dd = 0; dd < 3; ++dd) {
    EXPECT_NEAR(F[dd], d[dd] / (dt * dt * K), 1e-9);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(F[3 * (k + 1) + dd], -om[k] * d[dd] / (dt * dt * K), 1e-9);
    EXPECT_NEAR(w.x[dd], d[dd] / (m[0] * K), 1e-15);
  }
  EXPECT_NEAR(closed_along(w0, w, c), 1.0, 1e-12);
  EXPECT_LT(st.force_balance, 1e-12);
  const auto dp = momentum_change(w0, w);
  for (int dd = 0; dd < 3; ++dd) EXPECT_LT(std::abs(dp[dd]), 1e-10 * std::abs(F[2]) * dt);
}

// Every isolated case closes within the step: heavy or light point, either side
// fixed, weights at a vertex, an edge or inside the triangle. The paper's eqs (5)-(16)
// close 57 % (equal masses, weights 1/3), 25 % (fixed point into a soft face) and about
// 30 % (a point ten times heavier): method.md, "Where eqs (5)-(16) fall short".
TEST(ContactResponse, EveryIsolatedContactClosesInTheStep) {
  const std::array<double, 3> d = {0.0002, -0.0001, 0.0005};
  for (double mi : {0.1, 1.0, 10.0, 1000.0})
    for (int fixed_side : {0, 1, 2})  // none, the point, the triangle
      for (std::array<double, 3> om : {std::array<double, 3>{1.0 / 3, 1.0 / 3, 1.0 / 3}, {1, 0, 0}, {0.5, 0.5, 0},
                                       {0.1, 0.2, 0.7}}) {
        World w = toy_world({mi, 1, 2, 0.5}, {fixed_side == 1, fixed_side == 2, fixed_side == 2, fixed_side == 2});
        const World w0 = w;
        const Collision c = make(0, {1, 2, 3}, om, d);
        ContactResponse solver(two_materials(), w);
        ContactStats st;
        solver.respond(w, {c}, dt, st);
        EXPECT_NEAR(closed_along(w0, w, c), 1.0, 1e-12) << mi << " " << fixed_side << " " << om[0];
        EXPECT_LT(st.force_balance, 1e-12);
      }
}

TEST(ContactResponse, KinematicTriangleTakesTheReactionAndThePointMovesTheWholeDepth) {
  World w = toy_world({1.5, 1, 1, 1}, {false, true, true, true});
  const std::array<double, 3> d = {0, 0, 0.004};
  arrived(w, 0, d);
  ContactResponse solver(two_materials(), w);
  ContactStats st;
  solver.respond(w, {make(0, {1, 2, 3}, {0.25, 0.25, 0.5}, d)}, dt, st);
  EXPECT_DOUBLE_EQ(w.x[2], 0.004);
  for (int v = 1; v < 4; ++v)
    for (int dd = 0; dd < 3; ++dd) EXPECT_EQ(w.x[3 * v + dd], 0.0);
  const auto& F = solver.force();
  EXPECT_NEAR(F[2], 1.5 * 0.004 / (dt * dt), 1e-9);  // m d / dt^2
  // the reaction by the weights: 0.25, 0.25, 0.5
  EXPECT_NEAR(F[3 * 3 + 2], -0.5 * F[2], 1e-9);
  EXPECT_NEAR(F[3 * 1 + 2], -0.25 * F[2], 1e-9);
  EXPECT_LT(st.force_balance, 1e-15);
}

TEST(ContactResponse, KinematicPointMovesTheTriangle) {
  World w = toy_world({1, 2, 2, 2}, {true, false, false, false});
  const std::array<double, 3> d = {0.003, 0, 0};
  ContactResponse solver(two_materials(), w);
  ContactStats st;
  solver.respond(w, {make(0, {1, 2, 3}, {1.0, 0.0, 0.0}, d)}, dt, st);
  EXPECT_EQ(w.x[0], 0.0);
  // Vertex 1 (weight 1) moves the whole depth; the others do not move.
  EXPECT_NEAR(w.x[3], -0.003, 1e-15);
  EXPECT_EQ(w.x[6], 0.0);
  EXPECT_LT(st.force_balance, 1e-15);
}

// Two matching surfaces, each vertex inside the other's triangle at depth h (the
// symmetric configuration of two equal cubes pressed together): every vertex is pushed
// the same way by two collisions (as a point and as a triangle vertex), so each takes
// half, and the two sides meet in the middle plane instead of crossing.
TEST(ContactResponse, EqualBodiesMeetInTheMiddle) {
  World w = toy_world({1, 1, 1, 1, 1, 1}, {false, false, false, false, false, false});
  const double h = 0.002;
  for (int v = 0; v < 3; ++v) w.x[3 * v + 2] = -h / 2;
  for (int v = 3; v < 6; ++v) w.x[3 * v + 2] = h / 2;
  std::vector<Collision> col;
  for (int v = 0; v < 3; ++v) col.push_back(make(v, {3, 4, 5}, {v == 0 ? 1.0 : 0, v == 1 ? 1.0 : 0, v == 2 ? 1.0 : 0}, {0, 0, h}));
  for (int v = 3; v < 6; ++v) {
    Collision c = make(v, {0, 1, 2}, {v == 3 ? 1.0 : 0, v == 4 ? 1.0 : 0, v == 5 ? 1.0 : 0}, {0, 0, -h});
    c.object = 1;
    c.other_object = 0;
    col.push_back(c);
  }
  ContactResponse solver(two_materials(), w);
  ContactStats st;
  solver.respond(w, col, dt, st);
  for (int v = 0; v < 6; ++v) EXPECT_NEAR(w.x[3 * v + 2], 0.0, 1e-17) << v;
  EXPECT_LT(st.force_balance, 1e-15);
}

// A flat face of three vertices (mass 1 each) pressed by three points (mass 1), each
// touching the face with weights 1/3: every face vertex is in three collisions that push
// it the same way. Moved once per collision, the face would go 3/4 h and the points 3/4 h
// (1.5 h in all); shared, every gap closes exactly (the points h/2 up, the face h/2 down).
TEST(ContactResponse, SharedFaceVertexIsNotMovedOncePerCollision) {
  World w = toy_world({1, 1, 1, 1, 1, 1}, std::vector<bool>(6, false));
  const World w0 = w;
  const double h = 0.001;
  std::vector<Collision> col;
  for (int v = 0; v < 3; ++v) col.push_back(make(v, {3, 4, 5}, {1.0 / 3, 1.0 / 3, 1.0 / 3}, {0, 0, h}));
  ContactResponse solver(two_materials(), w);
  ContactStats st;
  solver.respond(w, col, dt, st);
  for (const Collision& c : col) EXPECT_NEAR(closed_along(w0, w, c), 1.0, 1e-12);
  for (int v = 0; v < 3; ++v) EXPECT_NEAR(w.x[3 * v + 2], h / 2, 1e-15);
  for (int v = 3; v < 6; ++v) EXPECT_NEAR(w.x[3 * v + 2], -h / 2, 1e-15);
  EXPECT_LT(st.force_balance, 1e-15);
}

// A point in a corner: against a fixed floor (d along z) and a fixed wall (d along x)
// it must move both depths (orthogonal pushes are not shared); against two fixed floor
// tiles side by side (both d along z) it must move the depth once, not twice.
TEST(ContactResponse, PointInTwoCollisionsMovesEachDepthOnce) {
  Scene scene = two_materials();
  scene.objects.resize(3);
  scene.objects[2].material = 1;
  for (bool corner : {true, false}) {
    World w = toy_world({1, 1, 1, 1, 1, 1, 1}, {false, true, true, true, true, true, true}, 3);
    const World w0 = w;
    Collision floor = make(0, {1, 2, 3}, {1.0 / 3, 1.0 / 3, 1.0 / 3}, {0, 0, 0.0004});
    Collision other = make(0, {4, 5, 6}, {1.0 / 3, 1.0 / 3, 1.0 / 3}, corner ? std::array<double, 3>{0.0003, 0, 0}
                                                                                : std::array<double, 3>{0, 0, 0.0004});
    other.other_object = 2;
    other.triangle_gid = 1;
    ContactResponse solver(scene, w);
    ContactStats st;
    solver.respond(w, {floor, other}, dt, st);
    EXPECT_NEAR(w.x[2], 0.0004, 1e-15) << corner;
    EXPECT_NEAR(w.x[0], corner ? 0.0003 : 0.0, 1e-15) << corner;
    EXPECT_NEAR(closed_along(w0, w, floor), 1.0, 1e-12);
  }
}

// An overlap that the step's motion does not explain (x~ = x^t, 5 mm deep: bodies that
// start overlapping) is pushed apart by a position-only correction of at most the
// separation speed times dt per step (set to 1 m/s here; 5 m/s by default): x moves 1 mm, x^t with it, and no
// velocity is added (not 5 m/s in one step). A fresh contact of the same depth, reached
// within the step, is closed in full and its approach velocity is stopped.
TEST(ContactResponse, OldOverlapSeparatesAtTheSeparationSpeedWithoutVelocity) {
  Scene scene = two_materials();
  scene.sim.separation_speed = 1.0;
  for (bool fresh : {false, true}) {
    World w = toy_world({1, 1, 1, 1}, {false, true, true, true});
    if (fresh) {
      w.x_prev[2] = 0.005;  // came down 5 mm within the step
      w.v[2] = -5.0;
    }
    const double xprev0 = w.x_prev[2];
    ContactResponse solver(scene, w);
    ContactStats st;
    solver.respond(w, {make(0, {1, 2, 3}, {1.0 / 3, 1.0 / 3, 1.0 / 3}, {0, 0, 0.005})}, dt, st);
    EXPECT_NEAR(w.x[2], fresh ? 0.005 : 1.0 * dt, 1e-15) << fresh;
    EXPECT_NEAR(w.v[2], 0.0, 1e-12) << fresh;  // stopped, or never moving
    EXPECT_NEAR(w.x[2] - w.x_prev[2], fresh ? 0.005 - xprev0 : 0.0, 1e-15) << fresh;  // Verlet's velocity
    EXPECT_EQ(st.separating, fresh ? 0 : 1);
    EXPECT_NEAR(solver.force()[2], fresh ? 5.0 / dt : 0.0, 1e-9) << fresh;  // force = momentum / dt
  }
}

// Mass ratios 1, 10, 1000: momentum conserved to 1e-10 relative; the lighter body takes
// the larger share of the separation (1/m_i over 1/m_i + sum_j w_j^2 / m_j).
TEST(ContactResponse, MassRatiosConserveMomentumAndTheLighterBodyMovesMore) {
  for (double ratio : {1.0, 10.0, 1000.0}) {
    // point 0 (mass 1) against a triangle of three vertices of mass `ratio`
    World w = toy_world({1, ratio, ratio, ratio}, {false, false, false, false});
    const World w0 = w;
    const std::array<double, 3> d = {0, 0, 0.001}, om = {1.0 / 3, 1.0 / 3, 1.0 / 3};
    ContactResponse solver(two_materials(), w);
    ContactStats st;
    solver.respond(w, {make(0, {1, 2, 3}, om, d)}, dt, st);
    const double K = 1 + 3 * (1.0 / 9) / ratio;
    EXPECT_NEAR(w.x[2], 0.001 / K, 1e-15);
    const double tri_move = w.x[3 * 1 + 2];  // each triangle vertex moves the same
    EXPECT_NEAR(tri_move, -(1.0 / 3) / ratio * 0.001 / K, 1e-15);
    EXPECT_NEAR(w.x[2] - tri_move, 0.001, 1e-15);  // closed
    if (ratio > 1) EXPECT_GT(w.x[2], std::abs(tri_move));
    const auto dp = momentum_change(w0, w);
    const double scale = 1.0 * w.x[2] / dt;  // |momentum given to the point|
    for (int dd = 0; dd < 3; ++dd) EXPECT_LE(std::abs(dp[dd]), 1e-10 * scale) << ratio;
  }
}

// Coulomb friction against a fixed triangle: a slow tangential motion is stopped
// exactly (static), a fast one is slowed by mu_k f_n dt / m (kinetic).
TEST(ContactResponse, FrictionSticksBelowTheConeAndSlidesAbove) {
  const double m = 2.0, depth = 1e-5;  // normal force m depth / dt^2 = 20 N
  const double fn = m * depth / (dt * dt);
  for (double speed : {0.004, 0.5}) {
    World w = toy_world({m, 1, 1, 1}, {false, true, true, true});
    // x~ - x^t: tangential speed * dt along x, and the penetration along -z.
    w.x[0] = speed * dt;
    w.x[2] = -depth;
    ContactResponse solver(two_materials(0.6, 0.4), w);
    ContactStats st;
    solver.respond(w, {make(0, {1, 2, 3}, {0.2, 0.3, 0.5}, {0, 0, depth})}, dt, st);
    EXPECT_NEAR(w.x[2], 0.0, 1e-20);  // normal correction onto the surface
    const double stop = m * speed / dt;  // force that stops it within the step
    if (stop <= 0.6 * fn) {
      EXPECT_EQ(st.sticking, 1);
      EXPECT_NEAR(w.x[0], 0.0, 1e-18);  // no creep
    } else {
      EXPECT_EQ(st.sliding, 1);
      EXPECT_NEAR(w.x[0], speed * dt - 0.4 * fn * dt * dt / m, 1e-15);
    }
    EXPECT_LT(st.force_balance, 1e-15);
  }
}

// Anchored stiction (contact.hpp): a point that stuck at the origin of a fixed triangle
// and starts a later step 4 um off it (slip left by earlier steps, no motion within the
// step) is pulled back exactly onto its anchor while the offset is inside the cone
// (4 um <= mu_s |d| = 6 um); a larger offset (10 um) slides back by mu_k |d| = 4 um and
// re-anchors where it ends; after more than kAnchorGrace steps without contact the
// anchor is forgotten and an offset stays. Positions to 1e-16 m (1e-11 of the offsets:
// rounding of the dt^2 scalings).
TEST(ContactResponse, StictionPullsLeftoverSlipBackToTheAnchor) {
  const double m = 2.0, depth = 1e-5;
  World w = toy_world({m, 1, 1, 1}, {false, true, true, true});
  const double tri[9] = {-1, -1, 0, 1, -1, 0, 0, 1, 0};
  for (int k = 0; k < 9; ++k) w.x[3 + k] = w.x_prev[3 + k] = tri[k];
  ContactResponse solver(two_materials(0.6, 0.4), w);
  ContactStats st;
  const Collision c = make(0, {1, 2, 3}, {0.25, 0.25, 0.5}, {0, 0, depth});
  // Starts the step at (x0, 0, 0) and arrives at (x0, 0, -depth): pure penetration.
  auto step = [&](double x0, bool contact) {
    w.x_prev[0] = x0;
    w.x_prev[1] = w.x_prev[2] = 0;
    w.x[0] = x0;
    w.x[1] = 0;
    w.x[2] = contact ? -depth : 0;
    solver.respond(w, contact ? std::vector<Collision>{c} : std::vector<Collision>{}, dt, st);
  };
  step(0.0, true);  // sticks at the origin: the anchor
  EXPECT_EQ(st.sticking, 1);
  EXPECT_EQ(w.x[0], 0.0);
  step(4e-6, true);  // leftover slip inside the cone: back onto the anchor
  EXPECT_EQ(st.sticking, 1);
  EXPECT_NEAR(w.x[0], 0.0, 1e-16);
  EXPECT_NEAR(w.x[2], 0.0, 1e-16);
  step(1e-5, true);  // outside the cone: slides back by mu_k |d| only
  EXPECT_EQ(st.sliding, 1);
  EXPECT_NEAR(w.x[0], 1e-5 - 0.4 * depth, 1e-16);
  const double slid_to = w.x[0];
  step(slid_to, true);  // the new anchor is where it slid to: nothing to undo
  EXPECT_NEAR(w.x[0], slid_to, 1e-16);
  for (int k = 0; k <= ContactResponse::kAnchorGrace; ++k) step(slid_to, false);
  step(slid_to + 4e-6, true);  // anchor forgotten: the offset stays
  EXPECT_NEAR(w.x[0], slid_to + 4e-6, 1e-16);
  EXPECT_LT(st.force_balance, 1e-15);
}

// Random contact sets: 1 and 2 threads give bitwise the same positions and forces, and
// the forces always sum to zero.
TEST(ContactResponse, ThreadCountDoesNotChangeResults) {
  std::mt19937_64 g(3);
  auto u = [&] { return static_cast<double>(g() >> 11) * 0x1.0p-53; };
  const int n = 400;
  std::vector<double> m(n);
  std::vector<bool> fixed(n);
  for (int i = 0; i < n; ++i) {
    m[i] = 0.1 + u();
    fixed[i] = u() < 0.1;
  }
  World base = toy_world(m, fixed);
  for (double& x : base.x) x = 1e-3 * u();
  std::vector<Collision> col;
  for (int q = 0; q < 2000; ++q) {
    const index_t i = static_cast<index_t>(g() % n);
    std::array<index_t, 3> t{static_cast<index_t>(g() % n), static_cast<index_t>(g() % n), static_cast<index_t>(g() % n)};
    if (t[0] == i || t[1] == i || t[2] == i || t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
    double a = u(), b = u(), c = u();
    const double s = a + b + c;
    col.push_back(make(i, t, {a / s, b / s, c / s}, {1e-4 * (u() - 0.5), 1e-4 * (u() - 0.5), 1e-4 * u()}));
  }
  std::sort(col.begin(), col.end(), [](const Collision& a, const Collision& b) { return a.point < b.point; });
  std::vector<std::vector<double>> x, f;
  for (int threads : {1, 2}) {
    omp_set_num_threads(threads);
    World w = base;
    ContactResponse solver(two_materials(0.5, 0.3), w);
    ContactStats st;
    solver.respond(w, col, dt, st);
    EXPECT_LT(st.force_balance, 1e-12);
    x.push_back(w.x);
    f.push_back(solver.force());
  }
  omp_set_num_threads(2);
  EXPECT_EQ(x[0], x[1]);
  EXPECT_EQ(f[0], f[1]);
}

// Anchors are kept per (point, other body): a point sticking to a floor and a wall at
// once keeps one on each, instead of alternating between them every step.
TEST(ContactResponse, PointAgainstTwoBodiesKeepsAnAnchorOnEach) {
  Scene scene = two_materials(0.6, 0.4);
  scene.objects.resize(3);
  scene.objects[2].material = 1;
  World w = toy_world({1, 1, 1, 1, 1, 1, 1}, {false, true, true, true, true, true, true}, 3);
  w.x_prev[2] = 1e-5;  // came down 10 um into the floor
  w.x_prev[0] = -1e-5; // and 10 um into the wall
  const double tri[9] = {-1, -1, 0, 1, -1, 0, 0, 1, 0};
  for (int k = 0; k < 9; ++k) w.x[3 + k] = w.x_prev[3 + k] = w.x[12 + k] = w.x_prev[12 + k] = tri[k];
  Collision floor = make(0, {1, 2, 3}, {1.0 / 3, 1.0 / 3, 1.0 / 3}, {0, 0, 1e-5});
  Collision wall = make(0, {4, 5, 6}, {1.0 / 3, 1.0 / 3, 1.0 / 3}, {-1e-5, 0, 0});
  wall.other_object = 2;
  wall.triangle_gid = 1;
  ContactResponse solver(scene, w);
  ContactStats st;
  for (int step = 0; step < 3; ++step) {
    solver.respond(w, {floor, wall}, dt, st);
    if (step == 0) EXPECT_EQ(st.sticking, 2);  // no tangential motion: both stick
    const StictionAnchor& a = solver.anchors()[0];
    ASSERT_NE(a.find(1), nullptr);
    ASSERT_NE(a.find(2), nullptr);
    EXPECT_EQ(a.find(1)->step, solver.anchor_step());
    EXPECT_EQ(a.find(2)->step, solver.anchor_step());
  }
}
