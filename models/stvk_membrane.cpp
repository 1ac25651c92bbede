#include "models/stvk_membrane.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "framework/error.hpp"
#include "framework/params.hpp"

namespace weft::models {
namespace membrane {

namespace {
// eps_il: e_i = sum_l eps_il v_l (methods/shells §1; opposite sign to Levi-Civita).
constexpr int eps[3][3] = {{0, -1, 1}, {1, 0, -1}, {-1, 1, 0}};

std::array<Eigen::Vector3d, 3> edges(const Eigen::Matrix3d& v) {
  return {Eigen::Vector3d(v.row(2) - v.row(1)), Eigen::Vector3d(v.row(0) - v.row(2)),
          Eigen::Vector3d(v.row(1) - v.row(0))};
}
}  // namespace

LameConstants isotropic_lame(double youngs_modulus, double poisson_ratio) {
  const double Y = youngs_modulus, nu = poisson_ratio;
  return {Y * nu / (1.0 - nu * nu), Y / (2.0 * (1.0 + nu)), 0.0, 0.0};
}

LameConstants orthotropic_lame(double Y, double eta, double nu, double G) {
  const double q = 1.0 - eta * nu * nu;
  return {Y / q - G, 0.5 * G, (eta * nu - 1.0) / q * Y + G, (1.0 + eta - 2.0 * eta * nu) / (2.0 * q) * Y - G};
}

LameConstants material_lame(const ShellMaterial& m) {
  if (!m.orthotropic()) return isotropic_lame(m.youngs_modulus, m.poisson_ratio);
  return orthotropic_lame(m.youngs_modulus_warp.value(), m.eta(), m.poisson_ratio, 2.0 * m.shear_modulus.value());
}

double double_area(const Eigen::Vector3d& v0, const Eigen::Vector3d& v1, const Eigen::Vector3d& v2) {
  return (v1 - v0).cross(v2 - v0).norm();
}

RestShape rest_shape(const Eigen::Matrix3d& rest, const Eigen::Vector3d& warp) {
  const auto e = edges(rest);
  RestShape r;
  r.length2 = Eigen::Vector3d(e[0].squaredNorm(), e[1].squaredNorm(), e[2].squaredNorm());
  if (warp.squaredNorm() > 0) {
    // Gram system [d00 d01; d01 d11] w = (warp . e0, warp . e1): w0 e0 + w1 e1 is the
    // projection of `warp` onto the rest plane (methods/shells §5).
    const double g00 = r.length2[0], g11 = r.length2[1], g01 = e[0].dot(e[1]);
    const double r0 = warp.dot(e[0]), r1 = warp.dot(e[1]);
    const double det = g00 * g11 - g01 * g01;  // (2 Abar)^2
    if (det > 0) r.warp = Eigen::Vector2d(g11 * r0 - g01 * r1, g00 * r1 - g01 * r0) / det;
  }
  return r;
}

bool element_matrix(const RestShape& rest, double thickness, const LameConstants& c, Eigen::Matrix3d& T) {
  const Eigen::Vector3d& l2 = rest.length2;
  if (!proper_triangle(l2)) return false;
  const double area = triangle_area(l2);
  // Rest edge dot products from lengths only (Eq. 4.10).
  Eigen::Matrix3d d;
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3, k = (i + 2) % 3;
    d(i, i) = l2[i];
    d(j, k) = d(k, j) = 0.5 * (l2[i] - l2[j] - l2[k]);
  }
  Eigen::Vector3d beta = Eigen::Vector3d::Zero();
  if (c.orthotropic()) {
    const Eigen::Vector2d& w = rest.warp;
    const double norm2 = w[0] * w[0] * d(0, 0) + 2.0 * w[0] * w[1] * d(0, 1) + w[1] * w[1] * d(1, 1);
    WEFT_ASSERT(norm2 > 0, "{}", "orthotropic element without a warp direction (RestShape::warp is zero)");
    beta = (w[0] * d.row(0) + w[1] * d.row(1)).transpose() / std::sqrt(norm2);
  }
  for (int i = 0; i < 3; ++i) {
    const int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
    for (int l = 0; l < 3; ++l) {
      const int l1 = (l + 1) % 3, l2i = (l + 2) % 3;
      const double t1 = d(i1, i2) * d(l1, l2i);
      const double t2 = d(i2, l1) * d(i1, l2i) + d(i2, l2i) * d(i1, l1);
      const double bi = beta[i1] * beta[i2], bl = beta[l1] * beta[l2i];
      const double t3 = bi * bl;
      const double t4 = d(i1, i2) * bl + d(l1, l2i) * bi;
      T(i, l) = c.lambda * t1 + c.mu * t2 + 2.0 * c.b * t3 + c.a * t4;
    }
  }
  T *= thickness / (32.0 * area * area * area);
  T = (0.5 * (T + T.transpose())).eval();  // exactly symmetric
  return true;
}

Eigen::Matrix3d stvk_T(const Eigen::Matrix3d& rest, double thickness, const LameConstants& c, const Eigen::Vector3d& direction) {
  const auto e = edges(rest);
  const Eigen::Vector3d nbar = e[1].cross(e[2]).normalized();  // (v1 - v0) x (v2 - v0) = e2 x (-e1)
  const RestShape r = rest_shape(rest, c.orthotropic() ? Eigen::Vector3d(nbar.cross(direction)) : Eigen::Vector3d::Zero());
  Eigen::Matrix3d T;
  const bool ok = element_matrix(r, thickness, c, T);
  WEFT_ASSERT(ok, "{}", "stvk_T: degenerate rest triangle");
  return T;
}

double element_energy(const Corners& x, const Element& el) {
  const auto e = edges(x);
  const Eigen::Vector3d s(0.5 * (e[0].squaredNorm() - el.rest_length2[0]), 0.5 * (e[1].squaredNorm() - el.rest_length2[1]),
                          0.5 * (e[2].squaredNorm() - el.rest_length2[2]));
  return s.dot(el.T * s);
}

Vec9 element_gradient(const Corners& x, const Element& el) {
  const auto e = edges(x);
  const Eigen::Vector3d s(0.5 * (e[0].squaredNorm() - el.rest_length2[0]), 0.5 * (e[1].squaredNorm() - el.rest_length2[1]),
                          0.5 * (e[2].squaredNorm() - el.rest_length2[2]));
  const Eigen::Vector3d r = 2.0 * (el.T * s);
  Vec9 g;
  for (int m = 0; m < 3; ++m) {
    const int m1 = (m + 1) % 3, m2 = (m + 2) % 3;
    g.segment<3>(3 * m) = r[m1] * e[m1] - r[m2] * e[m2];
  }
  return g;
}

Mat9 element_hessian(const Corners& x, const Element& el, bool projected) {
  const auto e = edges(x);
  const Eigen::Vector3d s(0.5 * (e[0].squaredNorm() - el.rest_length2[0]), 0.5 * (e[1].squaredNorm() - el.rest_length2[1]),
                          0.5 * (e[2].squaredNorm() - el.rest_length2[2]));
  const Eigen::Vector3d r = 2.0 * (el.T * s);
  Eigen::Matrix<double, 3, 9> B;
  for (int i = 0; i < 3; ++i)
    for (int m = 0; m < 3; ++m) B.block<1, 3>(i, 3 * m) = eps[i][m] * e[i].transpose();
  Mat9 H = B.transpose() * (2.0 * el.T) * B;
  // Geometric term: sum_i r_i (eps_i eps_i^T) (x) I3, the only source of indefiniteness.
  for (int i = 0; i < 3; ++i) {
    const double ri = projected ? std::max(r[i], 0.0) : r[i];
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b)
        if (eps[i][a] != 0 && eps[i][b] != 0) H.block<3, 3>(3 * a, 3 * b).diagonal().array() += ri * eps[i][a] * eps[i][b];
  }
  return 0.5 * (H + H.transpose());  // exactly symmetric, so the assembled matrix is too
}

}  // namespace membrane

