// Diagnostic of DV-regular-accordion.md (a scratch program kept for reproducibility, not part of
// the build): the first dropVertical system, SA+PPCG and plain PCG with the V-cycle, the slowest
// mode of I - B A, where it lives, and a column-block Jacobi around the cycle (regular sheets
// only: the columns are found by grid row and column). Usage: slow_mode M regular|irregular.
#include "apps/bench_linear_systems.hpp"
#include "linear/sa_ppcg.hpp"
#include "linear/sa_amg.hpp"
#include <fmt/core.h>
#include <Eigen/Core>
#include <random>
#include <map>
#include <functional>
#include <Eigen/Cholesky>
#include "linear/bsr.hpp"
using namespace weft;
using namespace weft::app::benchlin;

// plain PCG with SaAmg on A (no constraints)
int pcg(const BlockCsr& A, const linear::SaAmg& B, const Eigen::VectorXd& b, Eigen::VectorXd& x, double tol) {
  Eigen::VectorXd r = b, z, p, Ap;
  x.setZero(b.size());
  B.apply(r, z);
  p = z;
  double rz = r.dot(z), rz0 = rz;
  for (int it = 1; it < 2000; ++it) {
    A.multiply(p, Ap);
    double a = rz / p.dot(Ap);
    x += a * p; r -= a * Ap;
    B.apply(r, z);
    double rzn = r.dot(z);
    if (std::sqrt(rzn / rz0) < tol) return it;
    p = z + (rzn / rz) * p; rz = rzn;
  }
  return -1;
}

