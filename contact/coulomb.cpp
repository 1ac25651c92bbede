#include "contact/coulomb.hpp"

#include "contact/contact_newton.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace weft::contact {

using Eigen::Matrix3d;
using Eigen::Vector2d;
using Eigen::Vector3d;

namespace {

CoulombRegime classify(const Vector3d& r, double mu) {
  if (!(r[0] > 0)) return CoulombRegime::take_off;
  if (!(mu > 0)) return CoulombRegime::slide;
  return r.tail<2>().norm() < mu * r[0] * (1 - 1e-8) ? CoulombRegime::stick : CoulombRegime::slide;
}

struct Candidate {
  Vector3d r = Vector3d::Zero();
  double residual = std::numeric_limits<double>::infinity();
};

/// Newton on phi_FB from r0. \returns the best iterate.
Candidate newton(const Matrix3d& W, const Vector3d& b, double mu, double s, Vector3d r, double tol, int max_it, int& iterations) {
  auto F = [&](const Vector3d& q) { return fischer_burmeister_vector(q, W * q + b, mu, s); };
  Vector3d f = F(r);
  double f2 = f.squaredNorm();
  for (iterations = 0; iterations < max_it && std::sqrt(f2) > tol; ++iterations) {
    // J = dphi/dr + dphi/du W, an element of the generalised Jacobian (contact_newton.hpp).
    Matrix3d A, B;
    fischer_burmeister_jacobian(r, W * r + b, mu, s, A, B);
    const Matrix3d J = A + B * W;
    const Vector3d step = J.fullPivLu().solve(-f);
    if (!step.allFinite()) break;
    double t = 1.0;
    bool accepted = false;
    for (int k = 0; k < 40; ++k, t *= 0.5) {
      const Vector3d q = r + t * step;
      const Vector3d fq = F(q);
      if (fq.squaredNorm() <= (1 - 1e-4 * t) * f2) {
        r = q;
        f = fq;
        f2 = fq.squaredNorm();
        accepted = true;
        break;
      }
    }
    if (!accepted) break;
  }
  return {r, std::sqrt(f2)};
}

/// The enumerative failsafe over the sliding angle (file comment of coulomb.hpp). The
/// scalar equation e x u_t(theta) = 0 is multiplied by den(theta) = W_nn + mu W_nt . e,
///     F(theta) = e x (den b_t - b_n (W_tn + mu W_tt e)),
/// which has the same roots where den > 0 and no pole where den vanishes (the admissible
/// root may lie arbitrarily close to it: r_n = -b_n / den is then large). F is a
/// trigonometric polynomial of degree 2 (at most 4 roots: the quartic of Daviet et al.).
Candidate enumerate(const Matrix3d& W, const Vector3d& b, double mu, double s, int samples) {
  const Vector2d wtn = W.col(0).tail<2>();
  const Eigen::Matrix2d wtt = W.bottomRightCorner<2, 2>();
  const Vector2d wnt = W.row(0).tail<2>();
  auto F = [&](double th) {
    const Vector2d e(std::cos(th), std::sin(th));
    const double den = W(0, 0) + mu * wnt.dot(e);
    const Vector2d a = den * b.tail<2>() - b[0] * (wtn + mu * wtt * e);
    return e[0] * a[1] - e[1] * a[0];
  };
  Candidate best;
  auto consider = [&](double th) {
    const Vector2d e(std::cos(th), std::sin(th));
    const double den = W(0, 0) + mu * wnt.dot(e);
    if (!(den > 0)) return;
    const double rn = -b[0] / den;
    if (!(rn > 0) || !std::isfinite(rn)) return;
    const Vector3d r(rn, mu * rn * e[0], mu * rn * e[1]);
    const Vector3d u = W * r + b;
    if (e.dot(u.tail<2>()) > 1e-12 * u.tail<2>().norm()) return;  // u_t along the friction: not Coulomb
    const double res = fischer_burmeister(r, u, mu, s);
    if (res < best.residual) best = {r, res};
  };
  const double step = 2 * std::numbers::pi / samples;
  double prev = F(0.0);
  for (int i = 1; i <= samples; ++i) {
    double lo = (i - 1) * step, hi = i * step;
    const double next = F(hi);
    if (prev == 0) {
      consider(lo);
    } else if ((prev < 0) != (next < 0)) {
      double flo = prev;
      for (int k = 0; k < 200 && hi - lo > 4e-16 * std::max(1.0, hi); ++k) {
        const double mid = 0.5 * (lo + hi);
        const double fm = F(mid);
        if (fm == 0) {
          lo = hi = mid;
          break;
        }
        if ((fm < 0) == (flo < 0)) {
          lo = mid;
          flo = fm;
        } else {
          hi = mid;
        }
      }
      consider(0.5 * (lo + hi));
    }
    prev = next;
  }
  return best;
}

}  // namespace

