#pragma once
// Stable neo-Hookean (Smith, de Goes, Kim 2018, "Stable Neo-Hookean Flesh Simulation",
// ACM TOG 37(2), eq. 14 with the log term of their Sec. 3.4):
//
//   Psi = mu'/2 (I_C - 3) + lambda'/2 (J - a)^2 - mu'/2 log(I_C + 1) - Psi0   [J/m^3]
//   P   = mu' (1 - 1/(I_C + 1)) F + lambda' (J - a) cof(F)                   [Pa]
//
// with I_C = |F|^2, J = det F, cof(F) = dJ/dF = J F^-T, and
//   mu' = 4/3 mu,  lambda' = lambda + 5/6 mu,  a = 1 + 3 mu' / (4 lambda')
// (Smith et al., Sec. 3.4 and 4: a makes P(I) = 0; mu', lambda' make the linearisation
// at F = I equal Hooke's law with the material's Lame parameters mu, lambda). Psi0 is
// the value of the first three terms at F = I, subtracted so that the rest state has
// zero energy (it does not change any force). lambda' > 0 for every Poisson ratio in
// (-1, 0.5), so the model is defined for all valid materials.
//
// Unlike StVK, the energy does not soften under compression, and it stays finite and
// smooth through inversion (J < 0): at J = 0 the volume term's force lambda' a cof(F)
// points towards J > 0, so inverted elements are pushed back out, with no
// special-casing and no singular value decomposition. It is no barrier (nothing grows
// without bound as J -> 0, unlike the classical log J form): a large enough load holds
// an element inverted.
//
//   dP = mu'(1 - 1/(I_C+1)) dF + 2 mu' (F:dF) / (I_C+1)^2 F
//        + lambda' (cof(F):dF) cof(F) + lambda' (J - a) dcof(F)[dF]
//
// Damping: the Green-strain-rate form of StVK (stvk.hpp) with the material's Lame
// parameters; it vanishes for rigid motions and equals -beta K v at rest.
#include <cmath>

#include "material_law.hpp"
#include "stvk.hpp"

namespace softcontact::model {

struct NeoHookeanLaw {
  Lame lame;        ///< the material's Lame parameters (small-strain behaviour)
  double beta = 0;  ///< Rayleigh stiffness-proportional damping [s]
  double mu_s = 0, lambda_s = 0, alpha = 1, psi0 = 0;

  NeoHookeanLaw() = default;
  NeoHookeanLaw(const Lame& l, double beta_) : lame(l), beta(beta_) {
    mu_s = 4.0 / 3.0 * l.mu;
    lambda_s = l.lambda + 5.0 / 6.0 * l.mu;
    alpha = 1 + 0.75 * mu_s / lambda_s;
    psi0 = 0.5 * lambda_s * (1 - alpha) * (1 - alpha) - 0.5 * mu_s * std::log(4.0);
  }

  double energy(const Mat3& F) const {
    const double ic = ddot(F, F), j = det(F);
    return 0.5 * mu_s * (ic - 3) + 0.5 * lambda_s * (j - alpha) * (j - alpha) - 0.5 * mu_s * std::log(ic + 1) - psi0;
  }

  template <class T>
  M3<T> stress(const M3<T>& F) const {
    const T ic = ddot(F, F);
    const M3<T> c = cofactor(F);
    const T j = det_from_cofactor(F, c);
    const T a = mu_s * (1.0 - 1.0 / (ic + 1.0)), b = lambda_s * (j - alpha);
    M3<T> P;
    for (int k = 0; k < 9; ++k) P[k] = a * F[k] + b * c[k];
    return P;
  }

  Mat9 stress_derivative(const Mat3& F) const {
    const double ic = ddot(F, F), j = det(F);
    const Mat3 c = cofactor(F);
    const double a = mu_s * (1 - 1 / (ic + 1)), b = 2 * mu_s / ((ic + 1) * (ic + 1));
    return derivative_matrix([&](const Mat3& dF) {
      const Mat3 dc = cofactor_derivative(F, dF);
      const double fd = ddot(F, dF), cd = ddot(c, dF);
      Mat3 dP;
      for (int k = 0; k < 9; ++k)
        dP[k] = a * dF[k] + b * fd * F[k] + lambda_s * cd * c[k] + lambda_s * (j - alpha) * dc[k];
      return dP;
    });
  }

  template <class T>
  M3<T> damping_stress(const M3<T>& F, const M3<T>& Fdot) const {
    return green_rate_damping(lame, beta, F, Fdot);
  }
};

}  // namespace softcontact::model
