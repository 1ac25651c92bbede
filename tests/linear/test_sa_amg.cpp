// Smoothed aggregation multigrid (methods/multigrid §4-6, checklist V5-V14).
#include <doctest/doctest.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <numeric>
#include <queue>
#include <random>
#include <set>

#ifdef WEFT_WITH_OPENMP
#include <omp.h>
#endif

#include "framework/params_json.hpp"
#include "framework/union_find.hpp"
#include "linear/prefilter.hpp"
#include "linear/sa_amg.hpp"
#include "linear/sa_ppcg.hpp"
#include "tests/support/linear_fixtures.hpp"

using namespace weft;
using namespace weft::linear;
using support::Pins;

namespace {

/// A prefiltered system as PPCG sees it: Ahat, chat and the data SA needs.
struct Prefiltered {
  support::ClothSystem sys;
  BlockCsr Ahat;
  Eigen::VectorXd chat;
};

Prefiltered prefiltered_cloth(int m, Tessellation t = Tessellation::regular, Pins pins = Pins::boundary) {
  Prefiltered p{support::cloth_system(m, t, pins), {}, {}};
  p.Ahat = p.sys.A;
  prefilter_matrix(p.sys.A, p.sys.pins, p.Ahat);
  prefilter_rhs(p.sys.A, p.sys.pins, p.sys.b, p.chat);
  return p;
}

/// Grid positions of an m x m block Laplacian (unit spacing / m, z = 0).
Eigen::VectorXd grid_positions(int m) {
  Eigen::VectorXd x(3 * m * m);
  for (int j = 0; j < m; ++j)
    for (int i = 0; i < m; ++i) x.segment<3>(3 * (j * m + i)) = Eigen::Vector3d(double(i) / m, double(j) / m, 0.0);
  return x;
}

struct PcgResult {
  int iterations = 0;
  bool converged = false;
  double relative = 0;
};

/// Plain PCG with the spec's stopping test ||r||_{M^-1} / ||r_0||_{M^-1} < tol (methods/multigrid §8).
template <class Prec>
PcgResult pcg(const BlockCsr& A, const Eigen::VectorXd& b, const Prec& M, double tol = 1e-5, int max_it = 500) {
  PcgResult out;
  Eigen::VectorXd x = Eigen::VectorXd::Zero(b.size()), r = b, z, p, q;
  M.apply(r, z);
  double rz = r.dot(z);
  const double rz0 = rz;
  p = z;
  for (int it = 1; it <= max_it; ++it) {
    A.multiply(p, q);
    const double pq = p.dot(q);
    if (!(pq > 0) || !(rz > 0)) break;
    const double alpha = rz / pq;
    x += alpha * p;
    r -= alpha * q;
    M.apply(r, z);
    const double rz_new = r.dot(z);
    out.iterations = it;
    out.relative = std::sqrt(std::abs(rz_new / rz0));
    if (out.relative < tol) {
      out.converged = true;
      break;
    }
    p = z + (rz_new / rz) * p;
    rz = rz_new;
  }
  return out;
}

SaAmg::Params small_coarse(int coarse_size) {
  SaAmg::Params prm;
  prm.coarse_size = coarse_size;
  return prm;
}

Eigen::MatrixXd assemble_preconditioner(const SaAmg& sa, int N) {
  Eigen::MatrixXd B(N, N);
  Eigen::VectorXd e = Eigen::VectorXd::Zero(N), z;
  for (int j = 0; j < N; ++j) {
    e[j] = 1;
    sa.apply(e, z);
    B.col(j) = z;
    e[j] = 0;
  }
  return B;
}

/// The smallest eigenvalue of the symmetric part of B.
double min_symmetric_eigenvalue(const Eigen::MatrixXd& B) {
  return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(0.5 * (B + B.transpose())).eigenvalues().minCoeff();
}

/// The preconditioner's map, checked symmetric to 1e-12 and positive definite.
Eigen::MatrixXd checked_spd_map(const SaAmg& sa, int N) {
  const Eigen::MatrixXd B = assemble_preconditioner(sa, N);
  CHECK((B - B.transpose()).norm() <= 1e-12 * B.norm());
  CHECK(min_symmetric_eigenvalue(B) > 0);
  return B;
}

/// Dense D^-1 A similarity: eigenvalues of L^-1 A L^-T with D = blockdiag(A_ii) = L L^T.
Eigen::VectorXd jacobi_spectrum(const Eigen::MatrixXd& A, int b) {
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(A.rows(), A.cols());
  for (int i = 0; i < A.rows(); i += b) D.block(i, i, b, b) = A.block(i, i, b, b);
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> es(A, D, Eigen::EigenvaluesOnly);
  return es.eigenvalues();
}

/// `layers` copies of the prefiltered two-sides-pinned cloth stacked `gap` apart in z, each
/// free vertex joined to the one above it by a spring of stiffness k along z (Hessian
/// k e_z e_z^T, rank one): layers that slide freely over each other, like the aligned
/// accordion of the bench's regular dropVertical. k is in the matrix's units (M + dt^2 H);
/// the bench's springs are some 6000 vertex masses.
struct SpringStack {
  BlockCsr A;
  Eigen::VectorXd x, b;
  ConstraintSet pins;
  int per_layer = 0;
};

/// `tilt` > 0 turns each vertex's springs away from the normal by that angle [rad], about
/// three azimuths in turn (vertex i % 3): oblique springs that bond the layers in shear.
SpringStack spring_stack(int m, int layers, double k, double gap = 5e-3, double tilt = 0) {
  const Prefiltered p = prefiltered_cloth(m, Tessellation::regular, Pins::two_sides);
  const int n = p.Ahat.block_rows();
  SpringStack s;
  s.per_layer = n;
  auto sprung = [&](int i) { return p.sys.pins.count(i) == 0; };
  std::vector<std::vector<int>> columns(static_cast<std::size_t>(n) * layers);
  for (int l = 0; l < layers; ++l)
    for (int i = 0; i < n; ++i) {
      auto& c = columns[l * n + i];
      for (int q = p.Ahat.row_ptr()[i]; q < p.Ahat.row_ptr()[i + 1]; ++q) c.push_back(l * n + p.Ahat.col()[q]);
      if (sprung(i) && l > 0) c.push_back((l - 1) * n + i);
      if (sprung(i) && l + 1 < layers) c.push_back((l + 1) * n + i);
      std::sort(c.begin(), c.end());
    }
  s.A = BlockCsr(columns);
  s.A.set_zero();
  s.x.resize(3 * n * layers);
  s.b.resize(3 * n * layers);
  s.pins.reset(n * layers);
  for (int l = 0; l < layers; ++l)
    for (int i = 0; i < n; ++i) {
      const int r = l * n + i;
      const double phi = 2 * std::numbers::pi * (i % 3) / 3;
      const Eigen::Vector3d dir(std::sin(tilt) * std::cos(phi), std::sin(tilt) * std::sin(phi), std::cos(tilt));
      const Block3 Kz = k * dir * dir.transpose();
      for (int q = p.Ahat.row_ptr()[i]; q < p.Ahat.row_ptr()[i + 1]; ++q)
        s.A.block(s.A.find(r, l * n + p.Ahat.col()[q])) = p.Ahat.block(q);
      if (sprung(i))
        for (int o : {l - 1, l + 1})
          if (o >= 0 && o < layers) {
            s.A.block(s.A.diagonal(r)) += Kz;
            s.A.block(s.A.find(r, o * n + i)) -= Kz;
          }
      s.x.segment<3>(3 * r) = p.sys.x.segment<3>(3 * i) + Eigen::Vector3d(0, 0, l * gap);
      s.b.segment<3>(3 * r) = p.chat.segment<3>(3 * i);
      if (!sprung(i)) s.pins.fix(r, Eigen::Vector3d::Zero());
    }
  return s;
}

/// Fine-level aggregates of A at the default thresholds.
sa::Aggregates fine_aggregates(const BsrView<3, 3>& A) {
  std::vector<double> mu;
  std::vector<std::uint8_t> strong, special;
  sa::strength<3>(A, 0.48, SocMeasure::spectral, mu, strong);
  sa::special_nodes<3>(A, mu, 1e-2, strong, special);
  return sa::aggregate<3>(A, strong, special);
}

/// Aggregates with members in more than one layer of `per_layer` nodes.
int aggregates_across_layers(const sa::Aggregates& ag, int per_layer) {
  std::vector<int> layer(ag.count, -1), across(ag.count, 0);
  for (int i = 0; i < static_cast<int>(ag.node_agg.size()); ++i) {
    const int a = ag.node_agg[i];
    if (a < 0) continue;
    if (layer[a] < 0) layer[a] = i / per_layer;
    across[a] |= layer[a] != i / per_layer;
  }
  return static_cast<int>(std::count(across.begin(), across.end(), 1));
}

}  // namespace

TEST_SUITE("linear") {

TEST_CASE("sa: spectral radius of 3x3 blocks matches the general eigenvalue solver") {
  support::Rng rng(11);
  int complex_cases = 0;
  for (int t = 0; t < 2000; ++t) {
    Eigen::Matrix3d M;
    for (int a = 0; a < 3; ++a) M.row(a) = rng.vec3().transpose();
    if (t % 5 == 0) M = M + M.transpose().eval();              // real spectrum
    if (t % 7 == 0) M = rng.rotation() * (0.1 + rng.uniform());  // complex pair on a circle
    Eigen::EigenSolver<Eigen::Matrix3d> es(M, false);
    const double ref = es.eigenvalues().cwiseAbs().maxCoeff();
    complex_cases += es.eigenvalues().imag().cwiseAbs().maxCoeff() > 1e-3;
    CAPTURE(M);
    CHECK(std::abs(sa::spectral_radius3(M) - ref) <= 1e-7 * std::max(1.0, ref));
  }
  CHECK(complex_cases > 100);
  CHECK(sa::spectral_radius3(Eigen::Matrix3d::Zero()) == 0.0);
  CHECK(std::abs(sa::spectral_radius3(2.5 * Eigen::Matrix3d::Identity()) - 2.5) <= 1e-12);
}

TEST_CASE("sa: the 6x6 spectral radius estimate is a tight upper bound") {
  support::Rng rng(5);
  double worst = 0;
  for (int t = 0; t < 500; ++t) {
    Eigen::Matrix<double, 6, 6> M;
    for (int a = 0; a < 6; ++a)
      for (int b = 0; b < 6; ++b) M(a, b) = rng.uniform(-1, 1);
    if (t % 3 == 0) M = (M + M.transpose()).eval();
    Eigen::EigenSolver<Eigen::Matrix<double, 6, 6>> es(M, false);
    const double ref = es.eigenvalues().cwiseAbs().maxCoeff();
    const double est = sa::measure<6>(M, SocMeasure::spectral);
    CHECK(est >= ref * (1 - 1e-12));
    worst = std::max(worst, est / ref - 1);
  }
  MESSAGE("worst relative overestimate " << worst);
  CHECK(worst < 0.05);
  CHECK(sa::measure<6>(Eigen::Matrix<double, 6, 6>::Zero(), SocMeasure::spectral) == 0.0);
}

TEST_CASE("sa: strength of connection is symmetric and follows the theta limits") {
  Prefiltered p = prefiltered_cloth(15, Tessellation::irregular, Pins::two_sides);
  const auto A = bsr_view(p.Ahat);
  std::vector<double> mu;
  std::vector<std::uint8_t> strong, special;
  for (SocMeasure measure : {SocMeasure::spectral, SocMeasure::two_norm, SocMeasure::frobenius}) {
    CAPTURE(static_cast<int>(measure));
    sa::strength<3>(A, 0.48, measure, mu, strong);
    int nstrong = 0, nweak = 0;
    for (int i = 0; i < A.rows; ++i)
      for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
        const int j = A.col[k], kt = p.Ahat.find(j, i);
        CHECK(strong[k] == strong[kt]);
        CHECK(std::abs(mu[k] - mu[kt]) <= 1e-14 * std::max(1.0, mu[k]));
        if (j != i) (strong[k] ? nstrong : nweak)++;
        if (j == i) CHECK(strong[k] == 0);
      }
    CHECK(nstrong > 0);
    CHECK(nweak > 0);  // a real threshold: some connections are weak
  }
  // theta -> 0: every neighbour with a nonzero coupling is strong.
  sa::strength<3>(A, 1e-9, SocMeasure::spectral, mu, strong);
  for (int k = 0; k < A.nnz(); ++k)
    if (mu[k] > 0) CHECK(strong[k] == 1);
  // theta -> 1: only the per-row maxima (in one of the two rows) stay strong.
  sa::strength<3>(A, 1 - 1e-12, SocMeasure::spectral, mu, strong);
  std::vector<double> top(A.rows, 0);
  for (int i = 0; i < A.rows; ++i)
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) top[i] = std::max(top[i], mu[k]);
  int nstrong = 0;
  for (int i = 0; i < A.rows; ++i)
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k)
      if (strong[k]) {
        ++nstrong;
        const int j = A.col[k];
        CHECK((mu[k] >= top[i] * (1 - 1e-12) || mu[k] >= top[j] * (1 - 1e-12)));
      }
  CHECK(nstrong >= A.rows - p.sys.pins.constrained_vertices());
  CHECK(nstrong <= 4 * A.rows);
  // Fully constrained vertices have no strong neighbour and are special (V5).
  sa::strength<3>(A, 0.48, SocMeasure::spectral, mu, strong);
  const int nspecial = sa::special_nodes<3>(A, mu, 1e-2, strong, special);
  CHECK(nspecial >= p.sys.pins.constrained_vertices());
  for (int i = 0; i < A.rows; ++i)
    if (p.sys.pins.count(i) == 3) CHECK(special[i] == 1);
  for (int i = 0; i < A.rows; ++i)
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k)
      if (strong[k]) CHECK((!special[i] && !special[A.col[k]]));
}

TEST_CASE("sa: a strongly diagonally dominant row is special") {
  BlockCsr A = support::block_laplacian(6, 0.0);
  A.block(A.diagonal(7)) += 1e6 * Block3::Identity();  // node 7: dominant
  std::vector<double> mu;
  std::vector<std::uint8_t> strong, special;
  sa::strength<3>(bsr_view(A), 0.48, SocMeasure::spectral, mu, strong);
  sa::special_nodes<3>(bsr_view(A), mu, 1e-2, strong, special);
  CHECK(special[7] == 1);
  CHECK(special[8] == 0);
  sa::strength<3>(bsr_view(A), 0.48, SocMeasure::spectral, mu, strong);
  sa::special_nodes<3>(bsr_view(A), mu, 0.0, strong, special);  // tau_dd = 0: only isolated nodes
  CHECK(special[7] == 0);
}

