// One explicit instantiation per translation unit (STYLE.md §4, §9).
#include "policies/combo_factory.hpp"
#include "policies/presets.hpp"

namespace weft {

template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::ObstaclePenalty, linear::Direct>;

namespace combo_factories {
using Sim = Simulator<ClothTheta, integrators::IncrementalPotential, contact::ObstaclePenalty, linear::Direct>;
std::unique_ptr<AnySimulator> make_cloth_ip_penalty_direct(const Scene& scene) {
  return detail::make_combo<Sim>("cloth_ip_penalty_direct", scene);
}
std::vector<PolicyDoc> docs_cloth_ip_penalty_direct() { return detail::combo_docs<Sim>(); }
}  // namespace combo_factories

}  // namespace weft
