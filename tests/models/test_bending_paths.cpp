// The three implementations of the hinge-bending derivatives (refactored per triangle,
// closed form per hinge, forward-mode AD) against each other, and the properties the
// refactored assembly must have (methods/shells §9 items 5, 6, 13, 15).
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <string>
#include <vector>

#include "models/bending_autodiff.hpp"
#include "models/hinge_bending.hpp"
#include "tests/support/fd.hpp"
#include "tests/support/model_fixtures.hpp"

namespace {

using namespace weft;
using namespace weft::models;
using support::MeshData;

constexpr double ulp = 0x1p-53;  // the thesis' unit: ||H_a - H_b||_F / ||H_a||_F in units of 2^-53

/// An n x n vertex grid with unit spacing, jittered in plane, on a smooth random height
/// field (non-flat rest angles up to ~0.6 rad) and rigidly moved: well-shaped (all angles
/// above 15 degrees, checked by the callers) and non-flat.
MeshData curved_grid(std::uint32_t seed, int n) {
  support::Rng rng(seed);
  MeshData m = support::grid(n, n, n - 1.0, n - 1.0);
  const double kx = rng.uniform(0.5, 0.9), ky = rng.uniform(0.5, 0.9), p = rng.uniform(0, 6.28), amp = rng.uniform(0.4, 0.7);
  for (Eigen::Index i = 0; i < m.V.rows(); ++i) {
    m.V(i, 0) += rng.uniform(-0.12, 0.12);
    m.V(i, 1) += rng.uniform(-0.12, 0.12);
    m.V(i, 2) = amp * std::sin(kx * m.V(i, 0) + p) * std::cos(ky * m.V(i, 1)) + rng.uniform(-0.1, 0.1);
  }
  const Eigen::Matrix3d R = rng.rotation();
  const Eigen::Vector3d t = rng.vec3();
  for (Eigen::Index i = 0; i < m.V.rows(); ++i) m.V.row(i) = (R * m.V.row(i).transpose() + t).transpose();
  return m;
}

/// A deformed state of `m`: a smooth bend on top of a random perturbation.
Eigen::VectorXd deformed(const MeshData& m, std::uint32_t seed, double amplitude = 0.15) {
  support::Rng rng(seed);
  Eigen::VectorXd x = support::perturb(support::stack(m.V), amplitude, seed + 1);
  const Eigen::Vector3d dir = rng.vec3().normalized();
  for (Eigen::Index i = 0; i < x.size() / 3; ++i) {
    const double s = x.segment<3>(3 * i).dot(dir);
    x.segment<3>(3 * i) += 0.3 * std::sin(0.4 * s) * rng.vec3(-0.2, 0.2);
  }
  return x;
}

/// The three paths of a model, through one assembly plan.
template <class Angle>
struct Paths {
  HingeBending<Angle>& model;
  AssemblyPlan plan;
  ElementBuffer buf;
  Paths(HingeBending<Angle>& m, int num_vertices) : model(m) {
    model.declare(plan);
    plan.finalize(num_vertices);
    buf = plan.make_buffer();
  }
  enum Which { refactored, per_hinge, autodiff };
  BlockCsr hessian(const State& s, Which w, HessianMode mode = HessianMode::exact) {
    BlockCsr H = plan.pattern();
    buf.start(H);
    if (w == autodiff)
      bending::autodiff_evaluate(model, s, nullptr, &buf);
    else
      model.evaluate(s, nullptr, &buf, mode, w == refactored ? BendingAssembly::refactored : BendingAssembly::per_hinge);
    buf.finish();
    return H;
  }
  Eigen::VectorXd gradient(const State& s, Which w) {
    Eigen::VectorXd g = Eigen::VectorXd::Zero(s.x.size());
    if (w == autodiff)
      bending::autodiff_evaluate(model, s, &g, nullptr);
    else
      model.evaluate(s, &g, nullptr, HessianMode::exact, w == refactored ? BendingAssembly::refactored : BendingAssembly::per_hinge);
    return g;
  }
};

Eigen::Map<const Eigen::VectorXd> values(const BlockCsr& H) {
  return {H.values().data(), static_cast<Eigen::Index>(H.values().size())};
}
/// ||a - b||_F / ||a||_F in ulp (2^-53).
double ulps(const BlockCsr& a, const BlockCsr& b) { return (values(a) - values(b)).norm() / values(a).norm() / ulp; }

}  // namespace