TEST_CASE("sa: aggregates are disjoint and connected and cover the non-special nodes") {
  for (Tessellation t : {Tessellation::regular, Tessellation::irregular}) {
    Prefiltered p = prefiltered_cloth(21, t, Pins::boundary);
    const auto A = bsr_view(p.Ahat);
    std::vector<double> mu;
    std::vector<std::uint8_t> strong, special;
    sa::strength<3>(A, 0.48, SocMeasure::spectral, mu, strong);
    sa::special_nodes<3>(A, mu, 1e-2, strong, special);
    const sa::Aggregates ag = sa::aggregate<3>(A, strong, special);
    REQUIRE(ag.count > 1);
    CHECK(ag.count < A.rows / 3);  // real coarsening
    std::vector<std::vector<int>> members(ag.count);
    for (int i = 0; i < A.rows; ++i) {
      CHECK((ag.node_agg[i] >= 0) == (special[i] == 0));  // union = non-special nodes
      if (ag.node_agg[i] >= 0) members[ag.node_agg[i]].push_back(i);  // one aggregate per node: disjoint
    }
    std::vector<int> histogram(ag.max_size + 1, 0);
    for (int a = 0; a < ag.count; ++a) {
      REQUIRE(!members[a].empty());
      ++histogram[members[a].size()];
      // Connected in the strong graph: BFS from the first member reaches them all.
      std::set<int> seen{members[a][0]};
      std::queue<int> q;
      q.push(members[a][0]);
      while (!q.empty()) {
        const int i = q.front();
        q.pop();
        for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k)
          if (strong[k] && ag.node_agg[A.col[k]] == a && seen.insert(A.col[k]).second) q.push(A.col[k]);
      }
      CHECK(seen.size() == members[a].size());
    }
    CHECK(histogram[1] == 0);  // no singletons
    MESSAGE("aggregate sizes (tessellation " << static_cast<int>(t) << "): count " << ag.count << " max " << ag.max_size);
    // Deterministic.
    const sa::Aggregates again = sa::aggregate<3>(A, strong, special);
    CHECK(again.node_agg == ag.node_agg);
  }
}

TEST_CASE("sa: split_sheets cuts the aggregates of a spring-joined stack into its layers and leaves a single sheet alone") {
  const SpringStack st = spring_stack(21, 4, 0.01);
  const auto A = bsr_view(st.A);
  sa::Aggregates ag = fine_aggregates(A);
  const int before = ag.count, across = aggregates_across_layers(ag, st.per_layer);
  MESSAGE("stack of 4 layers of 441: " << before << " aggregates, " << across << " across layers");
  REQUIRE(across > before / 4);  // the springs are strong: aggregation follows them
  const sa::SheetEdges edges = sa::sheet_edges(A);
  for (const auto& [i, j] : edges) CHECK(i / st.per_layer == j / st.per_layer);  // springs are no sheet edges
  const int added = sa::split_sheets(edges, ag);
  CHECK(added == ag.count - before);
  CHECK(added >= across);  // each aggregate across layers gives at least one more
  CHECK(aggregates_across_layers(ag, st.per_layer) == 0);
  // The coarse level's sheets: its nodes stay within their layer.
  std::vector<int> layer_of(ag.count, -1);
  for (int i = 0; i < A.rows; ++i)
    if (ag.node_agg[i] >= 0) layer_of[ag.node_agg[i]] = i / st.per_layer;
  const sa::SheetEdges coarse = sa::coarse_sheet_edges(edges, ag);
  CHECK(coarse.size() > static_cast<std::size_t>(ag.count));
  CHECK(std::is_sorted(coarse.begin(), coarse.end()));
  for (const auto& [a, b] : coarse) CHECK((a < b && layer_of[a] == layer_of[b]));
  // Every piece is connected through the non-spring couplings of its layer, and aggregates
  // are numbered in the order of their first node.
  UnionFind pieces(A.rows);
  for (const auto& [i, j] : edges)
    if (ag.node_agg[i] >= 0 && ag.node_agg[i] == ag.node_agg[j]) pieces.unite(i, j);
  std::vector<int> piece_root(ag.count, -1);
  for (int i = 0; i < A.rows; ++i) {
    const int a = ag.node_agg[i];
    if (a < 0) continue;
    if (piece_root[a] < 0) piece_root[a] = pieces.find(i);
    CHECK(pieces.find(i) == piece_root[a]);
  }
  std::vector<int> first(ag.count, -1);
  for (int i = 0; i < A.rows; ++i)
    if (ag.node_agg[i] >= 0 && first[ag.node_agg[i]] < 0) first[ag.node_agg[i]] = i;
  CHECK(std::is_sorted(first.begin(), first.end()));
  CHECK(std::count(first.begin(), first.end(), -1) == 0);
  // A single sheet, regular and irregular (whose flat hinges couple wing tips by rank-one
  // blocks): the split changes nothing on the regular one, and on the irregular one only
  // cuts off nodes an aggregate held through a rank-one block alone.
  for (Tessellation t : {Tessellation::regular, Tessellation::irregular}) {
    const Prefiltered p = prefiltered_cloth(21, t, Pins::two_sides);
    const auto S = bsr_view(p.Ahat);
    sa::Aggregates one = fine_aggregates(S);
    const std::vector<int> original = one.node_agg;
    const int splits = sa::split_sheets(sa::sheet_edges(S), one);
    MESSAGE("single sheet, tessellation " << static_cast<int>(t) << ": " << splits << " splits of " << one.count - splits);
    if (t == Tessellation::regular) {
      CHECK(splits == 0);
      CHECK(one.node_agg == original);
    } else {
      CHECK(splits <= (one.count - splits) / 10);
    }
  }
}

TEST_CASE("sa: split_sheets keeps the V-cycle SPD and cuts the PCG iterations on a stack of unbonded layers") {
  SaAmg::Params split = small_coarse(20);
  split.split_sheets = true;
  {
    const SpringStack st = spring_stack(9, 3, 0.01);
    SaAmg sa(split);
    REQUIRE(sa.setup(st.A, SolveContext{&st.pins, &st.x}) == Status::success);
    CHECK(sa.stats().levels[0].sheet_splits > 0);
    checked_spd_map(sa, st.A.rows());
  }
  // Springs of about 100 vertex masses (the layers' mass matrix is 8.9e-5 per vertex): a
  // sweep of k in {0.01, 0.1, 1, 10} and m in {21, 41, 61} gave 30 -> 9, 33 -> 16, 48 -> 43
  // and 130 -> 66 iterations at m = 41; the default grows with m at every k.
  const SpringStack st = spring_stack(41, 4, 0.01);
  SaAmg plain(small_coarse(50)), layered([] {
    SaAmg::Params p = small_coarse(50);
    p.split_sheets = true;
    return p;
  }());
  REQUIRE(plain.setup(st.A, SolveContext{&st.pins, &st.x}) == Status::success);
  REQUIRE(layered.setup(st.A, SolveContext{&st.pins, &st.x}) == Status::success);
  const PcgResult a = pcg(st.A, st.b, plain), b = pcg(st.A, st.b, layered);
  MESSAGE("stack of 4 layers of 41 x 41: " << a.iterations << " iterations, " << b.iterations << " with split_sheets ("
                                           << layered.stats().levels[0].sheet_splits << " splits)");
  CHECK(a.converged);
  CHECK(b.converged);
  CHECK(b.iterations <= 0.5 * a.iterations);
  // On a single sheet the option changes nothing.
  const Prefiltered p = prefiltered_cloth(41, Tessellation::regular, Pins::two_sides);
  REQUIRE(plain.setup(p.Ahat, SolveContext{&p.sys.pins, &p.sys.x}) == Status::success);
  REQUIRE(layered.setup(p.Ahat, SolveContext{&p.sys.pins, &p.sys.x}) == Status::success);
  CHECK(layered.stats().levels[0].sheet_splits == 0);
  CHECK(pcg(p.Ahat, p.chat, layered).iterations == pcg(p.Ahat, p.chat, plain).iterations);
}

TEST_CASE("sa: merge_small_aggregates joins the split's small pieces to a neighbour within their sheet") {
  const SpringStack st = spring_stack(21, 4, 0.01);
  const auto A = bsr_view(st.A);
  const sa::SheetEdges edges = sa::sheet_edges(A);
  sa::Aggregates split = fine_aggregates(A);
  sa::split_sheets(edges, split);
  const int max_size = 3;
  std::vector<int> size(split.count, 0);
  for (const int a : split.node_agg)
    if (a >= 0) ++size[a];
  // The small aggregates that have a large one across a sheet coupling.
  std::vector<std::uint8_t> joinable(split.count, 0);
  for (const auto& [i, j] : edges) {
    const int a = split.node_agg[i], b = split.node_agg[j];
    if (a < 0 || b < 0 || a == b) continue;
    if (size[a] <= max_size && size[b] > max_size) joinable[a] = 1;
    if (size[b] <= max_size && size[a] > max_size) joinable[b] = 1;
  }
  const int expected = static_cast<int>(std::count(joinable.begin(), joinable.end(), 1));
  const int small = static_cast<int>(std::count_if(size.begin(), size.end(), [&](int s) { return s <= max_size; }));
  MESSAGE("stack of 4 layers of 441: " << split.count << " aggregates after the split, " << small << " of at most "
                                       << max_size << " nodes, " << expected << " with a larger sheet neighbour");
  REQUIRE(expected > split.count / 20);  // not a vacuous pass: the split leaves many pieces
  sa::Aggregates merged = split;
  const int removed = sa::merge_small_aggregates(edges, merged, max_size);
  CHECK(removed == expected);
  CHECK(merged.count == split.count - removed);
  // Large aggregates keep their members together and apart; a joinable piece lands in a
  // large aggregate it touched through a sheet coupling; the others keep their members.
  std::vector<int> image(split.count, -1);
  for (int i = 0; i < A.rows; ++i) {
    const int a = split.node_agg[i];
    REQUIRE((a < 0) == (merged.node_agg[i] < 0));
    if (a < 0) continue;
    if (image[a] < 0) image[a] = merged.node_agg[i];
    CHECK(merged.node_agg[i] == image[a]);
  }
  std::vector<int> owner(merged.count, -1);  // the unmerged aggregate each new one came from
  for (int a = 0; a < split.count; ++a)
    if (!joinable[a]) {
      CHECK(owner[image[a]] == -1);  // no two unmerged aggregates share an image
      owner[image[a]] = a;
    }
  CHECK(std::count(owner.begin(), owner.end(), -1) == 0);
  for (int a = 0; a < split.count; ++a) {
    if (!joinable[a]) continue;
    const int b = owner[image[a]];
    CHECK(size[b] > max_size);
    bool touches = false;
    for (const auto& [i, j] : edges)
      touches = touches || (split.node_agg[i] == a && split.node_agg[j] == b) || (split.node_agg[i] == b && split.node_agg[j] == a);
    CHECK(touches);
  }
  CHECK(aggregates_across_layers(merged, st.per_layer) == 0);  // still within one sheet
  std::vector<int> merged_size(merged.count, 0);
  for (const int a : merged.node_agg)
    if (a >= 0) ++merged_size[a];
  CHECK(merged.max_size == *std::max_element(merged_size.begin(), merged_size.end()));
  sa::Aggregates again = split;
  sa::merge_small_aggregates(edges, again, max_size);
  CHECK(again.node_agg == merged.node_agg);  // deterministic
  sa::Aggregates none = split;
  CHECK(sa::merge_small_aggregates(edges, none, 0) == 0);
  CHECK(none.node_agg == split.node_agg);
  // In the hierarchy: fewer coarse nodes, the V-cycle stays SPD, and PCG still converges.
  SaAmg::Params prm = small_coarse(20);
  prm.split_sheets = true;
  SaAmg plain(prm);
  prm.split_merge = max_size;
  SaAmg joined(prm);
  REQUIRE(plain.setup(st.A, SolveContext{&st.pins, &st.x}) == Status::success);
  REQUIRE(joined.setup(st.A, SolveContext{&st.pins, &st.x}) == Status::success);
  CHECK(joined.stats().levels[0].sheet_merges > 0);
  CHECK(joined.stats().levels[0].aggregates < plain.stats().levels[0].aggregates);
  {
    // The dense SPD check on a stack small enough to form B (3 layers of 9 x 9: 729 dofs).
    const SpringStack small = spring_stack(9, 3, 0.01);
    SaAmg sa(prm);
    REQUIRE(sa.setup(small.A, SolveContext{&small.pins, &small.x}) == Status::success);
    CHECK(sa.stats().levels[0].sheet_merges > 0);
    checked_spd_map(sa, small.A.rows());
  }
  const PcgResult a = pcg(st.A, st.b, plain), b = pcg(st.A, st.b, joined);
  MESSAGE("iterations: " << a.iterations << " split, " << b.iterations << " split + merge; level 1: "
                         << plain.stats().levels[1].rows << " -> " << joined.stats().levels[1].rows << " nodes");
  CHECK(a.converged);
  CHECK(b.converged);
  CHECK_THROWS_AS(SaAmg(SaAmg::Params{.split_merge = 2}), ConfigError);  // needs split_sheets
  CHECK_THROWS_AS(SaAmg(SaAmg::Params{.split_sheets = true, .split_merge = -1}), ConfigError);
}

TEST_CASE("sa: split_bonded splits the aggregates of sliding layers and keeps those bonded by oblique springs whole") {
  SaAmg::Params prm = small_coarse(20);
  prm.split_sheets = true;
  auto splits = [](const SpringStack& st, double bonded) {
    const auto A = bsr_view(st.A);
    sa::Aggregates ag = fine_aggregates(A);
    return sa::split_sheets(sa::sheet_edges(A), ag, {}, &A, bonded);
  };
  const SpringStack aligned = spring_stack(13, 3, 0.01), oblique = spring_stack(13, 3, 0.01, 5e-3, 0.5);
  const int aligned_all = splits(aligned, 0), oblique_all = splits(oblique, 0);
  MESSAGE("splits: aligned " << aligned_all << " / " << splits(aligned, 0.01) << " with split_bonded = 0.01, oblique "
                             << oblique_all << " / " << splits(oblique, 0.01));
  REQUIRE(aligned_all > 20);
  REQUIRE(oblique_all > 20);  // the split alone cannot tell them apart (springs are rank-one either way)
  CHECK(splits(aligned, 0.01) == aligned_all);
  // An aggregate held across the layers by springs of one direction only is still cut (a
  // single spring is rank-one, tilted or not); those with springs of two directions stay
  // whole. (On irregular dropVertical at 40k: 1740 splits -> 212, LEAN-aggregation.md.)
  CHECK(splits(oblique, 0.01) <= 0.75 * oblique_all);
  CHECK(splits(oblique, 0.99) == oblique_all);  // a bound no sum of springs reaches: nothing kept whole
  prm.split_bonded = 0.01;
  for (const SpringStack* st : {&aligned, &oblique}) {
    SaAmg sa(prm);
    REQUIRE(sa.setup(st->A, SolveContext{&st->pins, &st->x}) == Status::success);
    checked_spd_map(sa, st->A.rows());
    CHECK(pcg(st->A, st->b, sa).converged);
  }
  CHECK_THROWS_AS(SaAmg(SaAmg::Params{.split_bonded = 1.5}), ConfigError);
}

