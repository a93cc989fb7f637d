// The registry of material laws (src/model/material_registry.hpp): every line of the list
// in material_laws.hpp has an entry that scene files reach by its name, and the entry's
// flags say what its functions do.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "model/material_registry.hpp"
#include "softcontact/error.hpp"
#include "softcontact/forces.hpp"
#include "softcontact/scene.hpp"

using namespace softcontact;

namespace {

Scene scene_with(const std::string& model, const std::string& integrator) {
  return load_scene_from_string("simulation: {dt: 1e-4, steps: 1, integrator: " + integrator +
                                    "}\nmaterials:\n  - {name: m, model: " + model +
                                    ", young: 1e5, poisson: 0.3, density: 1000}\nobjects:\n"
                                    "  - {name: o, material: m, primitive: {type: box, size: [1, 1, 1], cells: [1, 1, 1]}}\n",
                                "registry.yaml");
}

}  // namespace

TEST(MaterialRegistry, EveryListedLawIsReachedByItsName) {
  ASSERT_GE(kModelKinds, 1);
  for (int k = 0; k < kModelKinds; ++k) {
    const ModelKind kind = static_cast<ModelKind>(k);
    const model::MaterialLaw& law = model::material_law(kind);
    EXPECT_TRUE(law.block_forces && law.energy && law.stiffness && law.rest_stiffness) << to_string(kind);
    EXPECT_EQ(scene_with(to_string(kind), "verlet").materials[0].model, kind) << to_string(kind);
  }
}

// The parser lets implicit Euler take exactly the laws whose entry says it may, and names
// them when it refuses one.
TEST(MaterialRegistry, ImplicitEulerTakesTheLawsThatSaySo) {
  for (int k = 0; k < kModelKinds; ++k) {
    const ModelKind kind = static_cast<ModelKind>(k);
    if (model::material_law(kind).implicit) {
      EXPECT_NO_THROW(scene_with(to_string(kind), "implicit_euler")) << to_string(kind);
      continue;
    }
    try {
      scene_with(to_string(kind), "implicit_euler");
      ADD_FAILURE() << to_string(kind) << " accepted with implicit_euler";
    } catch (const InputError& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find("supports the models 'linear' and 'corotational' only"), std::string::npos) << m;
      EXPECT_NE(m.find(std::string("with model '") + to_string(kind) + "'"), std::string::npos) << m;
    }
  }
}

// constant_stiffness: the stiffness is the same at rest and deformed (implicit Euler
// assembles it once); the laws without the flag do change.
TEST(MaterialRegistry, ConstantStiffnessFlagHolds) {
  const model::Mat3 Di = {1, 0.2, 0, 0, 1.1, 0.1, 0.05, 0, 0.9};
  const model::Mat3 I = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  const double c = std::cos(0.4), s = std::sin(0.4);
  const model::Mat3 F = {1.05 * c, -s, 0.02, s, 0.97 * c, 0.01, 0.03, 0, 1.02};  // rotated and strained
  const model::LawParams p{{5e4, 4e4}, 1e5, 0};
  for (int k = 0; k < kModelKinds; ++k) {
    const model::MaterialLaw& law = model::material_law(static_cast<ModelKind>(k));
    double K0[144], K1[144];
    law.stiffness(p, Di, 0.1, I, StiffnessKind::implicit, K0);
    law.stiffness(p, Di, 0.1, F, StiffnessKind::implicit, K1);
    bool same = true;
    for (int i = 0; i < 144; ++i) same = same && K0[i] == K1[i];
    EXPECT_EQ(same, law.constant_stiffness) << to_string(static_cast<ModelKind>(k));
  }
}
