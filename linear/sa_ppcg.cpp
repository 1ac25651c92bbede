// The Krylov templates instantiated for smoothed aggregation, once (STYLE.md §4).
#include "linear/sa_ppcg.hpp"

#include "linear/pcg_impl.hpp"

namespace weft::linear {

template class Ppcg<SaAmg>;
template class ModifiedPcg<SaAmg>;

}  // namespace weft::linear
