// One explicit instantiation per translation unit (docs/architecture.md, "Pre-built combinations").
#include "policies/combo_factory.hpp"
#include "policies/presets.hpp"

namespace weft {

template class Simulator<ClothOrtho, integrators::IncrementalPotential, contact::NoContact, linear::Direct>;
WEFT_DEFINE_COMBO(cloth_ortho_ip_direct, Simulator<ClothOrtho, integrators::IncrementalPotential, contact::NoContact, linear::Direct>)

}  // namespace weft
