#pragma once
// Test support: a scene's World stepped the way the run loop (src/sim/run.cpp) steps it,
// without output: forces (gravity + internal + damping), then the unconstrained step of
// the scene's integrator.
#include <memory>
#include <string>
#include <vector>

#include "softcontact/forces.hpp"
#include "softcontact/implicit_euler.hpp"
#include "softcontact/integrator.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

namespace softcontact::test_support {

struct Stepper {
  Scene scene;
  World w;
  ElasticForces forces;
  std::unique_ptr<ImplicitEuler> implicit;
  std::vector<double> f;

  explicit Stepper(Scene s)
      : scene(std::move(s)), w(build_world(scene, block_partition(scene, 1), 0)), forces(scene, w) {
    if (scene.sim.integrator == IntegratorKind::implicit_euler)
      implicit = std::make_unique<ImplicitEuler>(scene, w, forces);
  }

  static Stepper from_yaml(const std::string& yaml) { return Stepper(load_scene_from_string(yaml, "test.yaml")); }

  void compute_forces() {
    gravity_forces(w, scene.sim.gravity, f);
    forces.add_forces(w, f, !implicit);
  }

  /// Call after setting the initial state (World::x, World::v).
  void start() {
    compute_forces();
    start_integration(w, scene.sim, f);
  }

  void step() {
    compute_forces();
    if (implicit) implicit->step(w, scene.sim, f);
    else unconstrained_step(w, scene.sim, f);
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
