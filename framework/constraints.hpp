#pragma once
/// \file constraints.hpp
/// Per-vertex equality constraints of the linear systems (Baraff-Witkin style, methods/multigrid §1):
/// vertex i has k_i in {0,1,2,3} orthonormal directions n_{i,m} along which its unknown is
/// prescribed, n_{i,m}^T x_i = value_{i,m}. The filter S_i = I - sum_m n_{i,m} n_{i,m}^T
/// projects onto the constraint null space; z_i = sum_m value_{i,m} n_{i,m} holds the
/// prescribed part ((I - S_i) z_i = z_i).
///
/// Contact code emits a `ConstraintSet`; the linear solvers (not the contact code) build
/// the filters from it and own the prefiltering (methods/multigrid §13).
#include <Eigen/Core>

#include <cmath>
#include <cstdint>
#include <vector>

#include "framework/block_csr.hpp"
#include "framework/error.hpp"

namespace weft {

class ConstraintSet {
 public:
  ConstraintSet() = default;
  explicit ConstraintSet(int num_vertices) { reset(num_vertices); }

  /// Remove every constraint of a set of `num_vertices` vertices.
  void reset(int num_vertices) {
    count_.assign(num_vertices, 0);
    dirs_.assign(num_vertices, Eigen::Matrix3d::Zero());
    z_.setZero(3 * num_vertices);
    constrained_ = 0;
  }
  int num_vertices() const { return static_cast<int>(count_.size()); }

  /// Prescribe all three components of vertex i: x_i = value.
  void fix(int i, const Eigen::Vector3d& value) {
    if (count_[i] == 0) ++constrained_;
    count_[i] = 3;
    dirs_[i].setIdentity();
    z_.segment<3>(3 * i) = value;
  }
  /// Prescribe n^T x_i = value along one more direction. `n` is orthogonalised against the
  /// directions already present (Gram-Schmidt) and normalised; a direction in their span
  /// only updates nothing and returns false.
  bool add_direction(int i, const Eigen::Vector3d& n, double value) {
    WEFT_ASSERT(n.allFinite(), "constraint direction of vertex {} is not finite", i);
    Eigen::Vector3d u = n;
    const double scale = n.norm();
    for (int pass = 0; pass < 2; ++pass)  // Gram-Schmidt twice: orthogonal to round-off
      for (int m = 0; m < count_[i]; ++m) u -= dirs_[i].col(m).dot(u) * dirs_[i].col(m);
    if (count_[i] == 3 || u.norm() <= 1e-8 * scale) return false;
    // value along the normalised orthogonal part: n^T x = value and x's known part.
    const Eigen::Vector3d known = z_.segment<3>(3 * i);
    const double along = (value - n.dot(known)) / u.norm();
    u.normalize();
    if (count_[i] == 0) ++constrained_;
    dirs_[i].col(count_[i]++) = u;
    z_.segment<3>(3 * i) += along * u;
    return true;
  }

  /// k_i: the number of constrained directions of vertex i.
  int count(int i) const { return count_[i]; }
  /// Orthonormal constrained directions of vertex i (first count(i) columns).
  const Eigen::Matrix3d& directions(int i) const { return dirs_[i]; }
  /// The filter S_i (symmetric projector onto the free directions).
  Block3 filter(int i) const {
    Block3 S = Block3::Identity();
    for (int m = 0; m < count_[i]; ++m) S -= dirs_[i].col(m) * dirs_[i].col(m).transpose();
    return S;
  }
  /// z: the prescribed values, 3 per vertex, zero along free directions.
  const Eigen::VectorXd& target() const { return z_; }
  /// Number of vertices with at least one constraint.
  int constrained_vertices() const { return constrained_; }
  bool empty() const { return constrained_ == 0; }

  /// v <- S v.
  void filter(Eigen::Ref<Eigen::VectorXd> v) const {
    for (int i = 0; i < num_vertices(); ++i)
      for (int m = 0; m < count_[i]; ++m) {
        auto vi = v.segment<3>(3 * i);
        vi -= dirs_[i].col(m).dot(vi) * dirs_[i].col(m);
      }
  }
  /// max_i ||(I - S_i)(x_i - z_i)||_inf: how far x is from satisfying the constraints.
  double violation(const Eigen::VectorXd& x) const {
    double worst = 0;
    for (int i = 0; i < num_vertices(); ++i)
      for (int m = 0; m < count_[i]; ++m)
        worst = std::max(worst, std::abs(dirs_[i].col(m).dot(x.segment<3>(3 * i) - z_.segment<3>(3 * i))));
    return worst;
  }

 private:
  std::vector<std::uint8_t> count_;
  std::vector<Eigen::Matrix3d> dirs_;
  Eigen::VectorXd z_;
  int constrained_ = 0;
};

/// What a linear solver may know besides the matrix: the constraint set (solvers that
/// handle constraints filter or prefilter with it; others require it empty) and the
/// current vertex positions (the rotation modes of smoothed aggregation). Pointers stay
/// valid until the next `factorize`.
struct SolveContext {
  const ConstraintSet* constraints = nullptr;
  const Eigen::VectorXd* positions = nullptr;  ///< 3 per vertex [m]
};

}  // namespace weft
