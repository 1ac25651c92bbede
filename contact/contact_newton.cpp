#include "contact/contact_newton.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <Eigen/SparseLU>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "contact/coulomb.hpp"
#include "framework/interrupt.hpp"

namespace weft::contact {

using Eigen::Matrix3d;
using Eigen::MatrixXd;
using Eigen::Vector2d;
using Eigen::Vector3d;
using Eigen::VectorXd;

void fischer_burmeister_jacobian(const Vector3d& r, const Vector3d& u, double mu, double s, Matrix3d& A, Matrix3d& B) {
  A.setZero();
  B.setZero();
  if (!(mu > 0)) {  // phi = (a + c - |(a, c)|, s r_t), a = s r_n, c = u_n
    const double a = s * r[0], c = u[0], h = std::hypot(a, c);
    const double da = h > 0 ? 1 - a / h : 1 - std::numbers::sqrt2 / 2, dc = h > 0 ? 1 - c / h : 1 - std::numbers::sqrt2 / 2;
    A(0, 0) = s * da;
    B(0, 0) = dc;
    A(1, 1) = A(2, 2) = s;
    return;
  }
  // x = Dx r, y = y(u) with Dy = dy/du (|u_t| differentiated as u_t / |u_t|, 0 at u_t = 0).
  const Vector2d ut = u.tail<2>();
  const double nt = ut.norm();
  const Vector3d x(s * mu * r[0], s * r[1], s * r[2]);
  const Vector3d y((u[0] + mu * nt) / mu, ut[0], ut[1]);
  const Matrix3d Dx = Vector3d(s * mu, s, s).asDiagonal();
  Matrix3d Dy = Matrix3d::Identity();
  Dy(0, 0) = 1 / mu;
  if (nt > 0) Dy.block<1, 2>(0, 1) = ut.transpose() / nt;
  // w = (x o x + y o y)^1/2 by its spectral values wp >= wm >= 0 (as fischer_burmeister_vector).
  const double z0 = x.squaredNorm() + y.squaredNorm();
  const Vector2d zb = 2.0 * (x[0] * x.tail<2>() + y[0] * y.tail<2>());
  const double nz = zb.norm();
  const double wp = std::sqrt(std::max(0.0, z0 + nz));
  if (!(wp > 0)) {  // x = y = 0: the element with dw = 0
    A = Dx;
    B = Dy;
    return;
  }
  // w o w = x o x + y o y gives L_w dw = L_x dx + L_y dy (L_a: the arrow matrix of a). L_w is
  // singular where w reaches the cone's boundary (wm = 0): there wm is raised to 1e-10 wp,
  // which gives a nearby element (the Jacobian of the smoothed function, Chen, Sun & Sun 2003).
  const double wm = std::max(std::sqrt(std::max(0.0, z0 - nz)), 1e-10 * wp);
  const Vector2d dir = nz > 0 ? Vector2d(zb / nz) : Vector2d(1, 0);
  auto arrow = [](double a0, const Vector2d& ab) {
    Matrix3d L = a0 * Matrix3d::Identity();
    L.block<1, 2>(0, 1) = ab.transpose();
    L.block<2, 1>(1, 0) = ab;
    return L;
  };
  const Matrix3d Lw = arrow(0.5 * (wp + wm), 0.5 * (wp - wm) * dir);
  const Matrix3d Lw_inv = Lw.inverse();
  A = Dx - Lw_inv * arrow(x[0], x.tail<2>()) * Dx;
  B = Dy - Lw_inv * arrow(y[0], y.tail<2>()) * Dy;
}

NewtonContactResult solve_contacts_newton(const NewtonContactProblem& p, const NewtonContactOptions& opt) {
  NewtonContactResult res;
  const DelassusRows& W = *p.W;
  const int m = static_cast<int>(W.size());
  if (m == 0) return res;
  VectorXd lam(3 * m), u(3 * m), phi(3 * m);
  // lambda, u and Phi of the current iterate; returns max_k |Phi_k|.
  auto refresh = [&] {
    p.read(lam, u);
    double e = 0;
    for (int i = 0; i < m; ++i) {
      phi.segment<3>(3 * i) = fischer_burmeister_vector(lam.segment<3>(3 * i), u.segment<3>(3 * i), p.mu[i], p.scale[i]);
      e = std::max(e, phi.segment<3>(3 * i).norm());
    }
    return e;
  };
  // Phi at (l, w) without touching the state; returns 1/2 |Phi|^2.
  auto merit_at = [&](const VectorXd& l, const VectorXd& w) {
    double f2 = 0;
    for (int i = 0; i < m; ++i)
      f2 += fischer_burmeister_vector(l.segment<3>(3 * i), w.segment<3>(3 * i), p.mu[i], p.scale[i]).squaredNorm();
    return 0.5 * f2;
  };
  auto times_W = [&](const VectorXd& v) {
    VectorXd out = VectorXd::Zero(3 * m);
    for (int i = 0; i < m; ++i)
      for (const DelassusBlock& b : W[i]) out.segment<3>(3 * i) += b.w * v.segment<3>(3 * b.col);
    return out;
  };

  double err = refresh();
  double best = err;
  VectorXd best_lam = lam;
  int stalls = 0;
  std::vector<int> active, pos(m);
  std::vector<Matrix3d> A(m), B(m);
  while (err > opt.tolerance && res.iterations < opt.max_iterations) {
    if (stop_requested()) break;  // framework/interrupt.hpp: the caller reports the interruption
    ++res.iterations;
    // 1. The contacts in the system and their local derivatives.
    active.clear();
    for (int i = 0; i < m; ++i) {
      pos[i] = -1;
      if ((lam.segment<3>(3 * i).array() == 0).all() && u[3 * i] > 0) continue;  // take-off: stays at lambda = 0
      pos[i] = static_cast<int>(active.size());
      active.push_back(i);
      fischer_burmeister_jacobian(lam.segment<3>(3 * i), u.segment<3>(3 * i), p.mu[i], p.scale[i], A[i], B[i]);
    }
    const int n = 3 * static_cast<int>(active.size());
    if (n == 0) break;
    // 2. J = A + B W on them, and the regularised Jr = A + B (W + rho S).
    double U = std::numeric_limits<double>::min();
    for (int i : active) U = std::max({U, u.segment<3>(3 * i).norm(), p.scale[i] * lam.segment<3>(3 * i).norm()});
    const double rho = std::clamp(err / U, 1e-10, 1e-3);
    std::vector<Eigen::Triplet<double>> trip, trip_r;
    VectorXd f(n);
    for (int a = 0; a < static_cast<int>(active.size()); ++a) {
      const int i = active[a];
      f.segment<3>(3 * a) = phi.segment<3>(3 * i);
      for (const DelassusBlock& b : W[i]) {
        if (pos[b.col] < 0) continue;
        Matrix3d J = B[i] * b.w;
        if (b.col == i) J += A[i];
        Matrix3d Jr = J;
        if (b.col == i) Jr += rho * p.scale[i] * B[i];
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) {
            trip.emplace_back(3 * a + r, 3 * pos[b.col] + c, J(r, c));
            trip_r.emplace_back(3 * a + r, 3 * pos[b.col] + c, Jr(r, c));
          }
      }
    }
    Eigen::SparseMatrix<double> J(n, n), Jr(n, n);
    J.setFromTriplets(trip.begin(), trip.end());
    Jr.setFromTriplets(trip_r.begin(), trip_r.end());
    const bool dense = n <= opt.dense_limit;
    MatrixXd Jd, Jrd;
    if (dense) Jd = MatrixXd(J), Jrd = MatrixXd(Jr);
    const double merit = 0.5 * phi.squaredNorm();
    // 3. The step along delta (on the active contacts) that decreases the merit by Armijo's
    // rule, and that merit; an empty step when there is none.
    struct Trial {
      VectorXd step;
      double merit = std::numeric_limits<double>::infinity();
    };
    auto search = [&](const VectorXd& delta) {
      Trial best_trial;
      if (delta.size() != n || !delta.allFinite()) return best_trial;
      const VectorXd Jdelta = dense ? VectorXd(Jd * delta) : VectorXd(J * delta);
      const double slope = f.dot(Jdelta);
      if (!(slope < 0)) return best_trial;
      VectorXd step = VectorXd::Zero(3 * m);
      for (int a = 0; a < static_cast<int>(active.size()); ++a) step.segment<3>(3 * active[a]) = delta.segment<3>(3 * a);
      const VectorXd Wstep = times_W(step);
      for (double t = 1; t > 1e-10; t *= 0.5) {
        const double mt = merit_at(lam + t * step, u + t * Wstep);
        if (mt <= merit + 1e-4 * t * slope) {
          best_trial.step = t * step;
          best_trial.merit = mt;
          break;
        }
      }
      return best_trial;
    };
    // Levenberg-Marquardt direction: (J^T J + nu I) delta = -J^T f.
    const VectorXd g = dense ? VectorXd(Jd.transpose() * f) : VectorXd(J.transpose() * f);
    // J^T J only when a Levenberg-Marquardt step is tried (most iterations take the Newton
    // step; the product costs more than the LU of J).
    MatrixXd N;
    Eigen::SparseMatrix<double> Ns;
    double d0 = 0;  // largest diagonal entry of J^T J; 0: not formed yet
    auto normal_matrix = [&] {
      if (d0 > 0) return;
      d0 = std::numeric_limits<double>::min();
      if (dense) {
        N = Jd.transpose() * Jd;
        d0 = std::max(d0, N.diagonal().maxCoeff());
      } else {
        Ns = J.transpose() * J;
        for (int c = 0; c < n; ++c) d0 = std::max(d0, Ns.coeff(c, c));
      }
    };
    auto levenberg_marquardt = [&](double nu) -> VectorXd {
      if (dense) {
        MatrixXd Nn = N;
        Nn.diagonal().array() += nu;
        return Nn.ldlt().solve(-g);
      }
      Eigen::SparseMatrix<double> I(n, n);
      I.setIdentity();
      Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(Ns + nu * I);
      if (ldlt.info() != Eigen::Success) return VectorXd();
      return ldlt.solve(-g);
    };
    // The Newton step; with redundant contacts (J singular) it is large along the null
    // space and damped hard, so a lightly regularised Levenberg-Marquardt step competes
    // with it and the lower merit wins.
    // The stick step: every pressed contact (lambda_n > 0) sticks, u_k + (W delta)_k = 0 on
    // them (the normal row only without friction), the others keep their multipliers. A linear
    // system, exact when that regime is the solution's; W_SS + 1e-10 s I keeps the split of
    // exactly redundant contacts (minimum change along W's null space).
    auto stick_step = [&]() -> Trial {
      Trial out;
      std::vector<int> idx;  // entries of lambda in the system
      for (int i : active) {
        if (!(lam[3 * i] > 0)) continue;
        for (int c = 0; c < (p.mu[i] > 0 ? 3 : 1); ++c) idx.push_back(3 * i + c);
      }
      const int ns = static_cast<int>(idx.size());
      if (ns == 0) return out;
      std::vector<int> at(3 * m, -1);
      for (int a = 0; a < ns; ++a) at[idx[a]] = a;
      std::vector<Eigen::Triplet<double>> tw;
      VectorXd rhs(ns);
      for (int a = 0; a < ns; ++a) {
        const int i = idx[a] / 3, r = idx[a] % 3;
        rhs[a] = -u[idx[a]];
        tw.emplace_back(a, a, 1e-10 * p.scale[i]);
        for (const DelassusBlock& b : W[i])
          for (int c = 0; c < 3; ++c)
            if (at[3 * b.col + c] >= 0) tw.emplace_back(a, at[3 * b.col + c], b.w(r, c));
      }
      Eigen::SparseMatrix<double> Ws(ns, ns);
      Ws.setFromTriplets(tw.begin(), tw.end());
      VectorXd sol;
      if (ns <= opt.dense_limit) {
        sol = MatrixXd(Ws).ldlt().solve(rhs);
      } else {
        Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(Ws);
        if (ldlt.info() != Eigen::Success) return out;
        sol = ldlt.solve(rhs);
      }
      if (!sol.allFinite()) return out;
      VectorXd step = VectorXd::Zero(3 * m);
      for (int a = 0; a < ns; ++a) step[idx[a]] = sol[a];
      const double mt = merit_at(lam + step, u + times_W(step));
      if (mt < merit) out.step = std::move(step), out.merit = mt;
      return out;
    };
    Trial trial;
    {
      VectorXd delta;
      if (dense) {
        const Eigen::PartialPivLU<MatrixXd> lu(Jrd);
        delta = lu.solve(-f);
        if (!((Jrd * delta + f).norm() <= 1e-6 * f.norm())) delta.resize(0);
      } else {
        Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
        lu.compute(Jr);
        if (lu.info() == Eigen::Success) {
          delta = lu.solve(-f);
          if (!((Jr * delta + f).norm() <= 1e-6 * f.norm())) delta.resize(0);
        }
      }
      trial = search(delta);
      if (!(trial.merit <= 0.25 * merit)) {  // not a full Newton decrease: try the stick and regularised steps too
        Trial st = stick_step();
        if (st.merit < trial.merit) {
          trial = std::move(st);
          ++res.stick_steps;
        }
        // In the sparse path (NewtonContactOptions::sparse_lm_only_when_stuck) the damped step
        // competes only when neither step decreased the merit: there its LDL^T of J^T J (which
        // couples every contact to those two rods away) cost 53 of 94 s on V-21's 1600-contact
        // group and rarely won (bench/results/rods/contact_newton_v21/). The dense path keeps
        // it: on cloth's resting stacks (linear compliance) it wins often enough that solves
        // converged in 22 of 48 instead of 28 without it.
        if (!(trial.merit <= 0.25 * merit) && (dense || trial.step.size() == 0 || !opt.sparse_lm_only_when_stuck)) {
          normal_matrix();
          Trial lm = search(levenberg_marquardt(1e-10 * d0));
          if (lm.merit < trial.merit) {
            trial = std::move(lm);
            ++res.fallbacks;
          }
        }
      }
    }
    bool moved = trial.step.size() > 0;
    if (!moved) {  // Levenberg-Marquardt with nu raised until the merit decreases
      ++res.fallbacks;
      normal_matrix();
      for (double nu = 1e-8 * d0; !moved && nu <= 1e2 * d0; nu *= 100) {
        trial = search(levenberg_marquardt(nu));
        moved = trial.step.size() > 0;
      }
    }
    if (moved) p.apply(trial.step);
    if (!moved) {  // Gauss-Seidel: slow but always admissible
      p.sweep(opt.fallback_sweeps);
      res.sweeps += opt.fallback_sweeps;
    }
    const double before = best;
    err = refresh();
    if (err < best) best = err, best_lam = lam;
    // Fallbacks that do not improve on the best iterate three times in a row: give up.
    stalls = moved || best < (1 - 1e-3) * before ? 0 : stalls + 1;
    if (stalls >= 3) break;
  }
  if (err > best) {  // back to the best iterate
    p.apply(best_lam - lam);
    err = refresh();
  }
  res.residual = err;
  return res;
}

