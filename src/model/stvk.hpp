#pragma once
// St. Venant-Kirchhoff: Hooke's law on the Green-Lagrange strain, the non-linear FEM
// model of the paper (its Sec. 5 experiments with "Green-Lagrange strain").
//
//   E   = (F^T F - I) / 2                    (Green-Lagrange strain)
//   S   = 2 mu E + lambda tr(E) I            (second Piola-Kirchhoff stress)
//   Psi = mu E:E + lambda/2 tr(E)^2          [J/m^3]
//   P   = F S                                [Pa]
//   dP  = dF S + F (2 mu dE + lambda tr(dE) I),  dE = sym(F^T dF)
//
// Invariant under any rotation (E only sees F^T F). Known weakness: under strong
// compression the energy turns soft and an element can invert and stay inverted; the
// inverted-element count in the diagnostics shows it.
// Damping (Kelvin-Voigt on the Green strain rate): P_d = beta F (2 mu Edot + lambda
// tr(Edot) I), Edot = sym(F^T Fdot). It vanishes for every rigid motion, dissipates
// (P_d : Fdot = beta (2 mu Edot:Edot + lambda tr(Edot)^2) >= 0) and equals -beta K v at
// the rest state.
#include "material_law.hpp"

namespace softcontact::model {

/// F (2 mu E + lambda tr(E) I), shared by StVK and the Green-rate damping of the
/// non-linear laws.
template <class T>
inline M3<T> green_stress(const Lame& l, const M3<T>& F, const M3<T>& E) {
  M3<T> S = scaled(E, 2 * l.mu);
  const T tr = trace(E);
  for (int d = 0; d < 3; ++d) S[4 * d] += l.lambda * tr;
  return mul(F, S);
}

/// Stiffness-proportional damping stress from the Green strain rate (see above).
template <class T>
inline M3<T> green_rate_damping(const Lame& l, double beta, const M3<T>& F, const M3<T>& Fdot) {
  return scaled(green_stress(l, F, sym(mul_tn(F, Fdot))), beta);
}

struct StvkLaw {
  Lame lame;
  double beta = 0;  ///< Rayleigh stiffness-proportional damping [s]

  template <class T>
  static M3<T> green_strain(const M3<T>& F) {
    M3<T> E = mul_tn(F, F);
    for (int k = 0; k < 9; ++k) E[k] *= 0.5;
    for (int d = 0; d < 3; ++d) E[4 * d] -= 0.5;
    return E;
  }

  double energy(const Mat3& F) const {
    const Mat3 E = green_strain(F);
    const double tr = trace(E);
    return lame.mu * ddot(E, E) + 0.5 * lame.lambda * tr * tr;
  }

  template <class T>
  M3<T> stress(const M3<T>& F) const {
    return green_stress(lame, F, green_strain(F));
  }

  Mat9 stress_derivative(const Mat3& F) const {
    const Mat3 E = green_strain(F);
    Mat3 S = scaled(E, 2 * lame.mu);
    const double tr = trace(E);
    for (int d = 0; d < 3; ++d) S[4 * d] += lame.lambda * tr;
    return derivative_matrix([&](const Mat3& dF) {
      const Mat3 dE = sym(mul_tn(F, dF));
      Mat3 dS = scaled(dE, 2 * lame.mu);
      const double dtr = trace(dE);
      for (int d = 0; d < 3; ++d) dS[4 * d] += lame.lambda * dtr;
      return add(mul(dF, S), mul(F, dS));
    });
  }

  template <class T>
  M3<T> damping_stress(const M3<T>& F, const M3<T>& Fdot) const {
    return green_rate_damping(lame, beta, F, Fdot);
  }
};

}  // namespace softcontact::model
