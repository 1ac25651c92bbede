#pragma once
/// \file state.hpp
/// The dynamic state every policy reads: stacked vertex positions and velocities, lumped
/// masses, and which vertices are not simulated (pinned or scripted).
#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace weft {

/// How a vertex moves.
enum class Dof : std::uint8_t {
  free = 0,      ///< simulated
  pinned = 1,    ///< held at its position
  scripted = 2,  ///< follows a prescribed motion (see scene.hpp, `Motion`)
};

/// Positions, velocities and masses of all simulated vertices.
/// Vectors are stacked: `x` is #V*3 with vertex i at x.segment<3>(3*i).
struct State {
  Eigen::VectorXd x;          ///< #V*3 positions [m]
  Eigen::VectorXd v;          ///< #V*3 velocities [m/s]
  Eigen::VectorXd mass;       ///< #V lumped masses [kg]
  std::vector<Dof> dof;       ///< #V: free, pinned or scripted
  double t = 0;               ///< simulated time [s]

  int num_vertices() const { return static_cast<int>(mass.size()); }
  bool is_free(int i) const { return dof[i] == Dof::free; }
  auto position(int i) { return x.segment<3>(3 * i); }
  auto position(int i) const { return x.segment<3>(3 * i); }
  auto velocity(int i) { return v.segment<3>(3 * i); }
  auto velocity(int i) const { return v.segment<3>(3 * i); }

  /// Kinetic energy 1/2 v^T M v [J].
  double kinetic_energy() const {
    double e = 0;
    for (int i = 0; i < num_vertices(); ++i) e += 0.5 * mass[i] * v.segment<3>(3 * i).squaredNorm();
    return e;
  }
  /// Zero the entries of a stacked vector that belong to non-free vertices.
  void zero_constrained(Eigen::Ref<Eigen::VectorXd> g) const {
    for (int i = 0; i < num_vertices(); ++i)
      if (!is_free(i)) g.segment<3>(3 * i).setZero();
  }
};

}  // namespace weft