TEST_CASE("sa: sheet_strength aggregates the layers as sheets where stiff springs make their own couplings weak") {
  // Springs of 10^4 vertex masses outweigh the membrane: measured against them, every
  // coupling within a layer is weak, the aggregates follow the springs, and the split cuts
  // them into small pieces.
  const SpringStack st = spring_stack(31, 4, 1.0);
  SaAmg::Params prm = small_coarse(50);
  prm.split_sheets = true;
  SaAmg split(prm);
  prm.sheet_strength = true;
  SaAmg sheets(prm);
  const SolveContext ctx{&st.pins, &st.x};
  REQUIRE(split.setup(st.A, ctx) == Status::success);
  REQUIRE(sheets.setup(st.A, ctx) == Status::success);
  // The fine level's membrane still passes the threshold here; level 1, whose couplings
  // within a sheet are sums of membrane blocks and across sheets sums of springs, is where
  // the springs take over (406 -> 176 aggregates when written).
  REQUIRE(split.levels() >= 3);
  const int a = split.stats().levels[1].aggregates, b = sheets.stats().levels[1].aggregates;
  const PcgResult ra = pcg(st.A, st.b, split), rb = pcg(st.A, st.b, sheets);
  MESSAGE("4 layers of 31 x 31, stiff springs: " << a << " aggregates on level 1, " << ra.iterations << " iterations; with sheet_strength "
                                                 << b << ", " << rb.iterations << " iterations; memory "
                                                 << split.info().memory_bytes << " -> " << sheets.info().memory_bytes);
  CHECK(b <= 0.7 * a);
  CHECK(sheets.info().memory_bytes < split.info().memory_bytes);
  CHECK(ra.converged);
  CHECK(rb.converged);
  {
    const SpringStack small = spring_stack(9, 3, 1.0);
    SaAmg sa(prm);
    REQUIRE(sa.setup(small.A, SolveContext{&small.pins, &small.x}) == Status::success);
    checked_spd_map(sa, small.A.rows());
  }
  // On a single sheet the option changes nothing.
  const Prefiltered p = prefiltered_cloth(25, Tessellation::regular, Pins::two_sides);
  REQUIRE(split.setup(p.Ahat, SolveContext{&p.sys.pins, &p.sys.x}) == Status::success);
  REQUIRE(sheets.setup(p.Ahat, SolveContext{&p.sys.pins, &p.sys.x}) == Status::success);
  REQUIRE(sheets.levels() == split.levels());
  for (int l = 0; l < split.levels(); ++l) CHECK(sheets.stats().levels[l].aggregates == split.stats().levels[l].aggregates);
  CHECK_THROWS_AS(SaAmg(SaAmg::Params{.sheet_strength = true}), ConfigError);
}

TEST_CASE("sa: the tentative prolongator is orthonormal and interpolates the near null space") {
  Prefiltered p = prefiltered_cloth(17, Tessellation::irregular, Pins::boundary);
  const auto A = bsr_view(p.Ahat);
  std::vector<double> mu;
  std::vector<std::uint8_t> strong, special;
  sa::strength<3>(A, 0.48, SocMeasure::spectral, mu, strong);
  sa::special_nodes<3>(A, mu, 1e-2, strong, special);
  const sa::Aggregates ag = sa::aggregate<3>(A, strong, special);
  const NullSpace K = sa::rigid_body_modes(p.sys.x, &p.sys.pins);
  const sa::Tentative t = sa::tentative_prolongator<3>(ag, K, 1e-10);
  const int n = A.rows;
  Eigen::MatrixXd Phat = Eigen::MatrixXd::Zero(3 * n, 6 * ag.count);
  for (int i = 0; i < n; ++i) {
    const Eigen::Map<const BlockOf<3, 6>> Qi(t.Q.data() + 18 * i);
    if (ag.node_agg[i] < 0) {
      CHECK(Qi.norm() == 0.0);  // special rows: nothing
      continue;
    }
    Phat.block<3, 6>(3 * i, 6 * ag.node_agg[i]) = Qi;
  }
  Eigen::MatrixXd I = Eigen::MatrixXd::Identity(6 * ag.count, 6 * ag.count);
  for (int c = 0; c < 6 * ag.count; ++c)
    if (t.dummy[c]) I(c, c) = 0;
  CHECK((Phat.transpose() * Phat - I).norm() <= 1e-12 * std::sqrt(6.0 * ag.count));
  Eigen::MatrixXd Kspecial_free = K;
  for (int i = 0; i < n; ++i)
    if (ag.node_agg[i] < 0) Kspecial_free.middleRows<3>(3 * i).setZero();
  CHECK((Phat * t.Kc - Kspecial_free).norm() <= 1e-12 * K.norm());
  CHECK(K.norm() > 0);
}

TEST_CASE("sa: rank-deficient aggregates are detected and counted") {
  auto run = [](const Eigen::VectorXd& x, const ConstraintSet* c) {
    const int n = static_cast<int>(x.size() / 3);
    sa::Aggregates ag;
    ag.node_agg.assign(n, 0);
    ag.count = 1;
    const NullSpace K = sa::rigid_body_modes(x, c);
    sa::Tentative t = sa::tentative_prolongator<3>(ag, K, 1e-10);
    int dropped = 0;
    for (auto d : t.dummy) dropped += d;
    Eigen::MatrixXd Phat(3 * n, 6);
    for (int i = 0; i < n; ++i) Phat.middleRows<3>(3 * i) = Eigen::Map<const BlockOf<3, 6>>(t.Q.data() + 18 * i);
    CHECK((Phat * t.Kc - K).norm() <= 1e-12 * K.norm());  // dropped columns were in the span
    return std::pair<int, int>(dropped, t.deficient);
  };
  // Flat 2-node aggregate: the rotation about its axis vanishes (rank 5).
  Eigen::VectorXd two(6);
  two << 0.3, 0.1, 0.0, 0.5, 0.4, 0.0;
  CHECK(run(two, nullptr) == std::pair<int, int>(1, 1));
  // Three non-collinear nodes: full rank (control).
  Eigen::VectorXd three(9);
  three << 0, 0, 0, 1, 0, 0, 0, 1, 0;
  CHECK(run(three, nullptr) == std::pair<int, int>(0, 0));
  // Flat aggregate with every vertex constrained along z (lying on a box): t_z, r_x, r_y vanish.
  Eigen::VectorXd four(12);
  four << 0, 0, 0.2, 1, 0, 0.2, 0, 1, 0.2, 1, 1, 0.2;
  ConstraintSet c(4);
  for (int i = 0; i < 4; ++i) c.add_direction(i, Eigen::Vector3d::UnitZ(), 0.0);
  CHECK(run(four, &c) == std::pair<int, int>(3, 1));
  CHECK(run(four, nullptr) == std::pair<int, int>(0, 0));
}

/// The fine level's coarsening pieces of a small irregular cloth, and dense copies to check
/// the prolongator smoothing against: D^-1 and the filtered matrix A_f.
struct SmoothingCase {
  Prefiltered p = prefiltered_cloth(13, Tessellation::irregular, Pins::two_sides);
  BsrView<3, 3> A = bsr_view(p.Ahat);
  int n = A.rows;
  std::vector<double> mu, Dinv;
  std::vector<std::uint8_t> strong, special;
  sa::Aggregates ag;
  NullSpace K;
  sa::Tentative t;
  Eigen::MatrixXd Dinvd;
  SmoothingCase() {
    sa::strength<3>(A, 0.48, SocMeasure::spectral, mu, strong);
    sa::special_nodes<3>(A, mu, 1e-2, strong, special);
    ag = sa::aggregate<3>(A, strong, special);
    K = sa::rigid_body_modes(p.sys.x, &p.sys.pins);
    t = sa::tentative_prolongator<3>(ag, K, 1e-10);
    invert_block_diagonal<3>(A, Dinv);
    Dinvd = Eigen::MatrixXd::Zero(3 * n, 3 * n);
    for (int i = 0; i < n; ++i) Dinvd.block<3, 3>(3 * i, 3 * i) = Eigen::Map<const BlockOf<3, 3>>(Dinv.data() + 9 * i);
  }
  /// A with its weak blocks lumped into the diagonal (filtered) or A itself.
  Eigen::MatrixXd Af(bool filtered) const {
    const Eigen::MatrixXd Ad = p.Ahat.to_dense();
    Eigen::MatrixXd out = Ad;
    if (filtered)
      for (int i = 0; i < n; ++i)
        for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
          const int j = A.col[k];
          if (j == i || strong[k]) continue;
          out.block<3, 3>(3 * i, 3 * i) += Ad.block<3, 3>(3 * i, 3 * j);
          out.block<3, 3>(3 * i, 3 * j).setZero();
        }
    return out;
  }
  /// Z: special nodes get no interpolation.
  void zero_special_rows(Eigen::MatrixXd& M) const {
    for (int i = 0; i < n; ++i)
      if (special[i]) M.middleRows<3>(3 * i).setZero();
  }
  /// (Z (I - omega D^-1 A))^degree Z K: the near null space smoothed with the whole A.
  Eigen::MatrixXd smoothed_modes(double omega, int degree) const {
    const Eigen::MatrixXd S = Eigen::MatrixXd::Identity(3 * n, 3 * n) - omega * Dinvd * Af(false);
    Eigen::MatrixXd target = K;
    zero_special_rows(target);
    for (int d = 0; d < degree; ++d) {
      target = (S * target).eval();
      zero_special_rows(target);
    }
    return target;
  }
  /// The prolongator smoothed `degree` times, with the filter if `s` is given.
  BlockMatrix<3, 6> smoothed_prolongator(const std::vector<std::uint8_t>* s, double omega, int degree) const {
    BlockMatrix<3, 6> P = sa::prolongator_pattern<3>(A, s, ag);
    sa::prolongator_values<3>(A, Dinv, s, ag, t, omega, P);
    for (int d = 1; d < degree; ++d) P = sa::smooth_prolongator<3>(A, Dinv, s, ag, omega, P);
    return P;
  }
  template <int R>
  void check_special_rows_empty(const BlockMatrix<R, 6>& P) const {
    for (int i = 0; i < n; ++i)
      if (special[i]) CHECK(P.row_ptr()[i + 1] == P.row_ptr()[i]);  // no stored entries
  }
};

TEST_CASE("sa: the smoothed prolongator maps Kc to the smoothed near null space") {
  const SmoothingCase c;
  const double omega = 0.7;
  Eigen::MatrixXd Khat = c.K;  // = Phat Kc: special rows zero
  c.zero_special_rows(Khat);
  for (bool filtered : {false, true}) {
    CAPTURE(filtered);
    const std::vector<std::uint8_t>* s = filtered ? &c.strong : nullptr;
    BlockMatrix<3, 6> P = sa::prolongator_pattern<3>(c.A, s, c.ag);
    sa::prolongator_values<3>(c.A, c.Dinv, s, c.ag, c.t, omega, P);
    Eigen::MatrixXd expected = Khat - omega * c.Dinvd * c.Af(filtered) * Khat;
    c.zero_special_rows(expected);  // special rows hold nothing
    const Eigen::MatrixXd PK = P.to_dense() * c.t.Kc;
    CHECK((PK - expected).norm() <= 1e-12 * expected.norm());
    c.check_special_rows_empty(P);
    REQUIRE(P.nnz() > c.n / 2);
  }
}

TEST_CASE("sa: a second prolongator smoothing step is the one-step prolongator smoothed again") {
  const SmoothingCase c;
  REQUIRE(std::count(c.special.begin(), c.special.end(), 1) > 0);  // the Z rows are exercised
  const double omega = 0.7;
  for (bool filtered : {false, true}) {
    CAPTURE(filtered);
    const std::vector<std::uint8_t>* s = filtered ? &c.strong : nullptr;
    BlockMatrix<3, 6> P1 = sa::prolongator_pattern<3>(c.A, s, c.ag);
    sa::prolongator_values<3>(c.A, c.Dinv, s, c.ag, c.t, omega, P1);
    const BlockMatrix<3, 6> P2 = sa::smooth_prolongator<3>(c.A, c.Dinv, s, c.ag, omega, P1);
    const Eigen::MatrixXd P1d = P1.to_dense();
    Eigen::MatrixXd expected = P1d - omega * c.Dinvd * c.Af(filtered) * P1d;
    c.zero_special_rows(expected);
    CHECK((P2.to_dense() - expected).norm() <= 1e-12 * expected.norm());
    CHECK((expected - P1d).norm() > 1e-3 * P1d.norm());  // the step acts
    CHECK(P2.nnz() > P1.nnz());                          // on a wider pattern
    c.check_special_rows_empty(P2);
  }
}

