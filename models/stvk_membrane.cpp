#include "models/stvk_membrane.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

#include "framework/error.hpp"
#include "framework/params.hpp"

namespace weft::models {
namespace membrane {

namespace {
// eps_il: e_i = sum_l eps_il v_l (spec 01 §1; opposite sign to Levi-Civita).
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

double double_area(const Eigen::Vector3d& v0, const Eigen::Vector3d& v1, const Eigen::Vector3d& v2) {
  return (v1 - v0).cross(v2 - v0).norm();
}

Eigen::Matrix3d stvk_T(const Eigen::Matrix3d& rest, double thickness, const LameConstants& c,
                       const Eigen::Vector3d& direction) {
  const auto e = edges(rest);
  const Eigen::Vector3d normal = e[1].cross(e[2]);  // (v1 - v0) x (v2 - v0) = e2 x (-e1)
  const double area = 0.5 * normal.norm();
  Eigen::Matrix3d d;
  for (int i = 0; i < 3; ++i)
    for (int l = 0; l < 3; ++l) d(i, l) = e[i].dot(e[l]);
  // beta_i = ahat . mbar_i with mbar_i = nbar x ebar_i (length lbar_i); the sign of mbar is
  // immaterial because only products beta_{i+1} beta_{i+2} occur.
  Eigen::Vector3d beta = Eigen::Vector3d::Zero();
  if (c.a != 0 || c.b != 0) {
    const Eigen::Vector3d nbar = normal / normal.norm();
    for (int i = 0; i < 3; ++i) beta[i] = direction.dot(nbar.cross(e[i]));
  }
  Eigen::Matrix3d T;
  for (int i = 0; i < 3; ++i) {
    const int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
    for (int l = 0; l < 3; ++l) {
      const int l1 = (l + 1) % 3, l2 = (l + 2) % 3;
      const double t1 = d(i1, i2) * d(l1, l2);
      const double t2 = d(i2, l1) * d(i1, l2) + d(i2, l2) * d(i1, l1);
      const double bi = beta[i1] * beta[i2], bl = beta[l1] * beta[l2];
      const double t3 = bi * bl;
      const double t4 = d(i1, i2) * bl + d(l1, l2) * bi;
      T(i, l) = c.lambda * t1 + c.mu * t2 + 2.0 * c.b * t3 + c.a * t4;
    }
  }
  T *= thickness / (32.0 * area * area * area);
  return 0.5 * (T + T.transpose());  // exactly symmetric
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

namespace {
template <class Material>
membrane::LameConstants lame(const ShellMaterial& m) {
  static_assert(std::is_same_v<Material, Isotropic>, "only Isotropic so far");
  return membrane::isotropic_lame(m.youngs_modulus, m.poisson_ratio);
}
}  // namespace

template <class Material>
StvkMembrane<Material>::StvkMembrane(const Scene& scene, const Params& /*prm*/) {
  Checker check("stvk_membrane");
  for (size_t c = 0; c < scene.spec.cloths.size(); ++c) {
    const ShellMaterial& m = scene.spec.cloths[c].material;
    const std::string key = fmt::format("cloths.{}.material.", c);
    check.require(m.youngs_modulus > 0, key + "youngs_modulus", m.youngs_modulus, "> 0")
        .require(m.poisson_ratio > -1 && m.poisson_ratio < 1, key + "poisson_ratio", m.poisson_ratio,
                 "in (-1, 1) (2D plane stress)")
        .require(m.thickness > 0, key + "thickness", m.thickness, "> 0");
  }
  const auto& F = scene.mesh.faces();
  const auto& X = scene.mesh.rest();
  const int nf = scene.mesh.num_faces();
  if (static_cast<int>(scene.face_cloth.size()) != nf)
    check.fail(fmt::format("scene.face_cloth has {} entries for {} faces", scene.face_cloth.size(), nf));
  check.throw_if_failed("Invalid membrane configuration:");

  ids_.resize(3 * static_cast<size_t>(nf));
  elements_.resize(nf);
  int degenerate = 0;
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
    const ShellMaterial& m = scene.face_material(f);
    auto& el = elements_[f];
    el.rest_length2 = Eigen::Vector3d((rest.row(2) - rest.row(1)).squaredNorm(), (rest.row(0) - rest.row(2)).squaredNorm(),
                                      (rest.row(1) - rest.row(0)).squaredNorm());
    el.T = membrane::stvk_T(rest, m.thickness, lame<Material>(m));
  }
  if (degenerate > 10) check.fail(fmt::format("... and {} more degenerate faces", degenerate - 10));
  check.throw_if_failed("Invalid membrane configuration:");
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
  const int nf = num_elements();
#pragma omp parallel for schedule(static)
  for (int f = 0; f < nf; ++f) buf.set(group_, f, membrane::element_hessian(corners(s, f), elements_[f], projected));
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

}  // namespace weft::models
