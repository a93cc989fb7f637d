#include "softcontact/implicit_euler.hpp"

#include <petscksp.h>

#include <algorithm>
#include <sstream>
#include <string>

#include "softcontact/error.hpp"
#include "../model/material_registry.hpp"

namespace softcontact {

namespace {

void check(PetscErrorCode ierr, const char* call) {
  if (ierr != 0) throw RuntimeFailure(std::string("implicit Euler: PETSc call ") + call + " failed (error " +
                                      std::to_string(static_cast<int>(ierr)) + ")");
}

}  // namespace

/// One object's system: CSR pattern (3 rows per movable vertex, 3x3 blocks), the map from
/// each tet's corner pairs to their blocks, and the PETSc objects, which use our arrays.
struct ImplicitEuler::System {
  int object = 0;
  std::string name;                      ///< for messages
  std::size_t tet_begin = 0, tet_end = 0;
  bool constant = false;                 ///< the law's K does not depend on x (constant_stiffness)
  double assembled_dt = 0;               ///< dt of the assembled matrix (constant systems)
  double alpha = 0, beta = 0;
  bool failed = false;                   ///< the last solve did not converge
  std::vector<index_t> vertex;           ///< movable vertices (local indices), ascending
  std::vector<PetscInt> row_ptr, col;    ///< CSR, columns ascending in each row
  std::vector<PetscScalar> val;
  std::vector<std::int32_t> block;       ///< (tets, 4, 4): position of column block b in row block a, -1 if fixed
  std::vector<std::int32_t> diag;        ///< position of the diagonal block in each row block
  std::vector<PetscScalar> rhs, sol;
  Mat A = nullptr;
  Vec b = nullptr, x = nullptr;
  KSP ksp = nullptr;