template <class Material>
StvkMembrane<Material>::StvkMembrane(const Scene& scene, const Params& /*prm*/) {
  Checker check;
  const size_t ncloths = scene.spec.cloths.size();
  const int nf = scene.mesh.num_faces();
  if (static_cast<int>(scene.face_cloth.size()) != nf)
    check.fail(fmt::format("scene.face_cloth has {} entries for {} faces", scene.face_cloth.size(), nf));
  for (size_t c = 0; c < ncloths; ++c) {
    const ShellMaterial& m = scene.spec.cloths[c].material;
    const std::string key = fmt::format("cloths.{}.material", c);
    if (m.orthotropic() && !Material::accepts_orthotropic) {
      check.fail(fmt::format("{}.model = orthotropic, but this combination's membrane is StvkMembrane<Isotropic>: choose a "
                             "combination whose membrane is orthotropic (`weft list`: membrane(stvk, orthotropic), e.g. "
                             "combo = cloth_ortho_ip_direct), or set {}.model = isotropic",
                             key, key));
      continue;
    }
    check.merge(m.validate(key));
  }
  const bool ortho_faces = [&] {
    for (const auto& c : scene.spec.cloths)
      if (c.material.orthotropic()) return true;
    return false;
  }();
  if (ortho_faces && scene.face_warp.size() != static_cast<size_t>(nf))
    check.fail(fmt::format("an orthotropic material needs a warp direction per face: scene.face_warp has {} entries for {} faces "
                           "(set cloths.N.material.warp_from / warp_angle; scenes built in code fill Scene::face_warp)",
                           scene.face_warp.size(), nf));
  check.merge(check_rest_states(scene));
  check.throw_if_failed("Invalid membrane configuration:");

  for (size_t c = 0; c < ncloths; ++c) {
    const ShellMaterial& m = scene.spec.cloths[c].material;
    lame_.push_back(membrane::material_lame(m));
    thickness_.push_back(m.thickness);
    scripts_.push_back(scene.spec.cloths[c].rest_state);
  }
  applied_factor_.assign(ncloths, std::numeric_limits<double>::quiet_NaN());
  face_cloth_ = scene.face_cloth;

  const auto& F = scene.mesh.faces();
  const auto& X = scene.mesh.rest();
  ids_.resize(3 * static_cast<size_t>(nf));
  elements_.resize(nf);
  rest_.resize(nf);
  int degenerate = 0, undirected = 0;
  for (int f = 0; f < nf; ++f) {
    Eigen::Matrix3d rest;
    for (int k = 0; k < 3; ++k) {
      ids_[3 * f + k] = F(f, k);
      rest.row(k) = X.row(F(f, k));
    }
    const double a2 = membrane::double_area(rest.row(0), rest.row(1), rest.row(2));
    const double lmax2 = std::max({(rest.row(1) - rest.row(0)).squaredNorm(), (rest.row(2) - rest.row(1)).squaredNorm(),
                                   (rest.row(0) - rest.row(2)).squaredNorm()});
    // Zero area up to rounding: T ~ 1/Abar^3 would be meaningless.
    if (!(a2 > 1e-12 * lmax2)) {
      if (++degenerate <= 10)
        check.fail(fmt::format("face {} (vertices {} {} {}) has zero rest area; remove degenerate triangles from the mesh", f,
                               F(f, 0), F(f, 1), F(f, 2)));
      continue;
    }
    const int c = face_cloth_[f];
    const bool directed = scene.spec.cloths[c].material.orthotropic();
    const Eigen::Vector3d warp = directed ? scene.face_warp[f] : Eigen::Vector3d::Zero();
    rest_[f] = membrane::rest_shape(rest, warp);
    if (directed) {
      // The in-plane part of the warp, ||w0 e0 + w1 e1||, must not vanish (a direction normal
      // to the face, or none at all).
      const Eigen::Vector3d inplane = rest_[f].warp[0] * Eigen::Vector3d(rest.row(2) - rest.row(1)) +
                                      rest_[f].warp[1] * Eigen::Vector3d(rest.row(0) - rest.row(2));
      if (!(inplane.norm() > 1e-6 * warp.norm()) || !(warp.norm() > 0)) {
        if (++undirected <= 10)
          check.fail(fmt::format("cloths.{}: face {} has no warp direction in its rest plane (Scene::face_warp[{}] = [{}])", c, f, f,
                                 fmt::join(warp.data(), warp.data() + 3, ", ")));
        continue;
      }
    }
    if (!update_element(f, Eigen::Vector3d::Ones()) && ++degenerate <= 10)
      check.fail(fmt::format("face {} (vertices {} {} {}) is a degenerate rest triangle", f, F(f, 0), F(f, 1), F(f, 2)));
  }
  if (degenerate > 10) check.fail(fmt::format("... and {} more degenerate faces", degenerate - 10));
  if (undirected > 10) check.fail(fmt::format("... and {} more faces without a warp direction", undirected - 10));
  check.throw_if_failed("Invalid membrane configuration:");

  // Faces with at least one edge that follows a rest-state script.
  if (scene.has_animated_rest()) {
    const std::vector<unsigned char> sel = rest_state_edges(scene);
    for (int f = 0; f < nf; ++f) {
      AnimatedFace a{f, {}};
      bool any = false;
      for (int i = 0; i < 3; ++i) any |= a.scaled[i] = sel[scene.mesh.face_edges()[f][i]] != 0;
      if (any) animated_faces_.push_back(a);
    }
    set_rest_time(0.0);
  }
}

