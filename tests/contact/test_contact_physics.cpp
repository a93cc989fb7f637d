// The paper's contact response in the full step (Algorithm 1 with the deformation models
// and collision detection), against physical reference values. Each test states its
// reference and tolerance.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "contact_scenes.hpp"
#include "softcontact/diagnostics.hpp"

using namespace softcontact;
using namespace softcontact::test;

namespace {

constexpr double g = 9.81;

std::string floor_and_box(const std::string& box_material, double mu_s, double mu_k, const std::string& extra_box = "",
                          const std::string& sim = "  dt: auto\n  steps: 1\n") {
  return "simulation:\n" + sim + R"(
materials:
  - {name: ground, model: linear, young: 1.0e7, poisson: 0.3, density: 2000}
)" + box_material + "friction:\n  default: {static: " + std::to_string(mu_s) + ", kinetic: " + std::to_string(mu_k) + R"(}
objects:
  - name: floor
    material: ground
    primitive: {type: plate, size: [1.2, 0.6], thickness: 0.05, cells: [24, 12]}
    transform: {translate: [0, 0, -0.025]}
    kinematic: true
  - name: box
    material: soft
    primitive: {type: box, size: [0.1, 0.1, 0.1], cells: [3, 3, 3]}
)" + extra_box;
}

}  // namespace

// A box dropped 1 cm onto a fixed floor: no vertex ends a step inside the floor by more
// than 1% of the median edge length; it comes to rest; at rest the total contact force
// equals its weight within 0.5%.
TEST(ContactPhysics, BoxDroppedOnFloorRestsWithContactForceEqualToWeight) {
  auto r = make_run(floor_and_box(
      "  - {name: soft, model: corotational, young: 2.0e5, poisson: 0.3, density: 1000, damping: {mass: 8}}\n", 0.5,
      0.4, "    transform: {translate: [0, 0, 0.06]}\n"));
  Simulator& s = *r->sim;
  const double dt = r->scene.sim.dt;
  const int steps = static_cast<int>(std::ceil(1.2 / dt));
  double worst_residual = 0, fz_sum = 0, mass = 0;
  int samples = 0;
  for (int k = 0; k < steps; ++k) {
    s.step();
    StepDiagnostics d;
    s.measure(d);
    worst_residual = std::max(worst_residual, d.residual_penetration);
    const ObjectState box = object_state(s, 1);
    mass = box.mass;
    EXPECT_GT(box.min[2], -0.01 * s.median_edge()) << "step " << k;
    if (k >= steps - 200) {  // the last 0.2 s
      fz_sum += box.contact_force[2];
      ++samples;
    }
  }
  std::printf("[measured] box drop: worst residual %.3g median edges, rest force / weight %.5f\n", worst_residual,
              fz_sum / samples / (mass * g));
  EXPECT_LE(worst_residual, 0.01);
  const ObjectState box = object_state(s, 1);
  const double speed = std::hypot(box.momentum[0], box.momentum[1], box.momentum[2]) / box.mass;
  EXPECT_LT(speed, 1e-3);  // at rest
  EXPECT_NEAR(fz_sum / samples, mass * g, 0.005 * mass * g);
}

