#pragma once
// Unconstrained motion (step 2 of Algorithm 1, method.md) of the owned vertices under
// forces f (n_local,3) [N]: gravity + internal forces + Rayleigh damping (forces.hpp),
// evaluated at x^t (and v^t). Kinematic vertices (inverse mass 0) do not move here;
// prescribed_motion moves those that have a scene `motion`.
//
//  position Verlet      x~ = 2 x^t - x^(t-dt) + dt^2 f / m,   v = (x~ - x^t) / dt
//  symplectic Euler     v  = v^t + dt f / m,                  x~ = x^t + dt v
//  implicit Euler       implicit_euler.hpp (ImplicitEuler::step): a linear solve per
//                       object; unconstrained_step does not handle it.
// After the step x_prev holds x^t and x holds x~. Both explicit schemes are stable for
// dt below the limit that `dt: auto` uses (stable_step, docs/models.md), which includes
// the Rayleigh damping: the damping forces are explicit, at v^t.
//
// Velocities: Verlet's v is the backward difference (x~ - x^t) / dt, a first-order
// estimate of v at the middle of the step; the damping forces of the next step use it.
#include <vector>

#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

/// Prepares x_prev for the first Verlet step: x^(-dt) = x^0 - dt v^0 + dt^2/2 f/m, which
/// makes the first step exact for constant acceleration.
void start_integration(World& w, const Simulation& sim, const std::vector<double>& f);

/// Position Verlet or symplectic Euler (sim.integrator must not be implicit_euler).
void unconstrained_step(World& w, const Simulation& sim, const std::vector<double>& f);

/// Prescribed motion (scene key `motion`): moves the fixed owned vertices of every object
/// with a motion by velocity x (the part of [t0, t1] inside its [start, stop]) and sets
/// their velocity to that displacement / (t1 - t0), and to 0 outside [start, stop]. It
/// reads the motions of the owned objects only (World::owned_motion), never the whole
/// scene's. Called after the unconstrained step,
/// before collision detection, so that moving anchors push and drag (friction) what they
/// touch; fixed vertices of objects without a motion stay where they are.
void prescribed_motion(World& w, double t0, double t1);

/// External forces: gravity m g on every movable owned vertex, into f (resized to 3 per
/// owned vertex: the forces have no ghost rows; kinematic vertices get 0, the models then
/// add their internal forces).
void gravity_forces(const World& w, const Vec3& g, std::vector<double>& f);

}  // namespace softcontact
