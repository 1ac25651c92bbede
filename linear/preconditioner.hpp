#pragma once
/// \file preconditioner.hpp
/// The preconditioner concept of the Krylov solvers (methods/multigrid §13): a numeric setup from
/// the (prefiltered) matrix and a const `apply` that is, by contract, a fixed SPD linear
/// map (Appendix A): the same r always gives the same z, and z = B r with B = B^T > 0.
#include <Eigen/Core>

#include <concepts>
#include <cstddef>
#include <string_view>

#include "framework/block_csr.hpp"
#include "framework/concepts.hpp"
#include "framework/constraints.hpp"
#include "framework/status.hpp"

namespace weft::linear {

/// Statistics a preconditioner reports after `setup`.
struct PreconditionerInfo {
  std::size_t memory_bytes = 0;    ///< storage owned by the preconditioner
  int levels = 0;                  ///< multigrid levels (0 for one-level preconditioners)
  double operator_complexity = 0;  ///< sum_l nnz(A_l) / nnz(A_1)
  double grid_complexity = 0;      ///< sum_l rows(A_l) / rows(A_1)
};

/// `P(const P::Params&)`; `setup(A, ctx)` builds the preconditioner from A (A's pattern may
/// only change after `analyze_pattern`); `apply(r, z)` sets z = B r.
template <class P>
concept Preconditioner = Component<P> && std::constructible_from<P, const typename P::Params&> &&
    requires(P& p, const P& cp, const BlockCsr& A, const SolveContext& ctx, const Eigen::VectorXd& r,
             Eigen::VectorXd& z) {
      { p.analyze_pattern(A) } -> std::same_as<Status>;
      { p.setup(A, ctx) } -> std::same_as<Status>;
      cp.apply(r, z);
      { cp.info() } -> std::same_as<PreconditionerInfo>;
    };

}  // namespace weft::linear
