#pragma once
// The serial part of a step before contact (docs/architecture.md, "One step"): the
// forces p at (x^t, v^t) and the unconstrained motion to x~ with the scene's integrator
// (position Verlet, symplectic Euler or implicit Euler), then the prescribed motion of
// driven anchors, for one World. The Simulator steps its rank's World with it; tests
// step a World of their own with it, without MPI.
#include <memory>
#include <vector>

#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

class ElasticForces;
class ImplicitEuler;
class NeighbourExchange;
class SplitForces;

class UnconstrainedMotion {
public:
  /// The models' rest shapes from w.x (the scene's initial positions), but for the owned
  /// objects split over ranks (`split_owned`, whose forces SplitForces computes:
  /// ElasticForces' held_elsewhere).
  UnconstrainedMotion(const Scene& scene, const World& w, std::vector<int> split_owned = {});
  ~UnconstrainedMotion();
  UnconstrainedMotion(const UnconstrainedMotion&) = delete;
  UnconstrainedMotion& operator=(const UnconstrainedMotion&) = delete;

  /// f (n_local,3) = gravity + internal forces at World::x, and the Rayleigh damping at
  /// World::v unless implicit Euler treats it inside its linear system.
  /// Objects split over ranks (split_forces.hpp) take their internal forces from `split`
  /// (collective over the neighbours of `exchange`).
  void forces(const World& w, std::vector<double>& f, SplitForces* split = nullptr, NeighbourExchange* exchange = nullptr);
  /// After the initial state (World::x, World::v) is set: the integrator's start from f.
  void start(World& w, const std::vector<double>& f) const;
  /// World::x = x~ from f, World::x_prev = x^t; then the prescribed motion over
  /// [t, t + dt].
  void advance(World& w, const std::vector<double>& f, double t);

  ElasticForces& elastic() { return *elastic_; }
  const ElasticForces& elastic() const { return *elastic_; }
  /// The implicit Euler solver, or null with an explicit integrator.
  ImplicitEuler* implicit() { return implicit_.get(); }
  const ImplicitEuler* implicit() const { return implicit_.get(); }

private:
  const Scene& scene_;
  std::unique_ptr<ElasticForces> elastic_;
  std::unique_ptr<ImplicitEuler> implicit_;
};

}  // namespace softcontact