TEST_CASE("sa: preserve_modes makes the filtered prolongator map Kc to the near null space smoothed with the whole A") {
  // The filter lumps weak blocks into the diagonal: translations survive it, rotations do
  // not, so the filtered P maps Kc elsewhere than unfiltered smoothing would. The correction
  // restores (Z (I - omega D^-1 A))^degree Z K within P's pattern, and changes nothing where
  // that holds already (unfiltered smoothing).
  const SmoothingCase c;
  REQUIRE(std::count(c.special.begin(), c.special.end(), 1) > 0);  // the Z rows are exercised
  const double omega = 0.7;
  for (int degree : {1, 2}) {
    CAPTURE(degree);
    const Eigen::MatrixXd target = c.smoothed_modes(omega, degree);
    for (bool filtered : {false, true}) {
      CAPTURE(filtered);
      BlockMatrix<3, 6> P = c.smoothed_prolongator(filtered ? &c.strong : nullptr, omega, degree);
      const Eigen::MatrixXd before = P.to_dense();
      const double miss = (before * c.t.Kc - target).norm() / target.norm();
      const long long nnz = P.nnz();
      const double worst = sa::preserve_modes<3>(c.A, c.Dinv, c.ag, omega, degree, c.K, c.t.Kc, P);
      const Eigen::MatrixXd after = P.to_dense();
      CHECK(P.nnz() == nnz);  // the pattern is kept
      CHECK((after * c.t.Kc - target).norm() <= 1e-12 * target.norm());
      c.check_special_rows_empty(P);
      if (filtered) {
        CHECK(miss > 1e-3);  // not vacuous: the filter lost the modes
        CHECK(worst > 1e-3);
        // The least change: each row's correction lies in the span of its columns' Kc rows.
        for (int i = 0; i < c.n; ++i) {
          const int b = P.row_ptr()[i], e = P.row_ptr()[i + 1];
          if (b == e) continue;
          Eigen::MatrixXd Kr(6 * (e - b), 6), dP(3, 6 * (e - b));
          for (int k = b; k < e; ++k) {
            const int J = P.col()[k];
            Kr.middleRows<6>(6 * (k - b)) = c.t.Kc.middleRows<6>(6 * J);
            dP.middleCols<6>(6 * (k - b)) = after.block<3, 6>(3 * i, 6 * J) - before.block<3, 6>(3 * i, 6 * J);
          }
          const Eigen::MatrixXd proj = Kr * (Kr.transpose() * Kr).completeOrthogonalDecomposition().pseudoInverse() * Kr.transpose();
          CHECK((dP - dP * proj).norm() <= 1e-10 * (dP.norm() + 1e-300));
        }
      } else {
        CHECK(miss <= 1e-12);
        CHECK(worst <= 1e-12);
        CHECK((after - before).norm() <= 1e-12 * before.norm());
      }
    }
  }
}

TEST_CASE("sa: preserve_modes keeps the V-cycle SPD and cuts the PCG iterations on an irregular sheet") {
  Prefiltered small = prefiltered_cloth(13, Tessellation::irregular, Pins::reentrant);
  SolveContext sctx{&small.sys.pins, &small.sys.x};
  for (int degree : {1, 2}) {
    CAPTURE(degree);
    SaAmg::Params prm = small_coarse(8);
    prm.prolongator_degree = degree;
    prm.preserve_modes = true;
    SaAmg sa(prm);
    REQUIRE(sa.setup(small.Ahat, sctx) == Status::success);
    REQUIRE(sa.levels() >= 3);
    checked_spd_map(sa, small.Ahat.rows());
  }
  Prefiltered p = prefiltered_cloth(161, Tessellation::irregular, Pins::boundary);
  SolveContext ctx{&p.sys.pins, &p.sys.x};
  SaAmg::Params prm;
  SaAmg plain(prm);
  prm.preserve_modes = true;
  SaAmg kept(prm);
  REQUIRE(plain.setup(p.Ahat, ctx) == Status::success);
  REQUIRE(kept.setup(p.Ahat, ctx) == Status::success);
  // The fine P keeps its pattern; the levels below may aggregate their (different) Galerkin
  // operators differently.
  CHECK(kept.stats().levels[0].nnz_p == plain.stats().levels[0].nnz_p);
  CHECK(kept.stats().levels[0].aggregates == plain.stats().levels[0].aggregates);
  CHECK(std::abs(double(kept.info().memory_bytes) / double(plain.info().memory_bytes) - 1) < 0.02);
  // The statistics report how far the correction moved P's rows: nothing without it, a
  // visible but bounded change on every level that was filtered with it.
  for (int l = 0; l + 1 < kept.levels(); ++l) {
    CAPTURE(l);
    CHECK(plain.stats().levels[l].mode_correction == 0);
    MESSAGE("largest relative row correction: " << kept.stats().levels[l].mode_correction);
    CHECK(kept.stats().levels[l].mode_correction > 1e-5);
    CHECK(kept.stats().levels[l].mode_correction < 10);
  }
  const PcgResult rp = pcg(p.Ahat, p.chat, plain), rk = pcg(p.Ahat, p.chat, kept);
  MESSAGE("irregular 161 x 161 sheet: " << rp.iterations << " iterations, with preserve_modes " << rk.iterations);
  CHECK(rp.converged);
  CHECK(rk.converged);
  CHECK(rk.iterations < rp.iterations);
}

TEST_CASE("sa: truncation drops the small blocks of each prolongator row and preserve_modes repairs the rigid modes") {
  const SmoothingCase c;
  const double omega = 0.7;
  const Eigen::MatrixXd target = c.smoothed_modes(omega, 2);
  for (bool filtered : {false, true}) {
    CAPTURE(filtered);
    BlockMatrix<3, 6> P = c.smoothed_prolongator(filtered ? &c.strong : nullptr, omega, 2);
    const BlockMatrix<3, 6> full = P;
    const double fraction = 0.2;
    const long long dropped = sa::truncate_prolongator<3>(P, fraction);
    CHECK(dropped == full.nnz() - P.nnz());
    REQUIRE(dropped > full.nnz() / 10);  // not vacuous: a degree-2 P has many small blocks
    // Row by row: the kept blocks are those of the full row at or above the cut, unchanged.
    for (int i = 0; i < c.n; ++i) {
      double top = 0;
      for (int k = full.row_ptr()[i]; k < full.row_ptr()[i + 1]; ++k) top = std::max(top, full.block(k).norm());
      int kept = 0;
      for (int k = full.row_ptr()[i]; k < full.row_ptr()[i + 1]; ++k) {
        if (full.block(k).norm() < fraction * top * (1 - 1e-12)) continue;
        const int q = P.row_ptr()[i] + kept++;
        REQUIRE(q < P.row_ptr()[i + 1]);
        CHECK(P.col()[q] == full.col()[k]);
        CHECK((P.block(q) - full.block(k)).norm() == 0);
      }
      CHECK(P.row_ptr()[i + 1] - P.row_ptr()[i] == kept);
      CHECK((kept > 0) == (full.row_ptr()[i + 1] > full.row_ptr()[i]));  // a row keeps its largest block
    }
    // The dropped blocks lose the modes; the repair restores them within the kept pattern.
    const double miss = (P.to_dense() * c.t.Kc - target).norm() / target.norm();
    CHECK(miss > 1e-3);
    const long long nnz = P.nnz();
    sa::preserve_modes<3>(c.A, c.Dinv, c.ag, omega, 2, c.K, c.t.Kc, P);
    CHECK(P.nnz() == nnz);
    CHECK((P.to_dense() * c.t.Kc - target).norm() <= 1e-12 * target.norm());
    c.check_special_rows_empty(P);
  }
}

TEST_CASE("sa: prolongator truncation keeps the V-cycle SPD and shrinks P and the coarse operators at bounded iterations") {
  Prefiltered small = prefiltered_cloth(13, Tessellation::irregular, Pins::reentrant);
  SolveContext sctx{&small.sys.pins, &small.sys.x};
  SaAmg::Params prm = small_coarse(8);
  prm.prolongator_degree = 2;
  prm.preserve_modes = true;
  prm.prolongator_truncation = 0.1;
  SaAmg cut(prm);
  REQUIRE(cut.setup(small.Ahat, sctx) == Status::success);
  REQUIRE(cut.levels() >= 3);
  CHECK(cut.stats().levels[0].truncated > 0);
  checked_spd_map(cut, small.Ahat.rows());

  Prefiltered p = prefiltered_cloth(121, Tessellation::irregular, Pins::boundary);
  SolveContext ctx{&p.sys.pins, &p.sys.x};
  SaAmg::Params base;
  base.prolongator_degree = 2;
  base.prolongator_degree_levels = 1;
  base.preserve_modes = true;
  SaAmg whole(base);
  base.prolongator_truncation = 0.1;
  SaAmg trunc(base);
  REQUIRE(whole.setup(p.Ahat, ctx) == Status::success);
  REQUIRE(trunc.setup(p.Ahat, ctx) == Status::success);
  const SaLevelStats &w0 = whole.stats().levels[0], &t0 = trunc.stats().levels[0];
  CHECK(w0.truncated == 0);
  CHECK(t0.truncated == w0.nnz_p - t0.nnz_p);  // the same aggregates, fewer blocks
  CHECK(t0.aggregates == w0.aggregates);
  CHECK(t0.nnz_p < 0.9 * w0.nnz_p);
  CHECK(trunc.stats().levels[1].nnz_blocks < whole.stats().levels[1].nnz_blocks);
  CHECK(trunc.info().memory_bytes < whole.info().memory_bytes);
  const PcgResult rw = pcg(p.Ahat, p.chat, whole), rt = pcg(p.Ahat, p.chat, trunc);
  MESSAGE("irregular 121 x 121 sheet, degree 2 on level 0: P " << w0.nnz_p << " -> " << t0.nnz_p << " blocks, level 1 "
          << whole.stats().levels[1].nnz_blocks << " -> " << trunc.stats().levels[1].nnz_blocks << " blocks, memory "
          << whole.info().memory_bytes << " -> " << trunc.info().memory_bytes << " bytes, " << rw.iterations << " -> "
          << rt.iterations << " iterations");
  CHECK(rw.converged);
  CHECK(rt.converged);
  CHECK(rt.iterations <= rw.iterations + 2);
  // Without the repair the dropped blocks lose the modes.
  CHECK_THROWS_AS(SaAmg(SaAmg::Params{.prolongator_truncation = 0.1}), ConfigError);
  CHECK_THROWS_AS(SaAmg(SaAmg::Params{.prolongator_truncation = 1, .preserve_modes = true}), ConfigError);
}

TEST_CASE("sa: a truncated prolongator under reuse keeps its first pattern and the V-cycle SPD") {
  // reuse = aggregates keeps the coarse operators' patterns, so the values of a later setup
  // are restricted to the blocks the first truncation kept (and the modes repaired there).
  Prefiltered small = prefiltered_cloth(13, Tessellation::irregular, Pins::reentrant);
  SolveContext ctx{&small.sys.pins, &small.sys.x};
  const int N = small.Ahat.rows();
  SaAmg::Params prm = small_coarse(8);
  prm.prolongator_degree = 2;
  prm.preserve_modes = true;
  prm.prolongator_truncation = 0.1;
  prm.prolongator_storage = ValueStorage::double_precision;
  prm.reuse = SaReuse::aggregates;
  SaAmg sa(prm);
  REQUIRE(sa.setup(small.Ahat, ctx) == Status::success);
  REQUIRE(sa.levels() >= 3);
  const SaLevelStats first = sa.stats().levels[0];
  const long long first_coarse = sa.stats().levels[1].nnz_blocks;
  REQUIRE(first.truncated > 0);
  const Eigen::MatrixXd B = checked_spd_map(sa, N);
  // New values on the same pattern: a heavier, uneven diagonal (a smaller step's masses).
  BlockCsr A2 = small.Ahat;
  Eigen::VectorXd d(N);
  for (int k = 0; k < N; ++k) d[k] = 0.5 * (1.5 + std::sin(0.7 * k)) * std::abs(A2.block(A2.diagonal(k / 3))(k % 3, k % 3));
  A2.add_diagonal(d);
  REQUIRE(sa.setup(A2, ctx) == Status::success);
  REQUIRE(sa.stats().reused);
  CHECK(sa.stats().levels[0].nnz_p == first.nnz_p);
  CHECK(sa.stats().levels[1].nnz_blocks == first_coarse);
  CHECK(sa.stats().levels[0].truncated > 0);
  const Eigen::MatrixXd B2 = checked_spd_map(sa, N);
  CHECK((B2 - B).norm() > 1e-3 * B.norm());  // not vacuous: the values were refreshed
  SaAmg::Params fresh_prm = prm;
  fresh_prm.reuse = SaReuse::none;
  SaAmg fresh(fresh_prm);
  REQUIRE(fresh.setup(A2, ctx) == Status::success);
  const PcgResult kept = pcg(A2, small.chat, sa), rebuilt = pcg(A2, small.chat, fresh);
  CHECK(kept.converged);
  CHECK(kept.iterations <= rebuilt.iterations + 2);
}

TEST_CASE("sa: the degree-2 prolongator keeps the V-cycle symmetric positive definite and reuse exact") {
  Prefiltered p = prefiltered_cloth(13, Tessellation::irregular, Pins::reentrant);
  SolveContext ctx{&p.sys.pins, &p.sys.x};
  const int N = p.Ahat.rows();
  SaAmg one(small_coarse(8));
  REQUIRE(one.setup(p.Ahat, ctx) == Status::success);
  for (int levels : {1, 2}) {
    CAPTURE(levels);
    SaAmg::Params prm = small_coarse(8);
    prm.prolongator_degree = 2;
    prm.prolongator_degree_levels = levels;
    SaAmg two(prm);
    REQUIRE(two.setup(p.Ahat, ctx) == Status::success);
    REQUIRE(two.levels() >= 3);
    for (int l = 0; l + 1 < two.levels(); ++l) {
      CAPTURE(l);
      const long long wider = two.stats().levels[l].nnz_p, narrow = one.stats().levels[l].nnz_p;
      if (l < levels) CHECK(wider > narrow);
    }
    const Eigen::MatrixXd B = checked_spd_map(two, N);
    // Reuse of the aggregates rebuilds the wider P on the kept structure: the same map.
    prm.reuse = SaReuse::aggregates;
    SaAmg re(prm);
    REQUIRE(re.setup(p.Ahat, ctx) == Status::success);
    const long long first_nnz_p = re.stats().levels[0].nnz_p;
    BlockCsr A2 = p.Ahat;
    A2.scale(2.0);
    REQUIRE(re.setup(A2, ctx) == Status::success);
    REQUIRE(re.stats().reused);
    CHECK(re.stats().levels[0].nnz_p == first_nnz_p);  // formed from the one-step pattern, not from the last P
    const Eigen::MatrixXd B2 = assemble_preconditioner(re, N);
    CHECK((2 * B2 - B).norm() <= 1e-10 * B.norm());  // B(2A) = B(A) / 2
  }
  CHECK_THROWS_AS(SaAmg(SaAmg::Params{.prolongator_degree = 4}), ConfigError);
}

