#pragma once
// Linear (small-strain) elasticity, the geometrically linear FEM model.
//
//   eps = sym(F) - I                        (infinitesimal strain, F = I + grad u)
//   Psi = mu eps:eps + lambda/2 tr(eps)^2   [J/m^3]
//   P   = 2 mu eps + lambda tr(eps) I       [Pa]  (= the Cauchy stress of Hooke's law)
//   dP  = mu (dF + dF^T) + lambda tr(dF) I  (constant: the stiffness matrix K does not
//                                            depend on x, so implicit Euler is exact)
//
// Not invariant under finite rotations: a rotated body feels spurious forces of order
// (angle)^2. Translations and infinitesimal rotations (skew grad u) give exactly zero.
// Damping: -beta K v exactly, i.e. the stress beta (mu (Fdot + Fdot^T) + lambda tr(Fdot) I).
#include "material_law.hpp"

namespace softcontact::model {

struct LinearLaw {
  Lame lame;
  double beta = 0;  ///< Rayleigh stiffness-proportional damping [s]

  /// mu (G + G^T) + lambda tr(G) I (Hooke's law on sym G).
  template <class T>
  static M3<T> hooke(const Lame& l, const M3<T>& g) {
    const T tr = trace(g);
    M3<T> s;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) s[3 * i + j] = l.mu * (g[3 * i + j] + g[3 * j + i]);
    for (int d = 0; d < 3; ++d) s[4 * d] += l.lambda * tr;
    return s;
  }

  double energy(const Mat3& F) const {
    Mat3 e = sym(F);
    for (int d = 0; d < 3; ++d) e[4 * d] -= 1;
    const double tr = trace(e);
    return lame.mu * ddot(e, e) + 0.5 * lame.lambda * tr * tr;
  }

  template <class T>
  M3<T> stress(const M3<T>& F) const {
    M3<T> g = F;
    for (int d = 0; d < 3; ++d) g[4 * d] -= 1.0;
    return hooke(lame, g);  // hooke() symmetrises: mu (G + G^T) = 2 mu sym(G)
  }

  Mat9 stress_derivative(const Mat3&) const {
    return derivative_matrix([&](const Mat3& dF) { return hooke(lame, dF); });
  }

  template <class T>
  M3<T> damping_stress(const M3<T>&, const M3<T>& Fdot) const {
    return scaled(hooke(lame, Fdot), beta);
  }
};

/// Stiffness (12,12) of Hooke's law on a tet of rest volume V with Dm^-1 = Di, V G^T C G
/// in closed form, block (a, b) for the shape-function gradients g (material_law.hpp):
///   K_ab = V (mu (g_a . g_b) I + mu g_b g_a^T + lambda g_a g_b^T).
/// The linear law's K at any x, and every FEM law's at rest (the stability limit).
inline void hooke_stiffness(const Lame& l, const Mat3& Di, double V, double K[144]) {
  double g[12];
  shape_gradients(Di, g);
  for (int a = 0; a < 4; ++a)
    for (int b = 0; b < 4; ++b) {
      const double* ga = g + 3 * a;
      const double* gb = g + 3 * b;
      const double gg = ga[0] * gb[0] + ga[1] * gb[1] + ga[2] * gb[2];
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          K[12 * (3 * a + i) + 3 * b + j] = V * ((i == j ? l.mu * gg : 0.0) + l.mu * gb[i] * ga[j] + l.lambda * ga[i] * gb[j]);
    }
}

}  // namespace softcontact::model