// Mass ratios 1, 10, 1000: two boxes overlapping with no gravity are pushed apart in one
// step; total momentum stays zero to 1e-10 of the momentum exchanged, and the lighter
// box takes the larger share of the separation: m_a dx_a = -m_b dx_b.
TEST(ContactPhysics, MassRatiosConserveMomentumAndLighterBodyMovesMore) {
  for (double ratio : {1.0, 10.0, 1000.0}) {
    const std::string yaml = "simulation: {dt: 1.0e-4, steps: 1, gravity: [0, 0, 0], separation_speed: 1000}\nmaterials:\n"
                             "  - {name: a, young: 1.0e5, poisson: 0.3, density: 100}\n"
                             "  - {name: b, young: 1.0e5, poisson: 0.3, density: " +
                             std::to_string(100 * ratio) + "}\n" + R"(
objects:
  - name: light
    material: a
    primitive: {type: box, size: [0.1, 0.1, 0.1], cells: [3, 3, 3]}
    transform: {translate: [-0.0495, 0, 0]}
  - name: heavy
    material: b
    primitive: {type: box, size: [0.1, 0.12, 0.12], cells: [3, 4, 4]}
    transform: {translate: [0.05, 0, 0]}
)";
    auto r = make_run(yaml);
    Simulator& s = *r->sim;
    const ObjectState a0 = object_state(s, 0), b0 = object_state(s, 1);
    s.step();
    ASSERT_GT(s.collisions().size(), 0u) << ratio;
    const ObjectState a1 = object_state(s, 0), b1 = object_state(s, 1);
    const double dxa = a1.centroid[0] - a0.centroid[0], dxb = b1.centroid[0] - b0.centroid[0];
    EXPECT_LT(dxa, 0);
    EXPECT_GT(dxb, 0);
    const double exchanged = std::abs(a1.momentum[0]);
    for (int d = 0; d < 3; ++d) EXPECT_LE(std::abs(a1.momentum[d] + b1.momentum[d]), 1e-10 * exchanged) << ratio;
    EXPECT_NEAR(a1.mass * dxa, -b1.mass * dxb, 1e-9 * a1.mass * std::abs(dxa)) << ratio;
    if (ratio > 1) EXPECT_GT(std::abs(dxa), std::abs(dxb));
    EXPECT_LT(s.contact_stats().force_balance, 1e-12);
  }
}

// Two equal boxes overlapping by h along x with no gravity: every face vertex is pushed
// the same way as a point and as a triangle vertex and takes half of each, so the two
// contact faces move back by the same amount and meet in the middle plane x = 0 (the
// overlap is resolved in one step here: separation_speed is set high, since by default
// an overlap present from the start is pushed apart at 1 m/s, OldOverlapSeparates...). The
// faces' inner vertices (away from the rim, where smoothed normals tilt the penetration
// vectors) are measured: symmetric about x = 0 within 1% of h, each moved h/2 within
// 10% (the consistent depth of a coarse mesh overestimates by a few percent).
TEST(ContactPhysics, EqualBodiesMeetInTheMiddlePlane) {
  const double h = 0.004;
  auto r = make_run(R"(
simulation: {dt: 1.0e-4, steps: 1, gravity: [0, 0, 0], separation_speed: 1000}
materials:
  - {name: a, young: 1.0e6, poisson: 0.3, density: 1000}
objects:
  - name: left
    material: a
    primitive: {type: box, size: [0.1, 0.1, 0.1], cells: [3, 3, 3]}
    transform: {translate: [-0.048, 0.0001, 0.0002]}
  - name: right
    material: a
    primitive: {type: box, size: [0.1, 0.1, 0.1], cells: [3, 3, 3]}
    transform: {translate: [0.048, 0, 0]}
)");
  Simulator& s = *r->sim;
  World& w = s.world();
  // inner vertices of the contact faces: |y|, |z| < 0.03 at the face
  std::vector<std::size_t> left, right;
  for (std::size_t i = 0; i < w.n_owned; ++i) {
    const double* x = &w.x[3 * i];
    if (std::abs(x[1]) > 0.03 || std::abs(x[2]) > 0.03) continue;
    if (w.vertex_object[i] == 0 && std::abs(x[0] - h / 2) < 1e-9) left.push_back(i);
    if (w.vertex_object[i] == 1 && std::abs(x[0] + h / 2) < 1e-9) right.push_back(i);
  }
  ASSERT_EQ(left.size(), 4u);
  ASSERT_EQ(right.size(), 4u);
  s.step();
  double xl = 0, xr = 0;
  for (std::size_t i : left) xl += w.x[3 * i] / 4;
  for (std::size_t i : right) xr += w.x[3 * i] / 4;
  EXPECT_NEAR(xl + xr, 0.0, 0.01 * h);            // symmetric: alpha = 1/2
  EXPECT_NEAR(h / 2 - xl, h / 2, 0.1 * h / 2);     // each face moved h/2
  EXPECT_NEAR(xr + h / 2, h / 2, 0.1 * h / 2);
  const ObjectState a = object_state(s, 0), b = object_state(s, 1);
  EXPECT_NEAR(a.momentum[0], -b.momentum[0], 1e-12 * std::abs(a.momentum[0]));
}

