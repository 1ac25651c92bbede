#include "models/hinge_bending.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <climits>
#include <cmath>
#include <limits>
#include <numbers>

#include "framework/error.hpp"

namespace weft::models {
namespace bending {

TriangleFrame triangle_frame(const Eigen::Vector3d& v0, const Eigen::Vector3d& v1, const Eigen::Vector3d& v2) {
  TriangleFrame t;
  t.e = {v2 - v1, v0 - v2, v1 - v0};
  const Eigen::Vector3d c = t.e[1].cross(t.e[2]);  // = (v1 - v0) x (v2 - v0)
  const double a2 = c.norm();
  t.area = 0.5 * a2;
  t.n = c / a2;
  for (int i = 0; i < 3; ++i) {
    t.l[i] = t.e[i].norm();
    t.e_hat[i] = t.e[i] / t.l[i];
    t.h[i] = a2 / t.l[i];
  }
  for (int i = 0; i < 3; ++i) {
    t.cos_alpha[i] = -t.e_hat[(i + 1) % 3].dot(t.e_hat[(i + 2) % 3]);
    t.m[i] = t.e_hat[i].cross(t.n);
  }
  return t;
}

HingeFrames hinge_frames(const Eigen::Vector3d& x0, const Eigen::Vector3d& x1, const Eigen::Vector3d& x2,
                         const Eigen::Vector3d& x3) {
  return {triangle_frame(x0, x1, x2), triangle_frame(x3, x2, x1)};
}

HingeAngle hinge_angle(const HingeFrames& f) {
  const Eigen::Vector3d& n = f.T.n;
  const Eigen::Vector3d& nt = f.Tt.n;
  const double s = n.cross(nt).dot(f.T.e_hat[0]);
  HingeAngle a;
  a.theta = std::atan2(s, n.dot(nt));
  a.normal_sum = (n + nt).norm();
  // Eq. 5.12: better conditioned near |theta| = pi than sin / (1 + cos); at theta = 0 the
  // sign is irrelevant because ||n - n~|| = 0.
  a.tan_half = (s >= 0 ? 1.0 : -1.0) * (n - nt).norm() / a.normal_sum;
  return a;
}

namespace {
// Half-hinge gradient in local labels (wing 0, hinge 1, 2): -n/h0, cos a2/h1 n, cos a1/h2 n.
Eigen::Matrix<double, 9, 1> half_grad(const TriangleFrame& t) {
  Eigen::Matrix<double, 9, 1> g;
  g.segment<3>(0) = -t.n / t.h[0];
  g.segment<3>(3) = (t.cos_alpha[2] / t.h[1]) * t.n;
  g.segment<3>(6) = (t.cos_alpha[1] / t.h[2]) * t.n;
  return g;
}
constexpr int map_T[3] = {0, 1, 2};   // T = (x0, x1, x2)
constexpr int map_Tt[3] = {3, 2, 1};  // T~ = (x3, x2, x1)
}  // namespace

Vec12 grad_theta(const HingeFrames& f) {
  Vec12 g = Vec12::Zero();
  const auto gT = half_grad(f.T), gTt = half_grad(f.Tt);
  for (int k = 0; k < 3; ++k) {
    g.segment<3>(3 * map_T[k]) += gT.segment<3>(3 * k);
    g.segment<3>(3 * map_Tt[k]) += gTt.segment<3>(3 * k);
  }
  return g;
}

Mat9 half_hinge_hessian(const TriangleFrame& t, bool transpose_n0) {
  using M3 = Eigen::Matrix3d;
  const M3 M0 = t.n * t.m[0].transpose(), M1 = t.n * t.m[1].transpose(), M2 = t.n * t.m[2].transpose();
  const M3 N0 = M0 / (t.l[0] * t.l[0]);
  const double w00 = 1.0 / (t.h[0] * t.h[0]), w11 = 1.0 / (t.h[1] * t.h[1]), w22 = 1.0 / (t.h[2] * t.h[2]);
  const double w10 = 1.0 / (t.h[1] * t.h[0]), w20 = 1.0 / (t.h[2] * t.h[0]), w12 = 1.0 / (t.h[1] * t.h[2]);
  const double c1 = t.cos_alpha[1], c2 = t.cos_alpha[2];
  Mat9 B;
  B.block<3, 3>(0, 0) = -w00 * (M0 + M0.transpose());
  B.block<3, 3>(3, 3) = w11 * c2 * (M1 + M1.transpose()) - N0;
  B.block<3, 3>(6, 6) = w22 * c1 * (M2 + M2.transpose()) - N0;
  B.block<3, 3>(3, 0) = w10 * (c2 * M0.transpose() - M1);
  B.block<3, 3>(6, 0) = w20 * (c1 * M0.transpose() - M2);
  B.block<3, 3>(3, 6) = w12 * (c2 * M2.transpose() + c1 * M1);
  if (transpose_n0)
    B.block<3, 3>(3, 6) += N0.transpose();
  else
    B.block<3, 3>(3, 6) += N0;
  B.block<3, 3>(0, 3) = B.block<3, 3>(3, 0).transpose();
  B.block<3, 3>(0, 6) = B.block<3, 3>(6, 0).transpose();
  B.block<3, 3>(6, 3) = B.block<3, 3>(3, 6).transpose();
  return B;
}

Mat12 hess_theta(const HingeFrames& f) {
  Mat12 H = Mat12::Zero();
  const Mat9 BT = half_hinge_hessian(f.T, true), BTt = half_hinge_hessian(f.Tt, false);
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) {
      H.block<3, 3>(3 * map_T[a], 3 * map_T[b]) += BT.block<3, 3>(3 * a, 3 * b);
      H.block<3, 3>(3 * map_Tt[a], 3 * map_Tt[b]) += BTt.block<3, 3>(3 * a, 3 * b);
    }
  // The (x1, x1) and (x2, x2) blocks hold -(N0 + N0~), symmetric only up to rounding.
  return 0.5 * (H + H.transpose());
}

Mat12 project_psd(const Mat12& H) {
  Eigen::SelfAdjointEigenSolver<Mat12> es(H);
  const Vec12 d = es.eigenvalues().cwiseMax(0.0);
  Mat12 P = es.eigenvectors() * d.asDiagonal() * es.eigenvectors().transpose();
  return 0.5 * (P + P.transpose());
}

}  // namespace bending

