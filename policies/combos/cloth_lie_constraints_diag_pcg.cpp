// One explicit instantiation per translation unit (docs/architecture.md, "Pre-built combinations").
#include "policies/combo_factory.hpp"
#include "policies/presets.hpp"

namespace weft {

template class Simulator<ClothTheta, integrators::LinearlyImplicit, contact::ImplicitContact, linear::DiagPcg>;
WEFT_DEFINE_COMBO(cloth_lie_constraints_diag_pcg, Simulator<ClothTheta, integrators::LinearlyImplicit, contact::ImplicitContact, linear::DiagPcg>)

}  // namespace weft
