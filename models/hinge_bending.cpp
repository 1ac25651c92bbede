#include "models/hinge_bending.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <numbers>

#include "framework/error.hpp"
#include "models/bending_parallel.hpp"

namespace weft::models {
namespace bending {

TriangleFrame triangle_frame(const Eigen::Vector3d& v0, const Eigen::Vector3d& v1, const Eigen::Vector3d& v2) {
  TriangleFrame t;
  t.e = {v2 - v1, v0 - v2, v1 - v0};
  const Eigen::Vector3d c = t.e[1].cross(t.e[2]);  // = (v1 - v0) x (v2 - v0)
  const double a2 = c.norm(), inv_a2 = 1.0 / a2;
  t.area = 0.5 * a2;
  t.n = c / a2;  // a division: a normal along an axis comes out exactly unit (c * (1 / a2) may not)
  for (int i = 0; i < 3; ++i) {
    t.l[i] = t.e[i].norm();
    const double inv_l = 1.0 / t.l[i];
    t.e_hat[i] = t.e[i] * inv_l;
    t.h[i] = a2 * inv_l;
    t.inv_h[i] = t.l[i] * inv_a2;
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

HingeAngle hinge_angle(const Eigen::Vector3d& n, const Eigen::Vector3d& nt, const Eigen::Vector3d& e_hat) {
  const double s = n.cross(nt).dot(e_hat);
  HingeAngle a;
  a.theta = std::atan2(s, n.dot(nt));
  a.normal_sum = (n + nt).norm();
  // Eq. 5.12: better conditioned near |theta| = pi than sin / (1 + cos); at theta = 0 the
  // sign is irrelevant because ||n - n~|| = 0.
  a.tan_half = (s >= 0 ? 1.0 : -1.0) * (n - nt).norm() / a.normal_sum;
  return a;
}

HingeAngle hinge_angle(const HingeFrames& f) { return hinge_angle(f.T.n, f.Tt.n, f.T.e_hat[0]); }

namespace {
constexpr int map_T[3] = {0, 1, 2};   // T = (x0, x1, x2)
constexpr int map_Tt[3] = {3, 2, 1};  // T~ = (x3, x2, x1)
}  // namespace

Vec12 grad_theta(const TriangleFrame& T, int j, const TriangleFrame& Tt, int k) {
  // Eq. 5.4 with each triangle in its own labelling: the half-hinge gradient of a triangle
  // whose hinge is edge j is -n/h_j at the wing v_j, cos a_{j+2}/h_{j+1} n at v_{j+1} and
  // cos a_{j+1}/h_{j+2} n at v_{j+2}; T~ traverses the edge the other way (v_{k+1} = x2).
  const int j1 = (j + 1) % 3, j2 = (j + 2) % 3, k1 = (k + 1) % 3, k2 = (k + 2) % 3;
  Vec12 g;
  g.segment<3>(0) = -T.inv_h[j] * T.n;
  g.segment<3>(3) = (T.cos_alpha[j2] * T.inv_h[j1]) * T.n + (Tt.cos_alpha[k1] * Tt.inv_h[k2]) * Tt.n;
  g.segment<3>(6) = (T.cos_alpha[j1] * T.inv_h[j2]) * T.n + (Tt.cos_alpha[k2] * Tt.inv_h[k1]) * Tt.n;
  g.segment<3>(9) = -Tt.inv_h[k] * Tt.n;
  return g;
}

Vec12 grad_theta(const HingeFrames& f) { return grad_theta(f.T, 0, f.Tt, 0); }

Mat9 half_hinge_hessian(const TriangleFrame& t, bool transpose_n0) {
  using M3 = Eigen::Matrix3d;
  const M3 M0 = t.n * t.m[0].transpose(), M1 = t.n * t.m[1].transpose(), M2 = t.n * t.m[2].transpose();
  const M3 N0 = M0 / (t.l[0] * t.l[0]);
  const auto& ih = t.inv_h;
  const double w00 = ih[0] * ih[0], w11 = ih[1] * ih[1], w22 = ih[2] * ih[2];
  const double w10 = ih[1] * ih[0], w20 = ih[2] * ih[0], w12 = ih[1] * ih[2];
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

namespace {
/// Orthonormal basis of the complement of the translations in R^12: Q = B (x) I3 with the
/// Hadamard columns B = [1 1 -1 -1; 1 -1 1 -1; 1 -1 -1 1]^T / 2, orthogonal to (1, 1, 1, 1).
Eigen::Matrix<double, 12, 9> translation_complement() {
  const double B[4][3] = {{0.5, 0.5, 0.5}, {0.5, -0.5, -0.5}, {-0.5, 0.5, -0.5}, {-0.5, -0.5, 0.5}};
  Eigen::Matrix<double, 12, 9> Q = Eigen::Matrix<double, 12, 9>::Zero();
  for (int a = 0; a < 4; ++a)
    for (int c = 0; c < 3; ++c) Q.block<3, 3>(3 * a, 3 * c) = B[a][c] * Eigen::Matrix3d::Identity();
  return Q;
}
}  // namespace

Mat12 project_psd(const Mat12& H) {
  // H annihilates the translations (theta is invariant under them), so H = Q (Q^T H Q) Q^T
  // and its eigenpairs off the translations are those of the 9x9 Q^T H Q: the same
  // projection as a 12x12 eigen decomposition, in 0.81-0.93x the projected assembly's time
  // (bench/results/hinge-projection).
  static const Eigen::Matrix<double, 12, 9> Q = translation_complement();
  const Eigen::Matrix<double, 9, 9> H9 = Q.transpose() * H * Q;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 9, 9>> es(0.5 * (H9 + H9.transpose()));
  const Eigen::Matrix<double, 9, 1> d = es.eigenvalues().cwiseMax(0.0);
  const Eigen::Matrix<double, 12, 9> V = Q * es.eigenvectors();
  Mat12 P = V * d.asDiagonal() * V.transpose();
  return 0.5 * (P + P.transpose());
}

void triangle_terms(const TriangleFrame& t, const std::array<double, 3>& gamma, const std::array<bool, 3>& transpose,
                    bool hessian, TriangleTerms& out) {
  const auto& ih = t.inv_h;
  double d[3];
  for (int i = 0; i < 3; ++i) {
    const int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
    d[i] = gamma[i2] * t.cos_alpha[i1] + gamma[i1] * t.cos_alpha[i2] - gamma[i];
    out.grad[i] = (d[i] * ih[i]) * t.n;
  }
  if (!hessian) return;
  // sym(R_i) = rho_i S(M_i) with rho_i = gamma_i / (2 l_i^2): every term of the diagonal
  // blocks is a multiple of an exactly symmetric S(M), so they are exactly symmetric.
  Eigen::Matrix3d M[3], SM[3];
  double rho[3];
  for (int i = 0; i < 3; ++i) {
    M[i].noalias() = t.n * t.m[i].transpose();
    SM[i] = M[i] + M[i].transpose();
    rho[i] = 0.5 * gamma[i] / (t.l[i] * t.l[i]);
  }
  for (int i = 0; i < 3; ++i) {
    const int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
    out.diag[i] = (ih[i] * ih[i] * d[i]) * SM[i] - rho[i1] * SM[i1] - rho[i2] * SM[i2];
    out.upper[i] = (ih[i] * ih[i1]) * (d[i] * M[i1].transpose() + d[i1] * M[i]);
    if (transpose[i2])
      out.upper[i] += (2 * rho[i2]) * M[i2].transpose();  // R_{i+2}^T
    else
      out.upper[i] += (2 * rho[i2]) * M[i2];
  }
}

Mat9 triangle_hessian(const TriangleTerms& terms) {
  Mat9 H;
  for (int i = 0; i < 3; ++i) {
    const int i1 = (i + 1) % 3;
    H.block<3, 3>(3 * i, 3 * i) = terms.diag[i];
    H.block<3, 3>(3 * i, 3 * i1) = terms.upper[i];
    H.block<3, 3>(3 * i1, 3 * i) = terms.upper[i].transpose();
  }
  return H;
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
HingeBending<AngleFunction>::HingeBending(const Scene& scene, const Params& prm) : HingeBending(scene, prm, {}) {}

template <class AngleFunction>
HingeBending<AngleFunction>::HingeBending(const Scene& scene, const Params& prm, std::span<const unsigned char> flip_edges)
    : prm_(prm) {
  Checker errors = validate(prm);
  for (size_t c = 0; c < scene.spec.cloths.size(); ++c) {
    const double k = scene.spec.cloths[c].material.bending_k();
    errors.require(std::isfinite(k) && k >= 0, fmt::format("cloths.{}.material.bending_k()", c), k, ">= 0");
  }
  if (static_cast<int>(scene.face_cloth.size()) != scene.mesh.num_faces())
    errors.fail(fmt::format("scene.face_cloth has {} entries for {} faces", scene.face_cloth.size(), scene.mesh.num_faces()));
  if (!flip_edges.empty() && static_cast<int>(flip_edges.size()) != scene.mesh.num_edges())
    errors.fail(fmt::format("flip_edges has {} entries for {} edges", flip_edges.size(), scene.mesh.num_edges()));
  errors.throw_if_failed("Invalid bending configuration:");

  const TriangleMesh& mesh = scene.mesh;
  const auto& X = mesh.rest();
  num_vertices_ = mesh.num_vertices();
  auto local_edge = [&](int f, int e) {
    for (int i = 0; i < 3; ++i)
      if (mesh.face_edges()[f][i] == e) return i;
    return -1;
  };
  int bad = 0;
  auto report = [&](std::string msg) {
    if (++bad <= 10) errors.fail(std::move(msg));
  };
  for (const Hinge& hg : mesh.hinges()) {
    const int i = static_cast<int>(hinges_.size());
    bending::HingeRest r;
    r.v = hg.v;
    r.face = hg.face;
    r.edge = hg.edge;
    // The owner T traverses x1 -> x2 along the edge's global orientation (low -> high id
    // unless flipped); if face[0] goes against it, relabel the hinge from T~.
    std::array<int, 2> dir = mesh.edges()[hg.edge];
    if (!flip_edges.empty() && flip_edges[hg.edge]) std::swap(dir[0], dir[1]);
    if (!(r.v[1] == dir[0] && r.v[2] == dir[1])) {
      r.v = {hg.v[3], hg.v[2], hg.v[1], hg.v[0]};
      r.face = {hg.face[1], hg.face[0]};
    }
    r.local = {local_edge(r.face[0], hg.edge), local_edge(r.face[1], hg.edge)};
    const bending::HingeFrames f =
        bending::hinge_frames(X.row(r.v[0]).transpose(), X.row(r.v[1]).transpose(), X.row(r.v[2]).transpose(),
                              X.row(r.v[3]).transpose());
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
    // Each face's k for bending across this edge (its in-plane normal m to the edge against
    // the face's warp: orthotropic bending), averaged over the two faces.
    auto face_k = [&](int face, const Eigen::Vector3d& m) {
      const ShellMaterial& mat = scene.face_material(face);
      if (!mat.orthotropic() || static_cast<int>(scene.face_warp.size()) <= face) return mat.bending_k();
      return mat.bending_k(m.dot(scene.face_warp[face]));
    };
    const double k = 0.5 * (face_k(r.face[0], f.T.m[0]) + face_k(r.face[1], f.Tt.m[0]));
    const double a_e = 3.0 * f.T.l[0] * f.T.l[0] / (f.T.area + f.Tt.area);
    h.kappa = k * a_e;
  }
  if (bad > 10) errors.fail(fmt::format("... and {} more degenerate hinges", bad - 10));
  errors.throw_if_failed("Invalid bending configuration:");

  // Number the hinges by owner triangle (then local edge), so that the refactored loop over
  // triangles fills the hinge slots in memory order; the per-hinge loop is unaffected.
  std::stable_sort(hinges_.begin(), hinges_.end(), [](const bending::HingeRest& a, const bending::HingeRest& b) {
    return a.face[0] != b.face[0] ? a.face[0] < b.face[0] : a.local[0] < b.local[0];
  });
  ids_.reserve(4 * hinges_.size());
  for (const auto& h : hinges_) ids_.insert(ids_.end(), h.v.begin(), h.v.end());

  // Active triangles (those with an interior edge), in mesh order for locality.
  const int nf = mesh.num_faces(), nh = num_hinges();
  std::vector<int> active(nf, -1);
  for (const auto& h : hinges_) active[h.face[0]] = active[h.face[1]] = 0;
  for (int f = 0; f < nf; ++f) {
    if (active[f] < 0) continue;
    active[f] = static_cast<int>(faces_.size());
    Face F;
    for (int i = 0; i < 3; ++i) F.v[i] = mesh.faces()(f, i);
    for (int i = 0; i < 3; ++i) F.rest_length[i] = (X.row(F.v[(i + 2) % 3]) - X.row(F.v[(i + 1) % 3])).norm();
    faces_.push_back(F);
  }
  hinge_face_[0].resize(nh);
  hinge_face_[1].resize(nh);
  for (int h = 0; h < nh; ++h) {
    const auto& r = hinges_[h];
    for (int side = 0; side < 2; ++side) {
      Face& F = faces_[active[r.face[side]]];
      hinge_face_[side][h] = active[r.face[side]];
      F.hinge[r.local[side]] = h;
      if (side == 0) F.owns[r.local[0]] = true;
    }
  }
  for (int a = 0; a < num_active_triangles(); ++a) {
    Face& F = faces_[a];
    for (int j = 0; j < 3 && F.slot_hinge < 0; ++j)
      if (F.owns[j]) {
        F.slot_hinge = F.hinge[j];
        F.slot_edge = j;
      }
    if (F.slot_hinge < 0) {
      F.lone = static_cast<int>(lone_.size());
      lone_.push_back(a);
      lone_ids_.insert(lone_ids_.end(), F.v.begin(), F.v.end());
    }
  }
  // Corners of active triangles per vertex (counting sort), for the lock-free gradient gather.
  corner_ptr_.assign(num_vertices_ + 1, 0);
  for (const Face& F : faces_)
    for (int v : F.v) ++corner_ptr_[v + 1];
  for (int v = 0; v < num_vertices_; ++v) corner_ptr_[v + 1] += corner_ptr_[v];
  corner_.resize(3 * faces_.size());
  std::vector<int> fill(corner_ptr_.begin(), corner_ptr_.end() - 1);
  for (int a = 0; a < num_active_triangles(); ++a)
    for (int i = 0; i < 3; ++i) corner_[fill[faces_[a].v[i]]++] = 3 * a + i;

  frame_.resize(faces_.size());
  corner_grad_.resize(3 * faces_.size());
  dpsi_.resize(nh);
  ddpsi_.resize(nh);
  hinge_grad_.resize(nh);
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
void HingeBending<AngleFunction>::throw_first_degenerate(const State& s, std::string_view where) const {
  for (int i = 0; i < num_hinges(); ++i) {
    const auto f = frames(s, i);
    if (const Defect d = check(f, bending::hinge_angle(f), i); d != Defect::none) throw_degenerate(i, d, where);
  }
  // The per-triangle test saw a quantity exactly at a threshold that the per-hinge test,
  // rounding differently, accepts.
  throw InvariantError(fmt::format("hinge_bending::{}: a triangle altitude, hinge edge or normal sum is at its degeneracy "
                                   "threshold; derivatives are unreliable there, check admissible() first",
                                   where));
}

template <class AngleFunction>
void HingeBending<AngleFunction>::declare(AssemblyPlan& plan) {
  group_ = plan.add_group(4, ids_);
  tri_group_ = lone_.empty() ? -1 : plan.add_group(3, lone_ids_);
  // Pass C's writer is the triangle: it writes its lone slot and the slots of the hinges it
  // owns, so it touches its own vertices and the far wing of each owned hinge.
  std::vector<int> ptr{0}, ids;
  for (const Face& F : faces_) {
    ids.insert(ids.end(), F.v.begin(), F.v.end());
    for (int j = 0; j < 3; ++j)
      if (F.owns[j]) ids.insert(ids.end(), hinges_[F.hinge[j]].v.begin(), hinges_[F.hinge[j]].v.end());
    ptr.push_back(static_cast<int>(ids.size()));
  }
  tri_writers_ = Colouring(ptr, ids, num_vertices_);
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
  evaluate(s, &g, nullptr, HessianMode::exact, prm_.assembly);
}

template <class AngleFunction>
void HingeBending<AngleFunction>::add_hessian(const State& s, ElementBuffer& buf, HessianMode mode) const {
  evaluate(s, nullptr, &buf, mode, prm_.assembly);
}

template <class AngleFunction>
void HingeBending<AngleFunction>::evaluate(const State& s, Eigen::VectorXd* g, ElementBuffer* buf, HessianMode mode,
                                           BendingAssembly path) const {
  WEFT_ASSERT(s.x.size() == 3 * num_vertices_, "state has {} coordinates, the bending model {} vertices", s.x.size(), num_vertices_);
  if (g) WEFT_ASSERT(g->size() == s.x.size(), "gradient has size {}, expected {}", g->size(), s.x.size());
  if (buf) WEFT_ASSERT(group_ >= 0, "{}", "HingeBending::add_hessian before declare(): call declare(plan) first");
  const std::string_view where = !buf ? "add_gradient" : !g ? "add_hessian" : "evaluate";
  if (path == BendingAssembly::refactored && !(buf && mode == HessianMode::projected))
    evaluate_refactored(s, g, buf, where);
  else
    evaluate_per_hinge(s, g, buf, mode, where);
}

template <class AngleFunction>
void HingeBending<AngleFunction>::evaluate_refactored(const State& s, Eigen::VectorXd* g, ElementBuffer* buf,
                                                      std::string_view where) const {
  const int nf = num_active_triangles(), nh = num_hinges();
  const double alt_tol = prm_.altitude_tolerance, edge_tol = prm_.edge_tolerance, normal_tol = prm_.normal_tolerance;
  std::atomic<bool> bad{false};  // written only when a defect is found
  // Pass A: per-triangle geometry.
  bending::detail::for_each_element(nf, [&](int a) {
    const Face& F = faces_[a];
    bending::TriangleFrame& t = frame_[a];
    t = bending::triangle_frame(s.x.segment<3>(3 * F.v[0]), s.x.segment<3>(3 * F.v[1]), s.x.segment<3>(3 * F.v[2]));
    for (int k = 0; k < 3; ++k)
      if (!(t.h[k] >= alt_tol * F.rest_length[k])) bad.store(true, std::memory_order_relaxed);
  });
  // Pass B: per-edge scalars psi', psi''.
  bending::detail::for_each_element(nh, [&](int h) {
    const bending::HingeRest& r = hinges_[h];
    const bending::TriangleFrame& T = frame_[hinge_face_[0][h]];
    const bending::TriangleFrame& Tt = frame_[hinge_face_[1][h]];
    const int j = r.local[0];
    if (!(T.l[j] >= edge_tol * r.rest_length[0])) bad.store(true, std::memory_order_relaxed);
    const bending::HingeAngle ang = bending::hinge_angle(T.n, Tt.n, T.e_hat[j]);
    if constexpr (AngleFunction::requires_open_interval)
      if (!(ang.normal_sum >= normal_tol)) bad.store(true, std::memory_order_relaxed);
    const bending::Psi p = bending::psi<AngleFunction>(ang, r.phi_bar, r.kappa);
    dpsi_[h] = p.d1;
    ddpsi_[h] = p.d2;
  });
  if (bad.load()) throw_first_degenerate(s, where);

  // Pass C: per triangle H^tri, the gradient (d_i / h_i) n and the owned hinges' psi''
  // outer products. Every slot has one writer (the owner triangle), so no locks.
  const int hg = group_, tg = tri_group_;
  // With a buffer, triangles that write to a common vertex (their own, or the far wing of a
  // hinge they own) never run at the same time in direct mode (tri_writers_ colouring).
  auto pass_c = [&](int a) {
    const Face& F = faces_[a];
    const bending::TriangleFrame& t = frame_[a];
    std::array<double, 3> gamma;
    for (int i = 0; i < 3; ++i) gamma[i] = F.hinge[i] >= 0 ? dpsi_[F.hinge[i]] : 0.0;
    bending::TriangleTerms terms;
    bending::triangle_terms(t, gamma, F.owns, buf != nullptr, terms);
    if (g)
      for (int i = 0; i < 3; ++i) corner_grad_[3 * a + i] = terms.grad[i];
    if (!buf) return;
    // B += block (u, v) of H^tri, in the triangle's local vertex order.
    auto add_htri = [&terms](Block3& B, int u, int v) {
      if (u == v)
        B += terms.diag[u];
      else if (v == (u + 1) % 3)
        B += terms.upper[u];
      else
        B += terms.upper[v].transpose();
    };
    if (F.lone >= 0) {
      ElementBuffer::Slot lone = buf->slot(tg, F.lone);
      for (int u = 0; u < 3; ++u)
        for (int v = 0; v < 3; ++v) {
          Block3 B = Block3::Zero();
          add_htri(B, u, v);
          lone.block(u, v) = B;
        }
    }
    for (int j = 0; j < 3; ++j) {
      if (!F.owns[j]) continue;
      const int h = F.hinge[j];
      const bending::Vec12 gt = bending::grad_theta(t, j, frame_[hinge_face_[1][h]], hinges_[h].local[1]);
      const double c = ddpsi_[h];
      const bool primary = h == F.slot_hinge;
      // The slot's 4x4 blocks are contiguous, block-major (ElementBuffer's layout).
      ElementBuffer::Slot hinge_slot = buf->slot(hg, h);
      double* slot = hinge_slot.data();
      auto put = [slot](int p, int q) { return Eigen::Map<Block3>(slot + 9 * (4 * p + q)); };
      // Slot vertex p is local vertex (j + p) mod 3 for p < 3, the other wing for p = 3.
      for (int p = 0; p < 4; ++p) {
        const Eigen::Vector3d gp = gt.segment<3>(3 * p), cgp = c * gp;
        for (int q = p; q < 4; ++q) {
          Block3 B;
          if (q == p) {
            const Block3 outer = gp * gp.transpose();  // g g^T first, then the scale: exactly symmetric
            B = c * outer;
          } else {
            B.noalias() = cgp * gt.segment<3>(3 * q).transpose();
          }
          if (primary && q < 3) add_htri(B, (j + p) % 3, (j + q) % 3);
          put(p, q) = B;
          if (q != p) put(q, p) = B.transpose();
        }
      }
    }
  };
  if (buf)
    buf->for_each(tri_writers_, pass_c);
  else
    bending::detail::for_each_element(nf, pass_c);
  if (!g) return;
  // Gradient: sum the corner terms per vertex, in a fixed order.
  Eigen::VectorXd& gv = *g;
  const int nv = num_vertices_;
  bending::detail::for_each_element(nv, [&](int v) {
    if (corner_ptr_[v] == corner_ptr_[v + 1]) return;
    Eigen::Vector3d acc = Eigen::Vector3d::Zero();
    for (int c = corner_ptr_[v]; c < corner_ptr_[v + 1]; ++c) acc += corner_grad_[corner_[c]];
    gv.segment<3>(3 * v) += acc;
  });
}

template <class AngleFunction>
void HingeBending<AngleFunction>::evaluate_per_hinge(const State& s, Eigen::VectorXd* g, ElementBuffer* buf,
                                                     HessianMode mode, std::string_view where) const {
  const int nh = num_hinges();
  if (!buf) {
    for (int i = 0; i < nh; ++i) {
      const auto f = frames(s, i);
      const auto a = bending::hinge_angle(f);
      if (const Defect d = check(f, a, i); d != Defect::none) throw_degenerate(i, d, where);
      const double dpsi = bending::psi<AngleFunction>(a, hinges_[i].phi_bar, hinges_[i].kappa).d1;
      const bending::Vec12 gt = bending::grad_theta(f);
      for (int k = 0; k < 4; ++k) g->segment<3>(3 * hinges_[i].v[k]) += dpsi * gt.segment<3>(3 * k);
    }
    return;
  }
  // Exceptions must not leave an OpenMP region: record that a hinge is degenerate, throw after.
  std::atomic<bool> bad{false};
  buf->for_each(group_, [&](int i) {
    const auto f = frames(s, i);
    const auto a = bending::hinge_angle(f);
    if (check(f, a, i) != Defect::none) {
      bad.store(true, std::memory_order_relaxed);
      buf->set(group_, i, bending::Mat12::Zero());
      return;
    }
    const bending::Psi p = bending::psi<AngleFunction>(a, hinges_[i].phi_bar, hinges_[i].kappa);
    const bending::Vec12 gt = bending::grad_theta(f);
    bending::Mat12 H;
    if (mode == HessianMode::projected && prm_.projection == BendingProjection::gauss_newton) {
      H.noalias() = std::max(p.d2, 0.0) * gt * gt.transpose();
    } else {
      H = p.d1 * bending::hess_theta(f);
      H.noalias() += p.d2 * gt * gt.transpose();
      if (mode == HessianMode::projected) H = bending::project_psd(H);
    }
    buf->set(group_, i, H);
    if (g) hinge_grad_[i] = p.d1 * gt;
  });
  if (tri_group_ >= 0) buf->zero_group(tri_group_);
  if (bad.load()) throw_first_degenerate(s, where);
  if (!g) return;
  for (int i = 0; i < nh; ++i)
    for (int k = 0; k < 4; ++k) g->segment<3>(3 * hinges_[i].v[k]) += hinge_grad_[i].segment<3>(3 * k);
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