template <class AngleFunction>
Checker HingeBending<AngleFunction>::validate(const Params& p) {
  Checker c("hinge_bending");
  c.require(p.altitude_tolerance >= 0 && p.altitude_tolerance < 1, "altitude_tolerance", p.altitude_tolerance, "in [0, 1)")
      .require(p.edge_tolerance >= 0 && p.edge_tolerance < 1, "edge_tolerance", p.edge_tolerance, "in [0, 1)")
      .require(p.normal_tolerance >= 0 && p.normal_tolerance < 2, "normal_tolerance", p.normal_tolerance, "in [0, 2)");
  return c;
}

template <class AngleFunction>
HingeBending<AngleFunction>::HingeBending(const Scene& scene, const Params& prm) : prm_(prm) {
  Checker errors = validate(prm);
  for (size_t c = 0; c < scene.spec.cloths.size(); ++c) {
    const double k = scene.spec.cloths[c].material.bending_k();
    errors.require(std::isfinite(k) && k >= 0, fmt::format("cloths.{}.material.bending_k()", c), k, ">= 0");
  }
  if (static_cast<int>(scene.face_cloth.size()) != scene.mesh.num_faces())
    errors.fail(fmt::format("scene.face_cloth has {} entries for {} faces", scene.face_cloth.size(), scene.mesh.num_faces()));
  errors.throw_if_failed("Invalid bending configuration:");

  const auto& X = scene.mesh.rest();
  int bad = 0;
  auto report = [&](std::string msg) {
    if (++bad <= 10) errors.fail(std::move(msg));
  };
  for (const Hinge& hg : scene.mesh.hinges()) {
    const int i = static_cast<int>(hinges_.size());
    bending::HingeRest r;
    r.v = hg.v;
    r.edge = hg.edge;
    const bending::HingeFrames f =
        bending::hinge_frames(X.row(hg.v[0]).transpose(), X.row(hg.v[1]).transpose(), X.row(hg.v[2]).transpose(),
                              X.row(hg.v[3]).transpose());
    r.rest_length = f.T.l;
    r.rest_length_t = f.Tt.l;
    hinges_.push_back(r);
    const bending::HingeAngle a = bending::hinge_angle(f);
    const Defect d = check(f, a, i);
    // Explicit area test too: with altitude_tolerance = 0 a zero-area rest triangle passes `check`.
    if (d == Defect::edge || d == Defect::altitude || !(f.T.area > 0 && f.Tt.area > 0 && std::isfinite(a.theta))) {
      report(fmt::format("hinge {} (edge {}-{}, wings {} and {}) has a degenerate rest triangle (faces {}, {}); remove "
                         "zero-area triangles from the mesh",
                         i, hg.v[1], hg.v[2], hg.v[0], hg.v[3], hg.face[0], hg.face[1]));
      continue;
    }
    if (AngleFunction::requires_open_interval && (d == Defect::normals || !(std::abs(a.theta) < std::numbers::pi))) {
      report(fmt::format("hinge {} (edge {}-{}) has rest angle {} rad; the tan bending energy needs |thetabar| < pi (with "
                         "||n + n~|| >= normal_tolerance = {}): unfold the rest mesh there or use the theta energy",
                         i, hg.v[1], hg.v[2], a.theta, prm_.normal_tolerance));
      continue;
    }
    auto& h = hinges_.back();
    h.theta_bar = a.theta;
    h.phi_bar = AngleFunction::phi(a).value;
    const double k = 0.5 * (scene.face_material(hg.face[0]).bending_k() + scene.face_material(hg.face[1]).bending_k());
    const double a_e = 3.0 * f.T.l[0] * f.T.l[0] / (f.T.area + f.Tt.area);
    h.kappa = k * a_e;
  }
  if (bad > 10) errors.fail(fmt::format("... and {} more degenerate hinges", bad - 10));
  errors.throw_if_failed("Invalid bending configuration:");

  ids_.reserve(4 * hinges_.size());
  for (const auto& h : hinges_) ids_.insert(ids_.end(), h.v.begin(), h.v.end());
}

