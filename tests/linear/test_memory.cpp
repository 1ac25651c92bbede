// Memory of the prefiltered solvers (target "memory of SA+PPCG at most 1.5x that of
// Diag-PCG"): the prefiltered operator applied on the fly, the one-triangle coarse operators
// and the memory SA+PPCG owns against the matrix it is given.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "linear/bsr.hpp"
#include "linear/pcg.hpp"
#include "linear/prefilter.hpp"
#include "linear/sa_amg.hpp"
#include "linear/sa_ppcg.hpp"
#include "tests/support/linear_fixtures.hpp"

using namespace weft;
using namespace weft::linear;

using support::with_contacts;

namespace {

std::size_t matrix_bytes(const BlockCsr& A) {
  return sizeof(double) * A.values().capacity() + sizeof(int) * (A.col().capacity() + A.row_ptr().capacity() + A.block_rows());
}

struct Solved {
  Eigen::VectorXd x;
  LinearReport rep;
};

template <class Solver>
Solved solve(const BlockCsr& A, const Eigen::VectorXd& b, const ConstraintSet& c, const Eigen::VectorXd& positions,
             typename Solver::Params prm) {
  Solver s(prm);
  s.set_context(SolveContext{&c, &positions});
  REQUIRE(s.analyze_pattern(A) == Status::success);
  REQUIRE(s.factorize(A) == Status::success);
  Solved out;
  out.x = Eigen::VectorXd::Zero(A.rows());
  out.rep = s.solve(b, out.x);
  return out;
}

/// A random symmetric 6x6-block matrix stored by one triangle (single or double precision):
/// a structurally symmetric pattern with row lengths 1 to 40, columns far and near, so rows
/// mix stored and transposed blocks in every order; values over six decades.
SymBlockMatrix<6> random_sym6(support::Rng& rng, int n, bool single) {
  std::vector<std::vector<int>> cols(n);
  for (int i = 0; i < n; ++i) cols[i].push_back(i);
  for (int i = 0; i < n; ++i) {
    const int extra = static_cast<int>(rng.uniform(0, 20));
    for (int t = 0; t < extra; ++t) {
      const int j = static_cast<int>(rng.uniform(0, n - 1e-9));
      cols[i].push_back(j);
      cols[j].push_back(i);
    }
  }
  std::vector<int> ptr{0}, col;
  for (auto& c : cols) {
    std::sort(c.begin(), c.end());
    c.erase(std::unique(c.begin(), c.end()), c.end());
    col.insert(col.end(), c.begin(), c.end());
    ptr.push_back(static_cast<int>(col.size()));
  }
  SymBlockMatrix<6> S(n, ptr, col, single);
  for (int s = 0; s < S.stored_blocks(); ++s) {
    Eigen::Matrix<double, 6, 6> b;
    for (int e = 0; e < 36; ++e) b(e / 6, e % 6) = rng.uniform(-1, 1) * std::pow(10.0, rng.uniform(-3, 3));
    S.store(s, b);
  }
  for (int i = 0; i < n; ++i) {  // a symmetric matrix's diagonal blocks are symmetric
    const Eigen::Matrix<double, 6, 6> d = S.stored_value(S.diagonal_index(i));
    S.store(S.diagonal_index(i), 0.5 * (d + d.transpose()));
  }
  return S;
}

/// Largest relative difference between row_product<B, B, 6> on node-major blocks (a row-major
/// NullSpace) and six single-vector row products on its columns, over every block row; also
/// whether any entry differed at all (for the guard against a vacuous comparison).
template <int B>
double six_at_once_vs_single(const BsrView<B, B>& V, support::Rng& rng) {
  const int n = V.rows;
  NullSpace X(B * n, 6);
  for (int r = 0; r < X.rows(); ++r)
    for (int c = 0; c < 6; ++c) X(r, c) = rng.uniform(-1, 1);
  std::vector<Eigen::VectorXd> cols(6);
  for (int c = 0; c < 6; ++c) cols[c] = X.col(c);
  double worst = 0, scale = 0;
  for (int i = 0; i < n; ++i) {
    const BlockOf<B, 6> Y = row_product<B, B, 6>(V, i, X.data());
    for (int c = 0; c < 6; ++c) {
      const Eigen::Matrix<double, B, 1> y = row_product(V, i, cols[c].data());
      worst = std::max(worst, (Y.col(c) - y).cwiseAbs().maxCoeff());
      scale = std::max(scale, y.cwiseAbs().maxCoeff());
    }
  }
  REQUIRE(scale > 0);
  return worst / scale;
}

}  // namespace

