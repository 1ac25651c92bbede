// One explicit instantiation per translation unit (docs/architecture.md, "Pre-built combinations").
// Built only with its back end (policies/CMakeLists.txt), which is not declared in presets.hpp.
#include "linear/backends/cholmod_direct.hpp"
#include "policies/combo_factory.hpp"
#include "policies/presets.hpp"

namespace weft {

template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::Barrier, linear::CholmodDirect>;
WEFT_DEFINE_COMBO(cloth_ip_barrier_cholmod, Simulator<ClothTheta, integrators::IncrementalPotential, contact::Barrier, linear::CholmodDirect>)

}  // namespace weft
