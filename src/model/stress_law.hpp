#pragma once
// The registry functions of a law whose kernel is "stress of F" (material_law.hpp: linear,
// St. Venant-Kirchhoff, neo-Hookean), written once for the law's type. A law's file
// includes this after its floating-point pragmas, so the functions it instantiates round
// as its block kernel does, and keeps its own block kernel (which carries the
// instruction-set clones and calls stress_law_block).
#include "linear.hpp"
#include "material_registry.hpp"
#include "tet_kernels.hpp"

namespace softcontact::model {

/// The generic block kernel's body: P(F) per tet, with or without the damping stress.
template <class Law>
inline void stress_law_block(const TetView& T, std::size_t begin, std::size_t end, const LawParams& p, bool damp,
                             const double* x, const double* v, double* out) {
  if (damp) law_block<Law, true>(T, begin, end, Law{p.lame, p.beta}, x, v, out);
  else law_block<Law, false>(T, begin, end, Law{p.lame, p.beta}, x, v, out);
}

/// Strain energy V Psi(F) of tet t.
template <class Law>
double stress_law_energy(const TetView& T, std::size_t t, const LawParams& p, const double*, const Mat3& F) {
  return T.volume[t] * Law{p.lame, 0.0}.energy(F);
}

/// Element stiffness from the exact tangent dP/dF at F.
template <class Law>
void tangent_stiffness(const LawParams& p, const Mat3& Di, double V, const Mat3& F, StiffnessKind, double K[144]) {
  element_stiffness(Law{p.lame, 0.0}.stress_derivative(F), Di, V, K);
}

/// Hooke's element stiffness in closed form (the rest stiffness of every law that
/// linearises to isotropic small-strain elasticity, material_law.hpp).
inline void hooke_rest_stiffness(const double*, const Mat3& Di, double V, const LawParams& p, double K[144]) {
  hooke_stiffness(p.lame, Di, V, K);
}

}  // namespace softcontact::model
