#pragma once
/// \file linear_fixtures.hpp
/// Linear systems for the solver tests, built in code: vector block Laplacians and
/// assembled cloth matrices A = M + dt^2 H (StVK membrane + hinge bending at a sagged,
/// stressed state; PSD-projected element Hessians so A is SPD) with pin constraints.
#include <Eigen/Core>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <string_view>
#include <vector>

#include "framework/block_csr.hpp"
#include "framework/constraints.hpp"
#include "framework/mesh_generators.hpp"
#include "models/hinge_bending.hpp"
#include "models/stvk_membrane.hpp"
#include "tests/support/model_fixtures.hpp"

namespace weft::support {

/// Block Laplacian of an m x m grid (4-neighbour), each block c * (I + 0.5 * a a^T) with a
/// unit vector a varying with the edge (cross-component coupling), plus `shift` * I on the
/// diagonal: SPD for shift > 0, singular (translations in the kernel) for shift = 0.
inline BlockCsr block_laplacian(int m, double shift) {
  const int n = m * m;
  std::vector<std::vector<int>> cols(n);
  auto id = [m](int i, int j) { return j * m + i; };
  for (int j = 0; j < m; ++j)
    for (int i = 0; i < m; ++i) {
      if (i + 1 < m) cols[id(i, j)].push_back(id(i + 1, j)), cols[id(i + 1, j)].push_back(id(i, j));
      if (j + 1 < m) cols[id(i, j)].push_back(id(i, j + 1)), cols[id(i, j + 1)].push_back(id(i, j));
    }
  for (auto& c : cols) std::sort(c.begin(), c.end());
  BlockCsr A(cols);
  auto add_edge = [&](int p, int q, const Block3& B) {
    A.block(A.find(p, p)) += B;
    A.block(A.find(q, q)) += B;
    A.block(A.find(p, q)) -= B;
    A.block(A.find(q, p)) -= B;
  };
  for (int j = 0; j < m; ++j)
    for (int i = 0; i < m; ++i) {
      const double phi = 0.7 * i + 1.3 * j;
      const Eigen::Vector3d a = Eigen::Vector3d(std::cos(phi), std::sin(phi), 0.5).normalized();
      const Block3 B = Block3::Identity() + 0.5 * a * a.transpose();
      if (i + 1 < m) add_edge(id(i, j), id(i + 1, j), B);
      if (j + 1 < m) add_edge(id(i, j), id(i, j + 1), B);
    }
  for (int i = 0; i < n; ++i) A.block(A.diagonal(i)) += shift * Block3::Identity();
  return A;
}

enum class Pins { none, boundary, two_sides, reentrant };

/// A cloth system: the matrix, a right-hand side, current positions and the pin constraints.
struct ClothSystem {
  BlockCsr A;            ///< M + dt^2 H, unfiltered
  Eigen::VectorXd b;     ///< dt (M v - dt grad V) with v = 0: the first backward Euler step under gravity
  Eigen::VectorXd x;     ///< current positions
  ConstraintSet pins;    ///< pinned vertices, prescribed increment z (non-zero to test the projection)
  int m = 0;             ///< vertices per side
};

/// A 1 m x 1 m cotton-like sheet (density 0.15 kg/m^2, Y 20 MPa, nu 0.3, 0.3 mm) of m x m
/// vertices (m odd for `reentrant`, which uses the L-shape), sagged by a smooth bump of
/// 2 cm and stretched 1% in-plane so the membrane is stressed, with time step dt.
inline ClothSystem cloth_system(int m, Tessellation t = Tessellation::regular, Pins pins = Pins::boundary,
                                double dt = 2e-3, int seed = 1) {
  const weft::MeshData gen = pins == Pins::reentrant
                                 ? make_l_shape(Eigen::Vector2d(1, 1), {m, m}, t, seed)
                                 : make_rectangle(Eigen::Vector2d(1, 1), {m, m}, t, seed);
  MeshData mesh{gen.V, gen.F};
  ShellMaterial mat;
  Scene scene = make_scene(mesh, mat);
  State s = rest_state(scene);
  const int n = scene.mesh.num_vertices();
  for (int i = 0; i < n; ++i) {
    auto p = s.x.segment<3>(3 * i);
    const double u = p[0], v = p[1];
    p[0] *= 1.01;
    p[1] *= 1.01;
    p[2] = -0.02 * std::cos(M_PI * u) * std::cos(M_PI * v);
  }
  models::StvkMembrane<models::Isotropic> membrane(scene, {});
  // The eigen-projection of each hinge: the systems whose iteration counts are recorded.
  models::HingeBending<models::ThetaEnergy> bending(scene, {.projection = models::BendingProjection::eigen});
  AssemblyPlan plan;
  membrane.declare(plan);
  bending.declare(plan);
  plan.finalize(n);
  ElementBuffer buf = plan.make_buffer();
  ClothSystem sys;
  sys.m = m;
  sys.A = plan.pattern();
  buf.start(sys.A);
  membrane.add_hessian(s, buf, HessianMode::projected);
  bending.add_hessian(s, buf, HessianMode::projected);
  buf.finish();
  sys.A.scale(dt * dt);
  Eigen::VectorXd mass3(3 * n);
  for (int i = 0; i < n; ++i) mass3.segment<3>(3 * i).setConstant(s.mass[i]);
  sys.A.add_diagonal(mass3);
  Eigen::VectorXd g = Eigen::VectorXd::Zero(3 * n);
  membrane.add_gradient(s, g);
  bending.add_gradient(s, g);
  for (int i = 0; i < n; ++i) g[3 * i + 2] += 9.81 * s.mass[i];
  sys.b = -dt * dt * g;
  sys.x = s.x;
  sys.pins.reset(n);
  const double h = 1e-3;  // prescribed increments of pinned vertices [m]
  for (int i = 0; i < n; ++i) {
    const double u = gen.V(i, 0), v = gen.V(i, 1);
    const bool left = u < -0.5 + 1e-9, right = u > 0.5 - 1e-9, bottom = v < -0.5 + 1e-9, top = v > 0.5 - 1e-9;
    bool pin = false;
    switch (pins) {
      case Pins::none: break;
      case Pins::boundary: pin = left || right || bottom || top; break;
      case Pins::two_sides: pin = left || right; break;
      case Pins::reentrant: pin = (std::abs(u) < 1e-9 && v >= -1e-9) || (std::abs(v) < 1e-9 && u >= -1e-9); break;
    }
    if (pin) sys.pins.fix(i, Eigen::Vector3d(h * std::sin(7 * u), h * std::cos(5 * v), h * u * v));
  }
  return sys;
}

/// The pins of `base` plus contact-style constraints on free vertices: one direction on
/// every 5th vertex, two on (most) every 7th, with non-zero prescribed values.
inline ConstraintSet with_contacts(const ConstraintSet& base, std::uint32_t seed) {
  ConstraintSet c = base;
  Rng rng(seed);
  for (int i = 0; i < c.num_vertices(); ++i) {
    if (c.count(i) != 0) continue;
    if (i % 5 == 1) {
      c.add_direction(i, rng.vec3(), 1e-3 * rng.uniform(-1, 1));
    } else if (i % 7 == 2) {
      c.add_direction(i, rng.vec3(), 1e-3 * rng.uniform(-1, 1));
      c.add_direction(i, rng.vec3(), 1e-3 * rng.uniform(-1, 1));
    }
  }
  return c;
}

/// Ground truth for constrained solves: the dense KKT system [[A C^T][C 0]] [x; lambda] =
/// [b; C z] (methods/multigrid §7.1), rows of C the constrained directions n_{i,m}^T, by full-pivot LU.
inline Eigen::VectorXd dense_kkt_solve(const BlockCsr& A, const Eigen::VectorXd& b, const ConstraintSet& c) {
  const int n = A.rows();
  int m = 0;
  for (int i = 0; i < c.num_vertices(); ++i) m += c.count(i);
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n + m, n + m);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n + m);
  K.topLeftCorner(n, n) = A.to_dense();
  rhs.head(n) = b;
  int row = n;
  for (int i = 0; i < c.num_vertices(); ++i)
    for (int k = 0; k < c.count(i); ++k, ++row) {
      const Eigen::Vector3d nk = c.directions(i).col(k);
      K.block<1, 3>(row, 3 * i) = nk.transpose();
      K.block<3, 1>(3 * i, row) = nk;
      rhs[row] = nk.dot(c.target().segment<3>(3 * i));
    }
  return K.fullPivLu().solve(rhs).head(n);
}

}  // namespace weft::support
