#pragma once
// The per-tet force kernels: for a run [begin, end) of tets of one material, the corner
// forces (4,3) of each tet into `out`: chunk j (tets begin + j kLanes ...) at
// out + 12 kLanes j, as 12 vectors of kLanes lanes (vector 3a + d: component d of corner
// a). Each tet's result depends on that tet alone (no shared accumulator), which is what
// makes the assembly in forces.cpp independent of the thread count.
//
// Speed: tets go kLanes at a time through the laws, every quantity a vector of kLanes
// doubles (simd.hpp), i.e. structure of arrays across tets. Only the gather of corner
// positions and the scatter of corner forces touch single lanes. A chunk shorter than
// kLanes (the end of a run) repeats its last tet in the spare lanes; their results land
// in padding that nothing reads.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>

#include "corotational.hpp"
#include "mass_spring.hpp"
#include "material_law.hpp"
#include "simd.hpp"
#include "softcontact/mesh.hpp"

namespace softcontact::model {

/// Read-only view of the rest data (structure of arrays, forces.hpp).
struct TetView {
  const index_t* corner[4];
  const double* dm_inv[9];
  const double* volume;
  const double* inv_rest_length[6];
};

using VMat3 = M3<vdouble>;

inline Mat3 load_dm_inv(const TetView& T, std::size_t t) {
  Mat3 m;
  for (int k = 0; k < 9; ++k) m[k] = T.dm_inv[k][t];
  return m;
}

/// Ds(y) Dm^-1 for a per-vertex field y (n,3): F for positions, Fdot for velocities.
inline Mat3 gradient_at(const TetView& T, std::size_t t, const double* y, const Mat3& dm_inv) {
  return deformation_gradient(y + 3 * static_cast<std::size_t>(T.corner[0][t]),
                              y + 3 * static_cast<std::size_t>(T.corner[1][t]),
                              y + 3 * static_cast<std::size_t>(T.corner[2][t]),
                              y + 3 * static_cast<std::size_t>(T.corner[3][t]), dm_inv);
}

/// One chunk of n <= kLanes consecutive tets t0 .. t0+n-1.
struct Chunk {
  std::size_t t0 = 0;
  int n = 0;
  std::size_t vtx[4][kLanes];  ///< 3 * corner vertex index, per corner and lane
  VMat3 di;                    ///< Dm^-1
  vdouble vol;                 ///< rest volume

  Chunk() = default;
  Chunk(const TetView& T, std::size_t first, int count) : t0(first), n(count) {
    for (int l = 0; l < kLanes; ++l) {
      const std::size_t t = t0 + static_cast<std::size_t>(std::min(l, n - 1));
      for (int c = 0; c < 4; ++c) vtx[c][l] = 3 * static_cast<std::size_t>(T.corner[c][t]);
    }
    if (n == kLanes) {  // the common case: contiguous loads
      for (int k = 0; k < 9; ++k) di[k] = load_lanes(T.dm_inv[k] + t0);
      vol = load_lanes(T.volume + t0);
    } else {
      for (int l = 0; l < kLanes; ++l) {
        const std::size_t t = t0 + static_cast<std::size_t>(std::min(l, n - 1));
        for (int k = 0; k < 9; ++k) di[k][l] = T.dm_inv[k][t];
        vol[l] = T.volume[t];
      }
    }
  }

  /// Corner values of a per-vertex field y (n,3), c (4,3) per lane.
  void gather(const double* y, vdouble (&c)[12]) const {
    // Built as whole vectors (not lane by lane through memory, which would stall on
    // store forwarding when the vector is read back).
    static_assert(kLanes == 8, "the gather below spells out 8 lanes");
    for (int a = 0; a < 4; ++a)
      for (int i = 0; i < 3; ++i) {
        const std::size_t* q = vtx[a];
        c[3 * a + i] = vdouble{y[q[0] + i], y[q[1] + i], y[q[2] + i], y[q[3] + i],
                               y[q[4] + i], y[q[5] + i], y[q[6] + i], y[q[7] + i]};
      }
  }

  /// G = Ds(y) Dm^-1, the same arithmetic as deformation_gradient().
  VMat3 gradient(const double* y) const {
    vdouble c[12];
    gather(y, c);
    VMat3 ds;
    for (int i = 0; i < 3; ++i)
      for (int a = 1; a <= 3; ++a) ds[3 * i + (a - 1)] = c[3 * a + i] - c[i];
    return mul(ds, di);
  }

