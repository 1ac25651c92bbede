#include "contact/rods/rod_group_solver.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <Eigen/SparseLU>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "contact/coulomb.hpp"

namespace weft::contact::rods {

using Eigen::Matrix3d;
using Eigen::MatrixXd;
using Eigen::Vector2d;
using Eigen::Vector3d;
using Eigen::VectorXd;

Vector3d local_displacement(const RodContactRows& k, const GroupDisplacements& x) {
  Vector3d u = k.b;
  for (int side = 0; side < 2; ++side) {
    if (k.rods[side] < 0) continue;
    const VectorXd& xs = x[k.slot[side]];
    if (k.blocks[side] < 0) {
      u += k.G[side].transpose() * xs;
      continue;
    }
    for (int j = 0; j < k.blocks[side]; ++j) {
      const int row = 4 * k.stencil[side][j];
      u += k.G[side].middleRows<3>(row).transpose() * xs.segment<3>(row);
    }
  }
  return u;
}

void add_response(const RodContactRows& k, const Vector3d& r, GroupDisplacements& x) {
  for (int side = 0; side < 2; ++side)
    if (k.rods[side] >= 0) x[k.slot[side]] += k.P[side] * r;
}

double contact_error(const std::vector<RodContactRows>& cs, const std::vector<int>& ids, const GroupDisplacements& x) {
  double e = 0;
  for (int id : ids) {
    const RodContactRows& k = cs[id];
    e = std::max(e, fischer_burmeister(k.lambda, local_displacement(k, x), k.mu, k.scale));
  }
  return e;
}

std::pair<double, double> gauss_seidel_sweep(std::vector<RodContactRows>& cs, const std::vector<int>& ids, GroupDisplacements& x,
                                             SweepMode mode) {
  double change = 0, size = 0;
  for (int id : ids) {
    RodContactRows& k = cs[id];
    const Vector3d u = local_displacement(k, x);
    const Vector3d b = u - k.W * k.lambda;
    Vector3d r = k.lambda;
    if (mode == SweepMode::coulomb) {
      r = solve_coulomb(k.W, b, k.mu, k.lambda).r;
    } else if (mode == SweepMode::normal) {  // min over r_n >= 0 of 1/2 W_nn r_n^2 + r_n (b_n + W_nt r_t)
      const double bn = b[0] + k.W.row(0).tail<2>().dot(k.lambda.tail<2>());
      r[0] = k.W(0, 0) > 0 ? std::max(0.0, -bn / k.W(0, 0)) : 0.0;
    } else {  // min over |r_t| <= mu r_n of 1/2 r_t^T W_tt r_t + r_t^T (b_t + W_tn r_n): projected Newton on the disk
      const Eigen::Matrix2d Wt = k.W.bottomRightCorner<2, 2>();
      const Vector2d bt = b.tail<2>() + k.W.bottomLeftCorner<2, 1>() * k.lambda[0];
      const double radius = k.mu * std::max(0.0, k.lambda[0]);
      Vector2d rt = -Wt.ldlt().solve(bt);
      if (!(rt.norm() <= radius)) {
        // Projected gradient on the disk with step 1 / lambda_max(W_tt), to convergence.
        const double L = std::max(Wt.eigenvalues().real().maxCoeff(), 1e-300);
        rt = k.lambda.tail<2>();
        for (int it = 0; it < 200; ++it) {
          Vector2d next = rt - (Wt * rt + bt) / L;
          if (next.norm() > radius) next *= radius / next.norm();
          const bool done = (next - rt).norm() <= 1e-14 * (radius + 1e-300);
          rt = next;
          if (done) break;
        }
      }
      r.tail<2>() = rt;
    }
    add_response(k, r - k.lambda, x);
    change = std::max(change, (r - k.lambda).norm() * k.scale);
    size = std::max(size, r.norm() * k.scale);
    k.lambda = r;
  }
  return {change, size};
}

namespace {

/// The block rows of W = [G_k^T P_l] over the contacts `ids` (index = position in ids):
/// per rod slot, every pair of contacts on it, over the nonzero rows of G_k only.
DelassusRows delassus(const std::vector<RodContactRows>& cs, const std::vector<int>& ids) {
  const int m = static_cast<int>(ids.size());
  int slots = 0;
  for (int id : ids) slots = std::max({slots, cs[id].slot[0] + 1, cs[id].slot[1] + 1});
  std::vector<std::vector<std::pair<int, int>>> on(slots);  // (contact, side) per slot
  std::vector<std::array<std::vector<int>, 2>> rows(m);     // nonzero rows of G_k per side
  for (int i = 0; i < m; ++i) {
    const RodContactRows& k = cs[ids[i]];
    for (int side = 0; side < 2; ++side) {
      if (k.rods[side] < 0) continue;
      on[k.slot[side]].emplace_back(i, side);
      for (Eigen::Index r = 0; r < k.G[side].rows(); ++r)
        if (k.G[side].row(r).squaredNorm() > 0) rows[i][side].push_back(static_cast<int>(r));
    }
  }
  DelassusRows W(m);
  for (const auto& list : on)
    for (const auto& [i, a] : list)
      for (const auto& [j, b] : list) {
        Matrix3d w = Matrix3d::Zero();
        for (int r : rows[i][a]) w += cs[ids[i]].G[a].row(r).transpose() * cs[ids[j]].P[b].row(r);
        W[i].push_back({j, w});
      }
  // Two contacts between the same two rods meet on both slots: one block, summed in slot order.
  for (auto& row : W) {
    std::stable_sort(row.begin(), row.end(), [](const DelassusBlock& p, const DelassusBlock& q) { return p.col < q.col; });
    size_t out = 0;
    for (size_t k = 0; k < row.size(); ++k) {
      if (out > 0 && row[out - 1].col == row[k].col) row[out - 1].w += row[k].w;
      else row[out++] = row[k];
    }
    row.resize(out);
  }
  return W;
}

}  // namespace

NewtonContactResult solve_contacts_newton(std::vector<RodContactRows>& cs, const std::vector<int>& ids, GroupDisplacements& x,
                                          const NewtonContactOptions& opt) {
  const int m = static_cast<int>(ids.size());
  if (m == 0) return {};
  const DelassusRows W = delassus(cs, ids);
  std::vector<double> mu(m), scale(m);
  for (int i = 0; i < m; ++i) mu[i] = cs[ids[i]].mu, scale[i] = cs[ids[i]].scale;
  NewtonContactProblem p{.W = &W, .mu = mu, .scale = scale};
  p.read = [&](VectorXd& lam, VectorXd& u) {  // u from x, so that round-off does not drift
    for (int i = 0; i < m; ++i) {
      lam.segment<3>(3 * i) = cs[ids[i]].lambda;
      u.segment<3>(3 * i) = local_displacement(cs[ids[i]], x);
    }
  };
  p.apply = [&](const VectorXd& step) {  // lambda += step, x += P step
    for (int i = 0; i < m; ++i) {
      const Vector3d s = step.segment<3>(3 * i);
      if ((s.array() == 0).all()) continue;
      RodContactRows& k = cs[ids[i]];
      add_response(k, s, x);
      k.lambda += s;
    }
  };
  p.sweep = [&](int sweeps) {
    for (int s = 0; s < sweeps; ++s) gauss_seidel_sweep(cs, ids, x, SweepMode::coulomb);
  };
  return contact::solve_contacts_newton(p, opt);
}

}  // namespace weft::contact::rods
