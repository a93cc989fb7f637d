// Prescribed motion of fixed vertices (scene key `motion`): exact kinematics, and a moving
// kinematic pusher that drives a free body through contact.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "../contact/contact_scenes.hpp"
#include "softcontact/error.hpp"
#include "softcontact/integrator.hpp"
#include "softcontact/world.hpp"

using namespace softcontact;
using namespace softcontact::test;

namespace {

const char* kMaterials = R"(
materials:
  - {name: steel, model: linear, young: 1.0e7, poisson: 0.3, density: 2000}
  - {name: soft, model: corotational, young: 1.0e5, poisson: 0.3, density: 1000, damping: {mass: 2}}
)";

}  // namespace

// A kinematic box moving at 0.1 m/s from t = 0.02 s to t = 0.07 s, dt = 1 ms: before the
// start it stands still; afterwards every vertex has moved by exactly 0.1 * 0.05 = 5 mm
// (to 1e-12 m: only rounding of the per-step sums); its velocity is 0.1 m/s during the
// motion and exactly 0 after, with either explicit integrator (symplectic Euler leaves a
// kinematic vertex's velocity alone, so only the motion can set it back to 0).
class PrescribedMotionIntegrator : public ::testing::TestWithParam<const char*> {};

TEST_P(PrescribedMotionIntegrator, KinematicBoxMovesExactlyByVelocityTimesActiveTime) {
  auto r = make_run(std::string("simulation:\n  dt: 0.001\n  steps: 100\n  gravity: [0, 0, 0]\n  integrator: ") +
                    GetParam() + "\n" + kMaterials + R"(
objects:
  - name: anchor
    material: steel
    primitive: {type: box, size: [0.1, 0.1, 0.1], cells: [2, 2, 2]}
    kinematic: true
    motion: {velocity: [0.1, 0, 0], start: 0.02, stop: 0.07}
)");
  Simulator& s = *r->sim;
  const std::vector<double> x0 = s.world().x;
  for (int k = 0; k < 20; ++k) s.step();
  for (std::size_t i = 0; i < x0.size(); ++i) ASSERT_EQ(s.world().x[i], x0[i]) << "moved before start";
  for (int k = 0; k < 30; ++k) s.step();
  for (std::size_t i = 0; i < s.world().n_owned; ++i) EXPECT_NEAR(s.world().v[3 * i], 0.1, 1e-12);
  for (int k = 0; k < 50; ++k) s.step();
  const World& w = s.world();
  for (std::size_t i = 0; i < w.n_owned; ++i) {
    EXPECT_NEAR(w.x[3 * i] - x0[3 * i], 0.005, 1e-12);
    EXPECT_EQ(w.x[3 * i + 1], x0[3 * i + 1]);
    EXPECT_EQ(w.x[3 * i + 2], x0[3 * i + 2]);
    EXPECT_EQ(w.v[3 * i], 0.0);
  }
}

INSTANTIATE_TEST_SUITE_P(PrescribedMotion, PrescribedMotionIntegrator, ::testing::Values("verlet", "symplectic_euler"));

// Each rank keeps the motions of its own objects only (World::owned_motion), in
// owned_objects' order, and moves only their fixed vertices: three kinematic plates, the
// middle one moving, split over two "ranks" by hand (block_partition), each World alone.
TEST(PrescribedMotion, EachWorldKeepsAndMovesOnlyItsOwnObjectsMotions) {
  auto r = make_run(std::string("simulation:\n  dt: 0.001\n  steps: 10\n  gravity: [0, 0, 0]\n") + kMaterials + R"(
objects:
  - name: a
    material: steel
    primitive: {type: box, size: [0.1, 0.1, 0.02], cells: [2, 2, 1]}
    kinematic: true
  - name: b
    material: steel
    primitive: {type: box, size: [0.1, 0.1, 0.02], cells: [2, 2, 1]}
    transform: {translate: [0.2, 0, 0]}
    kinematic: true
    motion: {velocity: [0, 0, 0.5], start: 0, stop: 1}
  - name: c
    material: steel
    primitive: {type: box, size: [0.1, 0.1, 0.02], cells: [2, 2, 1]}
    transform: {translate: [0.4, 0, 0]}
    kinematic: true
)");
  const Scene& scene = r->scene;
  const std::vector<int> part = {0, 0, 1};
  for (int rank = 0; rank < 2; ++rank) {
    World w = build_world(scene, part, rank);
    ASSERT_EQ(w.owned_motion.size(), w.owned_objects.size());
    for (std::size_t j = 0; j < w.owned_objects.size(); ++j)
      EXPECT_EQ(w.owned_motion[j].velocity[2], w.owned_objects[j] == 1 ? 0.5 : 0.0);
    const std::vector<double> x0 = w.x;
    prescribed_motion(w, 0.0, 0.002);
    for (std::size_t i = 0; i < w.n_owned; ++i) {
      const double dz = w.vertex_object[i] == 1 ? 0.001 : 0.0;  // 0.5 m/s x 2 ms
      EXPECT_NEAR(w.x[3 * i + 2] - x0[3 * i + 2], dz, 1e-15) << "rank " << rank << " vertex " << i;
      EXPECT_NEAR(w.v[3 * i + 2], dz / 0.002, 1e-12);
    }
  }
}

