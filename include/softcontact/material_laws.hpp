#pragma once
// The registry list of material laws: one line X(name) per law (docs/models.md, "Adding a
// material law"). `name` is at once the law's name in scene files ('model: name'), the
// enumerator ModelKind::name (scene.hpp) and the registry entry model::name_law, which
// the law's own file src/model/name.cpp defines (src/model/material_registry.hpp says
// what an entry holds). Everything that depends on the model (scene parsing, force
// kernels, energy, stiffness, the stability limit, implicit Euler) looks the entry up;
// nothing else names a law.
//
// The order gives ModelKind's values, which a checkpoint's scene fingerprint hashes
// (io/checkpoint_read.cpp): add a new law at the end.
#define SOFTCONTACT_MATERIAL_LAWS(X) \
  X(linear)                          \
  X(corotational)                    \
  X(stvk)                            \
  X(neohookean)                      \
  X(mass_spring)
