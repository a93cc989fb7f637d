// The registry's table: one entry per line of SOFTCONTACT_MATERIAL_LAWS, in ModelKind
// order. A listed law without its file fails to link (undefined name_law).
#include "material_registry.hpp"

namespace softcontact::model {

#define SOFTCONTACT_DECLARE_LAW(name) extern const MaterialLaw name##_law;
SOFTCONTACT_MATERIAL_LAWS(SOFTCONTACT_DECLARE_LAW)
#undef SOFTCONTACT_DECLARE_LAW

#define SOFTCONTACT_LAW_ENTRY(name) &name##_law,
const MaterialLaw* const kMaterialLaws[] = {SOFTCONTACT_MATERIAL_LAWS(SOFTCONTACT_LAW_ENTRY)};
#undef SOFTCONTACT_LAW_ENTRY

static_assert(sizeof kMaterialLaws / sizeof kMaterialLaws[0] == kModelKinds);

}  // namespace softcontact::model
