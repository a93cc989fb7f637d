#include <gtest/gtest.h>

#include <cmath>

#include "softcontact/integrator.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

using namespace softcontact;

namespace {
Scene falling_box(const char* integrator) {
  return load_scene_from_string(std::string("simulation:\n  dt: 0.001\n  steps: 500\n  gravity: [0.5, 0, -9.81]\n"
                                            "  integrator: ") +
                                    integrator + R"(
materials:
  - {name: m, young: 1e5, poisson: 0.3, density: 1000}
objects:
  - material: m
    primitive: {type: box, size: [1, 1, 1], cells: [2, 2, 2]}
    velocity: [1, 2, 3]
  - material: m
    primitive: {type: box, size: [1, 1, 1], cells: [1, 1, 1]}
    transform: {translate: [5, 0, 0]}
    kinematic: true
)",
                                "scene.yaml");
}

void run(World& w, const Simulation& sim, std::int64_t n) {
  std::vector<double> f;
  gravity_forces(w, sim.gravity, f);
  start_integration(w, sim, f);
  for (std::int64_t k = 0; k < n; ++k) {
    gravity_forces(w, sim.gravity, f);
    unconstrained_step(w, sim, f);
  }
}
}  // namespace

// Position Verlet is exact for constant acceleration: x(t) = x0 + v0 t + g t^2 / 2.
TEST(Integrator, VerletFreeFallIsExact) {
  const Scene s = falling_box("verlet");
  World w = build_world(s, block_partition(s, 1), 0);
  const std::vector<double> x0 = w.x;
  const std::int64_t n = 500;
  run(w, s.sim, n);
  const double t = n * s.sim.dt;
  const double v0[3] = {1, 2, 3};
  for (std::size_t i = 0; i < w.n_owned; ++i)
    for (int d = 0; d < 3; ++d) {
      const bool fixed = w.inv_mass[i] == 0;
      const double expect = fixed ? x0[3 * i + d] : x0[3 * i + d] + v0[d] * t + 0.5 * s.sim.gravity[d] * t * t;
      EXPECT_NEAR(w.x[3 * i + d], expect, 1e-11) << "vertex " << i;
      // Backward-difference velocity lags the exact one by g dt / 2.
      if (!fixed) {
        EXPECT_NEAR(w.v[3 * i + d], v0[d] + s.sim.gravity[d] * (t - 0.5 * s.sim.dt), 1e-9);
      }
    }
}

// Symplectic Euler: v_n = v0 + n dt g, x_n = x0 + n dt v0 + dt^2 g n (n + 1) / 2.
// (Implicit Euler under gravity alone gives the same: test_implicit_euler.cpp.)
TEST(Integrator, SymplecticEulerMatchesItsClosedForm) {
  for (const char* name : {"symplectic_euler"}) {
    const Scene s = falling_box(name);
    World w = build_world(s, block_partition(s, 1), 0);
    const std::vector<double> x0 = w.x;
    const std::int64_t n = 500;
    run(w, s.sim, n);
    const double dt = s.sim.dt;
    const double v0[3] = {1, 2, 3};
    for (std::size_t i = 0; i < w.n_owned; ++i) {
      if (w.inv_mass[i] == 0) {
        for (int d = 0; d < 3; ++d) EXPECT_EQ(w.x[3 * i + d], x0[3 * i + d]);
        continue;
      }
      for (int d = 0; d < 3; ++d) {
        EXPECT_NEAR(w.x[3 * i + d], x0[3 * i + d] + n * dt * v0[d] + dt * dt * s.sim.gravity[d] * n * (n + 1) / 2.0,
                    1e-11);
        EXPECT_NEAR(w.v[3 * i + d], v0[d] + n * dt * s.sim.gravity[d], 1e-11);
      }
    }
  }
}
