// One explicit instantiation per translation unit (docs/architecture.md, "Pre-built combinations").
#include "policies/combo_factory.hpp"
#include "policies/presets.hpp"

namespace weft {

template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::Barrier, linear::Direct>;
WEFT_DEFINE_COMBO(cloth_ip_barrier_direct, Simulator<ClothTheta, integrators::IncrementalPotential, contact::Barrier, linear::Direct>)

}  // namespace weft
