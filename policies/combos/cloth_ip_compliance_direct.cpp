// One explicit instantiation per translation unit (STYLE.md §4, §9).
#include "policies/combo_factory.hpp"
#include "policies/presets.hpp"

namespace weft {

template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::LinearCompliance, linear::Direct>;
WEFT_DEFINE_COMBO(cloth_ip_compliance_direct, Simulator<ClothTheta, integrators::IncrementalPotential, contact::LinearCompliance, linear::Direct>)

}  // namespace weft
