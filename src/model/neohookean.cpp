// The neo-Hookean law's registry entry (neohookean.hpp, material_registry.hpp): the generic block
// kernel, and the exact tangent as stiffness (indefinite under compression, so not for
// implicit Euler).
//
// Floating-point contraction off and sqrt without errno, as in forces.cpp, for every
// function of this file (before any include, so that the inline functions of the headers
// get them too): the block kernel is cloned per instruction set and must round alike.
#pragma GCC optimize("fp-contract=off", "no-math-errno")
#pragma GCC diagnostic ignored "-Wpsabi"

#include "neohookean.hpp"
#include "linear.hpp"
#include "material_registry.hpp"
#include "tet_kernels.hpp"

namespace softcontact::model {

namespace {

SOFTCONTACT_BLOCK_KERNEL
void forces(const TetView& T, std::size_t begin, std::size_t end, const LawParams& p, bool damp, const double* x,
            const double* v, double* out) {
  if (damp) law_block<NeoHookeanLaw, true>(T, begin, end, NeoHookeanLaw(p.lame, p.beta), x, v, out);
  else law_block<NeoHookeanLaw, false>(T, begin, end, NeoHookeanLaw(p.lame, p.beta), x, v, out);
}

double energy(const TetView& T, std::size_t t, const LawParams& p, const double*, const Mat3& F) {
  return T.volume[t] * NeoHookeanLaw(p.lame, 0).energy(F);
}

void stiffness(const LawParams& p, const Mat3& Di, double V, const Mat3& F, StiffnessKind, double K[144]) {
  element_stiffness(NeoHookeanLaw(p.lame, 0).stress_derivative(F), Di, V, K);
}

// At rest the law linearises to Hooke's law (material_law.hpp).
void rest_stiffness(const double*, const Mat3& Di, double V, const LawParams& p, double K[144]) {
  hooke_stiffness(p.lame, Di, V, K);
}

}  // namespace

extern const MaterialLaw neohookean_law = {.block_forces = forces,
                                   .energy = energy,
                                   .stiffness = stiffness,
                                   .rest_stiffness = rest_stiffness};

}  // namespace softcontact::model
