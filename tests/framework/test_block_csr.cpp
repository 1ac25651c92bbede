#include <doctest/doctest.h>

#include <algorithm>
#include <random>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "framework/block_csr.hpp"
#include "framework/mesh_generators.hpp"
#include "framework/triangle_mesh.hpp"

using namespace weft;

namespace {
struct Fixture {
  TriangleMesh mesh;
  AssemblyPlan plan;
  int g3 = -1, g4 = -1;
  std::vector<int> tri, hinge;
  explicit Fixture(int nx = 7, int ny = 6) {
    const auto m = make_rectangle({1, 1}, {nx, ny}, Tessellation::irregular, 5);
    mesh = TriangleMesh(m.V, m.F);
    for (int f = 0; f < mesh.num_faces(); ++f)
      for (int k = 0; k < 3; ++k) tri.push_back(mesh.faces()(f, k));
    for (const auto& h : mesh.hinges()) hinge.insert(hinge.end(), h.v.begin(), h.v.end());
    g3 = plan.add_group(3, tri);
    g4 = plan.add_group(4, hinge);
    plan.finalize(mesh.num_vertices());
  }
  // Random local matrices; the dense reference scatters them naively.
  Eigen::MatrixXd fill(ElementBuffer& buf, unsigned seed) const {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1, 1);
    Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(3 * mesh.num_vertices(), 3 * mesh.num_vertices());
    auto group = [&](int g, int k, const std::vector<int>& ids) {
      for (size_t e = 0; e < ids.size() / k; ++e) {
        Eigen::MatrixXd L(3 * k, 3 * k);
        for (int i = 0; i < L.size(); ++i) L.data()[i] = u(rng);
        buf.set(g, static_cast<int>(e), L);
        for (int a = 0; a < k; ++a)
          for (int b = 0; b < k; ++b) dense.block<3, 3>(3 * ids[e * k + a], 3 * ids[e * k + b]) += L.block<3, 3>(3 * a, 3 * b);
      }
    };
    group(g3, 3, tri);
    group(g4, 4, hinge);
    return dense;
  }
};
}  // namespace

