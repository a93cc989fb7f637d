#pragma once
// Corotational linear FEM (Mueller et al. 2002 "Stable real-time deformations"; Mueller,
// Gross 2004 "Interactive virtual materials"): Hooke's law in a frame that rotates with
// the element, the rotation R taken from F (polar_decomposition.hpp; for inverted
// elements the rotation-variant SVD, which keeps R a proper rotation so that the force
// pushes the element back out).
//
//   S   = R^T F                                   (symmetric stretch)
//   Psi = mu |F - R|^2 + lambda/2 (tr S - 3)^2    [J/m^3]  (= the linear energy of the
//                                                  strain S - I)
//   P   = 2 mu (F - R) + lambda (tr S - 3) R      [Pa]
//
// P is the exact gradient of Psi: the terms from dR/dF vanish because R^T dR is skew and
// S symmetric (McAdams et al. 2011, "Efficient elasticity for character skinning with
// contact and collisions"). It equals the "warped stiffness" force R K0 (R^T x - X).
//
// Two derivatives:
//  - stress_derivative: the exact tangent, with dR = R [w]x, w = 2 (tr S I - S)^-1
//    axial(skew(R^T dF)) (from R^T dF = [w]x S + dS, McAdams et al. Sec. 4). Indefinite
//    under compression; used by the tests (finite differences) and the static solver.
//  - warped_stress_derivative: dP_w = R (mu (R^T dF + dF^T R) + lambda tr(R^T dF) I),
//    R held fixed: the stiffness warping of Mueller et al. 2002. Symmetric positive
//    semi-definite, so CG applies; it is what implicit Euler solves with and what
//    stiffness-proportional damping uses (-beta K_w v). It equals the exact tangent at
//    any rigidly rotated rest state.
// Damping stress beta R (mu (R^T Fdot + Fdot^T R) + lambda tr(R^T Fdot) I) = -beta K_w v.
#include "linear.hpp"
#include "material_law.hpp"
#include "polar_decomposition.hpp"

namespace softcontact::model {

struct CorotationalLaw {
  Lame lame;
  double beta = 0;  ///< Rayleigh stiffness-proportional damping [s]

  /// P from F and its rotation R (shared with the block kernel).
  template <class T>
  static M3<T> stress_given_rotation(const Lame& l, const M3<T>& F, const M3<T>& R) {
    const T s = l.lambda * (ddot(R, F) - 3.0);  // tr(R^T F) = R : F
    M3<T> P;
    for (int k = 0; k < 9; ++k) P[k] = 2 * l.mu * (F[k] - R[k]) + s * R[k];
    return P;
  }

  /// R (mu (R^T G + G^T R) + lambda tr(R^T G) I): the warped linear stress of a rate or
  /// a variation G.
  template <class T>
  static M3<T> warped(const Lame& l, const M3<T>& R, const M3<T>& G) {
    return mul(R, LinearLaw::hooke(l, mul_tn(R, G)));
  }

  double energy(const Mat3& F) const {
    const Mat3 R = rotation_part(F);
    double d2 = 0;
    for (int k = 0; k < 9; ++k) d2 += (F[k] - R[k]) * (F[k] - R[k]);
    const double t = ddot(R, F) - 3;
    return lame.mu * d2 + 0.5 * lame.lambda * t * t;
  }

  Mat3 stress(const Mat3& F) const { return stress_given_rotation(lame, F, rotation_part(F)); }

  Mat9 stress_derivative(const Mat3& F) const {
    const Mat3 R = rotation_part(F);
    const Mat3 S = mul_tn(R, F);
    const double trs = trace(S);
    // (tr S I - S)^-1, symmetric; singular only when two signed singular values cancel
    // (a degenerate inversion), where dR is undefined.
    Mat3 A = scaled(S, -1);
    for (int d = 0; d < 3; ++d) A[4 * d] += trs;
    const Mat3 Ac = cofactor(A);
    const double inv_det = 1 / (A[0] * Ac[0] + A[3] * Ac[3] + A[6] * Ac[6]);
    const double ts = trs - 3;
    return derivative_matrix([&](const Mat3& dF) {
      const Mat3 M = mul_tn(R, dF);
      const double a[3] = {M[7] - M[5], M[2] - M[6], M[3] - M[1]};  // 2 axial(skew(M))
      double w[3];
      for (int i = 0; i < 3; ++i) w[i] = inv_det * (Ac[3 * i] * a[0] + Ac[3 * i + 1] * a[1] + Ac[3 * i + 2] * a[2]);
      const Mat3 W = {0, -w[2], w[1], w[2], 0, -w[0], -w[1], w[0], 0};
      const Mat3 dR = mul(R, W);
      const double tr_rdf = trace(M);
      Mat3 dP;
      for (int k = 0; k < 9; ++k)
        dP[k] = 2 * lame.mu * (dF[k] - dR[k]) + lame.lambda * (tr_rdf * R[k] + ts * dR[k]);
      return dP;
    });
  }

  Mat9 warped_stress_derivative(const Mat3& F) const {
    const Mat3 R = rotation_part(F);
    return derivative_matrix([&](const Mat3& dF) { return warped(lame, R, dF); });
  }

  Mat3 damping_stress(const Mat3& F, const Mat3& Fdot) const {
    return scaled(warped(lame, rotation_part(F), Fdot), beta);
  }
};

}  // namespace softcontact::model
