// One explicit instantiation per translation unit (STYLE.md §4, §9).
#include "policies/combo_factory.hpp"
#include "policies/presets.hpp"

namespace weft {

template class Simulator<ClothTan, integrators::IncrementalPotential, contact::NoContact, linear::Direct>;
WEFT_DEFINE_COMBO(cloth_tan_ip_direct, Simulator<ClothTan, integrators::IncrementalPotential, contact::NoContact, linear::Direct>)

}  // namespace weft
