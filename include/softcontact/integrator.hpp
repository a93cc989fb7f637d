#pragma once
// Unconstrained motion (step 2 of Algorithm 1, method.md) of the owned vertices under
// forces f (n_local,3) [N]. Kinematic vertices (inverse mass 0) never move.
//
//  position Verlet      x~ = 2 x^t - x^(t-dt) + dt^2 f / m,   v = (x~ - x^t) / dt
//  symplectic Euler     v  = v^t + dt f / m,                  x~ = x^t + dt v
//  implicit Euler       M (v - v^t) = dt f(x~), x~ = x^t + dt v; with the forces that
//                       exist so far (gravity, independent of x) this equals symplectic
//                       Euler exactly; the models' stiffness enters with the PETSc KSP
//                       solve of the deformation-model work.
// After the step x_prev holds x^t and x holds x~.
#include <vector>

#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

/// Prepares x_prev for the first Verlet step: x^(-dt) = x^0 - dt v^0 + dt^2/2 f/m, which
/// makes the first step exact for constant acceleration.
void start_integration(World& w, const Simulation& sim, const std::vector<double>& f);

void unconstrained_step(World& w, const Simulation& sim, const std::vector<double>& f);

/// External forces: gravity m g on every movable owned vertex, into f (resized, zeroed).
void gravity_forces(const World& w, const Vec3& g, std::vector<double>& f);

}  // namespace softcontact
