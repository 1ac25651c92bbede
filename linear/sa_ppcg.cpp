// The Krylov templates instantiated for smoothed aggregation, once (docs/architecture.md, "Pre-built combinations").
#include "linear/sa_ppcg.hpp"

#include "linear/pcg_impl.hpp"

namespace weft::linear {

template class Ppcg<SaAmg>;
template class ModifiedPcg<SaAmg>;

}  // namespace weft::linear
