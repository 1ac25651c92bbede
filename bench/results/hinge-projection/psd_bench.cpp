// Projected hinge-Hessian assembly time on a drape grid (min of reps), one thread.
#include <chrono>
#include <cstdio>
#include <cmath>
#include <omp.h>
#include "models/hinge_bending.hpp"
#include "tests/support/model_fixtures.hpp"
using namespace weft; using namespace weft::models;
int main(int argc, char** argv) {
  omp_set_num_threads(1);
  const int n = argc > 1 ? std::atoi(argv[1]) : 201;
  const auto m = support::grid(n, n, 1.0, 1.0);
  Eigen::VectorXd x = support::stack(m.V);
  for (Eigen::Index i = 0; i < x.size() / 3; ++i) x[3 * i + 2] = 0.1 * std::sin(7 * x[3 * i]) * std::cos(5 * x[3 * i + 1]);
  auto p = support::make_patch<HingeBending<ThetaEnergy>>(m, x);
  AssemblyPlan plan; p.model.declare(plan); plan.finalize(p.state.num_vertices());
  ElementBuffer buf = plan.make_buffer(); BlockCsr H = plan.pattern(); buf.start(H);
  for (auto mode : {HessianMode::projected, HessianMode::exact}) {
    double best = 1e30;
    for (int r = 0; r < 15; ++r) {
      auto t0 = std::chrono::steady_clock::now();
      p.model.add_hessian(p.state, buf, mode);
      best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    std::printf("%s n=%d hinges=%d: %.2f ms (min of 15), %.1f ns per hinge\n", mode == HessianMode::projected ? "projected" : "exact    ", n,
                p.model.num_hinges(), 1e3 * best, 1e9 * best / p.model.num_hinges());
  }
}
