// One explicit instantiation per translation unit (docs/architecture.md, "Pre-built combinations").
#include "policies/combo_factory.hpp"
#include "policies/rod_presets.hpp"

namespace weft {

template class RodSimulator<models::DiscreteElasticRod, integrators::RodBackwardEuler, contact::rods::NoRodContact, linear::BandedLu>;
WEFT_DEFINE_ROD_COMBO(rods_none, RodSimulator<models::DiscreteElasticRod, integrators::RodBackwardEuler, contact::rods::NoRodContact, linear::BandedLu>)

}  // namespace weft
