#pragma once
/// \file autodiff_support.hpp
/// Helpers for the nested fixed-size Eigen `AutoDiffScalar`s of the test oracles
/// (models/bending_autodiff.cpp, the rod stencil oracle in models/discrete_elastic_rod.cpp).
#include <unsupported/Eigen/AutoDiff>

#include <cmath>

namespace weft::models::detail {

/// atan2 that keeps the fixed derivative size and recurses through the nesting (Eigen's own
/// returns a dynamically sized derivative: a heap allocation per call).
inline double ad_atan2(double y, double x) { return std::atan2(y, x); }
template <class Der>
Eigen::AutoDiffScalar<Der> ad_atan2(const Eigen::AutoDiffScalar<Der>& y, const Eigen::AutoDiffScalar<Der>& x) {
  using S = typename Der::Scalar;
  const S value = ad_atan2(y.value(), x.value());
  const S r2 = y.value() * y.value() + x.value() * x.value();
  Der d = (y.derivatives() * x.value() - x.derivatives() * y.value()) / r2;
  return Eigen::AutoDiffScalar<Der>(value, d);
}

}  // namespace weft::models::detail