TEST_SUITE("linear") {
  TEST_CASE("prefilter: the on-the-fly operator equals the explicit prefiltered matrix with pins and contacts") {
    const support::ClothSystem sys = support::cloth_system(15, Tessellation::irregular, support::Pins::boundary);
    const ConstraintSet c = with_contacts(sys.pins, 7);
    int partial = 0;
    for (int i = 0; i < c.num_vertices(); ++i) partial += c.count(i) == 1 || c.count(i) == 2;
    REQUIRE(partial > 0);
    BlockCsr Ahat = sys.A;
    prefilter_matrix(sys.A, c, Ahat);
    OperatorFilter F;
    F.build(sys.A, c);
    REQUIRE(!F.empty());
    CHECK(F.bytes() < matrix_bytes(sys.A) / 10);
    BsrView<3, 3> v = bsr_view(sys.A);
    v.filter = F.view();
    // Every block as the kernels read it is the block prefilter_matrix stores.
    double worst = 0;
    for (int i = 0; i < sys.A.block_rows(); ++i)
      for (int k = sys.A.row_ptr()[i]; k < sys.A.row_ptr()[i + 1]; ++k)
        worst = std::max(worst, (Eigen::Matrix3d(v.block(i, k)) - Eigen::Matrix3d(Ahat.block(k))).cwiseAbs().maxCoeff());
    CHECK(worst <= 1e-15 * sys.A.values()[0]);
    // The product y = Ahat x applied on the fly matches the explicit one to round-off.
    support::Rng rng(3);
    Eigen::VectorXd x(sys.A.rows()), y_explicit, y(sys.A.rows());
    for (int k = 0; k < x.size(); ++k) x[k] = rng.uniform(-1, 1);
    Ahat.multiply(x, y_explicit);
    spmv(v, x.data(), y.data());
    CHECK((y - y_explicit).norm() <= 1e-14 * y_explicit.norm());
    // A matrix whose fixed rows are already decoupled needs no filter at all.
    BlockCsr Afixed = sys.A;
    std::vector<unsigned char> fixed(sys.A.block_rows(), 0);
    for (int i = 0; i < sys.A.block_rows(); ++i) fixed[i] = sys.pins.count(i) == 3;
    Afixed.filter_rows(fixed, -1);
    F.build(Afixed, sys.pins);
    CHECK(F.empty());
  }

  TEST_CASE_TEMPLATE("ppcg: prefiltering on the fly gives the solution of the stored prefiltered matrix", Solver, DiagPpcg,
                     SaPpcg) {
    const support::ClothSystem sys = support::cloth_system(21, Tessellation::regular, support::Pins::two_sides);
    const ConstraintSet c = with_contacts(sys.pins, 9);
    typename Solver::Params fly;
    fly.tolerance = 1e-8;
    typename Solver::Params stored = fly;
    stored.setup = PreconditionerSetup::once_per_pattern;  // keeps the explicit copy of Ahat
    const Solved a = solve<Solver>(sys.A, sys.b, c, sys.x, fly);
    const Solved b = solve<Solver>(sys.A, sys.b, c, sys.x, stored);
    REQUIRE(a.rep.status == Status::success);
    REQUIRE(b.rep.status == Status::success);
    CAPTURE(a.rep.iterations);
    CAPTURE(b.rep.iterations);
    CHECK(a.rep.iterations == b.rep.iterations);
    CHECK((a.x - b.x).norm() <= 1e-10 * b.x.norm());
    CHECK(a.rep.constraint_violation <= 1e-14 * c.target().cwiseAbs().maxCoeff());
    // No copy of Ahat: at least A's values fewer bytes.
    CHECK(a.rep.memory_bytes + sizeof(double) * sys.A.values().size() <= b.rep.memory_bytes);
  }

  TEST_CASE("sa: coarse operators are stored by one triangle and exactly symmetric") {
    const support::ClothSystem sys = support::cloth_system(41, Tessellation::irregular, support::Pins::boundary);
    SaAmg sa({});
    REQUIRE(sa.analyze_pattern(sys.A) == Status::success);
    OperatorFilter F;
    F.build(sys.A, sys.pins);
    REQUIRE(sa.setup(sys.A, SolveContext{&sys.pins, &sys.x}, F.view()) == Status::success);
    REQUIRE(sa.levels() >= 3);
    for (int l = 1; l < sa.levels(); ++l) {
      CAPTURE(l);
      const Eigen::MatrixXd Ac = sa.level_matrix(l);
      CHECK((Ac - Ac.transpose()).cwiseAbs().maxCoeff() == 0.0);
      CHECK(Ac.llt().info() == Eigen::Success);
    }
    // One-triangle storage: a 6x6 block pattern symmetric by construction.
    const std::vector<int> ptr = {0, 2, 5, 7}, col = {0, 1, 0, 1, 2, 1, 2};
    SymBlockMatrix<6> S(3, ptr, col);
    CHECK(S.stored_blocks() == 5);
    support::Rng rng(4);
    for (double& v : S.values()) v = rng.uniform(-1, 1);
    for (int i = 0; i < 3; ++i) {  // diagonal blocks of a symmetric matrix are symmetric
      auto Dii = S.diagonal(i);
      Dii = (0.5 * (Dii + Dii.transpose())).eval();
    }
    const Eigen::MatrixXd D = S.to_dense();
    CHECK((D - D.transpose()).norm() == 0.0);
    CHECK(D.block<6, 6>(6, 0) == Eigen::MatrixXd(D.block<6, 6>(0, 6).transpose()));
    Eigen::VectorXd x(18), y(18);
    for (int k = 0; k < 18; ++k) x[k] = rng.uniform(-1, 1);
    spmv(S.view(), x.data(), y.data());
    CHECK((y - D * x).norm() <= 1e-14 * (D * x).norm());
    // The same blocks in single precision: stored rounded, read back as double by block(),
    // to_dense and the product; half the value bytes.
    SymBlockMatrix<6> Sf(3, ptr, col, /*single=*/true);
    CHECK(Sf.single());
    CHECK(Sf.stored_blocks() == 5);
    CHECK(Sf.memory_bytes() < S.memory_bytes());
    for (int s = 0; s < S.stored_blocks(); ++s) Sf.store(s, S.stored(s));
    const Eigen::MatrixXd Df = Sf.to_dense();
    CHECK(Df == D.cast<float>().cast<double>());
    CHECK((Df - D).norm() > 0);  // rounded
    CHECK((Df - Df.transpose()).norm() == 0.0);
    CHECK(Sf.stored_value(Sf.diagonal_index(1)) == Eigen::MatrixXd(Df.block<6, 6>(6, 6)));
    spmv(Sf.view(), x.data(), y.data());
    CHECK((y - Df * x).norm() <= 1e-14 * (Df * x).norm());
  }

  TEST_CASE("bsr: the single-precision one-triangle 6x6 product is the portable kernel's bit for bit and the rounded blocks' product to round-off") {
    support::Rng rng(11);
    const int n = 300;
    SymBlockMatrix<6> Sf = random_sym6(rng, n, /*single=*/true);
    const auto V = Sf.view();
    REQUIRE(V.valf != nullptr);
    int transposed = 0;
    for (int k = 0; k < V.nnz(); ++k) transposed += V.transposed(k);
    REQUIRE(transposed > 1000);
    Eigen::VectorXd x(6 * n), y(6 * n);
    for (int k = 0; k < 6 * n; ++k) x[k] = rng.uniform(-1, 1);
    spmv(V, x.data(), y.data());  // through row_product, the SSE2 kernel on x86-64
    int differ = 0;
    for (int i = 0; i < n; ++i) {
      const Eigen::Matrix<double, 6, 1> ref = sym_row_product_single_portable(V.row_ptr, V.col, V.src, V.valf, i, x.data());
      for (int c = 0; c < 6; ++c) differ += ref[c] != y[6 * i + c];
    }
    CHECK(differ == 0);
    const Eigen::MatrixXd D = Sf.to_dense();  // the rounded blocks, in double
    CHECK((D - D.transpose()).norm() == 0.0);
    const Eigen::VectorXd Dx = D * x;
    CHECK((y - Dx).norm() <= 1e-13 * Dx.norm());
    CHECK((y - Dx).norm() > 0);  // summed in another order than the dense product: a real comparison
  }

  TEST_CASE("bsr: row_product of six vectors at once is six single products through the prefilter and from one-triangle storage") {
    // preserve_modes multiplies the six rigid modes at once (node-major) as the cycle reads A.
    const support::ClothSystem sys = support::cloth_system(15, Tessellation::irregular, support::Pins::boundary);
    const ConstraintSet c = with_contacts(sys.pins, 7);
    OperatorFilter F;
    F.build(sys.A, c);
    REQUIRE(!F.empty());
    BsrView<3, 3> v = bsr_view(sys.A);
    support::Rng rng(5);
    CHECK(six_at_once_vs_single(v, rng) <= 1e-15);
    v.filter = F.view();
    CHECK(six_at_once_vs_single(v, rng) <= 1e-15);
    for (const bool single : {true, false}) {
      const SymBlockMatrix<6> S = random_sym6(rng, 200, single);
      CAPTURE(single);
      CHECK(six_at_once_vs_single(S.view(), rng) <= 1e-14);
    }
  }

  TEST_CASE("sa_ppcg: the memory it owns on a pinned cloth stays below a bound relative to the matrix") {
    const support::ClothSystem sys = support::cloth_system(81, Tessellation::regular, support::Pins::boundary);
    const ConstraintSet c = with_contacts(sys.pins, 5);  // contacts: the case that used to copy Ahat
    SaPpcg::Params prm;
    const Solved sa = solve<SaPpcg>(sys.A, sys.b, c, sys.x, prm);
    const Solved dg = solve<DiagPcg>(sys.A, sys.b, c, sys.x, DiagPcg::Params{});
    REQUIRE(sa.rep.status == Status::success);
    REQUIRE(dg.rep.status == Status::success);
    const double a = static_cast<double>(matrix_bytes(sys.A));
    const double own = static_cast<double>(sa.rep.memory_bytes), diag = static_cast<double>(dg.rep.memory_bytes);
    MESSAGE("A ", a / 1e6, " MB; SA+PPCG owns ", own / 1e6, " MB (", own / a, " A), Diag-PCG ", diag / 1e6,
            " MB; (A + SA) / (A + Diag) = ", (a + own) / (a + diag), "; op. complexity ", sa.rep.operator_complexity,
            "; iterations ", sa.rep.iterations);
    // Measured 2026-11-22 at 6561 vertices with contacts: 1.56 A (10.0 MB for A = 6.4 MB),
    // (A + SA) / (A + Diag-PCG) = 2.14, 5 iterations. Before the one-triangle coarse operators
    // and prefiltering on the fly, SA+PPCG owned 1.9 A on the pinned 10k bench system without
    // contacts, and a contact set added a copy of Ahat (0.95 A). 2026-11-27, with the coarse
    // operators and block inverses in float and PPCG iterating in x: 0.95 A, 1.63 (1.52 with
    // the implicit prolongator, since removed). Later that day, with P in fixed16, one work vector per level
    // (fused Chebyshev steps), PCG's idle vector lent to the fine level and no vector for
    // the prefiltered right-hand side: 0.75 A, 1.46 (1.44 implicit). The target is
    // 1.5. Then the fine smoother solved with A's diagonal blocks (no stored inverses) and
    // the cycle restricted by P's rows (no transpose index): 0.69 A, 1.41.
    CHECK(own <= 0.75 * a);
    CHECK((a + own) / (a + diag) <= 1.5);
    CHECK(sa.rep.operator_complexity < 2.3);
  }
}