int main(int argc, char** argv) {
  ExampleConfig cfg;
  cfg.example = Example::drop_vertical;
  cfg.m = argc > 1 ? std::atoi(argv[1]) : 200;
  cfg.tessellation = (argc > 2 && std::string(argv[2]) == "irregular") ? Tessellation::irregular : Tessellation::regular;
  LinearBenchSimulation sim(cfg);
  auto c = sim.build_system();
  const BlockCsr& A = sim.A();
  int n = sim.num_vertices();
  fmt::print("n {} springs {} box {}\n", n, c.springs, c.box_contacts);
  // (a) SA+PPCG with constraints
  linear::SaPpcg::Params prm;
  {
    linear::SaPpcg s(prm);
    s.set_context(sim.context());
    s.analyze_pattern(A); s.factorize(A);
    Eigen::VectorXd x;
    auto rep = s.solve(sim.b(), x);
    fmt::print("SA+PPCG constrained: {} iterations\n", rep.iterations);
  }
  // (b) SaAmg on A alone, plain PCG
  linear::SaAmg B(prm.preconditioner);
  Eigen::VectorXd pos = sim.positions();
  SolveContext ctx{nullptr, &pos};
  B.analyze_pattern(A); B.setup(A, ctx);
  Eigen::VectorXd x;
  fmt::print("SA PCG unconstrained: {} iterations\n", pcg(A, B, sim.b(), x, 1e-5));
  // (c) power iteration on E = I - B A
  std::mt19937 g(1); std::normal_distribution<double> N;
  Eigen::VectorXd e(3 * n), Ae, z;
  for (int i = 0; i < 3 * n; ++i) e[i] = N(g);
  for (int it = 0; it < 60; ++it) {
    A.multiply(e, Ae); B.apply(Ae, z);
    Eigen::VectorXd en = e - z;
    e = en / en.norm();
  }
  A.multiply(e, Ae); B.apply(Ae, z);
  fmt::print("stationary rate |E e|/|e| {:.4f}\n", (e - z).norm());
  // localisation
  const auto& X = sim.positions();
  std::vector<std::pair<double,int>> mag(n);
  Eigen::Vector3d comp = Eigen::Vector3d::Zero();
  for (int i = 0; i < n; ++i) { mag[i] = {e.segment<3>(3*i).squaredNorm(), i}; comp += e.segment<3>(3*i).cwiseAbs2(); }
  fmt::print("component energy x {:.3f} y {:.3f} z {:.3f}\n", comp[0], comp[1], comp[2]);
  std::sort(mag.rbegin(), mag.rend());
  double cum = 0;
  for (int k = 0; k < 30; ++k) {
    int i = mag[k].second; cum += mag[k].first;
    fmt::print("v {} (row {} col {}) pos {:.4f} {:.4f} {:.4f} |e|^2 {:.3e} cum {:.3f} e=({:.3f},{:.3f},{:.3f})\n", i, i / (cfg.m+1), i % (cfg.m+1), X[3*i], X[3*i+1], X[3*i+2], mag[k].first, cum, e[3*i], e[3*i+1], e[3*i+2]);
  }

  {
    std::vector<double> mu; std::vector<std::uint8_t> strong, special;
    auto V = linear::bsr_view(A);
    linear::sa::strength<3>(V, 0.48, linear::SocMeasure::spectral, mu, strong);
    int ns = linear::sa::special_nodes<3>(V, mu, 1e-2, strong, special);
    auto ag = linear::sa::aggregate<3>(V, strong, special);
    // classify blocks: spring (distance in rest > 3h) vs mesh
    const auto& rp = A.row_ptr(); const auto& col = A.col();
    double h = sim.repulsion_distance();
    // layer of vertex: z rounded in accordion region (x<0.? ) -> use z level index if z < 0.03
    auto layer = [&](int i){ double z = X[3*i+2]; return z < 0.025 ? (int)std::lround(z / 0.0063662) : -1; };
    long sp_strong=0, sp=0, me_strong=0, me=0; double sp_mu=0, me_mu=0;
    for (int i = 0; i < n; ++i) for (int k = rp[i]; k < rp[i+1]; ++k) { int j = col[k]; if (j==i) continue;
      bool spring = std::abs(X[3*i+2]-X[3*j+2]) > 1e-3 && layer(i)>=0 && layer(j)>=0 && layer(i)!=layer(j);
      if (spring) { ++sp; sp_strong += strong[k]; sp_mu += mu[k]; } else { ++me; me_strong += strong[k]; me_mu += mu[k]; } }
    fmt::print("special {} aggregates {} | spring blocks {} strong {} mean mu {:.3f} | mesh blocks {} strong {} mean mu {:.3f}\n", ns, ag.count, sp, sp_strong, sp_mu/sp, me, me_strong, me_mu/me);
    // aggregates spanning layers
    std::vector<int> lmask(ag.count, 0), cnt(ag.count,0);
    for (int i = 0; i < n; ++i) if (ag.node_agg[i] >= 0) { int l = layer(i); cnt[ag.node_agg[i]]++; if (l >= 0) lmask[ag.node_agg[i]] |= 1 << l; }
    int multi=0, single=0;
    for (int a = 0; a < ag.count; ++a) { int b = __builtin_popcount(lmask[a]); if (b>1) ++multi; else if (b==1) ++single; }
    fmt::print("accordion aggregates: single-layer {} multi-layer {}\n", single, multi);
  }

  {
    // e_z over the bottom layer: rows r (y) x columns (x), sampled every 10 columns
    for (int r = 0; r <= cfg.m / 2 + 2; ++r) {
      int i0 = r * (cfg.m + 1);
      fmt::print("row {:3d} y {:.3f} z {:.4f}:", r, X[3*i0+1], X[3*i0+2]);
      for (int col = 0; col <= cfg.m; col += 10) fmt::print(" {:6.3f}", 100 * e[3*(i0+col)+2]);
      fmt::print("\n");
    }
  }

  {
    // cluster (spring-connected) block Jacobi composed with the SA cycle
    const auto& rp = A.row_ptr(); const auto& col = A.col();
    int W = cfg.m + 1;
    std::vector<int> par(n); for (int i = 0; i < n; ++i) par[i] = i;
    std::function<int(int)> find = [&](int a){ while (par[a]!=a) a = par[a] = par[par[a]]; return a; };
    for (int i = 0; i < n; ++i) for (int k = rp[i]; k < rp[i+1]; ++k) { int j = col[k];
      if (std::abs(i / W - j / W) > 2 || std::abs(i % W - j % W) > 2) par[find(i)] = find(j); }
    std::map<int, std::vector<int>> cl;
    for (int i = 0; i < n; ++i) cl[find(i)].push_back(i);
    std::vector<std::vector<int>> clusters; std::vector<Eigen::LLT<Eigen::MatrixXd>> fac;
    int maxs = 0;
    for (auto& [r, v] : cl) {
      int s = v.size(); maxs = std::max(maxs, s);
      Eigen::MatrixXd Bc = Eigen::MatrixXd::Zero(3*s, 3*s);
      for (int a = 0; a < s; ++a) for (int b = 0; b < s; ++b) { int k = A.find(v[a], v[b]); if (k >= 0) Bc.block<3,3>(3*a,3*b) = A.block(k); }
      clusters.push_back(v); fac.emplace_back(Bc);
    }
    fmt::print("clusters {} largest {}\n", clusters.size(), maxs);
    auto Dc = [&](const Eigen::VectorXd& r, Eigen::VectorXd& z) {
      z.resize(r.size());
      for (size_t c = 0; c < clusters.size(); ++c) { auto& v = clusters[c]; int s = v.size();
        Eigen::VectorXd rr(3*s); for (int a = 0; a < s; ++a) rr.segment<3>(3*a) = r.segment<3>(3*v[a]);
        Eigen::VectorXd zz = fac[c].solve(rr); for (int a = 0; a < s; ++a) z.segment<3>(3*v[a]) = zz.segment<3>(3*a); }
    };
    // lambda_max of Dc^-1 A by power iteration
    Eigen::VectorXd q = Eigen::VectorXd::Random(3*n), t, u; double lam = 0;
    for (int it = 0; it < 50; ++it) { A.multiply(q, t); Dc(t, u); lam = u.norm() / q.norm(); q = u / u.norm(); }
    double om = 1.0 / (1.1 * lam);
    fmt::print("lambda(Dc^-1 A) {:.3f}\n", lam);

    { Eigen::VectorXd Ae2, De; A.multiply(e, Ae2); 
      // e^T Dc e = e^T (block) e: compute via cluster blocks directly
      double eDe = 0; for (size_t c = 0; c < clusters.size(); ++c) { auto& v = clusters[c]; int s = v.size();
        Eigen::VectorXd ee(3*s); for (int a = 0; a < s; ++a) ee.segment<3>(3*a) = e.segment<3>(3*v[a]);
        Eigen::MatrixXd L = fac[c].matrixL(); eDe += (L.transpose() * ee).squaredNorm(); }
      double eD3 = 0; for (int i = 0; i < n; ++i) eD3 += e.segment<3>(3*i).dot(A.block(A.diagonal(i)) * e.segment<3>(3*i));
      fmt::print("slow mode: eAe/eDc e {:.3e}  eAe/eD3e {:.3e}  (lambda Dc {:.3f})\n", e.dot(Ae2)/eDe, e.dot(Ae2)/eD3, lam); }

    for (int nsweep : {1, 2}) {
    auto Bp = [&](const Eigen::VectorXd& r, Eigen::VectorXd& z) {
      Eigen::VectorXd w, Az, zz; z.setZero(r.size());
      for (int s = 0; s < nsweep; ++s) { A.multiply(z, Az); Dc(r - Az, w); z += om * w; }
      A.multiply(z, Az); B.apply(r - Az, zz); z += zz;
      for (int s = 0; s < nsweep; ++s) { A.multiply(z, Az); Dc(r - Az, w); z += om * w; }
    };
    Eigen::VectorXd r = sim.b(), z, p, Ap, xx = Eigen::VectorXd::Zero(3*n);
    Bp(r, z); p = z; double rz = r.dot(z), rz0 = rz; int it = 1;
    for (; it < 2000; ++it) { A.multiply(p, Ap); double a = rz / p.dot(Ap); xx += a*p; r -= a*Ap; Bp(r, z); double rzn = r.dot(z);
      if (std::sqrt(rzn/rz0) < 1e-5) break; p = z + (rzn/rz)*p; rz = rzn; }
    fmt::print("SA + {} cluster Jacobi sweeps: {} iterations\n", nsweep, it);
    }
  }

  { for (int r : {10, 11, 12}) { int i0 = r * (cfg.m + 1); fmt::print("row {} cols 60..100 ez:", r);
      for (int c = 60; c <= 100; ++c) fmt::print(" {:.2f}", 100 * e[3*(i0+c)+2]); fmt::print("\n"); }
    for (int r : {10, 11, 12}) { int i0 = r * (cfg.m + 1); fmt::print("row {} cols 60..100 ey:", r);
      for (int c = 60; c <= 100; ++c) fmt::print(" {:.2f}", 100 * e[3*(i0+c)+1]); fmt::print("\n"); }
  }
  // how concentrated
  cum = 0; int k90 = 0;
  for (; k90 < n && cum < 0.9; ++k90) cum += mag[k90].first;
  fmt::print("90% of the mode in {} vertices\n", k90);
  // energy of mode e^T A e / e^T D e
}