TEST_CASE("sa: theta moves the smoothing filter between few couplings and all of them with aggregates fixed by aggregation_theta and keeps the V-cycle SPD") {
  // theta only sets the smoothing filter's threshold: the aggregates stay those of
  // aggregation_theta, P widens as theta falls, and with every coupling kept (no special node
  // on the unpinned sheet) P is the unfiltered smoother's, built from the stages with no
  // strong flags. theta = aggregation_theta is the thesis' filter (aggregation_theta = 0, the
  // default, means theta).
  Prefiltered p = prefiltered_cloth(13, Tessellation::irregular, Pins::reentrant);
  SolveContext ctx{&p.sys.pins, &p.sys.x};
  const int N = p.Ahat.rows();
  SaAmg::Params base = small_coarse(8);
  base.prolongator_storage = ValueStorage::double_precision;
  base.aggregation_theta = 0.48;
  long long previous = 0, thesis_nnz = 0, strict_nnz = 0;
  int aggregates = -1;
  for (const double theta : {0.9, 0.7, 0.48, 0.24, 0.12, 0.048}) {
    CAPTURE(theta);
    SaAmg::Params prm = base;
    prm.theta = theta;
    SaAmg sa(prm);
    REQUIRE(sa.setup(p.Ahat, ctx) == Status::success);
    REQUIRE(sa.levels() >= 3);
    const SaLevelStats& fine = sa.stats().levels[0];
    if (aggregates < 0) aggregates = fine.aggregates;
    CHECK(fine.aggregates == aggregates);
    CHECK(fine.nnz_p >= previous);
    if (theta == 0.9) strict_nnz = fine.nnz_p;
    if (theta == 0.48) {
      thesis_nnz = fine.nnz_p;
      CHECK(strict_nnz < thesis_nnz);  // not vacuous: a higher threshold dropped couplings
    }
    if (theta == 0.048) CHECK(fine.nnz_p > thesis_nnz);  // and a lower one kept more
    previous = fine.nnz_p;
    checked_spd_map(sa, N);
  }

  Prefiltered free = prefiltered_cloth(13, Tessellation::irregular, Pins::none);
  SolveContext fctx{&free.sys.pins, &free.sys.x};
  SaAmg::Params all = base, thesis = base;
  all.theta = 1e-12;
  all.aggregate_order = AggregateOrder::natural;  // P's columns in the order of the stages below
  SaAmg a(all), t(thesis);
  REQUIRE(a.setup(free.Ahat, fctx) == Status::success);
  REQUIRE(t.setup(free.Ahat, fctx) == Status::success);
  REQUIRE(a.stats().levels[0].special == 0);
  const Eigen::MatrixXd Pa = a.prolongator(0), Pt = t.prolongator(0);
  // The unfiltered P from the stages: the aggregates of the thesis' threshold, no flags.
  const BsrView<3, 3> V = bsr_view(free.Ahat);
  std::vector<double> mu, Dinv;
  std::vector<std::uint8_t> strong, special;
  sa::strength<3>(V, 0.48, SocMeasure::spectral, mu, strong);
  sa::special_nodes<3>(V, mu, base.diagonal_dominance, strong, special);
  const sa::Aggregates aggs = sa::aggregate<3>(V, strong, special);
  REQUIRE(aggs.count == a.stats().levels[0].aggregates);
  REQUIRE(invert_block_diagonal<3>(V, Dinv) == 0);
  const sa::Tentative tent = sa::tentative_prolongator<3>(aggs, sa::rigid_body_modes(free.sys.x, nullptr), base.qr_tolerance);
  BlockMatrix<3, 6> Pun = sa::prolongator_pattern<3>(V, nullptr, aggs);
  sa::prolongator_values<3>(V, Dinv, nullptr, aggs, tent, 4.0 / (3.0 * a.stats().levels[0].lambda), Pun);
  const Eigen::MatrixXd Pu = Pun.to_dense();
  CHECK((Pa - Pu).norm() <= 1e-12 * Pu.norm());
  CHECK((Pt - Pu).norm() > 1e-3 * Pu.norm());  // the thesis' filter differs from no filter here
  for (const double bad : {0.0, 1.0, -1.0}) {
    CAPTURE(bad);
    if (bad != 0.0) CHECK_THROWS_AS(SaAmg(SaAmg::Params{.aggregation_theta = bad}), ConfigError);
    CHECK_THROWS_AS(SaAmg(SaAmg::Params{.theta = bad}), ConfigError);
  }
  // aggregation_theta = 0 is theta itself: the same hierarchy as naming it.
  SaAmg::Params named = base;
  named.aggregation_theta = 0.0;
  named.theta = 0.48;
  SaAmg z(named), b(base);
  REQUIRE(z.setup(p.Ahat, ctx) == Status::success);
  REQUIRE(b.setup(p.Ahat, ctx) == Status::success);
  CHECK(z.prolongator(0) == b.prolongator(0));
}

TEST_CASE("sa: coarse operators are symmetric and positive definite with block size 6") {
  Prefiltered p = prefiltered_cloth(25, Tessellation::irregular, Pins::two_sides);
  // Both storages of A_c: double, and the default single precision (formed in double, rounded once).
  for (const bool single : {false, true}) {
    CAPTURE(single);
    SaAmg::Params prm = small_coarse(10);
    prm.single_coarse_operators = single;
    SaAmg sa(prm);
    SolveContext ctx{&p.sys.pins, &p.sys.x};
    REQUIRE(sa.setup(p.Ahat, ctx) == Status::success);
    REQUIRE(sa.levels() >= 3);
    CHECK(sa.stats().coarse_direct);
    for (int l = 1; l < sa.levels(); ++l) {
      CAPTURE(l);
      const auto& st = sa.stats().levels[l];
      CHECK(st.block_size == 6);
      const Eigen::MatrixXd Ac = sa.level_matrix(l);
      CHECK((Ac - Ac.transpose()).norm() == 0.0);  // one triangle stored, the diagonal blocks symmetrised
      Eigen::LLT<Eigen::MatrixXd> llt(Ac);
      CHECK(llt.info() == Eigen::Success);
      // Galerkin: A_c = P^T A P (up to the dummy-dof diagonal), to round-off or to float rounding.
      const Eigen::MatrixXd P = sa.prolongator(l - 1), Af = sa.level_matrix(l - 1);
      Eigen::MatrixXd G = P.transpose() * Af * P;
      for (int c = 0; c < G.rows(); ++c)
        if (P.col(c).norm() == 0) G(c, c) = Ac(c, c);
      CHECK((G - Ac).norm() <= (single ? 1e-7 : 1e-12) * Ac.norm());
      if (single) {
        CHECK(Ac == Ac.cast<float>().cast<double>());
        CHECK((G - Ac).norm() > 1e-12 * Ac.norm());  // the rounding did happen
      }
    }
    if (!single) continue;
    const PreconditionerInfo info = sa.info();
    MESSAGE("levels " << info.levels << " operator complexity " << info.operator_complexity << " grid complexity "
                      << info.grid_complexity << " memory " << info.memory_bytes);
    CHECK(info.levels == sa.levels());
    CHECK(info.operator_complexity > 1.0);
    CHECK(info.operator_complexity < 3.0);
    CHECK(info.memory_bytes > 0);
  }
}

TEST_CASE("sa: Lanczos underestimates lambda_max and the inflated bound covers it") {
  for (int m : {9, 15}) {
    for (bool cloth : {false, true}) {
      CAPTURE(m);
      CAPTURE(cloth);
      Prefiltered p = prefiltered_cloth(m, Tessellation::irregular, Pins::two_sides);
      const BlockCsr A = cloth ? p.Ahat : support::block_laplacian(m, 0.05);
      std::vector<double> Dinv;
      invert_block_diagonal<3>(bsr_view(A), Dinv);
      const sa::LanczosResult r = sa::lanczos<3>(bsr_view(A), Dinv, 10);
      const double lmax = jacobi_spectrum(A.to_dense(), 3).maxCoeff();
      MESSAGE("m " << m << " cloth " << cloth << ": ritz/lmax " << r.ritz / lmax << " (ritz+res)/lmax "
                   << (r.ritz + r.residual) / lmax);
      CHECK(r.ritz <= lmax * (1 + 1e-12));
      CHECK(r.ritz >= 0.5 * lmax);
      CHECK(r.ritz + r.residual >= lmax);
      CHECK(1.2 * (r.ritz + r.residual) > lmax);  // (lower + upper) * lambda covers the spectrum
    }
  }
}

TEST_CASE("sa: the Chebyshev smoother is energy convergent and fails with an underestimated interval") {
  Prefiltered p = prefiltered_cloth(11, Tessellation::irregular, Pins::two_sides);
  SolveContext ctx{&p.sys.pins, &p.sys.x};
  const Eigen::MatrixXd A = p.Ahat.to_dense();
  const int N = static_cast<int>(A.rows());
  const Eigen::LLT<Eigen::MatrixXd> llt(A);
  REQUIRE(llt.info() == Eigen::Success);
  auto max_p = [&](const SaAmg::Params& prm) {
    SaAmg sa(prm);
    REQUIRE(sa.setup(p.Ahat, ctx) == Status::success);
    // G = I - S A: column j is the error left from x* = e_j, f = A e_j, x0 = 0.
    Eigen::MatrixXd G(N, N);
    Eigen::VectorXd x(N), f(N);
    for (int j = 0; j < N; ++j) {
      x.setZero();
      f = A.col(j);
      sa.smooth(0, f, x);
      G.col(j) = Eigen::VectorXd::Unit(N, j) - x;
    }
    // G = p(D^-1 A) is self-adjoint in the energy product: L^T G L^-T is symmetric (A = L L^T).
    const Eigen::MatrixXd Lm = llt.matrixL();
    const Eigen::MatrixXd H = Lm.transpose() * G * Lm.transpose().inverse();
    CHECK((H - H.transpose()).norm() <= 1e-8 * H.norm());
    return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(0.5 * (H + H.transpose())).eigenvalues().cwiseAbs().maxCoeff();
  };
  SaAmg::Params good;
  const double rho_good = max_p(good);
  CHECK(rho_good < 1.0);
  CHECK(rho_good > 0.5);  // low frequencies are barely damped: the check is not vacuous
  SaAmg::Params bad;
  bad.lambda_bound = LambdaBound::ritz;
  bad.chebyshev_lower = 0.05;
  bad.chebyshev_upper = 0.45;  // a + b = 0.5 lambda < lambda_max: the top of the spectrum grows
  CHECK(max_p(bad) > 1.0);
}

TEST_CASE("sa: the V-cycle preconditioner is a symmetric positive definite map and widen_smoothers makes an indefinite one SPD") {
  for (Pins pins : {Pins::two_sides, Pins::reentrant}) {
    CAPTURE(static_cast<int>(pins));
    Prefiltered p = prefiltered_cloth(13, Tessellation::irregular, pins);
    SolveContext ctx{&p.sys.pins, &p.sys.x};
    const int N = p.Ahat.rows();
    SaAmg sa(small_coarse(8));
    REQUIRE(sa.setup(p.Ahat, ctx) == Status::success);
    REQUIRE(sa.levels() >= 3);
    const Eigen::MatrixXd B = checked_spd_map(sa, N);
    // Negative control: an interval with a + b < lambda_max makes B indefinite.
    SaAmg::Params prm = small_coarse(8);
    prm.lambda_bound = LambdaBound::ritz;
    prm.chebyshev_lower = 0.03;
    prm.chebyshev_upper = 0.3;
    SaAmg bad(prm);
    REQUIRE(bad.setup(p.Ahat, ctx) == Status::success);
    const Eigen::MatrixXd Bb = assemble_preconditioner(bad, N);
    CHECK(min_symmetric_eigenvalue(Bb) < 0);
    // widen_smoothers raises every interval to the guaranteed bound: SPD again, once.
    std::vector<double> before;
    for (const auto& l : bad.stats().levels) before.push_back(l.lambda);
    REQUIRE(bad.widen_smoothers());
    CHECK(bad.widened_levels() >= 1);
    for (std::size_t l = 0; l < before.size(); ++l) CHECK(bad.stats().levels[l].lambda >= before[l]);
    checked_spd_map(bad, N);
    CHECK_FALSE(bad.widen_smoothers());  // already covered: nothing to widen, no endless repeats
  }
}

TEST_CASE("sa: SA+PPCG recovers from the breakdown of a cycle with an underestimated interval") {
  Prefiltered p = prefiltered_cloth(13, Tessellation::irregular, Pins::two_sides);
  SolveContext ctx{&p.sys.pins, &p.sys.x};
  // The indefinite cycle of the negative control above (checked there).
  SaPpcg::Params sp;
  sp.preconditioner = small_coarse(8);
  sp.preconditioner.lambda_bound = LambdaBound::ritz;
  sp.preconditioner.chebyshev_lower = 0.03;
  sp.preconditioner.chebyshev_upper = 0.3;
  sp.tolerance = 1e-8;
  SaPpcg solver(sp);
  solver.set_context(ctx);
  REQUIRE(solver.analyze_pattern(p.sys.A) == Status::success);
  REQUIRE(solver.factorize(p.sys.A) == Status::success);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(p.sys.A.rows());
  const LinearReport rep = solver.solve(p.sys.b, x);
  CAPTURE(rep.message);
  CHECK(rep.status == Status::success);
  CHECK(solver.preconditioner().widened_levels() >= 1);  // the first solve broke down and widened
  CHECK(rep.relative_residual <= 1e-6);
}

TEST_CASE("sa: the W-cycle on the first coarse levels is a symmetric positive definite map") {
  Prefiltered p = prefiltered_cloth(13, Tessellation::irregular, Pins::two_sides);
  SolveContext ctx{&p.sys.pins, &p.sys.x};
  const int N = p.Ahat.rows();
  SaAmg v(small_coarse(8));
  REQUIRE(v.setup(p.Ahat, ctx) == Status::success);
  REQUIRE(v.levels() >= 3);
  const Eigen::MatrixXd Bv = assemble_preconditioner(v, N);
  for (int depth : {1, 2}) {
    CAPTURE(depth);
    SaAmg::Params prm = small_coarse(8);
    prm.cycle_gamma = 2;
    prm.cycle_gamma_levels = depth;
    SaAmg w(prm);
    REQUIRE(w.setup(p.Ahat, ctx) == Status::success);
    const Eigen::MatrixXd B = checked_spd_map(w, N);
    CHECK((B - Bv).norm() > 1e-6 * Bv.norm());  // the extra coarse cycle acts
    // A better coarse solve: the preconditioned spectrum is tighter than the V-cycle's.
    auto condition = [&](const Eigen::MatrixXd& M) {
      Eigen::LLT<Eigen::MatrixXd> llt(0.5 * (M + M.transpose()));
      REQUIRE(llt.info() == Eigen::Success);
      const Eigen::MatrixXd L = llt.matrixL();
      const Eigen::MatrixXd A = p.Ahat.to_dense();
      const Eigen::VectorXd e = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(L.transpose() * A * L).eigenvalues();
      return e.maxCoeff() / e.minCoeff();
    };
    CHECK(condition(B) <= condition(Bv));
  }
  CHECK_THROWS_AS(SaAmg(SaAmg::Params{.cycle_gamma = 0}), ConfigError);
  CHECK_THROWS_AS(SaAmg(SaAmg::Params{.cycle_gamma_levels = 0}), ConfigError);
}