template <class AngleFunction>
bending::HingeFrames HingeBending<AngleFunction>::frames(const State& s, int i) const {
  const auto& v = hinges_[i].v;
  return bending::hinge_frames(s.x.segment<3>(3 * v[0]), s.x.segment<3>(3 * v[1]), s.x.segment<3>(3 * v[2]),
                               s.x.segment<3>(3 * v[3]));
}

template <class AngleFunction>
typename HingeBending<AngleFunction>::Defect HingeBending<AngleFunction>::check(const bending::HingeFrames& f,
                                                                               const bending::HingeAngle& a, int i) const {
  const auto& r = hinges_[i];
  // Negated comparisons so that NaN counts as degenerate.
  if (!(f.T.l[0] >= prm_.edge_tolerance * r.rest_length[0])) return Defect::edge;
  for (int k = 0; k < 3; ++k)
    if (!(f.T.h[k] >= prm_.altitude_tolerance * r.rest_length[k]) || !(f.Tt.h[k] >= prm_.altitude_tolerance * r.rest_length_t[k]))
      return Defect::altitude;
  if constexpr (AngleFunction::requires_open_interval)
    if (!(a.normal_sum >= prm_.normal_tolerance)) return Defect::normals;
  return Defect::none;
}

template <class AngleFunction>
void HingeBending<AngleFunction>::throw_degenerate(int i, Defect d, std::string_view where) const {
  const auto& v = hinges_[i].v;
  const char* why = d == Defect::edge       ? "its hinge edge collapsed"
                    : d == Defect::altitude ? "a triangle altitude collapsed"
                                            : "its triangles folded onto each other (||n + n~|| below normal_tolerance)";
  throw InvariantError(fmt::format(
      "hinge_bending::{}: hinge {} (edge {}-{}, wings {} and {}) is degenerate: {}; derivatives are undefined there, "
      "check admissible() (or a finite energy()) before evaluating derivatives",
      where, i, v[1], v[2], v[0], v[3], why));
}

