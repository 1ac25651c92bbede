#pragma once
/// \file direct.hpp
/// `Direct`: sparse LDL^T (Eigen's SimplicialLDLT, AMD ordering). The symbolic analysis
/// is done once per pattern; each Newton iteration refactorises numerically, copying the
/// BlockCsr values into the factor's matrix through a precomputed index map.
#include <Eigen/SparseCholesky>

#include <string_view>
#include <vector>

#include "framework/block_csr.hpp"
#include "framework/concepts.hpp"
#include "framework/params.hpp"

namespace weft::linear {

class Direct {
 public:
  static constexpr std::string_view name = "direct";
  struct Params {
    bool check_residual = true;  ///< compute ||b - A x|| / ||b|| after each solve (one extra product)
    template <class V>
    void visit(V& v) {
      v.field("check_residual", check_residual, {Unit::none, Range::any(), "report the true relative residual of each solve"});
    }
  };

  explicit Direct(const Params& prm) : prm_(prm) {}
  Status analyze_pattern(const BlockCsr& A);
  Status factorize(const BlockCsr& A);
  LinearReport solve(const Eigen::VectorXd& b, Eigen::VectorXd& x);

 private:
  Params prm_;
  Eigen::SparseMatrix<double> lower_;                 // lower triangle, CSC
  std::vector<std::pair<int, int>> map_;              // (BlockCsr value index, lower_ value index)
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower> ldlt_;
  const BlockCsr* A_ = nullptr;
  double setup_seconds_ = 0;
  int negative_pivots_ = -1;
  bool analyzed_ = false, factorized_ = false;
};

static_assert(LinearSolver<Direct>);

}  // namespace weft::linear
