// The linear law's registry entry (linear.hpp, material_registry.hpp): the generic block
// kernel, Hooke's stiffness in closed form, which does not depend on x.
//
// forces.cpp's pragmas, before any include (the headers' inline functions need them too):
// the kernel is cloned per instruction set, and every clone must round alike.
#pragma GCC optimize("fp-contract=off", "no-math-errno")
#pragma GCC diagnostic ignored "-Wpsabi"

#include "linear.hpp"
#include "stress_law.hpp"

namespace softcontact::model {

namespace {

SOFTCONTACT_BLOCK_KERNEL
void forces(const TetView& T, std::size_t begin, std::size_t end, const LawParams& p, bool damp, const double* x,
            const double* v, double* out) {
  stress_law_block<LinearLaw>(T, begin, end, p, damp, x, v, out);
}

void stiffness(const LawParams& p, const Mat3& Di, double V, const Mat3&, StiffnessKind, double K[144]) {
  hooke_stiffness(p.lame, Di, V, K);
}

}  // namespace

extern const MaterialLaw linear_law = {.block_forces = forces,
                                       .energy = stress_law_energy<LinearLaw>,
                                       .stiffness = stiffness,
                                       .rest_stiffness = hooke_rest_stiffness,
                                       .implicit = true,
                                       .constant_stiffness = true};

}  // namespace softcontact::model