// A flat kinematic plate and a soft box on it, for the incline tests (the incline is
// written flat and gravity tilted instead).
namespace {
std::string incline_yaml(double mu, const std::string& damping) {
  return "simulation: {dt: auto, steps: 1}\nmaterials:\n"
         "  - {name: ground, model: linear, young: 1.0e7, poisson: 0.3, density: 2000}\n"
         "  - {name: soft, model: corotational, young: 1.0e7, poisson: 0.3, density: 1000" + damping + "}\n"
         "friction:\n  default: {static: " + std::to_string(mu) + ", kinetic: " + std::to_string(mu) +
         "}\nobjects:\n"
         "  - name: incline\n    material: ground\n"
         "    primitive: {type: plate, size: [1.2, 0.4], thickness: 0.05, cells: [24, 8]}\n"
         "    transform: {translate: [0, 0, -0.025]}\n    kinematic: true\n"
         "  - name: box\n    material: soft\n"
         "    primitive: {type: box, size: [0.1, 0.1, 0.1], cells: [3, 3, 3]}\n"
         "    transform: {translate: [0.45, 0, 0.05]}\n";
}
}  // namespace

// The same box on the same incline (26.6 degrees, mu_s = 0.6 > tan(theta) = 0.5) with no
// damping at all: its elastic vibration after the sudden load never dies out, and it
// must still stick. Reference: Coulomb, no motion; bound 0.1 mm over 2 s after 0.5 s of
// settling (1e-3 of the box size).
TEST(ContactPhysics, BoxOnInclineSticksWithoutDamping) {
  const double theta = std::atan(0.5);
  Scene scene = load_scene_from_string(incline_yaml(0.6, ""), "test.yaml");
  scene.sim.gravity = {-g * std::sin(theta), 0, -g * std::cos(theta)};
  Simulator s(MPI_COMM_WORLD, scene);
  const double dt = scene.sim.dt;
  const int settle = static_cast<int>(std::lround(0.5 / dt)), steps = static_cast<int>(std::lround(2.0 / dt));
  for (int k = 0; k < settle; ++k) s.step();
  const ObjectState start = object_state(s, 1);
  for (int k = 0; k < steps; ++k) s.step();
  const ObjectState end = object_state(s, 1);
  const double moved = std::hypot(end.centroid[0] - start.centroid[0], end.centroid[1] - start.centroid[1]);
  std::printf("[measured] incline mu=0.6, no damping: moved %.3g m in 2 s after settling\n", moved);
  EXPECT_LT(moved, 1e-4);
}

// A box on an incline of angle theta = atan(0.5): with mu = 0.6 > tan(theta) it sticks
// (its centroid moves less than 1e-3 of its size in 2 s, elastic settling included);
// with mu = 0.3 it slides with acceleration g (sin(theta) - mu cos(theta)) within 2%,
// measured between t = 0.2 s and 0.6 s (before it reaches the end of the incline).
// Stiffness-proportional damping calms the vibration that the sudden load of gravity
// starts (without it the contact chatters and the box creeps); it does not act on rigid
// motion, so the sliding acceleration is unaffected.
TEST(ContactPhysics, BoxOnInclineSticksOrSlidesByCoulomb) {
  const double theta = std::atan(0.5);
  for (double mu : {0.6, 0.3}) {
    const std::string yaml = incline_yaml(mu, ", damping: {stiffness: 2.0e-5}");
    // The incline is written flat and gravity tilted instead: g along
    // (-sin theta, 0, -cos theta) is the same physics as a tilted plane.
    Scene scene = load_scene_from_string(yaml, "test.yaml");
    scene.sim.gravity = {-g * std::sin(theta), 0, -g * std::cos(theta)};
    Simulator s(MPI_COMM_WORLD, scene);
    const double dt = scene.sim.dt;
    const ObjectState start = object_state(s, 1);
    const double t_end = mu > 0.5 ? 2.0 : 0.6;
    const int steps = static_cast<int>(std::lround(t_end / dt));
    const int k1 = static_cast<int>(std::lround(0.2 / dt));
    double v1 = 0;
    for (int k = 1; k <= steps; ++k) {
      s.step();
      if (k == k1) v1 = object_state(s, 1).momentum[0] / start.mass;
    }
    const ObjectState end = object_state(s, 1);
    if (mu > 0.5) {
      std::printf("[measured] incline mu=0.6: moved %.3g m in 2 s\n", end.centroid[0] - start.centroid[0]);
      EXPECT_LT(std::abs(end.centroid[0] - start.centroid[0]), 1e-3 * 0.1) << "mu = " << mu;
    } else {
      const double a = (end.momentum[0] / end.mass - v1) / (dt * (steps - k1));
      const double expect = -g * (std::sin(theta) - mu * std::cos(theta));
      std::printf("[measured] incline mu=0.3: acceleration %.5f m/s^2, reference %.5f\n", a, expect);
      EXPECT_NEAR(a, expect, 0.02 * std::abs(expect)) << "mu = " << mu;
    }
  }
}