template <class Material>
bool StvkMembrane<Material>::update_element(int f, const Eigen::Vector3d& factors) {
  membrane::RestShape r = rest_[f];
  r.length2 = r.length2.cwiseProduct(factors.cwiseProduct(factors));
  const int c = face_cloth_[f];
  auto& el = elements_[f];
  if (!membrane::element_matrix(r, thickness_[c], lame_[c], el.T)) return false;
  el.rest_length2 = r.length2;
  return true;
}

template <class Material>
void StvkMembrane<Material>::set_rest_time(double t) {
  if (animated_faces_.empty()) return;
  std::vector<double> g(scripts_.size(), 1.0);
  bool changed = false;
  for (size_t c = 0; c < scripts_.size(); ++c) {
    if (!scripts_[c].active()) continue;
    g[c] = scripts_[c].factor(t);
    changed |= !(g[c] == applied_factor_[c]);  // NaN (never applied) counts as changed
  }
  if (!changed) return;
  const int n = static_cast<int>(animated_faces_.size());
  int failed = -1;
#pragma omp parallel for schedule(static) if (n >= 256)
  for (int k = 0; k < n; ++k) {
    const AnimatedFace& a = animated_faces_[k];
    const double gc = g[face_cloth_[a.face]];
    if (!update_element(a.face, Eigen::Vector3d(a.scaled[0] ? gc : 1.0, a.scaled[1] ? gc : 1.0, a.scaled[2] ? gc : 1.0))) {
#pragma omp atomic write
      failed = a.face;
    }
  }
  // The constructor rejected every script under which a face stops being a proper triangle
  // (check_rest_states at the keyframe extremes), so this cannot fail for valid input; an
  // element that failed keeps its previous rest data (no NaN).
  WEFT_ASSERT(failed < 0, "animated rest state at t = {}: face {} is not a proper triangle (check_rest_states missed it)", t, failed);
  applied_factor_ = g;
}

