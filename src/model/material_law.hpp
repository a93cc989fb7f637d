#pragma once
// The interface every deformation model implements (style.md: material laws behind a
// tiny interface, separate from the loop over tetrahedra, after MFEM's
// HyperelasticModel::EvalW/EvalP), and the linear-tetrahedron kinematics they share.
//
// A law is a small value type with these const member functions of the deformation
// gradient F (dimensionless, row-major 3x3, see mat3.hpp):
//
//   double energy(const Mat3& F)              strain energy density Psi(F)      [J/m^3]
//   M3<T>  stress(const M3<T>& F)             first Piola-Kirchhoff P = dPsi/dF [Pa]
//   Mat9   stress_derivative(const Mat3& F)   dP/dF (tangent of stress)         [Pa]
//   M3<T>  damping_stress(const M3<T>& F, const M3<T>& Fdot)
//                                             stiffness-proportional Rayleigh damping
//                                             stress for the rate dF/dt = Fdot, with
//                                             beta folded in; 0 for rigid motions  [Pa]
//
// stress and damping_stress are templates over the element type T: double, or a vector
// of kLanes doubles (simd.hpp) that carries kLanes tets at once through the same code.
//
// Every law satisfies Psi(I) = 0 and P(I) = 0, and linearises at F = I to isotropic
// small-strain elasticity with the material's Lame parameters (mass-spring: lambda =
// mu = 2E/5 for the isotropic part, docs/models.md). Laws whose kernel is more than
// "stress of F" (corotational: its polar decomposition; mass-spring: edge form) have a
// block kernel of their own in their file (corotational.cpp, mass_spring.cpp), and tests
// check it against the law. What the rest of the code gets from a law (kernel, energy,
// stiffness, ...) is its registry entry: material_registry.hpp.
//
// Linear tetrahedron (rest corners X0..X3, current x0..x3):
//   Dm = [X1-X0, X2-X0, X3-X0],  Ds = [x1-x0, x2-x0, x3-x0],  F = Ds Dm^-1 (constant
//   in the tet), energy V Psi(F) with the rest volume V = det(Dm) / 6, and corner forces
//   f_a = -dE/dx_a:  [f1 f2 f3] = H = -V P Dm^-T,  f0 = -(f1 + f2 + f3).
#include "mat3.hpp"

namespace softcontact::model {

/// Lame parameters of an isotropic material [Pa].
struct Lame {
  double lambda = 0;
  double mu = 0;
};

/// F = Ds Dm^-1 from the four corners (each 3 doubles) and the rest Dm^-1.
inline Mat3 deformation_gradient(const double* x0, const double* x1, const double* x2, const double* x3,
                                 const Mat3& dm_inv) {
  const Mat3 ds = {x1[0] - x0[0], x2[0] - x0[0], x3[0] - x0[0], x1[1] - x0[1], x2[1] - x0[1],
                   x3[1] - x0[1], x1[2] - x0[2], x2[2] - x0[2], x3[2] - x0[2]};
  return mul(ds, dm_inv);
}

/// Corner forces (4,3) [N] of a tet of rest volume V under the stress P: H = -V P Dm^-T
/// gives f1..f3 as its columns, and f0 balances them.
inline void corner_forces(const Mat3& P, const Mat3& dm_inv, double volume, double f[12]) {
  const Mat3 h = mul_nt(P, dm_inv);  // P Dm^-T
  for (int a = 1; a <= 3; ++a)
    for (int d = 0; d < 3; ++d) f[3 * a + d] = -volume * h[3 * d + (a - 1)];
  for (int d = 0; d < 3; ++d) f[d] = -(f[3 + d] + f[6 + d] + f[9 + d]);
}

/// Gradient operator of the tet: dF_ij / dx_(a,k) = delta_ik g_a,j with the shape-function
/// gradients g_1..g_3 = rows of Dm^-1 and g_0 = -(g_1 + g_2 + g_3). Returns g (4,3).
inline void shape_gradients(const Mat3& dm_inv, double g[12]) {
  for (int a = 1; a <= 3; ++a)
    for (int j = 0; j < 3; ++j) g[3 * a + j] = dm_inv[3 * (a - 1) + j];
  for (int j = 0; j < 3; ++j) g[j] = -(g[3 + j] + g[6 + j] + g[9 + j]);
}

/// Element stiffness K = d(-f)/dx (12,12), row (3a+i), column (3b+k), from the tangent
/// dP/dF: K_(ai),(bk) = V sum_jl dP_ij/dF_kl g_a,j g_b,l.
inline void element_stiffness(const Mat9& dPdF, const Mat3& dm_inv, double volume, double K[144]) {
  double g[12];
  shape_gradients(dm_inv, g);
  for (int a = 0; a < 4; ++a)
    for (int i = 0; i < 3; ++i)
      for (int b = 0; b < 4; ++b)
        for (int k = 0; k < 3; ++k) {
          double s = 0;
          for (int j = 0; j < 3; ++j)
            for (int l = 0; l < 3; ++l) s += dPdF[9 * (3 * i + j) + 3 * k + l] * g[3 * a + j] * g[3 * b + l];
          K[12 * (3 * a + i) + 3 * b + k] = volume * s;
        }
}

}  // namespace softcontact::model
