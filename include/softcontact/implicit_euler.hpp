#pragma once
// Implicit (backward) Euler for the linear and corotational models, one linear solve per
// step and object with PETSc KSP (conjugate gradients, ICC(0) preconditioner). The
// scene parser rejects implicit_euler for the other models (docs/models.md says why).
//
// Backward Euler, M (v' - v) = dt f(x', v'), x' = x + dt v', with the internal forces
// linearised once about x (the stiffness K = -df/dx; for the corotational model the
// warped stiffness R K0 R^T, Mueller et al. 2002) and Rayleigh damping -(alpha M + beta K) v':
//
//   [(1 + dt alpha) M + (dt beta + dt^2) K] v' = M v + dt f(x)                     (*)
//
// with f(x) = internal + external forces at x (ElasticForces::add_forces with damping
// off, plus gravity). For the linear model K is constant and (*) is exactly backward
// Euler; for the corotational model it is one Newton step of it (Baraff and Witkin
// 1998), which is what makes large steps stable. The system matrix is symmetric
// positive definite (M > 0, K positive semi-definite).
//
// Kinematic vertices keep v = 0: their rows and columns are left out. Each object is its
// own system (objects are not coupled without contact), solved in object order: the
// result does not depend on how objects are distributed over ranks, nor on threads (the
// matrix entries are summed tet by tet, in tet order).
//
// PETSc options may refine the solver with the prefix 'implicit_' (PETSC_OPTIONS, e.g.
// "-implicit_ksp_rtol 1e-12 -implicit_pc_type jacobi").
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "softcontact/forces.hpp"
#include "softcontact/scene.hpp"
#include "softcontact/world.hpp"

namespace softcontact {

class ImplicitEuler {
public:
  /// Builds one sparse system per owned object with movable vertices (sparsity from the
  /// tets). PETSc must be initialised.
  ImplicitEuler(const Scene& scene, const World& world, const ElasticForces& forces);
  ~ImplicitEuler();
  ImplicitEuler(const ImplicitEuler&) = delete;
  ImplicitEuler& operator=(const ImplicitEuler&) = delete;

  /// One step: solves (*) with f (n_local,3) [N] = gravity + internal forces at World::x
  /// (no damping), then World::x_prev = x^t, World::v = v', World::x = x^t + dt v'.
  /// A solve that does not converge (KSP divergence, a PETSc error in KSPSolve) throws
  /// nothing: that object keeps x^t and v^t, and failed_object() / failure() say which
  /// and why (the first failure, lowest object id, is kept until clear_failure()). The
  /// caller makes it collective: the run loop's per-step reduction (health.cpp).
  void step(World& w, const Simulation& sim, const std::vector<double>& f);

  /// The object whose solve failed first (scene index), -1 when none has.
  int failed_object() const { return failed_object_; }
  /// What failed: solver, reason, iterations, residual against tolerance ("" when none).
  const std::string& failure() const { return failure_; }
  void clear_failure() {
    failed_object_ = -1;
    failure_.clear();
  }

  /// Krylov iterations of the last step, summed over objects.
  std::int64_t last_iterations() const { return last_iterations_; }

private:
  struct System;
  void assemble(System& s, const World& w, double dt) const;

  const ElasticForces& forces_;
  std::vector<std::unique_ptr<System>> systems_;
  std::int64_t last_iterations_ = 0;
  int failed_object_ = -1;
  std::string failure_;
};

}  // namespace softcontact
