// Walking a segment through a body's tets to its surface.
#include <gtest/gtest.h>

#include <random>

#include "collide/collision_topology.hpp"
#include "collide/point_in_tet.hpp"
#include "collide/tet_walk.hpp"
#include "collide_test_util.hpp"

using namespace softcontact;
using namespace softcontact::collide;

namespace {
index_t containing_tet(const World& w, const CollisionTopology& t, const V3& p) {
  for (std::size_t e = 0; e < w.tets.size() / 4; ++e)
    if (point_in_tet(w.x.data(), &w.tets[4 * e], t.boundary_mask[e], p) == TetSide::inside) return static_cast<index_t>(e);
  return -1;
}
}  // namespace

// From random points inside a 1 x 1 x 1 box (4^3 cells) towards random points outside:
// the exit is where the segment meets the box's surface (the first of the three slab
// crossings), on a triangle of that face, with barycentric coordinates reproducing it.
TEST(CollisionTetWalk, LeavesABoxWhereTheSegmentMeetsItsSurface) {
  const World w = test::world_from_objects("  - material: m\n    primitive: {type: box, size: [1, 1, 1], cells: [4, 4, 4]}\n");
  const CollisionTopology topo = build_collision_topology(w);
  std::mt19937_64 g(4);
  std::uniform_real_distribution<double> in(-0.45, 0.45), out(-3, 3);
  int exits = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const V3 p = {in(g), in(g), in(g)}, q = {out(g), out(g), out(g)};
    const index_t start = containing_tet(w, topo, p);
    ASSERT_GE(start, 0);
    const WalkResult r = walk_to_surface(w.x.data(), w.tets.data(), topo.face_neighbour.data(), w.triangles.data(), start,
                                         p, q, 1000);
    // Analytic exit: the smallest t at which a coordinate reaches +-0.5.
    double t_exit = 2;
    for (int d = 0; d < 3; ++d) {
      const double dd = q[d] - p[d];
      if (dd != 0) t_exit = std::min(t_exit, ((dd > 0 ? 0.5 : -0.5) - p[d]) / dd);
    }
    if (t_exit > 1) {
      EXPECT_EQ(r.status, WalkResult::ended_inside);
      continue;
    }
    ASSERT_EQ(r.status, WalkResult::exited);
    ++exits;
    EXPECT_NEAR(r.t, t_exit, 1e-12);
    const V3 s = p + r.t * (q - p);
    const index_t* tv = &w.triangles[3 * static_cast<std::size_t>(r.triangle)];
    V3 b{0, 0, 0};
    for (int c = 0; c < 3; ++c) b = b + r.bary[c] * load(w.x.data(), tv[c]);
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(b[d], s[d], 1e-12);
    EXPECT_LE(r.steps, 6 * 13);  // at most 13 cells crossed (3 x 4 + 1), 6 tets each: no cycling
  }
  EXPECT_GT(exits, 250);
}

TEST(CollisionTetWalk, EndsInsideAndStopsAtTheStepLimit) {
  const World w = test::world_from_objects("  - material: m\n    primitive: {type: box, size: [1, 1, 1], cells: [4, 4, 4]}\n");
  const CollisionTopology topo = build_collision_topology(w);
  const V3 p = {-0.4, -0.3, -0.2}, q = {0.4, 0.3, 0.2};
  const index_t start = containing_tet(w, topo, p);
  ASSERT_GE(start, 0);
  const WalkResult r = walk_to_surface(w.x.data(), w.tets.data(), topo.face_neighbour.data(), w.triangles.data(), start,
                                       p, q, 1000);
  EXPECT_EQ(r.status, WalkResult::ended_inside);
  EXPECT_GT(r.steps, 3);
  const WalkResult cut = walk_to_surface(w.x.data(), w.tets.data(), topo.face_neighbour.data(), w.triangles.data(),
                                         start, p, {3, 0.3, 0.2}, 2);
  EXPECT_EQ(cut.status, WalkResult::failed);
}
