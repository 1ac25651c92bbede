#pragma once
/// \file sa_ppcg.hpp
/// The smoothed-aggregation solvers: `SaPpcg` (the thesis' SA+PPCG, methods/multigrid §0: PCG on the
/// prefiltered system, preconditioned by one SA V-cycle built from that system) and
/// `SaMpcg` (the ablation "SA without prefiltering": the V-cycle built from the unfiltered A
/// inside Baraff-Witkin's modified PCG, methods/multigrid §7.2, thesis Fig. 11.8).
#include <string_view>

#include "linear/pcg.hpp"
#include "linear/sa_amg.hpp"

namespace weft::linear {

extern template class Ppcg<SaAmg>;
extern template class ModifiedPcg<SaAmg>;

class SaPpcg : public Ppcg<SaAmg> {
 public:
  static constexpr std::string_view name = "sa_ppcg";
  using Ppcg<SaAmg>::Ppcg;
};

class SaMpcg : public ModifiedPcg<SaAmg> {
 public:
  static constexpr std::string_view name = "sa_mpcg";
  using ModifiedPcg<SaAmg>::ModifiedPcg;
};

static_assert(LinearSolver<SaPpcg> && HasSolveContext<SaPpcg>);
static_assert(LinearSolver<SaMpcg> && HasSolveContext<SaMpcg>);

}  // namespace weft::linear
