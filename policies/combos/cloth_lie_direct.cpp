// One explicit instantiation per translation unit (docs/architecture.md, "Pre-built combinations").
#include "policies/combo_factory.hpp"
#include "policies/presets.hpp"

namespace weft {

template class Simulator<ClothTheta, integrators::LinearlyImplicit, contact::NoContact, linear::Direct>;
WEFT_DEFINE_COMBO(cloth_lie_direct, Simulator<ClothTheta, integrators::LinearlyImplicit, contact::NoContact, linear::Direct>)

}  // namespace weft