TEST_CASE("sa: the W-cycle option needs no more PCG iterations than the V-cycle on cloth") {
  for (int m : {41, 81}) {
    CAPTURE(m);
    Prefiltered p = prefiltered_cloth(m, Tessellation::regular, Pins::boundary);
    SolveContext ctx{&p.sys.pins, &p.sys.x};
    SaAmg v(small_coarse(50));
    SaAmg::Params prm = small_coarse(50);
    prm.cycle_gamma = 2;
    SaAmg w(prm);
    REQUIRE(v.setup(p.Ahat, ctx) == Status::success);
    REQUIRE(w.setup(p.Ahat, ctx) == Status::success);
    const PcgResult rv = pcg(p.Ahat, p.chat, v), rw = pcg(p.Ahat, p.chat, w);
    MESSAGE("cloth m " << m << ": V-cycle " << rv.iterations << " iterations, W on level 1 " << rw.iterations);
    CHECK(rv.converged);
    CHECK(rw.converged);
    CHECK(rw.iterations <= rv.iterations);
    CHECK(w.info().memory_bytes == v.info().memory_bytes);  // the extra cycles run in place, with no vectors of their own
  }
}

TEST_CASE("sa: fixed16 prolongators and single-precision coarse operators and block inverses keep the PCG iterations and take less memory") {
  // The defaults store P in fixed16 (its own test below), the coarse operators and the
  // smoother's block inverses in float; the all-double hierarchy is the reference.
  // Irregular cloth pinned at two sides and the re-entrant L.
  for (Pins pins : {Pins::two_sides, Pins::reentrant}) {
    CAPTURE(static_cast<int>(pins));
    Prefiltered p = prefiltered_cloth(61, Tessellation::irregular, pins);
    SolveContext ctx{&p.sys.pins, &p.sys.x};
    SaAmg::Params dp = small_coarse(50), sp = small_coarse(50);
    dp.prolongator_storage = ValueStorage::double_precision;
    dp.single_coarse_operators = dp.single_block_inverses = false;
    REQUIRE(sp.prolongator_storage == ValueStorage::fixed16);
    REQUIRE(sp.single_coarse_operators);
    REQUIRE(sp.single_block_inverses);
    SaAmg d(dp), f(sp);
    REQUIRE(d.setup(p.Ahat, ctx) == Status::success);
    REQUIRE(f.setup(p.Ahat, ctx) == Status::success);
    REQUIRE(f.levels() >= 3);
    const PcgResult rd = pcg(p.Ahat, p.chat, d), rf = pcg(p.Ahat, p.chat, f);
    MESSAGE("double: " << rd.iterations << " iterations, " << d.info().memory_bytes << " bytes; compact: " << rf.iterations
                       << " iterations, " << f.info().memory_bytes << " bytes");
    CHECK(rd.converged);
    CHECK(rf.converged);
    CHECK(std::abs(rf.iterations - rd.iterations) <= 1);
    CHECK(f.info().memory_bytes < 0.75 * d.info().memory_bytes);
    // Each of the three storages saves memory on its own.
    for (int which = 0; which < 3; ++which) {
      CAPTURE(which);
      SaAmg::Params q = small_coarse(50);
      if (which == 0)
        q.prolongator_storage = ValueStorage::double_precision;
      else
        (which == 1 ? q.single_coarse_operators : q.single_block_inverses) = false;
      SaAmg o(q);
      REQUIRE(o.setup(p.Ahat, ctx) == Status::success);
      const PcgResult ro = pcg(p.Ahat, p.chat, o);
      CHECK(ro.converged);
      CHECK(std::abs(ro.iterations - rf.iterations) <= 1);
      CHECK(f.info().memory_bytes < o.info().memory_bytes);
    }
  }
}

TEST_CASE("sa: fixed16 prolongators are int16 multiples of one scale per coarse dof and keep the V-cycle SPD") {
  // P = Q diag(s): each column of the stored P is an integer multiple (|q| <= 32767) of its
  // scale s_c = max_i |P_ic| / 32767, within s_c / 2 of the double P; the V-cycle built on it
  // stays symmetric positive definite and needs the iterations of the double hierarchy.
  for (const int m : {13, 61}) {
    CAPTURE(m);
    Prefiltered p = prefiltered_cloth(m, Tessellation::irregular, m == 13 ? Pins::reentrant : Pins::two_sides);
    SolveContext ctx{&p.sys.pins, &p.sys.x};
    SaAmg::Params dp = small_coarse(m == 13 ? 8 : 50), qp = dp;
    dp.prolongator_storage = ValueStorage::double_precision;
    qp.prolongator_storage = ValueStorage::fixed16;
    SaAmg d(dp), q(qp);
    REQUIRE(d.setup(p.Ahat, ctx) == Status::success);
    REQUIRE(q.setup(p.Ahat, ctx) == Status::success);
    REQUIRE(q.levels() >= 3);
    REQUIRE(q.levels() == d.levels());
    // Every level's P lies on its columns' grids; level 0 (the same fine matrix for both) is
    // the double P rounded to the nearest grid point. The coarser P differ beyond rounding:
    // they smooth with coarse operators formed from different P.
    for (int l = 0; l + 1 < q.levels(); ++l) {
      CAPTURE(l);
      const Eigen::MatrixXd Pd = d.prolongator(l), Pq = q.prolongator(l);
      REQUIRE(Pq.rows() == Pd.rows());
      double worst_grid = 0, worst_error = 0;
      int columns = 0;
      for (Eigen::Index c = 0; c < Pq.cols(); ++c) {
        const double top = Pq.col(c).cwiseAbs().maxCoeff(), scale = top / 32767.0;
        if (top == 0) continue;
        ++columns;
        for (Eigen::Index i = 0; i < Pq.rows(); ++i) {
          const double k = Pq(i, c) / scale;
          worst_grid = std::max(worst_grid, std::abs(k - std::round(k)));
          if (l == 0) worst_error = std::max(worst_error, std::abs(Pq(i, c) - Pd(i, c)) / scale);
        }
      }
      CHECK(columns > 0);
      CHECK(worst_grid <= 1e-6);  // on the column's int16 grid
      if (l == 0) {
        REQUIRE(Pq.cols() == Pd.cols());
        CHECK(worst_error <= 0.5 + 1e-6);  // rounded to the nearest point of it
        CHECK(worst_error > 1e-3);         // and the rounding happened
      }
    }
    if (m == 13) {
      const Eigen::MatrixXd Bq = assemble_preconditioner(q, p.Ahat.rows()), Bd = assemble_preconditioner(d, p.Ahat.rows());
      CHECK((Bq - Bq.transpose()).norm() <= 1e-12 * Bq.norm());
      CHECK(min_symmetric_eigenvalue(Bq) > 0);
      CHECK((Bq - Bd).norm() <= 1e-3 * Bd.norm());
      CHECK((Bq - Bd).norm() > 1e-7 * Bd.norm());
    } else {
      const PcgResult rd = pcg(p.Ahat, p.chat, d), rq = pcg(p.Ahat, p.chat, q);
      MESSAGE("double P: " << rd.iterations << " iterations, " << d.info().memory_bytes << " bytes; fixed16: "
                           << rq.iterations << " iterations, " << q.info().memory_bytes << " bytes");
      CHECK(rd.converged);
      CHECK(rq.converged);
      CHECK(std::abs(rq.iterations - rd.iterations) <= 1);
      CHECK(q.info().memory_bytes < d.info().memory_bytes);
    }
  }
}

TEST_CASE("sa: a lent work vector gives the same cycle and the hierarchy owns no fine-size vector") {
  // PCG lends its idle A p vector to the fine level (apply(r, z, work)); without it the first
  // apply allocates one. Both give the same z bit for bit.
  {
    Prefiltered p = prefiltered_cloth(31, Tessellation::irregular, Pins::two_sides);
    SolveContext ctx{&p.sys.pins, &p.sys.x};
    SaAmg sa(small_coarse(20));
    REQUIRE(sa.setup(p.Ahat, ctx) == Status::success);
    REQUIRE(sa.levels() >= 3);
    const std::size_t owned = sa.info().memory_bytes;
    const Eigen::VectorXd r = Eigen::VectorXd::Random(p.Ahat.rows());
    Eigen::VectorXd z_lent, z_own, work = Eigen::VectorXd::Constant(5, std::nan(""));
    sa.apply(r, z_lent, work);
    CHECK(work.size() == r.size());
    CHECK(sa.info().memory_bytes == owned);
    work.setConstant(std::nan(""));  // whatever the lent vector holds is overwritten
    Eigen::VectorXd z_again;
    sa.apply(r, z_again, work);
    CHECK(z_again == z_lent);
    sa.apply(r, z_own);
    CHECK(z_own == z_lent);
    CHECK(z_own.norm() > 0);
    CHECK(sa.info().memory_bytes == owned + sizeof(double) * static_cast<std::size_t>(r.size()));
  }
}

TEST_CASE("sa: the fine smoother solving with A's diagonal blocks is the stored-inverse cycle without their memory") {
  // fine_inverses_on_the_fly (the default) solves with each diagonal block of A, read through
  // the vertex filters when PPCG prefilters on the fly, instead of storing D^-1. Against the
  // same hierarchy with stored double inverses: the same cycle to round-off, the same PCG
  // iterations, 72 bytes per vertex less.
  for (const bool on_the_fly_filters : {false, true}) {
    CAPTURE(on_the_fly_filters);
    Prefiltered p = prefiltered_cloth(31, Tessellation::irregular, Pins::reentrant);
    SolveContext ctx{&p.sys.pins, &p.sys.x};
    OperatorFilter F;
    F.build(p.sys.A, p.sys.pins);
    const BlockCsr& A = on_the_fly_filters ? p.sys.A : p.Ahat;
    const VertexFilterView view = on_the_fly_filters ? F.view() : VertexFilterView{};
    SaAmg::Params sp = small_coarse(20);
    REQUIRE(sp.fine_inverses_on_the_fly);  // the default
    sp.single_block_inverses = false;      // double inverses on the coarse levels of both
    SaAmg::Params dp = sp;
    dp.fine_inverses_on_the_fly = false;
    SaAmg s(sp), d(dp);
    REQUIRE(s.setup(A, ctx, view) == Status::success);
    REQUIRE(d.setup(A, ctx, view) == Status::success);
    REQUIRE(s.levels() >= 3);
    const Eigen::VectorXd r = Eigen::VectorXd::Random(A.rows());
    Eigen::VectorXd zs, zd;
    s.apply(r, zs);
    d.apply(r, zd);
    CHECK(zd.norm() > 0);
    CHECK((zs - zd).norm() <= 1e-12 * zd.norm());
    CHECK(zs != zd);  // a different computation, not the stored path
    const std::size_t n = static_cast<std::size_t>(A.block_rows());
    CHECK(d.info().memory_bytes - s.info().memory_bytes >= 72 * n);
    const PcgResult rs = pcg(p.Ahat, p.chat, s), rd = pcg(p.Ahat, p.chat, d);
    CHECK(rs.converged);
    CHECK(rs.iterations == rd.iterations);
  }
}

namespace {

/// A with its block rows and columns renumbered: vertex i becomes perm[i].
BlockCsr renumbered(const BlockCsr& A, const std::vector<int>& perm) {
  const int n = A.block_rows();
  std::vector<std::vector<int>> cols(n);
  for (int i = 0; i < n; ++i)
    for (int k = A.row_ptr()[i]; k < A.row_ptr()[i + 1]; ++k) cols[perm[i]].push_back(perm[A.col()[k]]);
  for (auto& c : cols) std::sort(c.begin(), c.end());
  BlockCsr out(cols);
  for (int i = 0; i < n; ++i)
    for (int k = A.row_ptr()[i]; k < A.row_ptr()[i + 1]; ++k) out.block(out.find(perm[i], perm[A.col()[k]])) = A.block(k);
  return out;
}

}  // namespace

TEST_CASE("sa: restriction chunks cover the rows and hold every column within two consecutive chunks") {
  // The property that makes the parity-class scatter race-free, on banded patterns, random
  // ones and a column that spans every row; the chunks are at least min_rows long but the last.
  std::mt19937 rng(3);
  auto check = [&](int rows, int cols, const std::vector<std::vector<int>>& by_row, int min_rows) {
    std::vector<int> ptr{0}, col;
    for (const auto& r : by_row) {
      col.insert(col.end(), r.begin(), r.end());
      ptr.push_back(static_cast<int>(col.size()));
    }
    const std::vector<double> val(18 * col.size(), 1.0);
    const BsrView<3, 6> P{rows, cols, ptr.data(), col.data(), val.data()};
    const std::vector<int> b = sa::restriction_chunks<3>(P, min_rows);
    REQUIRE(b.size() >= 2);
    CHECK(b.front() == 0);
    CHECK(b.back() == rows);
    std::vector<int> chunk_of(rows);
    for (size_t c = 0; c + 1 < b.size(); ++c) {
      CHECK(b[c] < b[c + 1]);
      if (c + 2 < b.size()) CHECK(b[c + 1] - b[c] >= min_rows);
      for (int i = b[c]; i < b[c + 1]; ++i) chunk_of[i] = static_cast<int>(c);
    }
    std::vector<int> lo(cols, 1 << 30), hi(cols, -1);
    for (int i = 0; i < rows; ++i)
      for (int J : by_row[i]) lo[J] = std::min(lo[J], chunk_of[i]), hi[J] = std::max(hi[J], chunk_of[i]);
    int violations = 0;
    for (int J = 0; J < cols; ++J) violations += hi[J] >= 0 && hi[J] - lo[J] > 1;
    CHECK(violations == 0);
    return static_cast<int>(b.size()) - 1;
  };
  // Banded: row i touches the columns near i / 9 (a numbered sheet), up to 5 columns.
  const int rows = 20000, cols = rows / 9 + 1;
  std::vector<std::vector<int>> banded(rows), random(rows), spanning(rows);
  for (int i = 0; i < rows; ++i) {
    for (int J = std::max(0, i / 9 - 2); J <= std::min(cols - 1, i / 9 + 2); ++J) banded[i].push_back(J);
    std::set<int> r;
    for (int q = 0; q < 3; ++q) r.insert(std::uniform_int_distribution<int>(0, cols - 1)(rng));
    random[i].assign(r.begin(), r.end());
    spanning[i] = banded[i];
    if (i == 0 || i == rows - 1) {  // column 0 also holds the last row
      spanning[i].insert(spanning[i].begin(), 0);
      spanning[i].erase(std::unique(spanning[i].begin(), spanning[i].end()), spanning[i].end());
    }
  }
  for (const int min_rows : {1, 64, 512}) {
    CAPTURE(min_rows);
    const int nb = check(rows, cols, banded, min_rows);
    CHECK(nb >= rows / std::max(min_rows, 64) / 2);  // not vacuous: a banded pattern parallelises
    CHECK(check(rows, cols, random, min_rows) <= 3);  // every column spans about all rows
    CHECK(check(rows, cols, spanning, min_rows) <= 2);
  }
}

