// simulation.contact_closure: coupled (src/contact/coupled_closure.hpp, docs/contact.md
// "Coupled closure"): the cases the per-collision shares close only partly, with the gap
// of every collision measured after the step from the positions; the pulling case; and
// the solver against the 2 x 2 system solved by hand.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <omp.h>

#include "../../src/contact/coupled_closure.hpp"
#include "loose_world.hpp"
#include "softcontact/contact.hpp"
#include "softcontact/verify.hpp"

using namespace softcontact;

namespace {

Scene closure_scene(ContactClosure closure, int objects) {
  Scene s;
  s.materials.resize(1);
  s.friction.assign(1, std::vector<Friction>(1, Friction{0, 0}));
  s.objects.resize(static_cast<std::size_t>(objects));
  s.sim.separation_speed = 1e3;  // the equations alone
  s.sim.contact_closure = closure;
  return s;
}

Collision record(index_t i, std::array<index_t, 3> t, std::array<double, 3> d, softcontact::gid_t key, int other) {
  Collision c;
  c.point = i;
  c.triangle = t;
  c.weight = {1.0 / 3, 1.0 / 3, 1.0 / 3};
  c.depth = d;
  c.point_gid = i;
  c.triangle_gid = key;
  c.object = 0;
  c.other_object = other;
  return c;
}


constexpr double dt = 1e-3;
// The regularisation eps = 1e-3 leaves a gap of eps A_qq x_q: 0.1 % of an isolated
// collision's depth, 0.4 % for the squeezed point below (x = 4 times the isolated closure).
constexpr double kClosureTol = 5e-3;

// Runs both closures on the same records; returns the fractions closed.
std::vector<double> fractions(ContactClosure closure, const std::vector<double>& mass, const std::vector<bool>& fixed,
                              int objects, const std::vector<Collision>& col, ContactStats* stats = nullptr) {
  World w = test::loose_world(mass, fixed, objects);
  for (const Collision& c : col)  // every contact arrived within the step: all dynamic
    for (int d = 0; d < 3; ++d) w.x_prev[3 * c.point + d] = w.x[3 * c.point + d] + c.depth[d];
  const World w0 = w;
  ContactResponse solver(closure_scene(closure, objects), w);
  ContactStats st;
  solver.respond(w, col, dt, st);
  if (stats) *stats = st;
  std::vector<double> f;
  for (const Collision& c : col) f.push_back(test::closed_along(w0, w, c));
  return f;
}

}  // namespace

// A face of three free vertices pressed by three free points with depths h, 2h and 3h
// (all masses 1, weights 1/3): the shares split each face vertex by the summed pushes,
// which under-closes the deepest and over-closes the shallowest. The coupled closure
// closes each gap to its depth.
TEST(CoupledClosure, UnequalDepthsOnASharedFaceCloseExactly) {
  const double h = 1e-3;
  std::vector<Collision> col;
  for (int v = 0; v < 3; ++v) col.push_back(record(v, {3, 4, 5}, {0, 0, h * (v + 1)}, v, 1));
  const std::vector<double> m(6, 1.0);
  const std::vector<bool> fixed(6, false);
  const auto local = fractions(ContactClosure::local, m, fixed, 2, col);
  const auto coupled = fractions(ContactClosure::coupled, m, fixed, 2, col);
  EXPECT_LT(local[2], 0.97);  // the deepest under-closed by the shares
  EXPECT_GT(local[0], 1.03);  // the shallowest over-closed
  for (double f : coupled) EXPECT_NEAR(f, 1.0, kClosureTol);
}

// A free point inside two free bodies at once, pushed up out of the lower one and down
// out of the upper one: with shares both pushes act in full on the point and cancel, so
// each gap closes only through its triangle (about half). Coupled: both close.
TEST(CoupledClosure, PointSqueezedBetweenTwoBodiesClosesBothGaps) {
  const double h = 1e-3;
  const std::vector<Collision> col = {record(0, {1, 2, 3}, {0, 0, h}, 0, 1), record(0, {4, 5, 6}, {0, 0, -h}, 1, 2)};
  const std::vector<double> m(7, 1.0);
  const std::vector<bool> fixed(7, false);
  const auto local = fractions(ContactClosure::local, m, fixed, 3, col);
  const auto coupled = fractions(ContactClosure::coupled, m, fixed, 3, col);
  EXPECT_LT(local[0], 0.8);
  EXPECT_LT(local[1], 0.8);
  EXPECT_NEAR(coupled[0], 1.0, kClosureTol);
  EXPECT_NEAR(coupled[1], 1.0, kClosureTol);
}

