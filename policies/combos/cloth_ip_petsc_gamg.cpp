// One explicit instantiation per translation unit (docs/architecture.md, "Pre-built combinations").
// Built only with its back end (policies/CMakeLists.txt), which is not declared in presets.hpp.
#include "linear/backends/petsc_gamg.hpp"
#include "policies/combo_factory.hpp"
#include "policies/presets.hpp"

namespace weft {

template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::NoContact, linear::PetscGamg>;
WEFT_DEFINE_COMBO(cloth_ip_petsc_gamg, Simulator<ClothTheta, integrators::IncrementalPotential, contact::NoContact, linear::PetscGamg>)

}  // namespace weft