template <class Material>
void StvkMembrane<Material>::begin_step(const State& /*s*/, double t_end) {
  set_rest_time(t_end);
}

template <class Material>
membrane::Corners StvkMembrane<Material>::corners(const State& s, int f) const {
  membrane::Corners x;
  for (int k = 0; k < 3; ++k) x.row(k) = s.x.segment<3>(3 * ids_[3 * f + k]).transpose();
  return x;
}

template <class Material>
void StvkMembrane<Material>::declare(AssemblyPlan& plan) {
  group_ = plan.add_group(3, ids_);
}

template <class Material>
double StvkMembrane<Material>::energy(const State& s) const {
  double w = 0;
  for (int f = 0; f < num_elements(); ++f) w += membrane::element_energy(corners(s, f), elements_[f]);
  return w;
}

template <class Material>
void StvkMembrane<Material>::add_gradient(const State& s, Eigen::VectorXd& g) const {
  WEFT_ASSERT(g.size() == s.x.size(), "gradient has size {}, expected {}", g.size(), s.x.size());
  for (int f = 0; f < num_elements(); ++f) {
    const membrane::Vec9 ge = membrane::element_gradient(corners(s, f), elements_[f]);
    for (int k = 0; k < 3; ++k) g.segment<3>(3 * ids_[3 * f + k]) += ge.segment<3>(3 * k);
  }
}

template <class Material>
void StvkMembrane<Material>::add_hessian(const State& s, ElementBuffer& buf, HessianMode mode) const {
  WEFT_ASSERT(group_ >= 0, "{}", "StvkMembrane::add_hessian before declare(): call declare(plan) first");
  const bool projected = mode == HessianMode::projected;
  buf.for_each(group_, [&](int f) { buf.set(group_, f, membrane::element_hessian(corners(s, f), elements_[f], projected)); });
}

template <class Material>
void StvkMembrane<Material>::energy_terms(const State& s, EnergyTerms& terms) const {
  terms.emplace_back("membrane", energy(s));
}

template <class Material>
bool StvkMembrane<Material>::admissible(const State& s) const {
  return s.x.allFinite();
}

template class StvkMembrane<Isotropic>;
template class StvkMembrane<Orthotropic>;

}  // namespace weft::models
