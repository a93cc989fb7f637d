// The corotational law's registry entry (corotational.hpp, material_registry.hpp): its own
// block kernel, which computes each tet's rotation once for stress and damping; for
// implicit Euler the warped stiffness R K0 R^T (symmetric positive semi-definite), else
// the exact tangent.
//
// forces.cpp's pragmas, before any include (the headers' inline functions need them too):
// the kernel is cloned per instruction set, and every clone must round alike.
#pragma GCC optimize("fp-contract=off", "no-math-errno")
#pragma GCC diagnostic ignored "-Wpsabi"

#include "corotational.hpp"
#include "polar_decomposition.hpp"
#include "stress_law.hpp"

namespace softcontact::model {

namespace {

/// Rotations of C chunks' F (polar_decomposition.hpp): Newton's iteration on all lanes at
/// once, each lane frozen as soon as it has converged (so that its result is exactly that
/// of polar_newton, whatever its neighbours do), until all lanes have converged or
/// kPolarMaxIterations; then the rotation-variant SVD for the lanes that are inverted,
/// flat or not converged. Several chunks at once give the processor independent chains
/// of work to overlap: one Newton step is a chain of dependent operations (cofactors,
/// determinant, division) whose latency one chunk alone cannot hide.
template <int C>
inline void rotation_lanes(const VMat3 (&F)[C], const int (&n)[C], VMat3 (&X)[C]) {
  vmask ok[C], done[C];
  for (int c = 0; c < C; ++c) {
    ok[c] = det(F[c]) > broadcast(0.0);  // Newton would converge to a reflection otherwise
    done[c] = ~ok[c];
    X[c] = F[c];
  }
  const vdouble tol2 = broadcast(kPolarTolerance * kPolarTolerance);
  // One Newton step on chunk c (same arithmetic as polar_newton_step, lane-wise); frozen
  // lanes keep their value. Returns the squared size of the update.
  auto newton = [&](int c) {
    const VMat3 cof = cofactor(X[c]);
    const vdouble h = 0.5 / det_from_cofactor(X[c], cof);
    vdouble upd = broadcast(0.0);
    for (int k = 0; k < 9; ++k) {
      const vdouble d = h * cof[k] - 0.5 * X[c][k];
      X[c][k] = done[c] ? X[c][k] : X[c][k] + d;
      upd += d * d;
    }
    return upd;
  };
  // polar_newton tests convergence from the second step on.
  for (int c = 0; c < C; ++c) newton(c);
  for (int it = 1; it < kPolarMaxIterations; ++it) {
    bool all = true;
    for (int c = 0; c < C; ++c) {
      done[c] |= newton(c) <= tol2;
      long long d = done[c][0];
      for (int l = 1; l < kLanes; ++l) d &= done[c][l];
      all = all && d != 0;
    }
    if (all) break;
  }
  for (int c = 0; c < C; ++c)
    for (int l = 0; l < n[c]; ++l) {
      if (ok[c][l] != 0 && done[c][l] != 0) continue;
      Mat3 f;
      for (int k = 0; k < 9; ++k) f[k] = F[c][k][l];
      const Mat3 r = rotation_from_svd(f);
      for (int k = 0; k < 9; ++k) X[c][k][l] = r[k];
    }
}

/// Corotational model (corotational.hpp), two chunks at a time (see rotation_lanes); R
/// is computed once for stress and damping.
template <bool kDamp>
void corotational_block(const TetView& T, std::size_t begin, std::size_t end, const Lame& lame, double beta,
                        const double* x, const double* v, double* out) {
  constexpr int C = 2;
  for (std::size_t t0 = begin; t0 < end; t0 += C * kLanes, out += C * 12 * kLanes) {
    // Chunks past the end repeat the first one (computed, not stored).
    Chunk ch[C];
    int n[C];
    for (int c = 0; c < C; ++c) {
      const std::size_t tc = t0 + static_cast<std::size_t>(c) * kLanes;
      n[c] = tc < end ? static_cast<int>(std::min<std::size_t>(kLanes, end - tc)) : 0;
      ch[c] = n[c] > 0 ? Chunk(T, tc, n[c]) : ch[0];
    }
    VMat3 F[C], R[C];
    for (int c = 0; c < C; ++c) F[c] = ch[c].gradient(x);
    rotation_lanes(F, n, R);
    for (int c = 0; c < C && n[c] > 0; ++c) {
      VMat3 P = CorotationalLaw::stress_given_rotation(lame, F[c], R[c]);
      if constexpr (kDamp) P = add(P, scaled(CorotationalLaw::warped(lame, R[c], ch[c].gradient(v)), beta));
      ch[c].store_forces(P, out + c * 12 * kLanes);
    }
  }
}

SOFTCONTACT_BLOCK_KERNEL
void forces(const TetView& T, std::size_t begin, std::size_t end, const LawParams& p, bool damp, const double* x,
            const double* v, double* out) {
  if (damp) corotational_block<true>(T, begin, end, p.lame, p.beta, x, v, out);
  else corotational_block<false>(T, begin, end, p.lame, p.beta, x, v, out);
}

double energy(const TetView& T, std::size_t t, const LawParams& p, const double*, const Mat3& F) {
  return T.volume[t] * CorotationalLaw{p.lame, 0}.energy(F);
}

void stiffness(const LawParams& p, const Mat3& Di, double V, const Mat3& F, StiffnessKind kind, double K[144]) {
  if (kind == StiffnessKind::exact) {
    element_stiffness(CorotationalLaw{p.lame, 0}.stress_derivative(F), Di, V, K);
    return;
  }
  // Warped: Hooke's blocks K_ab rotated to R K_ab R^T.
  hooke_stiffness(p.lame, Di, V, K);
  const Mat3 R = rotation_part(F);
  for (int a = 0; a < 4; ++a)
    for (int b = 0; b < 4; ++b) {
      Mat3 k;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) k[3 * i + j] = K[12 * (3 * a + i) + 3 * b + j];
      k = mul_nt(mul(R, k), R);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) K[12 * (3 * a + i) + 3 * b + j] = k[3 * i + j];
    }
}

}  // namespace

extern const MaterialLaw corotational_law = {.block_forces = forces,
                                             .energy = energy,
                                             .stiffness = stiffness,
                                             .rest_stiffness = hooke_rest_stiffness,
                                             .implicit = true};

}  // namespace softcontact::model
