// Scratch program of R-coarse-locality.md (kept for reproducibility, not part of the build):
// per-level Chebyshev smoothing time of the SA hierarchy on a bench system (unconstrained A),
// and the mean number distance of coupled fine-level aggregates, natural and by RCM.
// Usage: levels M regular|irregular sheets|default EXAMPLE(0-4) natural|rcm|auto (default auto)
#include "apps/bench_linear_systems.hpp"
#include "linear/sa_ppcg.hpp"
#include "linear/sa_amg.hpp"
#include <fmt/core.h>
#include <algorithm>
#include <chrono>
#include "linear/bsr.hpp"
using namespace weft;
using namespace weft::app::benchlin;
int main(int argc, char** argv) {
  ExampleConfig cfg;
  cfg.example = Example(argc > 4 ? std::atoi(argv[4]) : 4);
  cfg.m = argc > 1 ? std::atoi(argv[1]) : 200;
  cfg.tessellation = (argc > 2 && std::string(argv[2]) == "irregular") ? Tessellation::irregular : Tessellation::regular;
  bool sheets = argc > 3 && std::string(argv[3]) == "sheets";
  LinearBenchSimulation sim(cfg);
  auto c = sim.build_system();
  const BlockCsr& A = sim.A();
  linear::SaAmg::Params prm;
  if (sheets) { prm.split_sheets = true; prm.aggregation_theta = 0.25; }
  if (argc > 5 && std::string(argv[5]) == "rcm") prm.aggregate_order = linear::AggregateOrder::rcm;
  if (argc > 5 && std::string(argv[5]) == "natural") prm.aggregate_order = linear::AggregateOrder::natural;
  linear::SaAmg B(prm);
  Eigen::VectorXd pos = sim.positions();
  SolveContext ctx{nullptr, &pos};
  B.analyze_pattern(A); B.setup(A, ctx);
  {
    std::vector<double> mu;
    std::vector<std::uint8_t> strong, special;
    const auto V = linear::bsr_view(A);
    linear::sa::strength<3>(V, prm.aggregation_theta > 0 ? prm.aggregation_theta : prm.theta, prm.strength, mu, strong);
    linear::sa::special_nodes<3>(V, mu, prm.diagonal_dominance, strong, special);
    linear::sa::Aggregates ag = linear::sa::aggregate<3>(V, strong, special);
    if (prm.split_sheets) linear::sa::split_sheets(linear::sa::sheet_edges(V), ag);
    auto mean = [&](const linear::sa::Aggregates& g) {
      std::vector<std::pair<int, int>> e;
      for (int i = 0; i < V.rows; ++i)
        for (int k = V.row_ptr[i]; k < V.row_ptr[i + 1]; ++k) {
          const int a = g.node_agg[i], b = g.node_agg[V.col[k]];
          if (a >= 0 && b > a) e.emplace_back(a, b);
        }
      std::sort(e.begin(), e.end());
      e.erase(std::unique(e.begin(), e.end()), e.end());
      double s = 0;
      for (auto [a, b] : e) s += b - a;
      return s / e.size();
    };
    linear::sa::Aggregates r = ag;
    linear::sa::order_aggregates<3>(V, r, linear::AggregateOrder::rcm);
    fmt::print("level 0 aggregates {}: mean number distance of coupled aggregates {:.1f} natural, {:.1f} RCM\n", ag.count, mean(ag), mean(r));
  }
  auto now = [] { return std::chrono::steady_clock::now(); };
  const int reps = 20;
  for (int l = 0; l < B.levels(); ++l) {
    int N = (l == 0 ? 3 * sim.num_vertices() : (int)B.stats().levels[l].rows * 6);
    Eigen::VectorXd f = Eigen::VectorXd::Random(N), x = Eigen::VectorXd::Zero(N);
    B.smooth(l, f, x);
    auto t0 = now();
    for (int r = 0; r < reps; ++r) B.smooth(l, f, x);
    double t = std::chrono::duration<double>(now() - t0).count() / reps;
    fmt::print("level {} dofs {} nnz_blocks {} smooth(deg {}) {:.2f} ms\n", l, N, B.stats().levels[l].nnz_blocks, prm.chebyshev_degree, 1e3 * t);
  }
  Eigen::VectorXd r = Eigen::VectorXd::Random(3 * sim.num_vertices()), z, Ar;
  B.apply(r, z);
  auto t0 = now();
  for (int k = 0; k < reps; ++k) B.apply(r, z);
  fmt::print("V-cycle {:.2f} ms\n", 1e3 * std::chrono::duration<double>(now() - t0).count() / reps);
  t0 = now();
  for (int k = 0; k < reps; ++k) A.multiply(r, Ar);
  fmt::print("fine SpMV (unfiltered) {:.2f} ms\n", 1e3 * std::chrono::duration<double>(now() - t0).count() / reps);
  fmt::print("check {:.17g}\n", z.squaredNorm());
}
