// One explicit instantiation per translation unit (docs/architecture.md, "Pre-built combinations").
#include "policies/combo_factory.hpp"
#include "policies/presets.hpp"

namespace weft {

template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::NoContact, linear::DiagPcg>;
WEFT_DEFINE_COMBO(cloth_ip_diag_pcg, Simulator<ClothTheta, integrators::IncrementalPotential, contact::NoContact, linear::DiagPcg>)

}  // namespace weft
