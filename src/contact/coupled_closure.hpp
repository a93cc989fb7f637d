#pragma once
// Coupled closure of the contact gaps (scene key `simulation.contact_closure: coupled`;
// docs/contact.md, "Coupled closure"). The per-collision closed form (contact.hpp)
// closes an isolated collision exactly and splits a shared vertex by the pushes on it
// (Jacobi-style shares), which under-closes the deeper of unequal collisions on a shared
// face and a point squeezed between two bodies. Here the magnitudes of all collisions
// are chosen together so that every gap closes by its applied depth when all
// corrections act at once:
//
//   A x = |d|,   A_qr = sum over the vertices v that q and r share of b_qv b_rv (n_q . n_r) / m_v
//
// x_q is collision q's correction (dt^2 / m_eff times its force magnitude), n_q its unit
// direction, b_qv its coefficient on v (the point side's weights pw and 1 - pw, -omega_j
// for the triangle's vertices): A is the Delassus operator of the collisions along their
// normals, symmetric positive semi-definite and block diagonal over the groups of
// collisions that share movable vertices. A group of one collision takes the closed form
// itself, x = |d| / A_qq (the isolated closure, exact). A larger group is solved with one
// LDL^T factorisation of A + eps diag(A): a compliance of eps relative to each
// collision's own stiffness, which leaves a gap of eps A_qq x_q (0.1 % of the depth with
// eps = 1e-3) and keeps ill-conditioned groups from asking for huge opposite
// corrections. Solving A itself to rounding (eps = 1e-8 and two steps of iterative
// refinement, tried) threw chess500's vertices at 95 m/s (a numerical failure at t =
// 0.30 s): corrections that nearly cancel on a squeezed point, each with its own dynamic
// fraction, do not cancel in the velocities. A collision whose x comes out negative would
// pull the bodies together; it is dropped (x = 0) and the rest of its group solved again,
// at most kMaxPasses solves per group; anything still negative after that is clamped to
// 0. A solve without some rows replaces their rows and columns by the identity's and
// factorises again numerically with the first ordering (a sparse group keeps its AMD
// ordering and symbolic factorisation). The groups are solved in parallel (OpenMP, the
// largest first); each writes only its own rows, so the result does not depend on the
// thread count.
//
// A singular A with an inconsistent right-hand side (a point squeezed between two fixed
// bodies, which no pushing forces can free) shows as rows whose gap the refined solution
// does not close (|A x - d| above kResidual |d|; x grows like 1 / eps there). Those rows
// are returned as NaN, the caller keeps its per-collision closed form for them, and the
// rest is solved again without them. Ill-conditioned but consistent rows are kept: a
// point squeezed between two free bodies needs 4 times its isolated closure
// (test_coupled_closure.cpp), and a cut-off at 10 times the isolated closure, tried
// first, left a tori200 vertex standing 0.039 h deep for 2 s.
//
// The velocity part stays the caller's: the dynamic fraction of each collision measured
// against what the corrections of all collisions close of its gap (contact.hpp). A
// second solve with the approaches on the right (tried) left a resting box 1 % short of
// its weight and moving at 1 cm/s (ContactPhysics tests).
//
// The rows are identified by global vertex ids and ordered by their collisions' keys,
// so that one rank, or the rank that gathers every rank's rows, builds the same matrix
// with the same arithmetic: the result does not depend on the rank or thread count.
#include <cstdint>
#include <vector>

#include "softcontact/world.hpp"

namespace softcontact::contact {

/// One collision's row. Entries with b = 0 or inverse mass 0 are left out by the solver.
struct ClosureRow {
  gid_t key_point = -1, key_triangle = -1;  ///< the collision's key (its order)
  double n[3] = {0, 0, 0};                  ///< unit direction of d
  double depth = 0;                         ///< the gap to close [m]; 0: no force
  std::int64_t nv = 0;                      ///< entries used (64 bits: no padding in the bytes sent)
  gid_t vertex[5] = {-1, -1, -1, -1, -1};   ///< global vertex ids: point, triangle (3), point2
  double b[5] = {0, 0, 0, 0, 0};
  double inv_mass[5] = {0, 0, 0, 0, 0};
};

struct ClosureStats {
  std::int64_t rows = 0;       ///< collisions with a gap and a movable vertex
  std::int64_t dropped = 0;    ///< collisions that would have pulled (x < 0), given no force
  std::int64_t local = 0;      ///< collisions returned as NaN (their gap cannot be closed: inconsistent rows)
  std::int64_t passes = 0;     ///< numeric factorisations (over all groups of more than one collision)
  bool failed = false;         ///< the factorisation failed: x is the isolated closure |d| / A_qq
};

constexpr int kMaxPasses = 4;
constexpr double kResidual = 0.1;
/// Groups up to this many collisions are solved as dense matrices (LDL^T with pivoting),
/// larger ones as sparse (Eigen's SimplicialLDLT, AMD ordering).
constexpr int kDenseRows = 48;

/// x per row (same order), the correction along n [m] that closes the depths (NaN: keep
/// the closed form of the collision alone). `rows` must be sorted by key. eps: the
/// relative regularisation of the diagonal.
std::vector<double> solve_closure(const std::vector<ClosureRow>& rows, double eps, ClosureStats& stats);

}  // namespace softcontact::contact
