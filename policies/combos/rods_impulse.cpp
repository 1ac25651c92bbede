// One explicit instantiation per translation unit (docs/architecture.md, "Pre-built combinations").
#include "policies/combo_factory.hpp"
#include "policies/rod_presets.hpp"

namespace weft {

template class RodSimulator<models::DiscreteElasticRod, integrators::RodBackwardEuler, contact::rods::RodImpulse, linear::BandedLu>;
WEFT_DEFINE_ROD_COMBO(rods_impulse, RodSimulator<models::DiscreteElasticRod, integrators::RodBackwardEuler, contact::rods::RodImpulse, linear::BandedLu>)

}  // namespace weft
