// The paper's 'archway' (Fig. 4, "Frictional contacts") in its two outcomes, run from the
// shipped scenes as they are: inputs/archway.yaml (mu_s = 0.95) stands while soft objects
// fall onto it, and inputs/archway_low_friction.yaml (mu = 0.1, nothing else changed)
// collapses. The geometry and the choice of size and density are explained in the
// scenes' header comments. Here, in the default suite, the standing arch runs the first
// 3 s of its 10 (the impacts, the ringing, and a second to measure a creep: 44 s of the
// 144 s the whole scene takes on one core); tests/scenes/long_test_archway.cpp runs the
// whole 10 s with the same criteria (label long). The measures are in archway_measure.hpp.
//
// Measured per voussoir, from its vertices (one rank: every vertex is owned):
//   - the mass-weighted centroid;
//   - the rotation from the rest orientation: the rotation factor of the polar
//     decomposition of A = sum_i m_i (x_i - c)(X_i - C)^T, the best-fitting rotation
//     in the least-squares sense (Kabsch), and its angle acos((tr R - 1) / 2).
// The rise h of the arch is taken from the meshes: the keystone's highest point above
// the springing line (the lowest point of the springers) at rest, 0.1825 m.
//
// The thresholds separate a standing arch from a mechanism, and are set from the
// physics, not from the measured values (which are printed as [measured] and recorded in
// docs/validation.md):
//   - An arch of stiff blocks that stands moves only by elastic deformation. A soft arch
//     sags under gravity applied at once and rings about its sag (crown about 7 mm down
//     at first, 5 % of h). An arch that has become a mechanism has no restoring force:
//     once a hinge opens or a joint slips, the crown keeps falling until the stones
//     hit the floor, a drop of the order of h.
//   - Standing: the keystone's centroid never drops more than 0.15 h (27 mm, half the
//     stones' thickness t = 0.06 m: a crown that has gone down by t / 2 has lost the
//     depth through which a thrust line can pass; three times the elastic sag); no
//     stone ever rotates by more than 10 degrees (a stone rotating about a hinge at one
//     edge of its 0.06 m joint by 10 degrees opens a 1 cm gap at the other: the joint
//     has opened; elastic ringing rotates stones by a few degrees); and no creep: the
//     centroids averaged over the second second and over the last second differ by less
//     than 0.25 mm per second between the two windows for every stone, 2 mm over the
//     whole scene's 8 s and 0.25 mm over 3 s (Coulomb stiction means no motion at all
//     once the ringing has died out; 2 mm is a thirtieth of the stones' size, and a creep
//     that slow would take minutes to bring the arch down; the creep of every joint
//     before anchored stiction was 1 to 2 mm/s, docs/validation.md).
//   - Collapse: within 1 s the keystone's centroid falls by more than 0.5 h. Free fall
//     from the rise takes sqrt(2 h / g) = 0.19 s; a collapsing arch has fallen this far
//     long before 1 s, a standing one never comes close (the standing criterion is 0.15 h).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <vector>

#include "archway_measure.hpp"

using namespace softcontact;
using namespace softcontact::archway_test;

// mu_s = 0.95: the arch stands for the first 3 s of the scene, through the impacts of the
// four falling objects (t = 0.1 to 0.25 s) and its ringing, with no creep from [1, 2) s to
// [2, 3] s. The scene's whole 10 s: long_test_archway.cpp (label long, in the extended
// suite). Criteria in the header comment.
TEST(Archway, StandsThroughTheImpactsWithHighFriction) {
  expect_stands(run_standing(SOFTCONTACT_INPUTS_DIR "/archway.yaml", 3.0));
}

// mu = 0.1: the same arch collapses under its own weight. Criterion in the header
// comment: within 1 s the keystone falls by more than half the rise.
TEST(Archway, CollapsesWithLowFriction) {
  const auto t0 = std::chrono::steady_clock::now();
  const Scene scene = load_scene(SOFTCONTACT_INPUTS_DIR "/archway_low_friction.yaml");
  Simulator s(MPI_COMM_WORLD, scene);
  const Arch arch(s);
  ASSERT_EQ(arch.size(), 9u);
  const double dt = scene.sim.dt, h = arch.rise();
  const std::int64_t steps = std::llround(1.0 / dt);
  const std::int64_t sample = std::max<std::int64_t>(1, std::llround(0.01 / dt));
  double drop = 0, worst_angle = 0, t_half = -1;
  for (std::int64_t k = 1; k <= steps; ++k) {
    s.step();
    if (k % sample != 0 && k != steps) continue;
    const std::vector<Pose> p = arch.poses(s);
    drop = std::max(drop, arch.rest()[arch.keystone()].centroid[2] - p[arch.keystone()].centroid[2]);
    for (const Pose& q : p) worst_angle = std::max(worst_angle, q.angle_deg);
    if (t_half < 0 && drop > 0.5 * h) t_half = s.time();
  }
  std::printf("[measured] archway mu = 0.1, 1 s simulated (%lld steps) in %.0f s wall: rise %.4f m; keystone "
              "drop %.4f m (%.2f of the rise), past half the rise at t = %.3f s; largest stone rotation %.1f deg\n",
              static_cast<long long>(steps), seconds_since(t0), h, drop, drop / h, t_half, worst_angle);
  EXPECT_GT(drop, 0.5 * h);
}
