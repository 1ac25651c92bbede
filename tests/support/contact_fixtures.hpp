#pragma once
/// \file contact_fixtures.hpp
/// Shared configurations for the contact tests: a crumpled sheet with self proximity, and
/// random displacements of it (a step's motion).
#include <Eigen/Core>

#include <cmath>
#include <random>

#include "framework/mesh_generators.hpp"

namespace weft::support {

struct Sheet {
  Eigen::MatrixX3d V;  ///< the flat rest grid
  Eigen::MatrixX3i F;
  Eigen::VectorXd x;   ///< crumpled positions, stacked
};

/// An n x n grid on [-0.5, 0.5]^2 folded by a few waves of the given amplitude, then displaced
/// at random by up to `jitter` times the spacing in every direction.
inline Sheet crumpled_sheet(int n, double amplitude, double jitter, unsigned seed) {
  const MeshData m = make_rectangle({1.0, 1.0}, {n, n}, Tessellation::regular, 0);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  const double h = 1.0 / (n - 1);
  Sheet s{m.V, m.F, Eigen::VectorXd(3 * m.V.rows())};
  for (Eigen::Index i = 0; i < m.V.rows(); ++i) {
    const double a = m.V(i, 0), b = m.V(i, 1);
    const Eigen::Vector3d p(a + 0.2 * amplitude * std::sin(5 * b), b, amplitude * std::sin(9 * a) * std::cos(7 * b));
    s.x.segment<3>(3 * i) = p + jitter * h * Eigen::Vector3d(u(rng), u(rng), u(rng));
  }
  return s;
}

/// x with every coordinate moved by a uniform random amount in [-amount, amount].
inline Eigen::VectorXd displaced(const Eigen::VectorXd& x, double amount, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-amount, amount);
  Eigen::VectorXd y = x;
  for (Eigen::Index i = 0; i < y.size(); ++i) y[i] += u(rng);
  return y;
}

}  // namespace weft::support
