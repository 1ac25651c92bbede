#pragma once
/// \file kkt_reference.hpp
/// Ground truth for the back-end tests: the constrained minimiser of 1/2 x^T A x - b^T x
/// subject to n_{i,m}^T x_i = n_{i,m}^T z_i, by a dense KKT solve (LU with partial pivoting).
#include <Eigen/Dense>

#include "framework/block_csr.hpp"
#include "framework/constraints.hpp"

namespace weft::support {

inline Eigen::VectorXd dense_kkt_solve(const BlockCsr& A, const Eigen::VectorXd& b, const ConstraintSet& c) {
  const int n = A.rows();
  int m = 0;
  for (int i = 0; i < c.num_vertices(); ++i) m += c.count(i);
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n + m, n + m);
  K.topLeftCorner(n, n) = A.to_dense();
  Eigen::VectorXd rhs(n + m);
  rhs.head(n) = b;
  int row = n;
  for (int i = 0; i < c.num_vertices(); ++i)
    for (int q = 0; q < c.count(i); ++q, ++row) {
      const Eigen::Vector3d d = c.directions(i).col(q);
      K.block<1, 3>(row, 3 * i) = d.transpose();
      K.block<3, 1>(3 * i, row) = d;
      rhs[row] = d.dot(c.target().segment<3>(3 * i));
    }
  return K.partialPivLu().solve(rhs).head(n);
}

}  // namespace weft::support