// The same point squeezed between two fixed bodies: no pushing forces can close both
// gaps (A is singular and the depths contradict it), and the solve runs away like
// 1 / eps. Both collisions keep their per-collision closed form, which moves the point
// by the difference of the two depths' pushes (the local closure's result).
TEST(CoupledClosure, PointSqueezedBetweenFixedBodiesKeepsTheClosedForm) {
  const std::vector<Collision> col = {record(0, {1, 2, 3}, {0, 0, 1e-3}, 0, 1), record(0, {4, 5, 6}, {0, 0, -4e-4}, 1, 2)};
  const std::vector<double> m(7, 1.0);
  std::vector<bool> fixed(7, true);
  fixed[0] = false;
  ContactStats st;
  const auto coupled = fractions(ContactClosure::coupled, m, fixed, 3, col, &st);
  const auto local = fractions(ContactClosure::local, m, fixed, 3, col);
  EXPECT_EQ(st.closure_rows, 2);
  EXPECT_EQ(st.closure_local, 2);
  EXPECT_EQ(coupled, local);
}

// A free point against two fixed tiles side by side, 1 mm deep in one and 0.5 mm in the
// other, both along z: no pair of pushing forces closes both gaps (the point can only
// move once); solved together, the shallower one would pull. It is dropped, and the point
// moves the deeper depth, which also clears the shallower tile.
TEST(CoupledClosure, CollisionThatWouldPullGetsNoForce) {
  const std::vector<Collision> col = {record(0, {1, 2, 3}, {0, 0, 1e-3}, 0, 1), record(0, {4, 5, 6}, {0, 0, 5e-4}, 1, 2)};
  const std::vector<double> m(7, 1.0);
  std::vector<bool> fixed(7, true);
  fixed[0] = false;
  ContactStats st;
  const auto f = fractions(ContactClosure::coupled, m, fixed, 3, col, &st);
  EXPECT_EQ(st.closure_rows, 2);
  EXPECT_EQ(st.closure_dropped, 1);
  EXPECT_NEAR(f[0], 1.0, kClosureTol);
  EXPECT_GT(f[1], 1.0);  // cleared (moved 2 x its depth)
}

// The solver on two rows sharing one vertex of inverse mass 2 at 60 degrees, against the
// 2 x 2 system solved by hand: A = [[a + 2, 1], [1, c + 2]] with the rows' own vertices
// of inverse masses a and c (b = 1 everywhere), plus eps times the diagonal.
TEST(CoupledClosure, SolverMatchesTheSystemSolvedByHand) {
  const double a = 1.0, c = 3.0, eps = 1e-3, d0 = 2e-3, d1 = 1e-3;
  contact::ClosureRow r0, r1;
  r0.key_point = 0;
  r1.key_point = 1;
  r0.n[2] = 1;
  r1.n[0] = std::sqrt(3.0) / 2;
  r1.n[2] = 0.5;
  r0.depth = d0;
  r1.depth = d1;
  r0.nv = r1.nv = 2;
  r0.vertex[0] = 10;
  r0.vertex[1] = 12;
  r1.vertex[0] = 11;
  r1.vertex[1] = 12;
  r0.b[0] = r0.b[1] = r1.b[0] = r1.b[1] = 1;
  r0.inv_mass[0] = a;
  r1.inv_mass[0] = c;
  r0.inv_mass[1] = r1.inv_mass[1] = 2;
  contact::ClosureStats st;
  const std::vector<double> x = contact::solve_closure({r0, r1}, eps, st);
  const double A00 = (a + 2) * (1 + eps), A11 = (c + 2) * (1 + eps), A01 = 2 * 0.5;
  const double det = A00 * A11 - A01 * A01;
  ASSERT_EQ(x.size(), 2u);
  EXPECT_NEAR(x[0], (A11 * d0 - A01 * d1) / det, 1e-15);
  EXPECT_NEAR(x[1], (A00 * d1 - A01 * d0) / det, 1e-15);
  EXPECT_EQ(st.rows, 2);
  EXPECT_EQ(st.dropped, 0);
  EXPECT_EQ(st.passes, 1);
}