TEST_SUITE("framework") {
  TEST_CASE("BlockCsr: gathered assembly equals a dense reference") {
    Fixture fx;
    ElementBuffer buf = fx.plan.make_buffer(AssemblyMode::stored);
    const Eigen::MatrixXd dense = fx.fill(buf, 11);
    BlockCsr A = fx.plan.pattern();
    fx.plan.gather(buf, A);
    REQUIRE(dense.norm() > 0);
    CHECK((A.to_dense() - dense).norm() <= 1e-13 * dense.norm());
    CHECK((Eigen::MatrixXd(A.to_sparse()) - dense).norm() <= 1e-13 * dense.norm());
    // The pattern holds exactly the vertex pairs that share an element.
    int nonzero_blocks = 0;
    for (int i = 0; i < fx.mesh.num_vertices(); ++i)
      for (int j = 0; j < fx.mesh.num_vertices(); ++j) nonzero_blocks += dense.block<3, 3>(3 * i, 3 * j).norm() > 0;
    CHECK(A.num_blocks() == nonzero_blocks);
  }

  TEST_CASE("BlockCsr: the pattern is reused across evaluations") {
    Fixture fx;
    ElementBuffer buf = fx.plan.make_buffer(AssemblyMode::stored);
    BlockCsr A = fx.plan.pattern();
    const auto col_before = A.col();
    fx.fill(buf, 1);
    fx.plan.gather(buf, A);
    const Eigen::MatrixXd d2 = fx.fill(buf, 2);
    fx.plan.gather(buf, A);  // overwrites, does not accumulate
    CHECK(A.col() == col_before);
    CHECK((A.to_dense() - d2).norm() <= 1e-13 * d2.norm());
  }

  TEST_CASE("BlockCsr: parallel assembly is bitwise deterministic across thread counts") {
    Fixture fx;
    ElementBuffer buf = fx.plan.make_buffer(AssemblyMode::stored);
    fx.fill(buf, 3);
    BlockCsr A = fx.plan.pattern(), B = fx.plan.pattern();
#ifdef _OPENMP
    const int saved = omp_get_max_threads();
    omp_set_num_threads(1);
    fx.plan.gather(buf, A);
    omp_set_num_threads(std::max(2, saved));
    fx.plan.gather(buf, B);
    omp_set_num_threads(saved);
#else
    fx.plan.gather(buf, A);
    fx.plan.gather(buf, B);
#endif
    REQUIRE(A.values().size() == B.values().size());
    CHECK(std::equal(A.values().begin(), A.values().end(), B.values().begin()));
  }

  TEST_CASE("BlockCsr: multiply / diagonal / scale and Dirichlet filter") {
    Fixture fx;
    ElementBuffer buf = fx.plan.make_buffer(AssemblyMode::stored);
    Eigen::MatrixXd dense = fx.fill(buf, 4);
    BlockCsr A = fx.plan.pattern();
    fx.plan.gather(buf, A);
    Eigen::VectorXd x = Eigen::VectorXd::LinSpaced(A.rows(), -1, 2), y;
    A.multiply(x, y);
    CHECK((y - dense * x).norm() <= 1e-12 * (dense * x).norm());

    Eigen::VectorXd d = Eigen::VectorXd::Constant(A.rows(), 0.5);
    A.add_diagonal(d);
    A.scale(2.0);
    dense = 2.0 * (dense + Eigen::MatrixXd(d.asDiagonal()));
    CHECK((A.to_dense() - dense).norm() <= 1e-12 * dense.norm());

    std::vector<unsigned char> fixed(A.block_rows(), 0);
    fixed[0] = fixed[5] = 1;
    A.filter_rows(fixed, 1.0);
    const Eigen::MatrixXd F = A.to_dense();
    for (int i : {0, 5}) {
      CHECK((F.block(3 * i, 0, 3, F.cols()).rowwise().norm() - Eigen::Vector3d::Ones()).norm() <= 1e-15);
      CHECK(F.block<3, 3>(3 * i, 3 * i).isIdentity());
      CHECK(F.block(0, 3 * i, F.rows(), 3).colwise().norm().isOnes());
    }
    CHECK(F.block(3, 3, 12, 12).isApprox(dense.block(3, 3, 12, 12)));

    // Scale-keeping filter: the fixed diagonal becomes tr(A_ii)/3 I, the couplings vanish.
    BlockCsr B = fx.plan.pattern();
    fx.plan.gather(buf, B);
    B.add_diagonal(Eigen::VectorXd::Constant(B.rows(), 7.0));
    const double expected = B.block(B.diagonal(5)).trace() / 3.0;
    REQUIRE(std::abs(expected - 1.0) > 1.0);
    B.filter_rows(fixed, -1.0);
    const Eigen::MatrixXd G = B.to_dense();
    CHECK(G.block<3, 3>(15, 15).isApprox(expected * Eigen::Matrix3d::Identity(), 1e-15));
    CHECK(G.block(15, 0, 3, 15).norm() == 0.0);
    CHECK(G.block(0, 15, 15, 3).norm() == 0.0);
  }

  TEST_CASE("BlockCsr: symmetric element matrices give a symmetric matrix - lower-only export") {
    Fixture fx;
    ElementBuffer buf = fx.plan.make_buffer(AssemblyMode::stored);
    std::mt19937 rng(8);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int e = 0; e < fx.mesh.num_faces(); ++e) {
      Eigen::Matrix<double, 9, 9> L;
      for (int i = 0; i < 81; ++i) L.data()[i] = u(rng);
      buf.set(fx.g3, e, L + L.transpose());
    }
    buf.zero_group(fx.g4);
    BlockCsr A = fx.plan.pattern();
    fx.plan.gather(buf, A);
    CHECK(A.asymmetry() <= 1e-15);
    const Eigen::MatrixXd lower = Eigen::MatrixXd(A.to_sparse(true));
    const Eigen::MatrixXd full = A.to_dense();
    CHECK((Eigen::MatrixXd(lower.triangularView<Eigen::Lower>()) - lower).norm() == 0.0);
    CHECK((Eigen::MatrixXd(lower.selfadjointView<Eigen::Lower>()) - full).norm() <= 1e-14 * full.norm());
  }

  TEST_CASE("Colouring: every element once and no vertex shared by two chunks of one colour") {
    Fixture fx(20, 16);
    for (auto [ids, k] : {std::pair{&fx.tri, 3}, std::pair{&fx.hinge, 4}})
      for (int chunk : {1, 2, 5, Colouring::default_chunk}) {
        CAPTURE(k);
        CAPTURE(chunk);
        const Colouring c = Colouring::uniform(*ids, k, fx.mesh.num_vertices(), chunk);
        const int ne = static_cast<int>(ids->size()) / k;
        REQUIRE(c.num_elements() == ne);
        REQUIRE(ne > 2 * chunk);      // guard: several chunks, so the colouring has work to do
        CHECK(c.num_colours() >= 2);  // adjacent chunks exist, so one colour cannot do
        // What the README states for chunks of 32 on the generated sheets: 3-4 colours for
        // triangles, 5-8 for hinges.
        if (chunk == Colouring::default_chunk) CHECK(c.num_colours() <= (k == 3 ? 4 : 8));
        if (chunk == 1) {  // greedy first-fit: at most one more colour than an element has neighbours
          std::vector<std::vector<int>> at(fx.mesh.num_vertices());
          for (int e = 0; e < ne; ++e)
            for (int a = 0; a < k; ++a) at[(*ids)[e * k + a]].push_back(e);
          size_t most = 0;
          for (int e = 0; e < ne; ++e) {
            std::vector<int> nb;
            for (int a = 0; a < k; ++a) nb.insert(nb.end(), at[(*ids)[e * k + a]].begin(), at[(*ids)[e * k + a]].end());
            std::sort(nb.begin(), nb.end());
            most = std::max(most, static_cast<size_t>(std::unique(nb.begin(), nb.end()) - nb.begin()) - 1);
          }
          CHECK(static_cast<size_t>(c.num_colours()) <= most + 1);
        }
        std::vector<int> seen(ne, 0);
        for (int col = 0; col < c.num_colours(); ++col) {
          CHECK(c.end_chunk(col) > c.first_chunk(col));
          std::vector<int> owner(fx.mesh.num_vertices(), -1);  // the chunk that holds the vertex
          size_t in_colour = 0;
          for (int q = c.first_chunk(col); q < c.end_chunk(col); ++q) {
            const auto el = c.chunk(q);
            CHECK(static_cast<int>(el.size()) <= chunk);
            CHECK(std::is_sorted(el.begin(), el.end()));
            CHECK(el.back() - el.front() == static_cast<int>(el.size()) - 1);  // consecutive elements
            in_colour += el.size();
            for (int e : el) {
              ++seen[e];
              for (int a = 0; a < k; ++a) {
                const int v = (*ids)[e * k + a];
                CHECK((owner[v] == -1 || owner[v] == q));
                owner[v] = q;
              }
            }
          }
          CHECK(in_colour == static_cast<size_t>(c.colour_size(col)));
        }
        CHECK(std::all_of(seen.begin(), seen.end(), [](int n) { return n == 1; }));
      }
    // More than 64 colours: 70 elements (chunk 1) or chunks (chunk 3) that all share vertex 0.
    for (int chunk : {1, 3}) {
      std::vector<int> fan;
      for (int e = 0; e < 70 * chunk; ++e) fan.insert(fan.end(), {0, e + 1});
      const Colouring wide = Colouring::uniform(fan, 2, 70 * chunk + 1, chunk);
      CHECK(wide.num_colours() == 70);
    }
  }

  TEST_CASE("BlockCsr: direct assembly equals the stored one and is deterministic across threads") {
    // 60 x 50 cells: colours of more than 256 elements in many chunks, so that the direct
    // assembly runs its chunks in parallel.
    Fixture fx(60, 50);
    const Colouring& hc = fx.plan.make_buffer().colouring(fx.g4);
    REQUIRE(hc.colour_size(0) >= 256);
    REQUIRE(hc.end_chunk(0) - hc.first_chunk(0) >= 8);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-1, 1);
    std::vector<Eigen::MatrixXd> tri(fx.tri.size() / 3), hin(fx.hinge.size() / 4);
    for (auto& L : tri) L = Eigen::MatrixXd::NullaryExpr(9, 9, [&] { return u(rng); });
    for (auto& L : hin) L = Eigen::MatrixXd::NullaryExpr(12, 12, [&] { return u(rng); });
    auto assemble = [&](AssemblyMode mode, int threads) {
#ifdef _OPENMP
      const int saved = omp_get_max_threads();
      omp_set_num_threads(threads);
#endif
      ElementBuffer buf = fx.plan.make_buffer(mode);
      BlockCsr A = fx.plan.pattern();
      A.values().assign(A.values().size(), 42.0);  // start() must overwrite, not accumulate
      buf.start(A);
      buf.for_each(fx.g3, [&](int e) { buf.set(fx.g3, e, tri[e]); });
      buf.for_each(fx.g4, [&](int e) { buf.set(fx.g4, e, hin[e]); });
      buf.finish();
#ifdef _OPENMP
      omp_set_num_threads(saved);
#else
      (void)threads;
#endif
      return A;
    };
    const BlockCsr S = assemble(AssemblyMode::stored, 1);
    const BlockCsr D1 = assemble(AssemblyMode::direct, 1), D2 = assemble(AssemblyMode::direct, 2);
    const Eigen::MatrixXd ds = S.to_dense();
    REQUIRE(ds.norm() > 0);
    CHECK((D1.to_dense() - ds).norm() <= 1e-14 * ds.norm());
    CHECK(std::equal(D1.values().begin(), D1.values().end(), D2.values().begin()));
    // A direct slot adds: two writes to one element sum.
    ElementBuffer buf = fx.plan.make_buffer();
    BlockCsr A = fx.plan.pattern();
    buf.start(A);
    buf.set(fx.g3, 0, tri[0]);
    buf.set(fx.g3, 0, tri[0]);
    buf.finish();
    const int v0 = fx.tri[0];
    CHECK((Eigen::Matrix3d(A.block(A.diagonal(v0))) - 2 * tri[0].block<3, 3>(0, 0)).norm() <= 1e-15 * tri[0].norm() + 1e-300);
  }
}