template <class AngleFunction>
void HingeBending<AngleFunction>::declare(AssemblyPlan& plan) {
  group_ = plan.add_group(4, ids_);
}

template <class AngleFunction>
double HingeBending<AngleFunction>::angle(const State& s, int i) const {
  return bending::hinge_angle(frames(s, i)).theta;
}

template <class AngleFunction>
double HingeBending<AngleFunction>::energy(const State& s) const {
  double w = 0;
  for (int i = 0; i < num_hinges(); ++i) {
    const auto f = frames(s, i);
    const auto a = bending::hinge_angle(f);
    if (check(f, a, i) != Defect::none) return std::numeric_limits<double>::infinity();
    w += bending::psi<AngleFunction>(a, hinges_[i].phi_bar, hinges_[i].kappa).value;
  }
  return w;
}

template <class AngleFunction>
void HingeBending<AngleFunction>::add_gradient(const State& s, Eigen::VectorXd& g) const {
  WEFT_ASSERT(g.size() == s.x.size(), "gradient has size {}, expected {}", g.size(), s.x.size());
  for (int i = 0; i < num_hinges(); ++i) {
    const auto f = frames(s, i);
    const auto a = bending::hinge_angle(f);
    if (const Defect d = check(f, a, i); d != Defect::none) throw_degenerate(i, d, "add_gradient");
    const double dpsi = bending::psi<AngleFunction>(a, hinges_[i].phi_bar, hinges_[i].kappa).d1;
    const bending::Vec12 gt = bending::grad_theta(f);
    for (int k = 0; k < 4; ++k) g.segment<3>(3 * hinges_[i].v[k]) += dpsi * gt.segment<3>(3 * k);
  }
}

template <class AngleFunction>
void HingeBending<AngleFunction>::add_hessian(const State& s, ElementBuffer& buf, HessianMode mode) const {
  WEFT_ASSERT(group_ >= 0, "{}", "HingeBending::add_hessian before declare(): call declare(plan) first");
  const int nh = num_hinges();
  int first_bad = INT_MAX;
  // Exceptions must not leave an OpenMP region: record the first degenerate hinge, throw after.
#pragma omp parallel for schedule(static) reduction(min : first_bad)
  for (int i = 0; i < nh; ++i) {
    const auto f = frames(s, i);
    const auto a = bending::hinge_angle(f);
    if (check(f, a, i) != Defect::none) {
      first_bad = std::min(first_bad, i);
      buf.set(group_, i, bending::Mat12::Zero());
      continue;
    }
    const bending::Psi p = bending::psi<AngleFunction>(a, hinges_[i].phi_bar, hinges_[i].kappa);
    const bending::Vec12 gt = bending::grad_theta(f);
    bending::Mat12 H = p.d1 * bending::hess_theta(f);
    H.noalias() += p.d2 * gt * gt.transpose();
    if (mode == HessianMode::projected) H = bending::project_psd(H);
    buf.set(group_, i, H);
  }
  if (first_bad != INT_MAX) {
    const auto f = frames(s, first_bad);
    throw_degenerate(first_bad, check(f, bending::hinge_angle(f), first_bad), "add_hessian");
  }
}

template <class AngleFunction>
void HingeBending<AngleFunction>::energy_terms(const State& s, EnergyTerms& terms) const {
  terms.emplace_back("bending", energy(s));
}

template <class AngleFunction>
bool HingeBending<AngleFunction>::admissible(const State& s) const {
  if (!s.x.allFinite()) return false;
  for (int i = 0; i < num_hinges(); ++i) {
    const auto f = frames(s, i);
    if (check(f, bending::hinge_angle(f), i) != Defect::none) return false;
  }
  return true;
}

template class HingeBending<ThetaEnergy>;
template class HingeBending<TanEnergy>;

}  // namespace weft::models
