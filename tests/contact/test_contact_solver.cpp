// The contact response on hand-made collision records: eqs (5), (6), (15), (16) of the
// paper against values computed independently here, momentum conservation, kinematic
// obstacles, mass ratios, friction and thread independence.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <random>

#include "softcontact/contact.hpp"

using namespace softcontact;

namespace {

// A World of n loose vertices (no tets): what the contact response needs.
World toy_world(const std::vector<double>& mass, const std::vector<bool>& fixed, int objects = 2) {
  World w;
  const std::size_t n = mass.size();
  w.n_owned = n;
  w.layout.resize(objects);
  w.vertex_offset.assign(objects, 0);  // every object starts at gid 0 = local 0 here
  for (std::size_t i = 0; i < n; ++i) {
    w.vertex_gid.push_back(static_cast<softcontact::gid_t>(i));
    w.vertex_object.push_back(0);
    w.mass.push_back(mass[i]);
    w.inv_mass.push_back(fixed[i] ? 0.0 : 1.0 / mass[i]);
  }
  w.x.assign(3 * n, 0.0);
  w.x_prev.assign(3 * n, 0.0);
  w.v.assign(3 * n, 0.0);
  return w;
}

Scene two_materials(double mu_s = 0, double mu_k = 0) {
  Scene s;
  s.materials.resize(2);
  s.friction.assign(2, std::vector<Friction>(2, Friction{mu_s, mu_k}));
  s.objects.resize(2);
  s.objects[0].material = 0;
  s.objects[1].material = 1;
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

}  // namespace

// One collision against a free triangle: every quantity against the formulas.
TEST(ContactSolver, SingleCollisionMatchesEquations5to16AndSumsToZero) {
  const std::vector<double> m = {2.0, 1.0, 3.0, 0.5};
  World w = toy_world(m, {false, false, false, false});
  const World w0 = w;
  const std::array<double, 3> om = {0.2, 0.3, 0.5}, d = {0.001, -0.002, 0.01};
  ContactSolver solver(two_materials(), w);
  ContactStats st;
  solver.respond(w, {make(0, {1, 2, 3}, om, d)}, dt, st);

  // s_j = omega_j (one collision), c_j = 1 / (1 + omega_j), c_i = 1.
  double MT = 0;
  for (int k = 0; k < 3; ++k) MT += om[k] / (1 + om[k]) * m[k + 1];
  const double alpha = MT / (m[0] + MT);
  const auto& F = solver.force();
  for (int dd = 0; dd < 3; ++dd) {
    EXPECT_NEAR(F[dd], m[0] * alpha * d[dd] / (dt * dt), 1e-9);
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(F[3 * (k + 1) + dd], -om[k] / (1 + om[k]) * m[k + 1] * (1 - alpha) * d[dd] / (dt * dt), 1e-9);
    // The point moves alpha d (c_i = 1).
    EXPECT_NEAR(w.x[dd], alpha * d[dd], 1e-15);
  }
  EXPECT_LT(st.force_balance, 1e-12);
  const auto dp = momentum_change(w0, w);
  for (int dd = 0; dd < 3; ++dd) EXPECT_LT(std::abs(dp[dd]), 1e-10 * m[0] * alpha * std::abs(d[2]) / dt);
}

// A fixed obstacle: the point moves exactly d, the triangle stays, the obstacle gets the
// reaction (recorded) in proportion to c_j omega_j.
TEST(ContactSolver, KinematicTriangleTakesTheReactionAndThePointMovesTheWholeDepth) {
  World w = toy_world({1.5, 1, 1, 1}, {false, true, true, true});
  const std::array<double, 3> d = {0, 0, 0.004};
  ContactSolver solver(two_materials(), w);
  ContactStats st;
  solver.respond(w, {make(0, {1, 2, 3}, {0.25, 0.25, 0.5}, d)}, dt, st);
  EXPECT_DOUBLE_EQ(w.x[2], 0.004);
  for (int v = 1; v < 4; ++v)
    for (int dd = 0; dd < 3; ++dd) EXPECT_EQ(w.x[3 * v + dd], 0.0);
  const auto& F = solver.force();
  EXPECT_NEAR(F[2], 1.5 * 0.004 / (dt * dt), 1e-9);  // weight-free: m d / dt^2
  EXPECT_NEAR(F[3 * 1 + 2] + F[3 * 2 + 2] + F[3 * 3 + 2], -F[2], 1e-9);
  // c_j omega_j = 0.25/1.25, 0.25/1.25, 0.5/1.5: shares 0.3, 0.3, 0.4 of the reaction
  EXPECT_NEAR(F[3 * 3 + 2] / F[3 * 1 + 2], (0.5 / 1.5) / (0.25 / 1.25), 1e-12);
  EXPECT_LT(st.force_balance, 1e-15);
}

TEST(ContactSolver, KinematicPointMovesTheTriangle) {
  World w = toy_world({1, 2, 2, 2}, {true, false, false, false});
  const std::array<double, 3> d = {0.003, 0, 0};
  ContactSolver solver(two_materials(), w);
  ContactStats st;
  solver.respond(w, {make(0, {1, 2, 3}, {1.0, 0.0, 0.0}, d)}, dt, st);
  EXPECT_EQ(w.x[0], 0.0);
  // Vertex 1 (omega 1, s = 1, c = 1/2) moves -c d = -d/2; the others do not move.
  EXPECT_NEAR(w.x[3], -0.0015, 1e-15);
  EXPECT_EQ(w.x[6], 0.0);
  EXPECT_LT(st.force_balance, 1e-15);
}

// Two matching surfaces, each vertex inside the other's triangle at depth h (the
// symmetric configuration of two equal cubes pressed together): alpha = 1/2 and
// each side moves h/2, so they meet in the middle plane.
TEST(ContactSolver, EqualBodiesMeetInTheMiddle) {
  World w = toy_world({1, 1, 1, 1, 1, 1}, {false, false, false, false, false, false});
  const double h = 0.002;
  // A: vertices 0..2 at z = +h/2 (inside B, whose surface is at z = -h/2 ... mirrored)
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
  ContactSolver solver(two_materials(), w);
  ContactStats st;
  solver.respond(w, col, dt, st);
  for (int v = 0; v < 6; ++v) EXPECT_NEAR(w.x[3 * v + 2], 0.0, 1e-17) << v;
  EXPECT_LT(st.force_balance, 1e-15);
}

// Mass ratios 1, 10, 1000: momentum conserved to 1e-10 relative; the lighter body takes
// the larger share of the separation: alpha = M_T / (c_i m_i + M_T) (eq. 5; with c = 1/2
// on both sides this is eq. (9)'s m_T / (m_i + m_T)).
TEST(ContactSolver, MassRatiosConserveMomentumAndTheLighterBodyMovesMore) {
  for (double ratio : {1.0, 10.0, 1000.0}) {
    // point 0 (mass 1) against a triangle of three vertices of mass `ratio`
    World w = toy_world({1, ratio, ratio, ratio}, {false, false, false, false});
    const World w0 = w;
    const std::array<double, 3> d = {0, 0, 0.001}, om = {1.0 / 3, 1.0 / 3, 1.0 / 3};
    ContactSolver solver(two_materials(), w);
    ContactStats st;
    solver.respond(w, {make(0, {1, 2, 3}, om, d)}, dt, st);
    const double MT = 3 * (1.0 / 3) / (1 + 1.0 / 3) * ratio;
    const double alpha = MT / (1 + MT);
    EXPECT_NEAR(w.x[2], alpha * 0.001, 1e-15);
    const double tri_move = w.x[3 * 1 + 2];  // each triangle vertex moves the same
    EXPECT_NEAR(tri_move, -(1.0 / 3) / (1 + 1.0 / 3) * (1 - alpha) * 0.001, 1e-15);
    if (ratio > 1) EXPECT_GT(w.x[2], std::abs(tri_move));
    const auto dp = momentum_change(w0, w);
    const double scale = 1.0 * alpha * 0.001 / dt;  // |momentum given to the point|
    for (int dd = 0; dd < 3; ++dd) EXPECT_LE(std::abs(dp[dd]), 1e-10 * scale) << ratio;
  }
}

// Coulomb friction against a fixed triangle: a slow tangential motion is stopped
// exactly (static), a fast one is slowed by mu_k f_n dt / m (kinetic).
TEST(ContactSolver, FrictionSticksBelowTheConeAndSlidesAbove) {
  const double m = 2.0, depth = 1e-5;  // normal force m depth / dt^2 = 20 N
  const double fn = m * depth / (dt * dt);
  for (double speed : {0.004, 0.5}) {
    World w = toy_world({m, 1, 1, 1}, {false, true, true, true});
    // x~ - x^t: tangential speed * dt along x, and the penetration along -z.
    w.x[0] = speed * dt;
    w.x[2] = -depth;
    ContactSolver solver(two_materials(0.6, 0.4), w);
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
TEST(ContactSolver, StictionPullsLeftoverSlipBackToTheAnchor) {
  const double m = 2.0, depth = 1e-5;
  World w = toy_world({m, 1, 1, 1}, {false, true, true, true});
  const double tri[9] = {-1, -1, 0, 1, -1, 0, 0, 1, 0};
  for (int k = 0; k < 9; ++k) w.x[3 + k] = w.x_prev[3 + k] = tri[k];
  ContactSolver solver(two_materials(0.6, 0.4), w);
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
  for (int k = 0; k <= ContactSolver::kAnchorGrace; ++k) step(slid_to, false);
  step(slid_to + 4e-6, true);  // anchor forgotten: the offset stays
  EXPECT_NEAR(w.x[0], slid_to + 4e-6, 1e-16);
  EXPECT_LT(st.force_balance, 1e-15);
}

// Random contact sets: 1 and 2 threads give bitwise the same positions and forces, and
// the forces always sum to zero.
TEST(ContactSolver, ThreadCountDoesNotChangeResults) {
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
    ContactSolver solver(two_materials(0.5, 0.3), w);
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
