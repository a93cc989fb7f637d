#include "softcontact/motion.hpp"

#include "softcontact/forces.hpp"
#include "softcontact/implicit_euler.hpp"
#include "softcontact/integrator.hpp"
#include "softcontact/split_forces.hpp"

namespace softcontact {

UnconstrainedMotion::UnconstrainedMotion(const Scene& scene, const World& w, std::vector<int> split_owned)
    : scene_(scene), elastic_(std::make_unique<ElasticForces>(scene, w, std::move(split_owned))) {
  if (scene.sim.integrator == IntegratorKind::implicit_euler)
    implicit_ = std::make_unique<ImplicitEuler>(scene, w, *elastic_);
}

UnconstrainedMotion::~UnconstrainedMotion() = default;

void UnconstrainedMotion::forces(const World& w, std::vector<double>& f, SplitForces* split, NeighbourExchange* exchange) {
  // Step 1 of Algorithm 1: p = gravity + internal forces + Rayleigh damping at (x^t, v^t);
  // implicit Euler treats damping inside its linear system instead.
  gravity_forces(w, scene_.sim.gravity, f);
  // The split objects' parts first (ElasticForces skips those objects): their exchanges
  // then wait only for parts of equal size, not for each rank's own objects.
  if (split) split->evaluate(w, !implicit_, exchange);
  elastic_->add_forces(w, f, !implicit_);
  if (split) split->merge(w, f, !implicit_);
}

void UnconstrainedMotion::start(World& w, const std::vector<double>& f) const { start_integration(w, scene_.sim, f); }

void UnconstrainedMotion::advance(World& w, const std::vector<double>& f, double t) {
  const Simulation& sim = scene_.sim;
  if (implicit_) implicit_->step(w, sim, f);
  else unconstrained_step(w, sim, f);  // World::x = x~, World::x_prev = x^t
  prescribed_motion(w, t, t + sim.dt);  // moving anchors (scene `motion`)
}

}  // namespace softcontact
