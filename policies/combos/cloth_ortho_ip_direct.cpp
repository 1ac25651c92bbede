// One explicit instantiation per translation unit (STYLE.md §4, §9).
#include "policies/combo_factory.hpp"
#include "policies/presets.hpp"

namespace weft {

template class Simulator<ClothOrtho, integrators::IncrementalPotential, contact::NoContact, linear::Direct>;

namespace combo_factories {
using Sim = Simulator<ClothOrtho, integrators::IncrementalPotential, contact::NoContact, linear::Direct>;
std::unique_ptr<AnySimulator> make_cloth_ortho_ip_direct(const Scene& scene) {
  return detail::make_combo<Sim>("cloth_ortho_ip_direct", scene);
}
std::vector<PolicyDoc> docs_cloth_ortho_ip_direct() { return detail::combo_docs<Sim>(); }
}  // namespace combo_factories

}  // namespace weft
