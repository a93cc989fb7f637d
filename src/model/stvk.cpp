// The St. Venant-Kirchhoff law's registry entry (stvk.hpp, material_registry.hpp): the generic block
// kernel, and the exact tangent as stiffness (indefinite under compression, so not for
// implicit Euler).
//
// forces.cpp's pragmas, before any include (the headers' inline functions need them too):
// the kernel is cloned per instruction set, and every clone must round alike.
#pragma GCC optimize("fp-contract=off", "no-math-errno")
#pragma GCC diagnostic ignored "-Wpsabi"

#include "stvk.hpp"
#include "stress_law.hpp"

namespace softcontact::model {

namespace {

SOFTCONTACT_BLOCK_KERNEL
void forces(const TetView& T, std::size_t begin, std::size_t end, const LawParams& p, bool damp, const double* x,
            const double* v, double* out) {
  stress_law_block<StvkLaw>(T, begin, end, p, damp, x, v, out);
}

}  // namespace

extern const MaterialLaw stvk_law = {.block_forces = forces,
                                     .energy = stress_law_energy<StvkLaw>,
                                     .stiffness = tangent_stiffness<StvkLaw>,
                                     .rest_stiffness = hooke_rest_stiffness};

}  // namespace softcontact::model