  /// Corner forces of the stress P, as corner_forces(): H = -V P Dm^-T.
  void store_forces(const VMat3& P, double* out) const {
    const VMat3 h = mul_nt(P, di);
    vdouble f[12];
    for (int a = 1; a <= 3; ++a)
      for (int d = 0; d < 3; ++d) f[3 * a + d] = -vol * h[3 * d + (a - 1)];
    for (int d = 0; d < 3; ++d) f[d] = -(f[3 + d] + f[6 + d] + f[9 + d]);
    store(f, out);
  }

  /// Stores the chunk's corner forces as 12 whole vectors: out (12, kLanes), component
  /// 3a + d of corner a, lane l (the layout forces.cpp gathers from).
  static void store(const vdouble (&f)[12], double* out) {
    for (int k = 0; k < 12; ++k) std::memcpy(out + k * kLanes, &f[k], sizeof(vdouble));
  }
};

/// Any law of the material_law.hpp interface (linear, StVK, neo-Hookean).
template <class Law, bool kDamp>
void law_block(const TetView& T, std::size_t begin, std::size_t end, const Law& law, const double* x,
               const double* v, double* out) {
  for (std::size_t t0 = begin; t0 < end; t0 += kLanes, out += 12 * kLanes) {
    const Chunk c(T, t0, static_cast<int>(std::min<std::size_t>(kLanes, end - t0)));
    const VMat3 F = c.gradient(x);
    VMat3 P = law.stress(F);
    if constexpr (kDamp) P = add(P, law.damping_stress(F, c.gradient(v)));
    c.store_forces(P, out);
  }
}

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

/// Mass-spring model in edge form (mass_spring.hpp): k_e = E V / L_e^2 per tet edge. With
/// the stored inverse rest length r = 1/L_e, the force on b is -s u with
/// s = k_e (l - L_e) / l = E V r (r - 1/l): one division and one square root per edge.
template <bool kDamp>
void spring_block(const TetView& T, std::size_t begin, std::size_t end, double young, double beta, const double* x,
                  const double* v, double* out) {
  for (std::size_t t0 = begin; t0 < end; t0 += kLanes, out += 12 * kLanes) {
    const Chunk c(T, t0, static_cast<int>(std::min<std::size_t>(kLanes, end - t0)));
    vdouble p[12], w[12], f[12];
    c.gather(x, p);
    if constexpr (kDamp) c.gather(v, w);
    for (int k = 0; k < 12; ++k) f[k] = broadcast(0.0);
    const vdouble ev = young * c.vol;
    for (int e = 0; e < 6; ++e) {
      const int a = kTetEdges[e][0], b = kTetEdges[e][1];
      vdouble r;
      if (c.n == kLanes) r = load_lanes(T.inv_rest_length[e] + t0);
      else
        for (int l = 0; l < kLanes; ++l) r[l] = T.inv_rest_length[e][t0 + static_cast<std::size_t>(std::min(l, c.n - 1))];
      vdouble u[3];
      for (int d = 0; d < 3; ++d) u[d] = p[3 * b + d] - p[3 * a + d];
      const vdouble inv_len = 1.0 / sqrt_lanes(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
      const vdouble evr = ev * r;
      vdouble s = evr * (r - inv_len);  // force on b is -s u
      if constexpr (kDamp) {
        const vdouble du = u[0] * (w[3 * b] - w[3 * a]) + u[1] * (w[3 * b + 1] - w[3 * a + 1]) +
                           u[2] * (w[3 * b + 2] - w[3 * a + 2]);
        s += beta * evr * r * du * inv_len * inv_len;
      }
      for (int d = 0; d < 3; ++d) {
        f[3 * b + d] -= s * u[d];
        f[3 * a + d] += s * u[d];
      }
    }
    c.store(f, out);
  }
}

/// Spring energy of one tet: sum_e k_e/2 (l_e - L_e)^2 = E V/2 sum_e (l_e / L_e - 1)^2.
inline double spring_energy(const TetView& T, std::size_t t, double young, const double* x) {
  double s = 0;
  for (int e = 0; e < 6; ++e) {
    const std::size_t ia = 3 * static_cast<std::size_t>(T.corner[kTetEdges[e][0]][t]);
    const std::size_t ib = 3 * static_cast<std::size_t>(T.corner[kTetEdges[e][1]][t]);
    const double l = std::sqrt((x[ib] - x[ia]) * (x[ib] - x[ia]) + (x[ib + 1] - x[ia + 1]) * (x[ib + 1] - x[ia + 1]) +
                               (x[ib + 2] - x[ia + 2]) * (x[ib + 2] - x[ia + 2]));
    const double q = l * T.inv_rest_length[e][t] - 1;  // strain of the spring
    s += q * q;
  }
  return 0.5 * young * T.volume[t] * s;
}

}  // namespace softcontact::model
