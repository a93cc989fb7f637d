#pragma once
// The per-tet force kernels: for a run [begin, end) of tets of one material, the corner
// forces (4,3) of each tet into `out`: chunk j (tets begin + j kLanes ...) at
// out + 12 kLanes j, as 12 vectors of kLanes lanes (vector 3a + d: component d of corner
// a). Each tet's result depends on that tet alone (no shared accumulator), which is what
// makes the assembly in forces.cpp independent of the thread count.
//
// Each law registers one block kernel (material_registry.hpp), defined in its own file:
// law_block below for a law that is only "stress of F" (linear, StVK, neo-Hookean), a
// kernel of its own otherwise (corotational.cpp, mass_spring.cpp).
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

#include "material_law.hpp"
#include "simd.hpp"
#include "softcontact/mesh.hpp"

/// The attributes of a block kernel: compiled for AVX-512, AVX2 and the x86-64 baseline
/// (the loader picks the best the processor has), with everything it calls inlined into
/// it (flatten), so that the lane vectors never cross a call between instruction sets.
/// The file that defines it must begin, before any include, with
///   #pragma GCC optimize("fp-contract=off", "no-math-errno")
/// so that no variant contracts into fused multiply-adds: all then round exactly alike.
/// clang refuses target_clones with flatten; its only build, the fuzz harnesses
/// (tests/fuzz, which reach the registry through the scene parser), gets the baseline.
#if defined(__clang__)
#define SOFTCONTACT_BLOCK_KERNEL __attribute__((flatten))
#else
#define SOFTCONTACT_BLOCK_KERNEL __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default"), flatten))
#endif

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

}  // namespace softcontact::model