// A box sliding on a floor with initial speed v0 stops after v0^2 / (2 mu g) within 2%.
TEST(ContactPhysics, SlidingBoxStopsAfterCoulombDistance) {
  const double v0 = 1.0, mu = 0.5;
  auto r = make_run(floor_and_box(
      "  - {name: soft, model: corotational, young: 1.0e7, poisson: 0.3, density: 1000}\n", mu, mu,
      "    transform: {translate: [-0.4, 0, 0.05]}\n    velocity: [1.0, 0, 0]\n"));
  Simulator& s = *r->sim;
  const double dt = r->scene.sim.dt;
  const ObjectState start = object_state(s, 1);
  const int steps = static_cast<int>(std::lround(0.4 / dt));  // stops after v0 / (mu g) = 0.2 s
  for (int k = 0; k < steps; ++k) s.step();
  const ObjectState end = object_state(s, 1);
  EXPECT_LT(std::abs(end.momentum[0] / end.mass), 1e-3);
  const double expect = v0 * v0 / (2 * mu * g);
  std::printf("[measured] sliding box: stopped after %.5f m, reference %.5f m\n", end.centroid[0] - start.centroid[0],
              expect);
  EXPECT_NEAR(end.centroid[0] - start.centroid[0], expect, 0.02 * expect);
}

// Two identical elastic bars (nu = 0, so c = sqrt(E / rho) = 10 m/s) meet head-on at
// +-v0: they exchange velocities, the contact lasts about 2 L / c (within 10%), and the
// frictionless collision does not gain energy (at most 0.1%). Energy is taken at whole
// steps, E_n = 1/2 m |(v_(n-1/2) + v_(n+1/2)) / 2|^2 + U(x_n), the form whose error
// under Verlet is O(dt^2) (the backward-difference velocity alone is off by O(dt)); a
// step of 0.1 of the stability limit keeps that error below the 0.1% asked for.
// The right bar is offset sideways by a quarter cell: with the cross-sections exactly
// aligned, the rim vertices of each end face lie exactly on the other bar's side faces,
// are not strictly inside, and slip in undetected until the other bar bulges; they are
// then caught deep, at a corner, and kicked out (measured: energy +60% that way). That
// is an edge-edge contact, which vertex-in-tet detection does not see (docs/collision.md).
TEST(ContactPhysics, ElasticBarsExchangeVelocitiesWithoutGainingEnergy) {
  const double v0 = 0.1, L = 0.2, c = 10.0;
  auto r = make_run(R"(
simulation: {dt: auto, dt_safety: 0.1, steps: 1, gravity: [0, 0, 0]}
materials:
  - {name: rod, model: linear, young: 1.0e5, poisson: 0.0, density: 1000}
friction:
  default: {static: 0, kinetic: 0}
objects:
  - name: left
    material: rod
    primitive: {type: box, size: [0.2, 0.02, 0.02], cells: [20, 4, 4]}
    transform: {translate: [-0.1005, 0, 0]}
    velocity: [0.1, 0, 0]
  - name: right
    material: rod
    primitive: {type: box, size: [0.2, 0.02, 0.02], cells: [20, 4, 4]}
    transform: {translate: [0.1005, 0.0013, 0.0013]}
    velocity: [-0.1, 0, 0]
)");
  Simulator& s = *r->sim;
  World& w = s.world();
  const double dt = r->scene.sim.dt;
  const double e0 = 2 * 0.5 * (1000 * 0.2 * 0.02 * 0.02) * v0 * v0;
  int first = -1, last = -1;
  double emax = 0;
  std::vector<double> v_prev = w.v;  // v_(n-1/2) once the loop runs
  StepDiagnostics dn;
  const int steps = static_cast<int>(std::lround(0.12 / dt));
  for (int k = 1; k <= steps; ++k) {
    if (k > 1) s.measure(dn);  // U(x_n) before the step that gives v_(n+1/2)
    const std::vector<double> v_before = w.v;
    s.step();
    if (!s.collisions().empty()) {
      if (first < 0) first = k;
      last = k;
    }
    if (k > 1) {
      double ke = 0;
      for (std::size_t i = 0; i < w.n_owned; ++i)
        for (int d = 0; d < 3; ++d) {
          const double vc = 0.5 * (v_before[3 * i + d] + w.v[3 * i + d]);
          ke += 0.5 * w.mass[i] * vc * vc;
        }
      emax = std::max(emax, ke + dn.elastic_energy);
    }
    v_prev = v_before;
  }
  ASSERT_GT(first, 0);
  const double duration = (last - first + 1) * dt;
  const ObjectState a = object_state(s, 0), b = object_state(s, 1);
  std::printf("[measured] bars: contact %.5f s (2L/c = %.5f), max energy / initial %.5f, velocities %.5f %.5f\n",
              duration, 2 * L / c, emax / e0, a.momentum[0] / a.mass, b.momentum[0] / b.mass);
  EXPECT_NEAR(duration, 2 * L / c, 0.1 * 2 * L / c);
  EXPECT_LE(emax, 1.001 * e0);
  EXPECT_NEAR(a.momentum[0] / a.mass, -v0, 0.05 * v0);
  EXPECT_NEAR(b.momentum[0] / b.mass, v0, 0.05 * v0);
}

