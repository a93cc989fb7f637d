#pragma once
// The registry of material laws: what each law (linear, corotational, ...) gives the rest
// of the code, one entry per law, defined in the law's own file src/model/<name>.cpp and
// listed in include/softcontact/material_laws.hpp. forces.cpp, stability.cpp, the scene
// parser and implicit Euler look a material's entry up by its ModelKind instead of
// switching on it, so that a new law is its file plus one line in that list
// (docs/models.md, "Adding a material law").
//
// Dispatch costs one indirect call per block of up to 256 tets (forces.cpp); inside a
// block the law's kernel runs inlined, kLanes tets at a time (tet_kernels.hpp).
#include <cstddef>

#include "material_law.hpp"
#include "softcontact/forces.hpp"
#include "softcontact/scene.hpp"

namespace softcontact::model {

struct TetView;

/// A material's parameters as the laws take them.
struct LawParams {
  Lame lame;          ///< Lame parameters [Pa]
  double young = 0;   ///< Young's modulus E [Pa] (mass_spring)
  double beta = 0;    ///< Rayleigh stiffness-proportional damping [s]
};

inline LawParams law_params(const Material& m) {
  return {{m.lame_lambda(), m.lame_mu()}, m.young, m.damping_stiffness};
}

struct MaterialLaw {
  /// Corner forces of the tets [begin, end) of one object into `out`, in tet_kernels.hpp's
  /// layout, plus the law's stiffness-proportional damping at the velocities v when `damp`
  /// (v is not read otherwise). A block kernel: compiled with SOFTCONTACT_BLOCK_KERNEL in a
  /// file that starts with forces.cpp's pragmas (tet_kernels.hpp), so that it rounds
  /// exactly alike on every instruction set.
  void (*block_forces)(const TetView& T, std::size_t begin, std::size_t end, const LawParams& p, bool damp,
                       const double* x, const double* v, double* out);
  /// Strain energy of tet t [J] at the positions x; F is its deformation gradient there.
  double (*energy)(const TetView& T, std::size_t t, const LawParams& p, const double* x, const Mat3& F);
  /// Stiffness K = -df/dx (12,12) [N/m] of a tet of rest volume V with Dm^-1 = Di at the
  /// deformation gradient F (ElasticForces::tet_stiffness says which K each kind is).
  void (*stiffness)(const LawParams& p, const Mat3& Di, double V, const Mat3& F, StiffnessKind kind, double K[144]);
  /// Stiffness (12,12) at rest of a tet with rest corners X (4,3), Dm^-1 = Di and volume V,
  /// for the explicit stability limit (stability.cpp).
  void (*rest_stiffness)(const double X[12], const Mat3& Di, double V, const LawParams& p, double K[144]);
  /// StiffnessKind::implicit is symmetric positive semi-definite, so implicit Euler may use
  /// the law (the scene parser refuses the others).
  bool implicit = false;
  /// The stiffness does not depend on the positions: implicit Euler assembles it once.
  bool constant_stiffness = false;
  /// The kernel reads TetView::inv_rest_length (ElasticForces stores it only then).
  bool spring_rest_lengths = false;
};

/// The entries in ModelKind order (material_registry.cpp).
extern const MaterialLaw* const kMaterialLaws[];

inline const MaterialLaw& material_law(ModelKind m) { return *kMaterialLaws[static_cast<int>(m)]; }

}  // namespace softcontact::model
