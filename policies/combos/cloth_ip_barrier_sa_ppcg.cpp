// One explicit instantiation per translation unit (docs/architecture.md, "Pre-built combinations").
#include "policies/combo_factory.hpp"
#include "policies/presets.hpp"

namespace weft {

template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::Barrier, linear::SaPpcg>;
WEFT_DEFINE_COMBO(cloth_ip_barrier_sa_ppcg, Simulator<ClothTheta, integrators::IncrementalPotential, contact::Barrier, linear::SaPpcg>)

}  // namespace weft