// Only the vertices inside a `fixed` box follow the motion: a bar clamped at one end and
// pulled along its axis at 0.02 m/s for 0.1 s. The clamped end moves by exactly 2 mm; the
// free end, a wave travel time away, follows: after the pull and 0.4 s of damped
// vibration, the bar's centroid has moved by the same 2 mm to within 10% (rigid motion is
// all that is left once the elastic waves decay).
TEST(PrescribedMotion, FixedBoxVerticesDragTheRestOfTheBody) {
  auto r = make_run(std::string("simulation:\n  dt: auto\n  end_time: 0.5\n  gravity: [0, 0, 0]\n") + kMaterials + R"(
objects:
  - name: bar
    material: soft
    primitive: {type: box, size: [0.2, 0.05, 0.05], cells: [8, 2, 2]}
    fixed: {min: [-0.11, -1, -1], max: [-0.099, 1, 1]}
    motion: {velocity: [0.02, 0, 0], stop: 0.1}
)");
  Simulator& s = *r->sim;
  const World& w = s.world();
  const std::vector<double> x0 = w.x;
  const std::int64_t steps = total_steps(r->scene.sim);
  for (std::int64_t k = 0; k < steps; ++k) s.step();
  double moved = 0, mass = 0;
  for (std::size_t i = 0; i < w.n_owned; ++i) {
    if (w.inv_mass[i] == 0) {
      EXPECT_NEAR(w.x[3 * i] - x0[3 * i], 0.002, 1e-12) << "clamped vertex " << i;
    }
    moved += w.mass[i] * (w.x[3 * i] - x0[3 * i]);
    mass += w.mass[i];
  }
  std::printf("[measured] clamped bar: centroid moved %.4g m (clamp 0.002 m)\n", moved / mass);
  EXPECT_NEAR(moved / mass, 0.002, 0.0002);
}

// A kinematic pusher moving at V = 0.05 m/s into a free soft box (no gravity, 5 mm gap).
// References: the box never ends a step inside the pusher by more than 1% of the median
// edge; after 0.4 s it has been pushed, so it moves in +x at least at 0.9 V and, since a
// body rebounding from a wall of infinite mass moving at V leaves at most at 2 V (the
// elastic limit), at most 2 V (+2% for the box's own vibration).
TEST(PrescribedMotion, MovingPusherDrivesAFreeBoxWithoutPenetration) {
  auto r = make_run(std::string("simulation:\n  dt: auto\n  end_time: 0.4\n  gravity: [0, 0, 0]\n") + kMaterials + R"(
friction:
  default: {static: 0.0, kinetic: 0.0}
objects:
  - name: pusher
    material: steel
    primitive: {type: box, size: [0.05, 0.2, 0.2], cells: [2, 6, 6]}
    transform: {translate: [-0.08, 0, 0]}
    kinematic: true
    motion: {velocity: [0.05, 0, 0]}
  - name: box
    material: soft
    primitive: {type: box, size: [0.1, 0.1, 0.1], cells: [3, 3, 3]}
)");
  Simulator& s = *r->sim;
  const double V = 0.05;
  const std::int64_t steps = total_steps(r->scene.sim);
  double worst = 0;
  for (std::int64_t k = 0; k < steps; ++k) {
    s.step();
    const ObjectState p = object_state(s, 0), b = object_state(s, 1);
    worst = std::max(worst, (p.max[0] - b.min[0]) / s.median_edge());
  }
  const ObjectState b = object_state(s, 1);
  const double vx = b.momentum[0] / b.mass;
  std::printf("[measured] pusher: worst overlap %.3g median edges, box speed %.4g m/s (V = %.3g)\n", worst, vx, V);
  EXPECT_LE(worst, 0.01);
  EXPECT_GE(vx, 0.9 * V);
  EXPECT_LE(vx, 2.02 * V);
}

// Bad input: a motion needs fixed vertices, and stop must follow start.
TEST(PrescribedMotion, SceneRejectsMotionWithoutFixedVerticesOrWithStopBeforeStart) {
  const std::string head = std::string("simulation:\n  dt: auto\n  steps: 1\n") + kMaterials + "objects:\n";
  const std::string free_box = head + R"(  - name: b
    material: soft
    primitive: {type: box, size: [0.1, 0.1, 0.1]}
    motion: {velocity: [1, 0, 0]}
)";
  try {
    load_scene_from_string(free_box, "m.yaml");
    FAIL() << "accepted a motion without fixed vertices";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("m.yaml:12"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("has none"), std::string::npos) << e.what();
  }
  const std::string backwards = head + R"(  - name: b
    material: soft
    primitive: {type: box, size: [0.1, 0.1, 0.1]}
    kinematic: true
    motion: {velocity: [1, 0, 0], start: 0.5, stop: 0.2}
)";
  try {
    load_scene_from_string(backwards, "m.yaml");
    FAIL() << "accepted stop < start";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'motion.stop' must be later"), std::string::npos) << e.what();
  }
}