Vector3d fischer_burmeister_vector(const Vector3d& r, const Vector3d& u, double mu, double s) {
  if (!(mu > 0)) {
    const double a = s * r[0], c = u[0];
    return Vector3d(a + c - std::hypot(a, c), s * r[1], s * r[2]);
  }
  const Vector2d ut = u.tail<2>();
  const Vector3d x(s * mu * r[0], s * r[1], s * r[2]);
  const Vector3d y((u[0] + mu * ut.norm()) / mu, ut[0], ut[1]);
  const double z0 = x.squaredNorm() + y.squaredNorm();
  const Vector2d zb = 2.0 * (x[0] * x.tail<2>() + y[0] * y.tail<2>());
  const double nz = zb.norm();
  const Vector2d dir = nz > 0 ? Vector2d(zb / nz) : Vector2d(1, 0);
  const double wp = std::sqrt(std::max(0.0, z0 + nz)), wm = std::sqrt(std::max(0.0, z0 - nz));
  Vector3d root;
  root[0] = 0.5 * (wp + wm);
  root.tail<2>() = 0.5 * (wp - wm) * dir;
  return x + y - root;
}

double coulomb_scale(const Matrix3d& W) {
  const double t = W.trace() / 3;
  return t > 0 && std::isfinite(t) ? t : 1.0;
}

double fischer_burmeister(const Vector3d& r, const Vector3d& u, double mu, double scale) {
  return fischer_burmeister_vector(r, u, mu, scale).norm();
}

CoulombResult solve_coulomb(const Matrix3d& W, const Vector3d& b, double mu, const Vector3d& guess, const CoulombOptions& opt) {
  CoulombResult res;
  const double s = coulomb_scale(W);
  auto finish = [&](const Vector3d& r, CoulombRegime regime) -> CoulombResult& {
    res.r = r;
    res.u = W * r + b;
    res.residual = fischer_burmeister(r, res.u, mu, s);
    res.regime = regime;
    return res;
  };
  // 1. Take-off.
  if (!(b[0] < 0)) return finish(Vector3d::Zero(), CoulombRegime::take_off);
  const double tol = std::max(opt.tolerance * (b.norm() + s * guess.norm()), std::numeric_limits<double>::min());
  // Frictionless: closed form.
  if (!(mu > 0)) {
    if (!(W(0, 0) > 0)) return finish(Vector3d::Zero(), CoulombRegime::failed);
    return finish(Vector3d(-b[0] / W(0, 0), 0, 0), CoulombRegime::slide);
  }
  // 2. Stick.
  const Eigen::FullPivLU<Matrix3d> lu(W);
  const Vector3d stick = lu.solve(-b);
  // (backward-stable test: a singular W is rejected unless its least-squares r solves it)
  if (stick.allFinite() && (W * stick + b).norm() <= 1e-10 * (b.norm() + W.norm() * stick.norm()) && stick[0] > 0 &&
      stick.tail<2>().norm() <= mu * stick[0] * (1 + 1e-12))
    return finish(stick, CoulombRegime::stick);
  // 3. Slide: Newton from the warm start when it is in the cone, else from the projection
  // of the stick solution onto the cone (or the isotropic guess).
  Vector3d r0;
  if (guess[0] > 0 && guess.tail<2>().norm() <= mu * guess[0] * (1 + 1e-9)) {
    r0 = guess;
  } else {
    const double wn = W(0, 0) > 0 ? W(0, 0) : s;
    const double rn = -b[0] / wn;
    const Vector2d bt = b.tail<2>();
    r0 = Vector3d(rn, 0, 0);
    if (bt.norm() > 0) r0.tail<2>() = -mu * rn * bt / bt.norm();
    if (stick.allFinite() && stick[0] > 0) {  // projection of the stick solution onto the cone
      const double nt = stick.tail<2>().norm();
      const double a = (stick[0] + mu * nt) / (1 + mu * mu);
      if (a > 0 && nt > 0) r0 = Vector3d(a, mu * a * stick[1] / nt, mu * a * stick[2] / nt);
    }
  }
  Candidate best = newton(W, b, mu, s, r0, tol, opt.max_newton, res.newton_iterations);
  if (!(best.residual <= tol) || classify(best.r, mu) == CoulombRegime::take_off || best.r[0] < 0 ||
      best.r.tail<2>().norm() > mu * best.r[0] * (1 + 1e-6)) {
    // 4. Enumerative failsafe.
    const Candidate e = enumerate(W, b, mu, s, opt.angle_samples);
    if (e.residual < best.residual || best.r[0] < 0) {
      best = e;
      res.enumerative = true;
      if (!(best.residual <= tol)) {  // polish: Newton from the root (near a pole of r_n(theta))
        int it = 0;
        const Candidate p = newton(W, b, mu, s, best.r, tol, opt.max_newton, it);
        res.newton_iterations += it;
        if (p.residual < best.residual && p.r[0] > 0) best = p;
      }
    }
  }
  if (!std::isfinite(best.residual)) return finish(Vector3d::Zero(), CoulombRegime::failed);
  CoulombResult& out = finish(best.r, classify(best.r, mu));
  if (!(out.residual <= 1e4 * tol)) out.regime = CoulombRegime::failed;  // neither path converged
  return out;
}

}  // namespace weft::contact