TEST_CASE("sa: the row-chunked restriction is P^T on well and randomly numbered meshes") {
  // The cycle restricts by P's rows in chunks whose parity classes share no coarse column.
  // Randomly numbered vertices make every aggregate span the whole row range (few, long
  // chunks); the cycle must stay symmetric (the restriction is exactly P^T of the
  // prolongation) and converge the same on both numberings.
  support::ClothSystem sys = support::cloth_system(61, Tessellation::irregular, Pins::none);
  const int n = sys.A.block_rows();
  REQUIRE(n > parallel_rows);  // the restriction runs in parallel where OpenMP is on
  std::vector<int> perm(n);
  std::iota(perm.begin(), perm.end(), 0);
  std::mt19937 rng(7);
  std::shuffle(perm.begin(), perm.end(), rng);
  const BlockCsr Ar = renumbered(sys.A, perm);
  Eigen::VectorXd xr(3 * n), br(3 * n);
  for (int i = 0; i < n; ++i) {
    xr.segment<3>(3 * perm[i]) = sys.x.segment<3>(3 * i);
    br.segment<3>(3 * perm[i]) = sys.b.segment<3>(3 * i);
  }
  CHECK((Ar.to_sparse() * xr).norm() == doctest::Approx((sys.A.to_sparse() * sys.x).norm()).epsilon(1e-12));
  int iterations[2] = {0, 0};
  for (const bool random : {false, true}) {
    CAPTURE(random);
    const BlockCsr& A = random ? Ar : sys.A;
    SolveContext ctx{nullptr, random ? &xr : &sys.x};
    SaAmg sa({});
    REQUIRE(sa.setup(A, ctx) == Status::success);
    REQUIRE(sa.levels() >= 3);
    const int chunks = sa.stats().levels[0].restriction_chunks;
    MESSAGE("fine restriction chunks: " << chunks);
    if (random)
      CHECK(chunks <= 3);  // every aggregate spans the rows
    else
      CHECK(chunks >= 4);  // the banded numbering of the generator scatters in parallel
    const Eigen::VectorXd u = Eigen::VectorXd::Random(A.rows()), v = Eigen::VectorXd::Random(A.rows());
    Eigen::VectorXd Bu, Bv;
    sa.apply(u, Bu);
    sa.apply(v, Bv);
    CHECK(std::abs(v.dot(Bu) - u.dot(Bv)) <= 1e-12 * std::abs(u.dot(Bv)));
    CHECK(u.dot(Bu) > 0);
    const PcgResult res = pcg(A, random ? br : sys.b, sa);
    CHECK(res.converged);
    iterations[random] = res.iterations;
#ifdef WEFT_WITH_OPENMP
    const int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    Eigen::VectorXd Bu1;
    sa.apply(u, Bu1);
    omp_set_num_threads(std::max(2, threads));
    Eigen::VectorXd Bu2;
    sa.apply(u, Bu2);
    omp_set_num_threads(threads);
    CHECK((Bu1 - Bu2).norm() == 0.0);
#endif
  }
  MESSAGE("PCG iterations: " << iterations[0] << " (mesh numbering), " << iterations[1] << " (random numbering)");
  CHECK(std::abs(iterations[1] - iterations[0]) <= iterations[0] / 2 + 1);
}

namespace {
/// Mean |a - b| over the pairs of aggregates that A couples.
double mean_aggregate_distance(const BsrView<3, 3>& A, const sa::Aggregates& ag) {
  std::vector<std::pair<int, int>> e;
  for (int i = 0; i < A.rows; ++i)
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
      const int a = ag.node_agg[i], b = ag.node_agg[A.col[k]];
      if (a >= 0 && b > a) e.emplace_back(a, b);
    }
  std::sort(e.begin(), e.end());
  e.erase(std::unique(e.begin(), e.end()), e.end());
  double sum = 0;
  for (const auto& [a, b] : e) sum += b - a;
  return e.empty() ? 0.0 : sum / static_cast<double>(e.size());
}
}  // namespace

TEST_CASE("sa: aggregate_order renumbers a spring-joined stack's aggregates for locality and keeps them as sets") {
  // Layers numbered one after the other, cut into sheets: each piece is coupled by springs
  // to the pieces above and below it, numbered a layer's worth of aggregates away. Mean
  // distances natural / RCM measured on stacks of m x m layers: 48 / 27 (m = 21, 2 layers),
  // 170 / 80 (41, 4), 197 / 173 (41, 8), 329 / 82 (61, 2): the fuller the stack, the less
  // RCM gains (dropVertical's folds overlap in part: 1057 / 96 on its first level at 160k).
  const SpringStack st = spring_stack(61, 2, 0.01);
  const auto V = bsr_view(st.A);
  sa::Aggregates ag = fine_aggregates(V);
  sa::split_sheets(sa::sheet_edges(V), ag);
  sa::Aggregates natural = ag;
  CHECK(sa::order_aggregates<3>(V, natural, AggregateOrder::natural).empty());
  CHECK(natural.node_agg == ag.node_agg);
  sa::Aggregates reordered = ag;
  const std::vector<int> label = sa::order_aggregates<3>(V, reordered, AggregateOrder::automatic);
  REQUIRE(static_cast<int>(label.size()) == ag.count);
  std::vector<int> sorted = label;
  std::sort(sorted.begin(), sorted.end());
  for (int a = 0; a < ag.count; ++a) REQUIRE(sorted[a] == a);  // a permutation
  for (std::size_t i = 0; i < ag.node_agg.size(); ++i)
    CHECK(reordered.node_agg[i] == (ag.node_agg[i] < 0 ? -1 : label[ag.node_agg[i]]));
  CHECK(reordered.count == ag.count);
  CHECK(reordered.max_size == ag.max_size);
  const double before = mean_aggregate_distance(V, ag), after = mean_aggregate_distance(V, reordered);
  MESSAGE("mean number distance of coupled aggregates: " << before << " natural, " << after << " RCM");
  CHECK(after < 0.5 * before);
  // A single sheet numbered by rows: RCM gains nothing, and `automatic` keeps the seeds' order.
  const Prefiltered p = prefiltered_cloth(41, Tessellation::regular, Pins::two_sides);
  const auto Vs = bsr_view(p.Ahat);
  sa::Aggregates sheet = fine_aggregates(Vs);
  const sa::Aggregates kept = sheet;
  CHECK(sa::order_aggregates<3>(Vs, sheet, AggregateOrder::automatic).empty());
  CHECK(sheet.node_agg == kept.node_agg);
  CHECK(!sa::order_aggregates<3>(Vs, sheet, AggregateOrder::rcm).empty());
  CHECK(mean_aggregate_distance(Vs, sheet) >= 0.5 * mean_aggregate_distance(Vs, kept));
}

TEST_CASE("sa: aggregation and the split into sheets visiting a renumbered matrix in the original order give the original aggregates") {
  // What lets a level renumbered by RCM aggregate as its natural numbering would: the scan
  // order of pass 1.
  const support::ClothSystem sys = support::cloth_system(31, Tessellation::irregular, Pins::boundary);
  const int n = sys.A.block_rows();
  std::vector<int> perm(n);
  std::iota(perm.begin(), perm.end(), 0);
  std::mt19937 rng(3);
  std::shuffle(perm.begin(), perm.end(), rng);
  const BlockCsr Ar = renumbered(sys.A, perm);
  const sa::Aggregates a = fine_aggregates(bsr_view(sys.A));
  std::vector<double> mu;
  std::vector<std::uint8_t> strong, special;
  const auto Vr = bsr_view(Ar);
  sa::strength<3>(Vr, 0.48, SocMeasure::spectral, mu, strong);
  sa::special_nodes<3>(Vr, mu, 1e-2, strong, special);
  const sa::Aggregates by_index = sa::aggregate<3>(Vr, strong, special);
  const sa::Aggregates by_scan = sa::aggregate<3>(Vr, strong, special, perm);  // step t visits old node t
  REQUIRE(a.count > 20);
  CHECK(by_scan.count == a.count);
  int same = 0, same_by_index = 0;
  for (int i = 0; i < n; ++i) {
    same += by_scan.node_agg[perm[i]] == a.node_agg[i];
    same_by_index += by_index.node_agg[perm[i]] == a.node_agg[i];
  }
  CHECK(same == n);
  CHECK(same_by_index < n / 2);  // not vacuous: by index the aggregates differ
  // The split into sheets numbers its pieces in the same visiting order.
  const SpringStack st = spring_stack(21, 3, 0.01);
  const int ns = st.A.block_rows();
  std::vector<int> sperm(ns);
  std::iota(sperm.begin(), sperm.end(), 0);
  std::shuffle(sperm.begin(), sperm.end(), rng);
  const BlockCsr Sr = renumbered(st.A, sperm);
  sa::Aggregates natural = fine_aggregates(bsr_view(st.A));
  REQUIRE(sa::split_sheets(sa::sheet_edges(bsr_view(st.A)), natural) > 0);
  const auto Vs = bsr_view(Sr);
  sa::strength<3>(Vs, 0.48, SocMeasure::spectral, mu, strong);
  sa::special_nodes<3>(Vs, mu, 1e-2, strong, special);
  sa::Aggregates split = sa::aggregate<3>(Vs, strong, special, sperm);
  sa::split_sheets(sa::sheet_edges(Vs), split, sperm);
  CHECK(split.count == natural.count);
  int same_split = 0;
  for (int i = 0; i < ns; ++i) same_split += split.node_agg[sperm[i]] == natural.node_agg[i];
  CHECK(same_split == ns);
}

TEST_CASE("sa: RCM-numbered aggregates keep the V-cycle SPD and the PCG iterations of the natural numbering") {
  SaAmg::Params natural = small_coarse(20), rcm = small_coarse(20);
  natural.split_sheets = rcm.split_sheets = true;
  natural.aggregate_order = AggregateOrder::natural;
  rcm.aggregate_order = AggregateOrder::rcm;
  {
    const SpringStack st = spring_stack(9, 3, 0.01);
    SaAmg sa(rcm);
    REQUIRE(sa.setup(st.A, SolveContext{&st.pins, &st.x}) == Status::success);
    CHECK(sa.stats().levels[0].reordered);
    checked_spd_map(sa, st.A.rows());
  }
  const SpringStack st = spring_stack(41, 4, 0.01);
  for (const bool split : {false, true}) {
    CAPTURE(split);
    natural.split_sheets = rcm.split_sheets = split;
    natural.coarse_size = rcm.coarse_size = 50;
    SaAmg a(natural), b(rcm);
    REQUIRE(a.setup(st.A, SolveContext{&st.pins, &st.x}) == Status::success);
    REQUIRE(b.setup(st.A, SolveContext{&st.pins, &st.x}) == Status::success);
    CHECK(!a.stats().levels[0].reordered);
    CHECK(b.stats().levels[0].reordered);
    REQUIRE(a.levels() >= 3);
    // Level 1 has the same aggregates renumbered, and aggregates (and splits) them in their
    // natural order, so level 2 has the same size too. Deeper levels may differ: the coarse
    // operators are summed in another order (with split = true: 7 levels against 6).
    for (int l = 1; l <= 2; ++l) {
      CAPTURE(l);
      CHECK(b.stats().levels[l].rows == a.stats().levels[l].rows);
    }
    MESSAGE("levels: " << a.levels() << " natural, " << b.levels() << " RCM");
    const PcgResult ra = pcg(st.A, st.b, a), rb = pcg(st.A, st.b, b);
    MESSAGE("stack of 4 layers of 41 x 41: " << ra.iterations << " iterations natural, " << rb.iterations << " RCM");
    CHECK(ra.converged);
    CHECK(rb.converged);
    CHECK(std::abs(ra.iterations - rb.iterations) <= 1);
  }
}

TEST_CASE("sa: setup without positions is invalid input") {
  BlockCsr A = support::block_laplacian(5, 0.1);
  SaAmg sa({});
  CHECK(sa.setup(A, SolveContext{}) == Status::invalid_input);
  CHECK(sa.stats().message.find("positions") != std::string::npos);
  Eigen::VectorXd wrong = Eigen::VectorXd::Zero(6);
  CHECK(sa.setup(A, SolveContext{nullptr, &wrong}) == Status::invalid_input);
  const Eigen::VectorXd x = grid_positions(5);
  CHECK(sa.setup(A, SolveContext{nullptr, &x}) == Status::success);
  // 25 nodes <= coarse_size: one level, solved exactly.
  CHECK(sa.levels() == 1);
  Eigen::VectorXd r = Eigen::VectorXd::LinSpaced(A.rows(), -1, 2), z;
  sa.apply(r, z);
  Eigen::VectorXd Az;
  A.multiply(z, Az);
  CHECK((Az - r).norm() <= 1e-12 * r.norm());
  CHECK_THROWS_AS(SaAmg(SaAmg::Params{.theta = 1.5}), ConfigError);
}

TEST_CASE("sa: PCG iteration counts stay bounded on block Laplacians") {
  std::vector<int> its;
  for (int m : {21, 41, 81}) {
    const BlockCsr A = support::block_laplacian(m, 1e-3);
    const Eigen::VectorXd x = grid_positions(m);
    Eigen::VectorXd b(A.rows());
    for (int k = 0; k < b.size(); ++k) b[k] = std::sin(0.37 * k) + 0.5;
    SaAmg sa(small_coarse(50));
    REQUIRE(sa.setup(A, SolveContext{nullptr, &x}) == Status::success);
    const PcgResult r = pcg(A, b, sa);
    MESSAGE("laplacian m " << m << ": levels " << sa.levels() << " iterations " << r.iterations << " op complexity "
                           << sa.info().operator_complexity);
    CHECK(r.converged);
    its.push_back(r.iterations);
  }
  CHECK(its.back() <= 2 * its.front());
}