// A stack of three boxes (0.14, 0.12 and 0.10 m wide, so that no rim lies on another
// box's side face) on a fixed floor: at rest each interface carries the weight above it
// within 1%, and over 10^4 steps the stack does not drift (top centroid moves less than
// 1e-3 of a box size between steps 5000 and 10^4).
TEST(ContactPhysics, StackOfThreeBoxesCarriesTheWeightAbove) {
  auto r = make_run(R"(
simulation: {dt: auto, steps: 1}
materials:
  - {name: ground, model: linear, young: 1.0e7, poisson: 0.3, density: 2000}
  - {name: soft, model: corotational, young: 1.0e6, poisson: 0.3, density: 1000, damping: {mass: 5, stiffness: 1.0e-4}}
friction:
  default: {static: 0.8, kinetic: 0.6}
objects:
  - name: floor
    material: ground
    primitive: {type: plate, size: [0.5, 0.5], thickness: 0.05, cells: [10, 10]}
    transform: {translate: [0.003, 0.002, -0.025]}
    kinematic: true
  - name: bottom
    material: soft
    primitive: {type: box, size: [0.14, 0.14, 0.1], cells: [4, 4, 3]}
    transform: {translate: [0, 0, 0.05]}
  - name: middle
    material: soft
    primitive: {type: box, size: [0.12, 0.12, 0.1], cells: [4, 4, 3]}
    transform: {translate: [0, 0, 0.15]}
  - name: top
    material: soft
    primitive: {type: box, size: [0.1, 0.1, 0.1], cells: [3, 3, 3]}
    transform: {translate: [0, 0, 0.25]}
)");
  Simulator& s = *r->sim;
  World& w = s.world();
  const double W[4] = {0, 1000 * 0.14 * 0.14 * 0.1 * g, 1000 * 0.12 * 0.12 * 0.1 * g, 1000 * 0.1 * 0.1 * 0.1 * g};
  // bottom-face vertices of each box (in the rest configuration)
  std::vector<int> bottom_face(w.n_owned, 0);
  for (std::size_t i = 0; i < w.n_owned; ++i) {
    const int o = w.vertex_object[i];
    if (o > 0 && std::abs(w.x[3 * i + 2] - 0.1 * (o - 1)) < 1e-9) bottom_face[i] = o;
  }
  double load[4] = {0, 0, 0, 0};
  int samples = 0;
  std::array<double, 3> top_mid{};
  for (int k = 1; k <= 10000; ++k) {
    s.step();
    if (k == 5000) top_mid = object_state(s, 3).centroid;
    if (k > 9500) {
      const auto& F = s.contact_force();
      for (std::size_t i = 0; i < w.n_owned; ++i) load[bottom_face[i]] += F[3 * i + 2];
      ++samples;
    }
  }
  std::printf("[measured] stack: interface loads / weight above %.5f %.5f %.5f\n",
              load[1] / samples / (W[1] + W[2] + W[3]), load[2] / samples / (W[2] + W[3]), load[3] / samples / W[3]);
  EXPECT_NEAR(load[1] / samples, W[1] + W[2] + W[3], 0.01 * (W[1] + W[2] + W[3]));
  EXPECT_NEAR(load[2] / samples, W[2] + W[3], 0.01 * (W[2] + W[3]));
  EXPECT_NEAR(load[3] / samples, W[3], 0.01 * W[3]);
  const auto top_end = object_state(s, 3).centroid;
  EXPECT_LT(std::hypot(top_end[0] - top_mid[0], top_end[1] - top_mid[1], top_end[2] - top_mid[2]), 1e-3 * 0.1);
}