  ~System() {
    if (ksp) KSPDestroy(&ksp);
    if (A) MatDestroy(&A);
    if (b) VecDestroy(&b);
    if (x) VecDestroy(&x);
  }
};

ImplicitEuler::ImplicitEuler(const Scene& scene, const World& w, const ElasticForces& forces) : forces_(forces) {
  for (const ElasticForces::Segment& seg : forces.segments()) {
    if (!seg.active) continue;
    auto s = std::make_unique<System>();
    s->object = seg.object;
    s->tet_begin = seg.begin;
    s->tet_end = seg.end;
    s->constant = model::material_law(seg.model).constant_stiffness;
    s->alpha = seg.alpha;
    s->beta = seg.beta;
    // Movable vertices of this object, numbered in local order.
    std::vector<std::int32_t> id(w.n_local(), -1);
    for (std::size_t t = seg.begin; t < seg.end; ++t)
      for (int c = 0; c < 4; ++c) {
        const index_t v = w.tets[4 * t + c];
        if (w.inv_mass[v] != 0 && id[v] < 0) id[v] = 0;
      }
    for (std::size_t v = 0; v < w.n_local(); ++v)
      if (id[v] == 0) {
        id[v] = static_cast<std::int32_t>(s->vertex.size());
        s->vertex.push_back(static_cast<index_t>(v));
      }
    const std::size_t nv = s->vertex.size();
    if (nv == 0) continue;
    // Block adjacency (movable pairs sharing a tet, and the diagonal), sorted.
    std::vector<std::vector<std::int32_t>> adj(nv);
    for (std::size_t i = 0; i < nv; ++i) adj[i].push_back(static_cast<std::int32_t>(i));
    for (std::size_t t = seg.begin; t < seg.end; ++t)
      for (int a = 0; a < 4; ++a)
        for (int c = 0; c < 4; ++c) {
          const std::int32_t ia = id[w.tets[4 * t + a]], ic = id[w.tets[4 * t + c]];
          if (ia >= 0 && ic >= 0) adj[ia].push_back(ic);
        }
    for (auto& r : adj) {
      std::sort(r.begin(), r.end());
      r.erase(std::unique(r.begin(), r.end()), r.end());
    }
    s->row_ptr.assign(3 * nv + 1, 0);
    for (std::size_t i = 0; i < nv; ++i)
      for (int d = 0; d < 3; ++d)
        s->row_ptr[3 * i + d + 1] = s->row_ptr[3 * i + d] + static_cast<PetscInt>(3 * adj[i].size());
    s->col.resize(s->row_ptr.back());
    for (std::size_t i = 0; i < nv; ++i)
      for (int d = 0; d < 3; ++d) {
        PetscInt* c = &s->col[s->row_ptr[3 * i + d]];
        for (std::size_t k = 0; k < adj[i].size(); ++k)
          for (int e = 0; e < 3; ++e) c[3 * k + e] = static_cast<PetscInt>(3 * adj[i][k] + e);
      }
    s->val.assign(s->col.size(), 0.0);
    auto position = [&](std::int32_t i, std::int32_t j) {
      return static_cast<std::int32_t>(std::lower_bound(adj[i].begin(), adj[i].end(), j) - adj[i].begin());
    };
    s->diag.resize(nv);
    for (std::size_t i = 0; i < nv; ++i) s->diag[i] = position(static_cast<std::int32_t>(i), static_cast<std::int32_t>(i));
    s->block.assign(16 * (seg.end - seg.begin), -1);
    for (std::size_t t = seg.begin; t < seg.end; ++t)
      for (int a = 0; a < 4; ++a)
        for (int c = 0; c < 4; ++c) {
          const std::int32_t ia = id[w.tets[4 * t + a]], ic = id[w.tets[4 * t + c]];
          if (ia >= 0 && ic >= 0) s->block[16 * (t - seg.begin) + 4 * a + c] = position(ia, ic);
        }
    s->rhs.assign(3 * nv, 0.0);
    s->sol.assign(3 * nv, 0.0);

    const PetscInt n = static_cast<PetscInt>(3 * nv);
    check(MatCreateSeqAIJWithArrays(PETSC_COMM_SELF, n, n, s->row_ptr.data(), s->col.data(), s->val.data(), &s->A),
          "MatCreateSeqAIJWithArrays");
    check(MatSetOption(s->A, MAT_SYMMETRIC, PETSC_TRUE), "MatSetOption");
    check(MatSetOption(s->A, MAT_SPD, PETSC_TRUE), "MatSetOption");
    check(VecCreateSeqWithArray(PETSC_COMM_SELF, 1, n, s->rhs.data(), &s->b), "VecCreateSeqWithArray");
    check(VecCreateSeqWithArray(PETSC_COMM_SELF, 1, n, s->sol.data(), &s->x), "VecCreateSeqWithArray");
    check(KSPCreate(PETSC_COMM_SELF, &s->ksp), "KSPCreate");
    check(KSPSetType(s->ksp, KSPCG), "KSPSetType");
    PC pc = nullptr;
    check(KSPGetPC(s->ksp, &pc), "KSPGetPC");
    check(PCSetType(pc, PCICC), "PCSetType");
    // ICC(0) of an SPD matrix can still meet a non-positive pivot; a positive shift keeps
    // the preconditioner definite, as CG needs.
    check(PCFactorSetShiftType(pc, MAT_SHIFT_POSITIVE_DEFINITE), "PCFactorSetShiftType");
    // Relative to |b| = |M v + dt f|, which is never small for a moving or loaded body.
    check(KSPSetTolerances(s->ksp, 1e-10, 1e-50, PETSC_DEFAULT, 10000), "KSPSetTolerances");
    check(KSPSetInitialGuessNonzero(s->ksp, PETSC_TRUE), "KSPSetInitialGuessNonzero");
    check(KSPSetOptionsPrefix(s->ksp, "implicit_"), "KSPSetOptionsPrefix");
    check(KSPSetFromOptions(s->ksp), "KSPSetFromOptions");
    check(KSPSetOperators(s->ksp, s->A, s->A), "KSPSetOperators");
    s->name = scene.objects[seg.object].name;
    systems_.push_back(std::move(s));
  }
}

ImplicitEuler::~ImplicitEuler() = default;

void ImplicitEuler::assemble(System& s, const World& w, double dt) const {
  std::fill(s.val.begin(), s.val.end(), 0.0);
  const double k_coef = dt * s.beta + dt * dt;
  double K[144];
  for (std::size_t t = s.tet_begin; t < s.tet_end; ++t) {
    forces_.tet_stiffness(t, w.x.data(), StiffnessKind::implicit, K);
    const std::int32_t* blk = &s.block[16 * (t - s.tet_begin)];
    for (int a = 0; a < 4; ++a) {
      const index_t va = w.tets[4 * t + a];
      if (w.inv_mass[va] == 0) continue;
      // Row block of va: its rows start at row_ptr[3 i], i the movable index of va; the
      // block's first column within each of the 3 rows is 3 * position.
      const std::size_t i =
          static_cast<std::size_t>(std::lower_bound(s.vertex.begin(), s.vertex.end(), va) - s.vertex.begin());
      for (int c = 0; c < 4; ++c) {
        if (blk[4 * a + c] < 0) continue;
        for (int d = 0; d < 3; ++d) {
          PetscScalar* row = &s.val[s.row_ptr[3 * i + d] + 3 * blk[4 * a + c]];
          for (int e = 0; e < 3; ++e) row[e] += k_coef * K[12 * (3 * a + d) + 3 * c + e];
        }
      }
    }
  }
  for (std::size_t i = 0; i < s.vertex.size(); ++i) {
    const double m = (1 + dt * s.alpha) * w.mass[s.vertex[i]];
    for (int d = 0; d < 3; ++d) s.val[s.row_ptr[3 * i + d] + 3 * s.diag[i] + d] += m;
  }
}

void ImplicitEuler::step(World& w, const Simulation& sim, const std::vector<double>& f) {
  const double dt = sim.dt;
  // Matrix values in our arrays, in parallel over objects (each object's own arrays, its
  // tets summed in order: deterministic); PETSc then solves object after object.
  const std::ptrdiff_t ns = static_cast<std::ptrdiff_t>(systems_.size());
#pragma omp parallel for schedule(dynamic) if (ns > 1)
  for (std::ptrdiff_t k = 0; k < ns; ++k) {
    System& s = *systems_[k];
    if (s.constant && s.assembled_dt == dt) continue;
    assemble(s, w, dt);
  }
  last_iterations_ = 0;
  for (const auto& sp : systems_) {
    System& s = *sp;
    if (!(s.constant && s.assembled_dt == dt)) {
      // The matrix wraps our value array: tell PETSc its values changed, so that the
      // preconditioner is rebuilt (getting and restoring the array does exactly that).
      PetscScalar* a = nullptr;
      check(MatSeqAIJGetArray(s.A, &a), "MatSeqAIJGetArray");
      check(MatSeqAIJRestoreArray(s.A, &a), "MatSeqAIJRestoreArray");
      s.assembled_dt = dt;
    }
    // b and x wrap rhs and sol; writing through Get/RestoreArray tells PETSc that their
    // values changed.
    PetscScalar *rhs = nullptr, *sol = nullptr;
    check(VecGetArray(s.b, &rhs), "VecGetArray");
    check(VecGetArray(s.x, &sol), "VecGetArray");
    for (std::size_t i = 0; i < s.vertex.size(); ++i) {
      const std::size_t v = s.vertex[i];
      for (int d = 0; d < 3; ++d) {
        rhs[3 * i + d] = w.mass[v] * w.v[3 * v + d] + dt * f[3 * v + d];
        sol[3 * i + d] = w.v[3 * v + d];  // initial guess v^t
      }
    }
    check(VecRestoreArray(s.b, &rhs), "VecRestoreArray");
    check(VecRestoreArray(s.x, &sol), "VecRestoreArray");
    // A solve that fails (PETSc error or divergence) leaves the object where it was and
    // is recorded, not thrown: only this rank knows, and the others may be in a
    // collective call. The run loop's per-step reduction stops every rank together
    // (Simulator::local_health, docs/reliability.md). PETSc's own error printing is off
    // meanwhile: the message is ours.
    PetscPushErrorHandler(PetscReturnErrorHandler, nullptr);
    const PetscErrorCode ierr = KSPSolve(s.ksp, s.b, s.x);
    PetscPopErrorHandler();
    KSPConvergedReason reason = KSP_CONVERGED_ITERATING;
    PetscInt its = 0;
    KSPGetConvergedReason(s.ksp, &reason);
    KSPGetIterationNumber(s.ksp, &its);
    last_iterations_ += its;
    s.failed = ierr != 0 || reason < 0;
    if (s.failed && failed_object_ < 0) {
      PetscReal rtol = 0, abstol = 0, dtol = 0;
      PetscInt maxits = 0;
      KSPGetTolerances(s.ksp, &rtol, &abstol, &dtol, &maxits);
      // The true relative residual |b - A x| / |b| of where the solve stopped (KSP's own
      // norm is the preconditioned one).
      PetscReal bnorm = 0, rnorm = 0;
      Vec r = nullptr;
      VecNorm(s.b, NORM_2, &bnorm);
      if (VecDuplicate(s.b, &r) == 0) {
        MatMult(s.A, s.x, r);
        VecAYPX(r, -1.0, s.b);
        VecNorm(r, NORM_2, &rnorm);
        VecDestroy(&r);
      }
      std::ostringstream m;
      m.precision(3);
      m << "the implicit Euler solve of object '" << s.name << "' did not converge: ";
      if (ierr != 0) {
        const char* text = nullptr;
        PetscErrorMessage(ierr, &text, nullptr);
        m << "PETSc error " << static_cast<int>(ierr);
        if (text) m << " (" << text << ")";
        m << " in KSPSolve";
        if (reason < 0) m << ", ";
      }
      if (reason < 0) m << KSPConvergedReasons[reason];
      m << " after " << its << " of at most " << maxits << " iterations, relative residual "
        << (bnorm > 0 ? rnorm / bnorm : rnorm) << " (tolerance " << rtol << ")";
      failed_object_ = s.object;
      failure_ = m.str();
    }
  }
  // x_prev = x^t, and the new state for movable vertices; kinematic vertices stay.
  w.x_prev.assign(w.x.begin(), w.x.end());
  for (const auto& sp : systems_) {
    const System& s = *sp;
    if (s.failed) continue;  // stays at x^t, v^t
    const std::ptrdiff_t nv = static_cast<std::ptrdiff_t>(s.vertex.size());
    for (std::ptrdiff_t i = 0; i < nv; ++i) {
      const std::size_t v = s.vertex[i];
      for (int d = 0; d < 3; ++d) {
        w.v[3 * v + d] = s.sol[3 * i + d];
        w.x[3 * v + d] += dt * s.sol[3 * i + d];
      }
    }
  }
}

}  // namespace softcontact