NewtonContactResult solve_contacts_newton(DenseDelassus& op, std::span<const double> mu, std::vector<Vector3d>& r,
                                          const NewtonContactOptions& opt, const CoulombOptions& local) {
  const int m = op.num_contacts();
  if (static_cast<int>(r.size()) != m) r.assign(m, Vector3d::Zero());
  if (m == 0) return {};
  DelassusRows W(m);
  std::vector<double> scale(m);
  for (int i = 0; i < m; ++i) {
    scale[i] = coulomb_scale(op.block(i));
    for (int j = 0; j < m; ++j) {
      const Matrix3d w = op.matrix().block<3, 3>(3 * i, 3 * j);
      if ((w.array() != 0).any()) W[i].push_back({j, w});
    }
  }
  NewtonContactProblem p{.W = &W, .mu = mu, .scale = scale};
  p.read = [&](VectorXd& lam, VectorXd& u) {
    for (int i = 0; i < m; ++i) lam.segment<3>(3 * i) = r[i];
    u = op.velocities();
  };
  p.apply = [&](const VectorXd& step) {
    for (int i = 0; i < m; ++i) {
      const Vector3d s = step.segment<3>(3 * i);
      if ((s.array() == 0).all()) continue;
      op.add_response(i, s);
      r[i] += s;
    }
  };
  p.sweep = [&](int sweeps) {
    gauss_seidel(op, mu, r, GaussSeidelParams{.tolerance = opt.tolerance, .max_sweeps = sweeps, .local = local});
  };
  return solve_contacts_newton(p, opt);
}

}  // namespace weft::contact
