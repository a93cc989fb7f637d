#pragma once
// Mass-spring network on the mesh edges, written as a per-tet energy.
//
// Each tet of rest volume V holds a spring on each of its six edges e = (a, b), with rest
// length L_e and stiffness
//
//   k_e = E V / L_e^2                                                  [N/m]
//
// An edge shared by several tets is one spring whose stiffness is the sum of theirs.
// Energy and forces per tet:
//   U_T = sum_e k_e/2 (l_e - L_e)^2,   l_e = |x_b - x_a|
//   f_b = -k_e (l_e - L_e) (x_b - x_a) / l_e = -f_a
// The same energy as a density of F (the law interface), with the unit rest edge
// directions d_e = (X_b - X_a) / L_e, since F d_e = (x_b - x_a) / L_e:
//   Psi = E/2 sum_e (|F d_e| - 1)^2                                     [J/m^3]
//   P   = E sum_e (1 - 1/|F d_e|) (F d_e) d_e^T                         [Pa]
//   dP  = E sum_e [(1 - 1/n) dF d d^T + ((F d) . (dF d)) / n^3 (F d) d^T],  n = |F d|
//
// Why k_e = E V / L_e^2 (derivation in docs/models.md): under a uniform small strain eps
// the tet's springs store V/2 sum_e E (d_e^T eps d_e)^2, i.e. the elasticity tensor
// C = E sum_e d_e (x) d_e (x) d_e (x) d_e. C has the symmetry of the tet (no tet gives an
// isotropic network), but its isotropic part, the average over all orientations, depends
// only on the number of edges and not on the tet's shape: lambda = mu = 2E/5, Young's
// modulus exactly E and Poisson ratio 1/4 (the only one a central-force network can have:
// the Cauchy relations). On the box primitive's Kuhn cells the lattice is cubic, with a
// modulus of 1.355 E along a cell axis. The material's Poisson ratio is not used.
//
// Damping: each spring resists its rate of stretch, f_b = -beta k_e (u . (v_b - v_a)) u
// / l^2 (u = x_b - x_a), i.e. P_d = beta E sum_e ((F d) . (Fdot d)) / n^2 (F d) d^T: zero
// for rigid motions, -beta K v at rest.
#include <array>
#include <cmath>

#include "material_law.hpp"
#include "softcontact/mesh.hpp"

namespace softcontact::model {

struct MassSpringLaw {
  double young = 0;  ///< E [Pa]
  double beta = 0;   ///< Rayleigh stiffness-proportional damping [s]
  std::array<std::array<double, 3>, 6> d{};  ///< unit rest edge directions d_e

  /// The law of one tet, from its rest corners X (4,3).
  static MassSpringLaw from_rest(double young, double beta, const double X[12]) {
    MassSpringLaw law;
    law.young = young;
    law.beta = beta;
    for (int e = 0; e < 6; ++e) {
      const int a = kTetEdges[e][0], b = kTetEdges[e][1];
      double u[3], l = 0;
      for (int k = 0; k < 3; ++k) {
        u[k] = X[3 * b + k] - X[3 * a + k];
        l += u[k] * u[k];
      }
      l = std::sqrt(l);
      for (int k = 0; k < 3; ++k) law.d[e][k] = u[k] / l;
    }
    return law;
  }

  /// F d_e and its length.
  std::array<double, 3> stretched(const Mat3& F, int e, double& n) const {
    const auto& v = d[e];
    const std::array<double, 3> a = {F[0] * v[0] + F[1] * v[1] + F[2] * v[2], F[3] * v[0] + F[4] * v[1] + F[5] * v[2],
                                     F[6] * v[0] + F[7] * v[1] + F[8] * v[2]};
    n = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    return a;
  }

  double energy(const Mat3& F) const {
    double s = 0;
    for (int e = 0; e < 6; ++e) {
      double n;
      stretched(F, e, n);
      s += (n - 1) * (n - 1);
    }
    return 0.5 * young * s;
  }

  Mat3 stress(const Mat3& F) const {
    Mat3 P{};
    for (int e = 0; e < 6; ++e) {
      double n;
      const auto a = stretched(F, e, n);
      const double c = young * (1 - 1 / n);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) P[3 * i + j] += c * a[i] * d[e][j];
    }
    return P;
  }

  Mat9 stress_derivative(const Mat3& F) const {
    return derivative_matrix([&](const Mat3& dF) {
      Mat3 dP{};
      for (int e = 0; e < 6; ++e) {
        double n;
        const auto a = stretched(F, e, n);
        const auto& v = d[e];
        const double da[3] = {dF[0] * v[0] + dF[1] * v[1] + dF[2] * v[2], dF[3] * v[0] + dF[4] * v[1] + dF[5] * v[2],
                              dF[6] * v[0] + dF[7] * v[1] + dF[8] * v[2]};
        const double c = 1 - 1 / n, q = (a[0] * da[0] + a[1] * da[1] + a[2] * da[2]) / (n * n * n);
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) dP[3 * i + j] += young * (c * da[i] + q * a[i]) * v[j];
      }
      return dP;
    });
  }

  Mat3 damping_stress(const Mat3& F, const Mat3& Fdot) const {
    Mat3 P{};
    for (int e = 0; e < 6; ++e) {
      double n;
      const auto a = stretched(F, e, n);
      const auto& v = d[e];
      const double r[3] = {Fdot[0] * v[0] + Fdot[1] * v[1] + Fdot[2] * v[2],
                           Fdot[3] * v[0] + Fdot[4] * v[1] + Fdot[5] * v[2],
                           Fdot[6] * v[0] + Fdot[7] * v[1] + Fdot[8] * v[2]};
      const double c = beta * young * (a[0] * r[0] + a[1] * r[1] + a[2] * r[2]) / (n * n);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) P[3 * i + j] += c * a[i] * v[j];
    }
    return P;
  }
};

}  // namespace softcontact::model
