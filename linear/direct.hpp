#pragma once
/// \file direct.hpp
/// `Direct`: sparse LDL^T (Eigen's SimplicialLDLT, AMD ordering). The symbolic analysis
/// is done once per pattern; each Newton iteration refactorises numerically, copying the
/// BlockCsr values into the factor's matrix through a precomputed index map.
///
/// With a constraint set (`set_context`) it factorises the prefiltered
///   Ahat = S A S + Sigma (I - S)   and returns   x = z + S y,  Ahat y = S (b - A z)
/// (linear/prefilter.hpp, methods/multigrid §7.3 and §13 "Direct policies"). Ahat keeps A's pattern,
/// so the symbolic analysis survives changes of the contact set.
#include <Eigen/SparseCholesky>

#include <string>
#include <string_view>
#include <vector>

#include "framework/block_csr.hpp"
#include "framework/concepts.hpp"
#include "framework/params.hpp"
#include "linear/prefilter.hpp"

namespace weft::linear {

class Direct {
 public:
  static constexpr std::string_view name = "direct";
  /// Checkpoints: the symbolic analysis is redone the same from the same pattern.
  static constexpr bool stateless = true;
  struct Params {
    bool check_residual = true;  ///< compute ||S (b - A x)|| / ||S b|| after each solve (one extra product; S = I without constraints)
    template <class V>
    void visit(V& v) {
      v.field("check_residual", check_residual, {Unit::none, Range::any(), "report the true relative residual of each solve"});
    }
  };

  explicit Direct(const Params& prm) : prm_(prm) {}
  Status analyze_pattern(const BlockCsr& A);
  Status factorize(const BlockCsr& A);
  LinearReport solve(const Eigen::VectorXd& b, Eigen::VectorXd& x);
  /// The constraints of the next factorize (positions are not used).
  void set_context(const SolveContext& ctx) { pre_.set_context(ctx); }

 private:
  Params prm_;
  PrefilteredSystem pre_;
  Eigen::SparseMatrix<double> lower_;                 // lower triangle, CSC
  std::vector<std::pair<int, int>> map_;              // (BlockCsr value index, lower_ value index)
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower> ldlt_;
  const BlockCsr* A_ = nullptr;
  double setup_seconds_ = 0;
  int negative_pivots_ = -1;
  bool analyzed_ = false, factorized_ = false;
  std::string failure_ = "call analyze_pattern() and factorize() before solve()";
};

static_assert(LinearSolver<Direct> && HasSolveContext<Direct>);

}  // namespace weft::linear
