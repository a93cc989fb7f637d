#pragma once
// Test support: a scene's World stepped the way the Simulator steps it
// (UnconstrainedMotion, motion.hpp: forces, then the unconstrained step of the scene's
// integrator and the prescribed motion), without contact, output or MPI.
#include <memory>
#include <string>
#include <vector>

#include "softcontact/forces.hpp"
#include "softcontact/implicit_euler.hpp"
#include "softcontact/motion.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

namespace softcontact::test_support {

struct Stepper {
  Scene scene;
  World w;
  UnconstrainedMotion motion;
  ElasticForces& forces;
  ImplicitEuler* implicit;
  std::vector<double> f;
  std::int64_t steps = 0;

  explicit Stepper(Scene s)
      : scene(std::move(s)), w(build_world(scene, block_partition(scene, 1), 0)), motion(scene, w),
        forces(motion.elastic()), implicit(motion.implicit()) {}

  static Stepper from_yaml(const std::string& yaml) { return Stepper(load_scene_from_string(yaml, "test.yaml")); }

  void compute_forces() { motion.forces(w, f); }

  /// Call after setting the initial state (World::x, World::v).
  void start() {
    compute_forces();
    motion.start(w, f);
  }

  void step() {
    compute_forces();
    motion.advance(w, f, static_cast<double>(steps) * scene.sim.dt);
    ++steps;
  }

  /// Strain energy of all objects [J].
  double elastic_energy() const {
    ElasticMeasures m;
    forces.measure(w, m);
    double e = 0;
    for (double x : m.energy) e += x;
    return e;
  }

  /// Kinetic energy 1/2 sum m |v|^2 of the movable vertices for the velocities v (n,3).
  double kinetic_energy(const std::vector<double>& v) const {
    double e = 0;
    for (std::size_t i = 0; i < w.n_owned; ++i)
      if (w.inv_mass[i] != 0)
        e += 0.5 * w.mass[i] * (v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]);
    return e;
  }
};

}  // namespace softcontact::test_support