TEST_SUITE("models") {
  TEST_CASE_TEMPLATE("bending paths: refactored and per-hinge and autodiff Hessians agree to 16 ulp (methods/shells §9 item 5)", Angle,
                     ThetaEnergy, TanEnergy) {
    double worst[3] = {0, 0, 0};
    for (std::uint32_t seed = 1; seed <= 6; ++seed) {
      CAPTURE(seed);
      const MeshData m = curved_grid(100 + seed, 7);
      const Eigen::VectorXd x = deformed(m, 200 + seed);
      REQUIRE(support::min_angle(m, support::stack(m.V)) > 15 * std::numbers::pi / 180);
      REQUIRE(support::min_angle(m, x) > 15 * std::numbers::pi / 180);
      auto p = support::make_patch<HingeBending<Angle>>(m, x);
      Paths<Angle> paths(p.model, p.state.num_vertices());
      const BlockCsr Hn = paths.hessian(p.state, Paths<Angle>::refactored);
      const BlockCsr Hs = paths.hessian(p.state, Paths<Angle>::per_hinge);
      const BlockCsr Ha = paths.hessian(p.state, Paths<Angle>::autodiff);
      REQUIRE(values(Hn).norm() > 0);
      const double ns = ulps(Hn, Hs), na = ulps(Hn, Ha), sa = ulps(Hs, Ha);
      CAPTURE(ns);
      CAPTURE(na);
      CAPTURE(sa);
      CHECK(ns <= 16);
      CHECK(na <= 16);
      CHECK(sa <= 16);
      worst[0] = std::max(worst[0], ns);
      worst[1] = std::max(worst[1], na);
      worst[2] = std::max(worst[2], sa);
    }
    MESSAGE(fmt::format("max normwise difference over 6 meshes [ulp]: refactored vs per-hinge {:.2f}, refactored vs autodiff "
                        "{:.2f}, per-hinge vs autodiff {:.2f}",
                        worst[0], worst[1], worst[2]));
  }

  TEST_CASE_TEMPLATE("bending paths: per-triangle gradient equals the per-hinge gradient (methods/shells §9 item 6)", Angle, ThetaEnergy,
                     TanEnergy) {
    for (std::uint32_t seed = 1; seed <= 4; ++seed) {
      CAPTURE(seed);
      const MeshData m = curved_grid(110 + seed, 6);
      auto p = support::make_patch<HingeBending<Angle>>(m, deformed(m, 210 + seed));
      Paths<Angle> paths(p.model, p.state.num_vertices());
      const Eigen::VectorXd gn = paths.gradient(p.state, Paths<Angle>::refactored);
      const Eigen::VectorXd gs = paths.gradient(p.state, Paths<Angle>::per_hinge);
      const Eigen::VectorXd ga = paths.gradient(p.state, Paths<Angle>::autodiff);
      REQUIRE(gs.norm() > 0);
      CHECK(support::relative_error(gs, gn) <= 1e-14);
      CHECK(support::relative_error(gs, ga) <= 1e-14);
      // The default path of add_gradient is the refactored one.
      CHECK(support::relative_error(gn, support::gradient(p.model, p.state)) <= 0.0);
    }
  }

  TEST_CASE("bending paths: forward-mode AD of theta matches the closed forms of grad and Hess theta (methods/shells §9 item 4)") {
    for (std::uint32_t seed = 70; seed < 76; ++seed) {
      CAPTURE(seed);
      support::Rng rng(seed);
      const Eigen::VectorXd x = support::stack(support::random_hinge(seed, rng.uniform(-2.5, 2.5)).V);
      const auto f = bending::hinge_frames(x.segment<3>(0), x.segment<3>(3), x.segment<3>(6), x.segment<3>(9));
      const auto ad = bending::theta_derivatives_autodiff(x.segment<3>(0), x.segment<3>(3), x.segment<3>(6), x.segment<3>(9));
      const bending::Vec12 g = bending::grad_theta(f);
      const bending::Mat12 H = bending::hess_theta(f);
      CHECK(std::abs(ad.angle.theta - bending::hinge_angle(f).theta) <= 1e-15 * std::max(1.0, std::abs(ad.angle.theta)));
      REQUIRE(g.norm() > 0);
      REQUIRE(H.norm() > 0);
      CHECK((ad.grad - g).norm() <= 1e-14 * g.norm());
      CHECK((ad.hess - H).norm() <= 1e-14 * H.norm());
      CHECK((ad.hess - ad.hess.transpose()).norm() <= 0.0);
    }
  }

  TEST_CASE_TEMPLATE("bending paths: the result does not depend on the global edge orientation (methods/shells §9 item 13)", Angle,
                     ThetaEnergy, TanEnergy) {
    const MeshData m = curved_grid(120, 7);
    const Scene scene = support::make_scene(m);
    const State s = support::make_state(scene, deformed(m, 220));
    HingeBending<Angle> base(scene, {});
    Paths<Angle> ref(base, s.num_vertices());
    const BlockCsr Hn = ref.hessian(s, Paths<Angle>::refactored), Hs = ref.hessian(s, Paths<Angle>::per_hinge);
    const Eigen::VectorXd gn = ref.gradient(s, Paths<Angle>::refactored);
    REQUIRE(values(Hn).norm() > 0);
    support::Rng rng(221);
    const int ne = scene.mesh.num_edges();
    std::vector<unsigned char> random_flips(ne), all_flips(ne, 1);
    for (auto& f : random_flips) f = rng.uniform() < 0.5;
    for (const auto* flips : {&random_flips, &all_flips}) {
      CAPTURE(flips == &all_flips);  // all flipped: every hinge swaps its transposing (and "upper") triangle
      HingeBending<Angle> model(scene, {}, *flips);
      // Some hinges now have the other triangle as T (x0, x1, x2).
      std::map<int, int> owner;
      for (int i = 0; i < base.num_hinges(); ++i) owner[base.hinge(i).edge] = base.hinge(i).face[0];
      int swapped = 0;
      for (int i = 0; i < model.num_hinges(); ++i) swapped += model.hinge(i).face[0] != owner.at(model.hinge(i).edge);
      REQUIRE(swapped > 0);
      if (flips == &all_flips) CHECK(swapped == model.num_hinges());
      Paths<Angle> paths(model, s.num_vertices());
      // The pattern is that of the hinges whatever the layout of the slots.
      REQUIRE(paths.plan.structure().col() == ref.plan.structure().col());
      const BlockCsr Fn = paths.hessian(s, Paths<Angle>::refactored), Fs = paths.hessian(s, Paths<Angle>::per_hinge);
      CHECK(ulps(Hn, Fn) * ulp <= 1e-14);
      CHECK(ulps(Hs, Fs) * ulp <= 1e-14);  // which triangle is "upper" in §6.6 does not matter
      CHECK(Fn.asymmetry() <= 0.0);        // exactly symmetric (symmetric diagonal blocks, mirrored off-diagonal ones)
      CHECK(support::relative_error(gn, paths.gradient(s, Paths<Angle>::refactored)) <= 1e-14);
      CHECK(std::abs(model.energy(s) - base.energy(s)) <= 1e-14 * base.energy(s));
    }
  }

  TEST_CASE("bending paths: with the low to high orientation every triangle owns an interior edge except near the boundary") {
    const MeshData m = support::grid(9, 9, 1.0, 1.0);
    const Scene scene = support::make_scene(m);
    HingeBending<ThetaEnergy> model(scene, {});
    AssemblyPlan plan;
    model.declare(plan);
    CHECK(model.num_active_triangles() == scene.mesh.num_faces());
    CHECK(model.num_lone_triangles() <= scene.mesh.num_boundary_edges());
    CHECK(plan.num_groups() == (model.num_lone_triangles() > 0 ? 2 : 1));
    MESSAGE(fmt::format("9x9 grid: {} triangles, {} hinges, {} triangles own no hinge", scene.mesh.num_faces(),
                        model.num_hinges(), model.num_lone_triangles()));
  }

  TEST_CASE("bending paths: one edge of the per-triangle terms is psi' times the half hinge (methods/shells §6.7)") {
    support::Rng rng(80);
    for (int j = 0; j < 3; ++j) {
      CAPTURE(j);
      const Eigen::Vector3d v[3] = {rng.vec3(), rng.vec3(), rng.vec3()};
      // The triangle with edge j as its edge 0: local order (v_j, v_{j+1}, v_{j+2}).
      const auto t = bending::triangle_frame(v[0], v[1], v[2]);
      const auto tj = bending::triangle_frame(v[j], v[(j + 1) % 3], v[(j + 2) % 3]);
      for (bool transpose : {false, true}) {
        CAPTURE(transpose);
        std::array<double, 3> gamma{0, 0, 0};
        gamma[j] = 0.7;
        std::array<bool, 3> tr{false, false, false};
        tr[j] = transpose;
        bending::TriangleTerms terms;
        bending::triangle_terms(t, gamma, tr, true, terms);
        const bending::Mat9 H = bending::triangle_hessian(terms);
        const bending::Mat9 B = bending::half_hinge_hessian(tj, transpose);
        bending::Mat9 B_sym = 0.7 * 0.5 * (B + B.transpose());  // only the diagonal blocks of B are not symmetric
        bending::Mat9 B_local;                                  // back to the order (v0, v1, v2)
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) B_local.block<3, 3>(3 * ((j + a) % 3), 3 * ((j + b) % 3)) = B_sym.block<3, 3>(3 * a, 3 * b);
        REQUIRE(B_local.norm() > 0);
        CHECK((H - B_local).norm() <= 1e-14 * B_local.norm());
        // Gradient: psi' times the half-hinge gradient.
        const Eigen::Vector3d hg[3] = {-tj.n / tj.h[0], tj.cos_alpha[2] / tj.h[1] * tj.n, tj.cos_alpha[1] / tj.h[2] * tj.n};
        for (int a = 0; a < 3; ++a) CHECK((terms.grad[(j + a) % 3] - 0.7 * hg[a]).norm() <= 1e-14 * hg[0].norm());
      }
    }
  }

  TEST_CASE_TEMPLATE("bending paths: boundary edges contribute nothing (methods/shells §9 item 15)", Angle, ThetaEnergy, TanEnergy) {
    // Cut a curved grid along the middle row of horizontal edges by giving the faces above
    // the cut their own copies of the cut vertices: the cut edges become boundary edges
    // (chi = 0) of the cut mesh. Its energy and derivatives, summed back onto the original
    // vertices, must equal the uncut mesh's minus exactly the cut hinges.
    const int n = 7, cut_row = 3;
    const MeshData m = curved_grid(130, n);
    MeshData c = m;
    const int nv = static_cast<int>(m.V.rows());
    c.V.conservativeResize(nv + n, 3);
    for (int i = 0; i < n; ++i) c.V.row(nv + i) = m.V.row(cut_row * n + i);
    for (Eigen::Index f = 0; f < c.F.rows(); ++f) {
      bool above = true;
      for (int k = 0; k < 3; ++k) above = above && c.F(f, k) / n >= cut_row;
      if (above)
        for (int k = 0; k < 3; ++k)
          if (c.F(f, k) / n == cut_row) c.F(f, k) = nv + c.F(f, k) % n;
    }
    std::vector<int> to_original(nv + n);
    for (int i = 0; i < nv; ++i) to_original[i] = i;
    for (int i = 0; i < n; ++i) to_original[nv + i] = cut_row * n + i;

    const Eigen::VectorXd x = deformed(m, 230);
    Eigen::VectorXd xc(3 * (nv + n));
    for (int i = 0; i < nv + n; ++i) xc.segment<3>(3 * i) = x.segment<3>(3 * to_original[i]);
    auto whole = support::make_patch<HingeBending<Angle>>(m, x);
    auto cut = support::make_patch<HingeBending<Angle>>(c, xc);
    REQUIRE(cut.model.num_hinges() == whole.model.num_hinges() - (n - 1));
    REQUIRE(cut.scene.mesh.num_boundary_edges() == whole.scene.mesh.num_boundary_edges() + 2 * (n - 1));

    // The cut hinges by the closed form: energy, gradient and Hessian.
    double w_cut = 0;
    Eigen::VectorXd g_cut = Eigen::VectorXd::Zero(x.size());
    Eigen::MatrixXd H_cut = Eigen::MatrixXd::Zero(x.size(), x.size());
    int found = 0;
    for (int i = 0; i < whole.model.num_hinges(); ++i) {
      const auto& r = whole.model.hinge(i);
      if (!(r.v[1] / n == cut_row && r.v[2] / n == cut_row)) continue;
      ++found;
      const auto f = bending::hinge_frames(x.segment<3>(3 * r.v[0]), x.segment<3>(3 * r.v[1]), x.segment<3>(3 * r.v[2]),
                                           x.segment<3>(3 * r.v[3]));
      const bending::Psi p = bending::psi<Angle>(bending::hinge_angle(f), r.phi_bar, r.kappa);
      const bending::Vec12 gt = bending::grad_theta(f);
      const bending::Mat12 Hh = p.d1 * bending::hess_theta(f) + p.d2 * gt * gt.transpose();
      w_cut += p.value;
      for (int a = 0; a < 4; ++a) {
        g_cut.segment<3>(3 * r.v[a]) += p.d1 * gt.segment<3>(3 * a);
        for (int b = 0; b < 4; ++b) H_cut.block<3, 3>(3 * r.v[a], 3 * r.v[b]) += Hh.block<3, 3>(3 * a, 3 * b);
      }
    }
    REQUIRE(found == n - 1);
    REQUIRE(w_cut > 0);

    Eigen::MatrixXd P = Eigen::MatrixXd::Zero(x.size(), xc.size());  // cut dofs -> original dofs
    for (int i = 0; i < nv + n; ++i) P.block<3, 3>(3 * to_original[i], 3 * i).setIdentity();
    const double W = whole.model.energy(whole.state);
    CHECK(std::abs(cut.model.energy(cut.state) - (W - w_cut)) <= 1e-14 * W);
    for (BendingAssembly path : {BendingAssembly::refactored, BendingAssembly::per_hinge}) {
      CAPTURE(enum_name(path, bending_assembly_names));
      Paths<Angle> pw(whole.model, nv), pc(cut.model, nv + n);
      const auto which = path == BendingAssembly::refactored ? Paths<Angle>::refactored : Paths<Angle>::per_hinge;
      const Eigen::VectorXd g = pw.gradient(whole.state, which), gc = P * pc.gradient(cut.state, which);
      const Eigen::MatrixXd H = pw.hessian(whole.state, which).to_dense();
      const Eigen::MatrixXd Hc = P * pc.hessian(cut.state, which).to_dense() * P.transpose();
      CHECK((gc - (g - g_cut)).norm() <= 1e-14 * g.norm());
      CHECK((Hc - (H - H_cut)).norm() <= 1e-14 * H.norm());
    }
  }

  TEST_CASE_TEMPLATE("bending paths: the projected Hessian is per hinge whatever the assembly parameter (methods/shells §6.12)", Angle,
                     ThetaEnergy, TanEnergy) {
    const MeshData m = curved_grid(140, 5);
    const Eigen::VectorXd x = deformed(m, 240, 0.3);
    typename HingeBending<Angle>::Params refactored, per_hinge;
    per_hinge.assembly = BendingAssembly::per_hinge;
    auto a = support::make_patch<HingeBending<Angle>>(m, x, refactored);
    auto b = support::make_patch<HingeBending<Angle>>(m, x, per_hinge);
    const BlockCsr Ha = support::assembled_hessian(a.model, a.state, HessianMode::projected);
    const BlockCsr Hb = support::assembled_hessian(b.model, b.state, HessianMode::projected);
    REQUIRE(values(Ha).norm() > 0);
    CHECK((values(Ha) - values(Hb)).norm() <= 0.0);
    // ... while the exact ones come from different paths (equal to rounding).
    const BlockCsr Ea = support::assembled_hessian(a.model, a.state, HessianMode::exact);
    const BlockCsr Eb = support::assembled_hessian(b.model, b.state, HessianMode::exact);
    CHECK(ulps(Ea, Eb) <= 16);
  }
}