// The response works with every deformation model in one scene, and with every
// integrator: five boxes, one per model, dropped 5 mm onto a fixed floor, come to rest
// carrying their weight (total contact force on the boxes = total weight within 1%,
// averaged over the last 0.1 s). Implicit Euler runs the two models it supports.
TEST(ContactPhysics, EveryModelAndIntegratorRestsOnTheFloor) {
  struct Case {
    const char* integrator;
    std::vector<const char*> models;
  };
  const Case cases[] = {{"verlet", {"linear", "corotational", "stvk", "neohookean", "mass_spring"}},
                        {"symplectic_euler", {"linear", "corotational", "stvk", "neohookean", "mass_spring"}},
                        {"implicit_euler", {"linear", "corotational"}}};
  for (const Case& c : cases) {
    std::string yaml = std::string("simulation: {dt: ") +
                       (std::string(c.integrator) == "implicit_euler" ? "2.0e-4" : "auto") +
                       ", steps: 1, integrator: " + c.integrator +
                       "}\nmaterials:\n  - {name: ground, model: linear, young: 1.0e7, poisson: 0.3, density: 2000}\n";
    for (const char* m : c.models)
      yaml += std::string("  - {name: ") + m + ", model: " + m +
              ", young: 2.0e5, poisson: 0.3, density: 1000, damping: {mass: 10}}\n";
    yaml += "objects:\n  - name: floor\n    material: ground\n"
            "    primitive: {type: plate, size: [1.2, 0.4], thickness: 0.05, cells: [24, 8]}\n"
            "    transform: {translate: [0.002, 0.003, -0.025]}\n    kinematic: true\n";
    double x = -0.4;
    for (const char* m : c.models) {
      yaml += std::string("  - name: ") + m + "\n    material: " + m +
              "\n    primitive: {type: box, size: [0.1, 0.1, 0.1], cells: [3, 3, 3]}\n" +
              "    transform: {translate: [" + std::to_string(x) + ", 0, 0.055]}\n";
      x += 0.2;
    }
    auto r = make_run(yaml);
    Simulator& s = *r->sim;
    const double dt = r->scene.sim.dt;
    // 1 s: the StVK box's vertical bounce decays by about 5x every 0.15 s and is under
    // 1 mm/s from 0.85 s on (its bottom sticks to the floor as a patch, docs/contact.md).
    const int steps = static_cast<int>(std::lround(1.0 / dt));
    const int window = static_cast<int>(std::lround(0.1 / dt));
    double fz = 0, weight = 0;
    for (int k = 1; k <= steps; ++k) {
      s.step();
      if (k > steps - window)
        for (std::size_t o = 1; o <= c.models.size(); ++o) fz += object_state(s, static_cast<int>(o)).contact_force[2];
    }
    for (std::size_t o = 1; o <= c.models.size(); ++o) weight += object_state(s, static_cast<int>(o)).mass * g;
    std::printf("[measured] %s: contact force / weight %.5f\n", c.integrator, fz / window / weight);
    EXPECT_NEAR(fz / window, weight, 0.01 * weight) << c.integrator;
    for (std::size_t o = 1; o <= c.models.size(); ++o) {
      const ObjectState b = object_state(s, static_cast<int>(o));
      EXPECT_LT(std::abs(b.momentum[2] / b.mass), 1e-3) << c.integrator << " " << c.models[o - 1];
      EXPECT_GT(b.min[2], -0.01 * s.median_edge()) << c.integrator << " " << c.models[o - 1];
    }
  }
}