void check_cloth_iterations(Pins pins) {
  for (Tessellation t : {Tessellation::regular, Tessellation::irregular}) {
    std::vector<int> its;
    for (int m : {21, 41, 81}) {
      CAPTURE(m);
      Prefiltered p = prefiltered_cloth(m, t, pins);
      SaAmg sa(small_coarse(50));
      REQUIRE(sa.setup(p.Ahat, SolveContext{&p.sys.pins, &p.sys.x}) == Status::success);
      const PcgResult r = pcg(p.Ahat, p.chat, sa);
      MESSAGE("cloth tess " << static_cast<int>(t) << " pins " << static_cast<int>(pins) << " m " << m << ": levels "
                            << sa.levels() << " iterations " << r.iterations << " op complexity "
                            << sa.info().operator_complexity);
      CHECK(r.converged);
      its.push_back(r.iterations);
    }
    CHECK(its.back() <= 2 * its.front());
  }
}

TEST_CASE("sa: PCG iteration counts stay bounded on a cloth pinned at its boundary") { check_cloth_iterations(Pins::boundary); }
TEST_CASE("sa: PCG iteration counts stay bounded on a cloth pinned at two sides") { check_cloth_iterations(Pins::two_sides); }
TEST_CASE("sa: PCG iteration counts stay bounded on the re-entrant L-shape") { check_cloth_iterations(Pins::reentrant); }

TEST_CASE("sa: reuse levels give the same map for the same matrix and frozen keeps it") {
  Prefiltered p = prefiltered_cloth(21, Tessellation::irregular, Pins::two_sides);
  SolveContext ctx{&p.sys.pins, &p.sys.x};
  Eigen::VectorXd r(p.Ahat.rows()), z0, z1, z2;
  for (int k = 0; k < r.size(); ++k) r[k] = std::cos(0.1 * k);
  SaAmg none({});
  REQUIRE(none.setup(p.Ahat, ctx) == Status::success);
  none.apply(r, z0);
  for (SaReuse reuse : {SaReuse::aggregates, SaReuse::frozen}) {
    CAPTURE(static_cast<int>(reuse));
    SaAmg::Params prm;
    prm.reuse = reuse;
    SaAmg sa(prm);
    REQUIRE(sa.analyze_pattern(p.Ahat) == Status::success);
    REQUIRE(sa.setup(p.Ahat, ctx) == Status::success);
    CHECK_FALSE(sa.stats().reused);
    sa.apply(r, z1);
    CHECK((z1 - z0).norm() <= 1e-12 * z0.norm());
    // Same pattern, new values: aggregates recomputes the numbers, frozen keeps the old map.
    BlockCsr A2 = p.Ahat;
    A2.scale(2.0);
    REQUIRE(sa.setup(A2, ctx) == Status::success);
    CHECK(sa.stats().reused);
    sa.apply(r, z2);
    if (reuse == SaReuse::aggregates)
      CHECK((2 * z2 - z0).norm() <= 1e-10 * z0.norm());  // B(2A) = B(A) / 2
    else
      CHECK((z2 - z0).norm() <= 1e-12 * z0.norm());
    const PcgResult res = pcg(A2, p.chat, sa);
    CHECK(res.converged);
    // analyze_pattern forgets everything.
    REQUIRE(sa.analyze_pattern(A2) == Status::success);
    REQUIRE(sa.setup(A2, ctx) == Status::success);
    CHECK_FALSE(sa.stats().reused);
    sa.apply(r, z2);
    CHECK((2 * z2 - z0).norm() <= 1e-10 * z0.norm());
  }
}

TEST_CASE("sa: reuse = step keeps the map within a step and refreshes it at the next") {
  Prefiltered p = prefiltered_cloth(21, Tessellation::irregular, Pins::two_sides);
  SolveContext ctx{&p.sys.pins, &p.sys.x};
  Eigen::VectorXd r(p.Ahat.rows()), z0, z1, z2;
  for (int k = 0; k < r.size(); ++k) r[k] = std::cos(0.1 * k);
  SaAmg::Params prm;
  prm.reuse = SaReuse::step;
  SaAmg sa(prm);
  REQUIRE(sa.analyze_pattern(p.Ahat) == Status::success);
  sa.begin_step();
  REQUIRE(sa.setup(p.Ahat, ctx) == Status::success);
  sa.apply(r, z0);
  CHECK_FALSE(sa.kept());
  const Eigen::MatrixXd C0 = sa.level_matrix(1);
  REQUIRE(C0.norm() > 0);
  // A later Newton iteration of the same step: new values; the coarse levels stay, the fine
  // level smooths with the new matrix (no copy of the old one is kept).
  BlockCsr A2 = p.Ahat;
  A2.scale(2.0);
  REQUIRE(sa.setup(A2, ctx) == Status::success);
  CHECK(sa.stats().reused);
  CHECK(sa.kept());
  CHECK(sa.refreshes() == 1);
  CHECK((sa.level_matrix(1) - C0).norm() == 0);
  sa.apply(r, z1);
  // Neither B(A) (a fine copy) nor B(2A) = B(A) / 2 (a refresh): the smoothed part halves, the
  // coarse correction does not.
  CHECK((z1 - z0).norm() >= 1e-3 * z0.norm());
  CHECK((2 * z1 - z0).norm() >= 1e-3 * z0.norm());
  const PcgResult kept = pcg(A2, p.chat, sa);
  CHECK(kept.converged);
  // The next step refreshes the values on the kept structure: B(2A) = B(A) / 2.
  sa.begin_step();
  REQUIRE(sa.setup(A2, ctx) == Status::success);
  CHECK(sa.stats().reused);
  CHECK_FALSE(sa.kept());
  CHECK(sa.refreshes() == 2);
  CHECK((sa.level_matrix(1) - 2 * C0).norm() <= 1e-6 * C0.norm());
  sa.apply(r, z2);
  CHECK((2 * z2 - z0).norm() <= 1e-10 * z0.norm());
  CHECK((z2 - z0).norm() >= 0.4 * z0.norm());
}

TEST_CASE("sa: reuse rebuilds when blocks move with the block count unchanged") {
  // Contact pairs that come and go between Newton iterations can keep the number of blocks
  // while moving them: reusing the old structure there would read the new values through the
  // old pattern. Move one coupling (i, j) to an empty (a, b), keeping A SPD: the removed block
  // B goes into both diagonals as ||B|| I, and the new block is zero.
  Prefiltered p = prefiltered_cloth(21, Tessellation::irregular, Pins::two_sides);
  SolveContext ctx{&p.sys.pins, &p.sys.x};
  const BlockCsr& A = p.Ahat;
  const int n = A.block_rows();
  std::vector<std::vector<int>> cols(n);
  for (int r = 0; r < n; ++r) cols[r].assign(A.col().begin() + A.row_ptr()[r], A.col().begin() + A.row_ptr()[r + 1]);
  const int i = n / 2, j = cols[i].front() != i ? cols[i].front() : cols[i].back();
  REQUIRE(j != i);
  int a = 0, b = n - 1;
  for (; a < n && (a == i || a == j || A.find(a, b) >= 0); ++a) {}
  REQUIRE(a < n);
  REQUIRE(b != i);
  REQUIRE(b != j);
  std::erase(cols[i], j);
  std::erase(cols[j], i);
  cols[a].push_back(b);
  cols[b].push_back(a);
  for (auto& c : cols) std::sort(c.begin(), c.end());
  BlockCsr M(cols);
  REQUIRE(M.num_blocks() == A.num_blocks());
  M.set_zero();
  for (int r = 0; r < n; ++r)
    for (int k = A.row_ptr()[r]; k < A.row_ptr()[r + 1]; ++k)
      if (const int m = M.find(r, A.col()[k]); m >= 0) M.block(m) = A.block(k);
  const double shift = A.block(A.find(i, j)).norm();
  M.block(M.diagonal(i)) += shift * Block3::Identity();
  M.block(M.diagonal(j)) += shift * Block3::Identity();

  SaAmg::Params prm;
  prm.reuse = SaReuse::aggregates;
  SaAmg kept(prm), fresh(prm);
  REQUIRE(kept.setup(A, ctx) == Status::success);
  REQUIRE(kept.setup(M, ctx) == Status::success);
  CHECK_FALSE(kept.stats().reused);
  REQUIRE(fresh.setup(M, ctx) == Status::success);
  Eigen::VectorXd r(M.rows()), z1, z2;
  for (int k = 0; k < r.size(); ++k) r[k] = std::cos(0.1 * k);
  kept.apply(r, z1);
  fresh.apply(r, z2);
  CHECK((z1 - z2).norm() <= 1e-12 * z2.norm());
  CHECK(z2.norm() > 0);
}

#ifdef WEFT_WITH_OPENMP
TEST_CASE("sa: setup and apply do not depend on the thread count") {
  Prefiltered p = prefiltered_cloth(61, Tessellation::irregular, Pins::reentrant);
  REQUIRE(p.Ahat.block_rows() > parallel_rows);  // the fine level runs in parallel
  SolveContext ctx{&p.sys.pins, &p.sys.x};
  Eigen::VectorXd r(p.Ahat.rows()), z1, z2;
  for (int k = 0; k < r.size(); ++k) r[k] = std::sin(0.3 * k);
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  SaAmg a({});
  REQUIRE(a.setup(p.Ahat, ctx) == Status::success);
  a.apply(r, z1);
  omp_set_num_threads(std::max(2, threads));
  SaAmg b({});
  REQUIRE(b.setup(p.Ahat, ctx) == Status::success);
  b.apply(r, z2);
  omp_set_num_threads(threads);
  CHECK(z1.norm() > 0);
  CHECK((z1 - z2).norm() == 0.0);
}
#endif

}  // TEST_SUITE("linear")


TEST_CASE("sa: a preset is read before the keys beside it and names a bad value") {
  const auto read = [](const std::string& text) { return read_params<SaAmg::Params>(Json::parse(text), "p", "invalid:"); };
  const SaAmg::Params thesis = read(R"({"preset": "thesis"})");
  CHECK(thesis.preset == SaPreset::thesis);
  CHECK(thesis.reuse == SaReuse::none);
  CHECK(thesis.prolongator_degree == 1);
  // Keys beside the preset change it, whatever their order in the object.
  for (const char* text : {R"({"preset": "large", "cycle_gamma": 1})", R"({"cycle_gamma": 1, "preset": "large"})"}) {
    CAPTURE(text);
    const SaAmg::Params large = read(text);
    CHECK(large.preset == SaPreset::large);
    CHECK(large.cycle_gamma == 1);
    CHECK(large.prolongator_degree == 2);
    CHECK(large.split_sheets);
    CHECK(large.prolongator_truncation == 0.05);
  }
  // No preset key: the member defaults, which are auto's.
  const SaAmg::Params none = read(R"({"theta": 0.3})");
  CHECK(none.preset == SaPreset::automatic);
  CHECK(none.reuse == SaReuse::step);
  CHECK(none.theta == 0.3);
  try {
    read(R"({"preset": "fast"})");
    FAIL("an unknown preset was accepted");
  } catch (const ConfigError& e) {
    CHECK(std::string(e.what()).find("p.preset = \"fast\" is not a valid choice: valid are auto, thesis, large") != std::string::npos);
  }
}

TEST_CASE("sa: preset auto takes the large settings from large_from rows and keeps the keys given") {
  // The same sheet on both sides of the threshold: below it, the thesis' hierarchy; from it,
  // the large preset's (the same prolongator), with a given key kept even where it equals
  // auto's default.
  Prefiltered p = prefiltered_cloth(31, Tessellation::irregular, Pins::two_sides);
  SolveContext ctx{&p.sys.pins, &p.sys.x};
  const int rows = p.Ahat.block_rows();
  const auto read = [](const std::string& text) { return read_params<SaAmg::Params>(Json::parse(text), "p", "invalid:"); };
  const SaAmg::Params below = read(fmt::format(R"({{"coarse_size": 20, "large_from": {}}})", rows + 1));
  const SaAmg::Params from = read(fmt::format(R"({{"coarse_size": 20, "large_from": {}}})", rows));
  const SaAmg::Params given = read(fmt::format(R"({{"coarse_size": 20, "large_from": {}, "cycle_gamma": 1}})", rows));
  CHECK(below.resolved(rows).preset == SaPreset::automatic);
  const SaAmg::Params r = from.resolved(rows);
  CHECK(r.preset == SaPreset::large);
  CHECK(r.coarse_size == 20);  // differs from auto's: kept
  CHECK(r.cycle_gamma == 2);
  CHECK(given.resolved(rows).cycle_gamma == 1);  // equal to auto's, but given
  // The same without a scene: settings that differ from auto's hold.
  SaAmg::Params code = SaAmg::Params{.large_from = 1, .theta = 0.3};
  CHECK(code.resolved(5).theta == 0.3);
  CHECK(code.resolved(5).split_sheets);

  SaAmg::Params thesis = SaAmg::Params::of(SaPreset::thesis), large = SaAmg::Params::of(SaPreset::large);
  thesis.coarse_size = large.coarse_size = 20;
  SaAmg a_below(below), a_from(from), a_thesis(thesis), a_large(large);
  for (SaAmg* sa : {&a_below, &a_from, &a_thesis, &a_large}) REQUIRE(sa->setup(p.Ahat, ctx) == Status::success);
  REQUIRE(a_from.levels() >= 3);
  CHECK(a_below.prolongator(0) == a_thesis.prolongator(0));
  CHECK(a_from.prolongator(0) == a_large.prolongator(0));
  CHECK(a_from.prolongator(0).cols() != a_below.prolongator(0).cols());  // not vacuous: the two hierarchies differ
  checked_spd_map(a_from, p.Ahat.rows());
}

TEST_CASE("sa: preset auto validates the large settings with the keys given before any setup") {
  // split_sheets = false beside auto leaves large's split_merge without its split.
  try {
    SaAmg sa(SaAmg::Params{.split_sheets = false, .given = {"split_sheets"}});
    FAIL("the large settings were not validated");
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    CAPTURE(what);
    CHECK(what.find("from large_from = 160000 fine rows") != std::string::npos);
    CHECK(what.find("split_merge") != std::string::npos);
  }
  CHECK_NOTHROW(SaAmg(SaAmg::Params{.preset = SaPreset::thesis, .split_sheets = false, .given = {"split_sheets"}}));
  CHECK_THROWS_AS(SaAmg(SaAmg::Params{.large_from = 0}), ConfigError);
}