namespace {

// A chain of n collisions: row q pushes its own light vertex (b = 1, inverse mass 1)
// against heavier vertices q and q + 1 shared with its neighbours (b = -1/2 each,
// inverse mass 1/2); directions tilted from +z by a little per row. Diagonally dominant.
std::vector<contact::ClosureRow> chain(int n) {
  std::vector<contact::ClosureRow> rows(static_cast<std::size_t>(n));
  for (int q = 0; q < n; ++q) {
    contact::ClosureRow& r = rows[static_cast<std::size_t>(q)];
    r.key_point = 1000 + q;
    const double t = 0.3 * std::sin(0.7 * q);
    r.n[0] = std::sin(t);
    r.n[2] = std::cos(t);
    r.depth = 1e-3 * (1.0 + 0.5 * std::cos(1.3 * q));
    r.nv = 3;
    r.vertex[0] = 1000 + q;
    r.vertex[1] = q;
    r.vertex[2] = q + 1;
    r.b[0] = 1;
    r.b[1] = r.b[2] = -0.5;
    r.inv_mass[0] = 1;
    r.inv_mass[1] = r.inv_mass[2] = 0.5;
  }
  return rows;
}

// (A + eps diag A) x = d over the rows not in `out`, built and solved here densely.
std::vector<double> dense_reference(const std::vector<contact::ClosureRow>& rows, double eps,
                                    const std::vector<int>& out) {
  const auto n = static_cast<Eigen::Index>(rows.size());
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n);
  for (Eigen::Index p = 0; p < n; ++p)
    for (Eigen::Index q = 0; q < n; ++q) {
      const auto& rp = rows[static_cast<std::size_t>(p)];
      const auto& rq = rows[static_cast<std::size_t>(q)];
      const double nn = rp.n[0] * rq.n[0] + rp.n[1] * rq.n[1] + rp.n[2] * rq.n[2];
      for (int e = 0; e < rp.nv; ++e)
        for (int f = 0; f < rq.nv; ++f)
          if (rp.vertex[e] == rq.vertex[f]) a(p, q) += rp.b[e] * rq.b[f] * nn * rp.inv_mass[e];
    }
  Eigen::VectorXd d(n);
  for (Eigen::Index p = 0; p < n; ++p) d[p] = rows[static_cast<std::size_t>(p)].depth;
  for (Eigen::Index p = 0; p < n; ++p) a(p, p) *= 1 + eps;
  for (int o : out) {
    a.row(o).setZero();
    a.col(o).setZero();
    a(o, o) = 1;
    d[o] = 0;
  }
  const Eigen::VectorXd x = a.ldlt().solve(d);
  return std::vector<double>(x.data(), x.data() + n);
}

}  // namespace

// A group of one collision is the per-collision closed form itself: no regularisation.
TEST(CoupledClosure, IsolatedCollisionClosesExactly) {
  const std::vector<contact::ClosureRow> rows = chain(1);
  contact::ClosureStats st;
  const std::vector<double> x = contact::solve_closure(rows, 1e-3, st);
  EXPECT_NEAR(x[0], rows[0].depth / 1.25, 1e-18);  // A = 1 + 2 * (1/2)^2 * (1/2)
  EXPECT_EQ(st.passes, 0);
}

// A group larger than kDenseRows (the sparse path) against the dense system built
// independently here, and the same to the bit on 1 and 2 threads.
TEST(CoupledClosure, LargeGroupMatchesTheDenseSystemOnAnyThreadCount) {
  const int n = 3 * contact::kDenseRows;
  const std::vector<contact::ClosureRow> rows = chain(n);
  const double eps = 1e-3;
  const std::vector<double> ref = dense_reference(rows, eps, {});
  const int before = omp_get_max_threads();
  omp_set_num_threads(1);
  contact::ClosureStats st1, st2;
  const std::vector<double> x1 = contact::solve_closure(rows, eps, st1);
  omp_set_num_threads(2);
  const std::vector<double> x2 = contact::solve_closure(rows, eps, st2);
  omp_set_num_threads(before);
  ASSERT_EQ(x1.size(), static_cast<std::size_t>(n));
  EXPECT_EQ(st1.dropped, 0);
  for (int q = 0; q < n; ++q) {
    EXPECT_NEAR(x1[static_cast<std::size_t>(q)], ref[static_cast<std::size_t>(q)], 1e-12 * ref[static_cast<std::size_t>(q)] + 1e-18) << q;
    EXPECT_EQ(x1[static_cast<std::size_t>(q)], x2[static_cast<std::size_t>(q)]) << q;
  }
}

