// One explicit instantiation per translation unit (docs/architecture.md, "Pre-built combinations").
#include "policies/combo_factory.hpp"
#include "policies/presets.hpp"

namespace weft {

template class Simulator<ClothTheta, integrators::LinearlyImplicit, contact::NoContact, linear::SaPpcg>;
WEFT_DEFINE_COMBO(cloth_lie_sa_ppcg, Simulator<ClothTheta, integrators::LinearlyImplicit, contact::NoContact, linear::SaPpcg>)

}  // namespace weft