// A row that would pull in the sparse path: the group is factorised again without it
// (the same ordering), and the others equal the reduced system solved densely.
TEST(CoupledClosure, PullingRowInALargeGroupLeavesTheReducedSystem) {
  const int n = 3 * contact::kDenseRows;
  std::vector<contact::ClosureRow> rows = chain(n);
  const int k = n / 2;
  rows[static_cast<std::size_t>(k)].depth = 1e-7;  // its neighbours' pushes close it and more
  const double eps = 1e-3;
  const std::vector<double> full = dense_reference(rows, eps, {});
  ASSERT_LT(full[static_cast<std::size_t>(k)], 0);  // the case: it would pull
  const std::vector<double> ref = dense_reference(rows, eps, {k});
  contact::ClosureStats st;
  const std::vector<double> x = contact::solve_closure(rows, eps, st);
  EXPECT_EQ(st.dropped, 1);
  EXPECT_EQ(st.passes, 2);
  EXPECT_EQ(x[static_cast<std::size_t>(k)], 0);
  for (int q = 0; q < n; ++q)
    if (q != k) EXPECT_NEAR(x[static_cast<std::size_t>(q)], ref[static_cast<std::size_t>(q)], 1e-12 * std::abs(ref[static_cast<std::size_t>(q)])) << q;
}

// The causes the in-run check reports for a vertex left inside (ContactResponse::record_status,
// verify.hpp RecordStatus), each against the gap measured from the positions: an
// isolated fresh contact is closed; the squeezed point's two records under the shares
// close less than 90 % (its deeper record decides); an old overlap deeper than the
// separation speed allows is capped. A vertex that is no point keeps kNoRecord.
TEST(CoupledClosure, RecordStatusNamesWhyAGapWasLeft) {
  const double h = 1e-3;
  const std::vector<double> m(7, 1.0);
  const std::vector<bool> fixed(7, false);
  auto status_of = [&](const std::vector<Collision>& col, double separation_speed, bool fresh) {
    World w = test::loose_world(m, fixed, 3);
    if (fresh)
      for (const Collision& c : col)
        for (int d = 0; d < 3; ++d) w.x_prev[3 * c.point + d] = w.x[3 * c.point + d] + c.depth[d];
    Scene s = closure_scene(ContactClosure::local, 3);
    s.sim.separation_speed = separation_speed;
    ContactResponse solver(s, w);
    ContactStats st;
    const World w0 = w;
    solver.respond(w, col, dt, st);
    std::vector<std::int8_t> status;
    solver.record_status(col, w.n_owned, status);
    return std::make_pair(status, test::closed_along(w0, w, col[0]));
  };
  const auto [isolated, closed_isolated] = status_of({record(0, {1, 2, 3}, {0, 0, h}, 0, 1)}, 1e3, true);
  EXPECT_NEAR(closed_isolated, 1.0, 1e-12);
  EXPECT_EQ(isolated[0], kClosed);
  for (std::size_t v = 1; v < isolated.size(); ++v) EXPECT_EQ(isolated[v], kNoRecord);
  const auto [squeezed, closed_squeezed] =
      status_of({record(0, {1, 2, 3}, {0, 0, 2 * h}, 0, 1), record(0, {4, 5, 6}, {0, 0, -h}, 1, 2)}, 1e3, true);
  EXPECT_LT(closed_squeezed, 0.9);
  EXPECT_EQ(squeezed[0], kUnderClosed);
  // No approach within the step (x^t = x~) and 1 mm/s: 1 um of the 1 mm is removed.
  const auto [old, closed_old] = status_of({record(0, {1, 2, 3}, {0, 0, h}, 0, 1)}, 1e-3, false);
  EXPECT_NEAR(closed_old, 1e-3, 1e-9);
  EXPECT_EQ(old[0], kCapped);
}
