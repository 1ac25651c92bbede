#include "apps/bench_bending.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <string>
#include <thread>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "apps/bench_common.hpp"
#include "framework/build_info.hpp"
#include "apps/runner.hpp"
#include "framework/params_json.hpp"
#include "framework/scene.hpp"
#include "models/bending_autodiff.hpp"
#include "models/hinge_bending.hpp"
#include "policies/registry.hpp"

namespace weft::app {
namespace {

namespace fs = std::filesystem;
using models::BendingAssembly;


constexpr double ulp = 0x1p-53;  // the thesis' unit for the normwise Hessian differences
constexpr int num_methods = 3;
enum Method { refactored, per_hinge, autodiff };
constexpr const char* method_key[num_methods] = {"refactored", "per_hinge", "autodiff"};
constexpr const char* method_label[num_methods] = {"N (refactored)", "S (per hinge, closed form)", "A (forward-mode AD)"};
constexpr const char* pair_label[3] = {"N vs S", "N vs A", "S vs A"};

// Thesis chapter 5 (methods/shells §8): Table 5.2, cloth-sphere row, and Table 5.1.
constexpr double thesis_k = 1.062, thesis_ln_a[num_methods] = {-5.175, -4.129, -3.632};
constexpr double thesis_speedup_s = 2.85, thesis_speedup_a = 4.68;

/// min and median wall time of `reps` calls after one warm-up call.
struct Timing {
  double min = 0, median = 0;
  int reps = 0;
};

template <class F>
Timing time_it(F&& f, double budget, int max_reps) {
  f();  // warm-up
  std::vector<double> t;
  const auto start = Clock::now();
  while (t.size() < 3 || (seconds_since(start) < budget && static_cast<int>(t.size()) < max_reps)) {
    const auto t0 = Clock::now();
    f();
    t.push_back(seconds_since(t0));
  }
  std::sort(t.begin(), t.end());
  const size_t n = t.size();
  return {t[0], n % 2 ? t[n / 2] : 0.5 * (t[n / 2 - 1] + t[n / 2]), static_cast<int>(n)};
}

/// Everything measured at one resolution.
struct Resolution {
  int n = 0, vertices = 0, triangles = 0, hinges = 0, lone = 0;
  // recording run
  int steps = 0, newton = 0, assemblies = 0;
  double dt = 0, step_seconds = 0, sim_hessian_seconds = 0, linear_seconds = 0;  // totals over the run
  std::string failure;
  std::vector<double> max_theta, p99_theta;  // per recorded state
  std::vector<int> state_step;
  // Hessian agreement per recorded state [ulp]: N-S, N-A, S-A
  std::vector<std::array<double, 3>> ulps;
  // timings on the last recorded state
  Timing fh[num_methods], fha[num_methods];  // forces + Hessian; + assembly
  Timing fh_projected;  // forces + PSD-projected Hessian, per hinge (the only path of HessianMode::projected)
  double mean_step() const { return steps ? step_seconds / steps : 0; }
  double assemblies_per_step() const { return steps ? double(assemblies) / steps : 0; }
  /// Share of a full step in bending forces + Hessian + assembly for method m: the recording
  /// ran method N; for S and A the step time is corrected by the difference.
  double share(int m) const {
    const double per_step_n = assemblies_per_step() * fha[refactored].min, per_step_m = assemblies_per_step() * fha[m].min;
    const double step = mean_step() - per_step_n + per_step_m;
    return step > 0 ? per_step_m / step : 0;
  }
};

/// Least squares y = k x + b.
std::pair<double, double> fit_line(const std::vector<double>& x, const std::vector<double>& y) {
  const double mx = std::accumulate(x.begin(), x.end(), 0.0) / x.size(), my = std::accumulate(y.begin(), y.end(), 0.0) / y.size();
  double sxy = 0, sxx = 0;
  for (size_t i = 0; i < x.size(); ++i) sxy += (x[i] - mx) * (y[i] - my), sxx += (x[i] - mx) * (x[i] - mx);
  const double k = sxx > 0 ? sxy / sxx : std::nan("");
  return {k, my - k * mx};
}

/// The thesis' fit: one exponent k for all methods, then ln a per method.
struct Fit {
  double k_common = 0;
  double ln_a[num_methods] = {};   ///< with k_common
  double k_own[num_methods] = {};  ///< each method fitted alone
};
Fit fit_methods(const std::vector<double>& lx, const std::vector<double> (&ly)[num_methods]) {
  Fit f;
  const double mx = std::accumulate(lx.begin(), lx.end(), 0.0) / lx.size();
  double sxy = 0, sxx = 0;
  for (int m = 0; m < num_methods; ++m) {
    f.k_own[m] = fit_line(lx, ly[m]).first;
    const double my = std::accumulate(ly[m].begin(), ly[m].end(), 0.0) / ly[m].size();
    for (size_t i = 0; i < lx.size(); ++i) sxy += (lx[i] - mx) * (ly[m][i] - my), sxx += (lx[i] - mx) * (lx[i] - mx);
  }
  f.k_common = sxx > 0 ? sxy / sxx : std::nan("");
  for (int m = 0; m < num_methods; ++m)
    f.ln_a[m] = std::accumulate(ly[m].begin(), ly[m].end(), 0.0) / ly[m].size() - f.k_common * mx;
  return f;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string ms(const Timing& t) { return fmt::format("{:.3f} / {:.3f} ({})", 1e3 * t.min, 1e3 * t.median, t.reps); }

/// Record, compare and time one resolution.
template <class Angle>
Resolution run_resolution(int n, const std::string& scene_path, const std::vector<std::string>& base_overrides,
                          const BenchBendingOptions& opt, int record_steps, int num_states, double budget) {
  Resolution r;
  r.n = n;
  std::vector<std::string> overrides = base_overrides;
  overrides.push_back(fmt::format("cloths.0.mesh.resolution=[{},{}]", n, n));
  overrides.push_back(fmt::format("time.dt={:.17g}", opt.record_dt));
  // A frame interval that the recording time step divides.
  overrides.push_back(fmt::format("time.frame_rate={:.17g}", 1.0 / opt.record_dt));
  overrides.push_back(fmt::format("time.duration={:.17g}", (record_steps + 1) * opt.record_dt));
  const Scene loaded = load_scene(scene_path, overrides);
  std::unique_ptr<AnySimulator> sim = make_simulator(loaded);
  const Scene& scene = sim->scene();
  r.vertices = scene.mesh.num_vertices();
  r.triangles = scene.mesh.num_faces();
  r.dt = scene.spec.time.dt;

  // 1. Recording run (one thread, like every measurement here): step, keep the last states.
  std::vector<int> record_at;
  for (int k = 0; k < num_states; ++k) record_at.push_back(record_steps - (num_states - 1 - k) * std::max(1, record_steps / (2 * num_states)));
  std::vector<State> states;
  for (int step = 1; step <= record_steps; ++step) {
    const auto t0 = Clock::now();
    const StepReport rep = sim->step();
    const double t = seconds_since(t0);
    if (!rep.ok()) {
      r.failure = fmt::format("step {} failed in {}: {}", step, rep.failed_stage, rep.message);
      break;
    }
    ++r.steps;
    r.step_seconds += t;
    r.sim_hessian_seconds += rep.times[Stage::hessian];
    r.linear_seconds += rep.times[Stage::linear_setup] + rep.times[Stage::linear_solve];
    r.newton += rep.newton.iterations;
    // One assembly per Newton iteration, plus one more when the adaptive Hessian fell back to projection.
    r.assemblies += rep.newton.iterations;
    for (const auto& it : rep.newton.history) r.assemblies += it.projected ? 1 : 0;
    if (std::find(record_at.begin(), record_at.end(), step) != record_at.end()) {
      states.push_back(sim->state());
      r.state_step.push_back(step);
    }
  }
  if (states.empty()) states.push_back(sim->state());  // the run failed before the first recorded step
  if (r.state_step.empty()) r.state_step.push_back(r.steps);

  // 2. The bending model of the combination, alone in its own assembly plan.
  // P times the eigen-projection per hinge (the default Gauss-Newton projection needs no eigen-solve).
  models::HingeBending<Angle> model(scene, {.projection = models::BendingProjection::eigen});
  r.hinges = model.num_hinges();
  r.lone = model.num_lone_triangles();
  AssemblyPlan plan;
  model.declare(plan);
  plan.finalize(scene.mesh.num_vertices());
  // Stored mode: "f+H" fills every element's slot, "+assembly" adds the gather (thesis Table 5.x).
  ElementBuffer buf = plan.make_buffer(AssemblyMode::stored);
  BlockCsr H[num_methods] = {plan.pattern(), plan.pattern(), plan.pattern()};
  Eigen::VectorXd g = Eigen::VectorXd::Zero(3 * r.vertices);
  auto evaluate = [&](int m, const State& s, Eigen::VectorXd* grad) {
    if (m == autodiff)
      models::bending::autodiff_evaluate(model, s, grad, &buf);
    else
      model.evaluate(s, grad, &buf, HessianMode::exact, m == refactored ? BendingAssembly::refactored : BendingAssembly::per_hinge);
  };

  // 3. Angles and Hessian agreement on every recorded state.
  for (const State& s : states) {
    std::vector<double> th(r.hinges);
    for (int i = 0; i < r.hinges; ++i) th[i] = std::abs(model.angle(s, i));
    std::sort(th.begin(), th.end());
    r.max_theta.push_back(th.empty() ? 0 : th.back());
    r.p99_theta.push_back(th.empty() ? 0 : th[static_cast<size_t>(0.99 * (th.size() - 1))]);
    for (int m = 0; m < num_methods; ++m) {
      evaluate(m, s, nullptr);
      plan.gather(buf, H[m]);
    }
    auto diff = [&](int a, int b) {
      const Eigen::Map<const Eigen::VectorXd> va(H[a].values().data(), H[a].values().size()), vb(H[b].values().data(), H[b].values().size());
      return (va - vb).norm() / va.norm() / ulp;
    };
    r.ulps.push_back({diff(refactored, per_hinge), diff(refactored, autodiff), diff(per_hinge, autodiff)});
  }

  // 4. Timings on the last recorded state.
  const State& s = states.back();
  for (int m = 0; m < num_methods; ++m) {
    r.fh[m] = time_it(
        [&] {
          g.setZero();
          evaluate(m, s, &g);
        },
        budget, opt.max_reps);
    r.fha[m] = time_it(
        [&] {
          g.setZero();
          evaluate(m, s, &g);
          plan.gather(buf, H[m]);
        },
        budget, opt.max_reps);
  }
  // The PSD-projected Hessian (integrator.hessian = projected and its fallbacks): per hinge,
  // one eigen decomposition per hinge. Not in the thesis.
  r.fh_projected = time_it(
      [&] {
        g.setZero();
        model.evaluate(s, &g, &buf, HessianMode::projected, BendingAssembly::per_hinge);
      },
      budget, opt.max_reps);
  return r;
}

}  // namespace

int bench_bending(const BenchBendingOptions& opt_in) {
  BenchBendingOptions opt = opt_in;
  const std::string data = app::data_dir();
  if (opt.scene.empty()) opt.scene = (fs::path(data) / "scenes" / "hanging_cloth.json").string();
  if (!fs::exists(opt.scene)) {
    fmt::print(stderr, "error: scene {} not found: pass --scene path/to/scenes/hanging_cloth.json (or set WEFT_DATA_DIR)\n",
               opt.scene);
    return exit_config;
  }
  const fs::path out = opt.out_dir.empty() ? fs::path("out/bench_bending") : fs::path(opt.out_dir);
  const double budget = opt.budget >= 0 ? opt.budget : opt.quick ? 0.02 : 0.2;
  const int num_states = opt.quick ? 1 : std::max(1, opt.states);
  const int record_steps = opt.quick ? 4 : std::max(1, static_cast<int>(std::lround(opt.record_time / opt.record_dt)));
  std::vector<int> resolutions = opt.resolutions;
  if (!resolutions.empty())
    ;
  else if (opt.quick)
    resolutions = {11, 15, 19, 23};
  else
    for (int n = 11; n <= 81; n += 2) resolutions.push_back(n);
  // Output files off; everything else is the scene as shipped.
  const std::vector<std::string> base_overrides = {"output.obj=false", "output.vtp=false", "output.stats=false"};

  const int hw_threads = static_cast<int>(std::thread::hardware_concurrency());
#ifdef _OPENMP
  const int omp_threads = omp_get_max_threads();
  omp_set_num_threads(1);  // every measurement on one core, as in the thesis
#else
  const int omp_threads = 1;
#endif

  std::string combo, energy;
  bool tan = false, obstacles = false;
  try {
    const Scene probe = load_scene(opt.scene, base_overrides);
    combo = probe.spec.combo;
    obstacles = !probe.spec.obstacles.empty();
    for (const auto& c : combos())
      if (c.key == combo) energy = std::string(c.energy);
    tan = energy.find("bending(tan)") != std::string::npos;
  } catch (const ConfigError& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return exit_config;
  }

  std::vector<Resolution> res;
  const auto wall0 = Clock::now();
  try {
    for (int n : resolutions) {
      const auto t0 = Clock::now();
      res.push_back(tan ? run_resolution<models::TanEnergy>(n, opt.scene, base_overrides, opt, record_steps, num_states, budget)
                        : run_resolution<models::ThetaEnergy>(n, opt.scene, base_overrides, opt, record_steps, num_states, budget));
      const Resolution& r = res.back();
      fmt::print(stderr, "bench bending: n = {:2d}: {} steps recorded{}, {:.1f} s\n", n, r.steps,
                 r.failure.empty() ? "" : " (" + r.failure + ")", seconds_since(t0));
    }
  } catch (const ConfigError& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return exit_config;
  }
#ifdef _OPENMP
  omp_set_num_threads(omp_threads);
#endif
  const double wall = seconds_since(wall0);

  // Fits over the resolutions: f in ms per evaluation, x = vertices.
  std::vector<double> lx, ly_fh[num_methods], ly_fha[num_methods];
  for (const auto& r : res) {
    lx.push_back(std::log(static_cast<double>(r.vertices)));
    for (int m = 0; m < num_methods; ++m) {
      ly_fh[m].push_back(std::log(1e3 * r.fh[m].min));
      ly_fha[m].push_back(std::log(1e3 * r.fha[m].min));
    }
  }
  const Fit fit_fh = fit_methods(lx, ly_fh), fit_fha = fit_methods(lx, ly_fha);
  std::vector<double> all_ulps[3];
  for (const auto& r : res)
    for (const auto& u : r.ulps)
      for (int p = 0; p < 3; ++p) all_ulps[p].push_back(u[p]);

  // ---- Markdown report ----
  const std::string cpu = cpu_model(), git = build_commit();
  std::string md;
  auto w = [&md](const std::string& s) { md += s; };
  w("# weft bench bending: thesis Tables 5.1 and 5.2 (methods/shells §8)\n\n");
  const std::string states_at = fmt::format("{}", fmt::join(res.empty() ? std::vector<int>{} : res.front().state_step, ", "));
  if (obstacles)
    w(fmt::format("**Configurations: recorded states of {}** at each resolution (combo `{}`: {}; recording run dt = {:.4g} s, {} "
                  "steps, states after steps {}). Bending energy: `HingeBending<{}>`.\n\n",
                  opt.scene, combo, energy, opt.record_dt, record_steps, states_at, tan ? "TanEnergy" : "ThetaEnergy"));
  else
    w(fmt::format(
        "**Configurations: recorded states of a HANGING CLOTH** ({} at each resolution, combo `{}`: {}; recording run "
        "dt = {:.4g} s, {} steps, states after steps {}), **not** the thesis' cloth-sphere drape: cloth-sphere contact does not "
        "exist in weft yet. Bending energy: `HingeBending<{}>`.\n\n",
        opt.scene, combo, energy, opt.record_dt, record_steps, states_at, tan ? "TanEnergy" : "ThetaEnergy"));
  w(fmt::format("Hardware: {}; {} hardware threads; measurements on 1 thread (OpenMP default here: {}). Compiler: {} `{}`; git {}.\n\n",
                cpu, hw_threads, omp_threads, __VERSION__, build_flags(), git));
  w(fmt::format("Protocol: one warm-up call, then at least 3 and at most {} repetitions within {:.3g} s per resolution and method; "
                "times are min / median [ms] with the repetition count in parentheses. \"forces + Hessian\" = gradient and "
                "element Hessians into the `ElementBuffer`; \"+ assembly\" adds `AssemblyPlan::gather` into the `BlockCsr` "
                "(bending groups only). Methods: N = refactored per triangle (default), S = closed form per hinge (stands in "
                "for the thesis' symbolic code), A = forward-mode AD of theta (nested `Eigen::AutoDiffScalar`, 12-vectors).{}\n\n",
                opt.max_reps, budget, opt.quick ? " **--quick: reduced run (4 resolutions, 1 state).**" : ""));

  w("## Recording runs\n\n| n | vertices | triangles | hinges | steps | Newton its | Hessian assemblies | full step [s] (mean over steps) | "
    "linear solver / Hessian stage share of the step | max abs theta [rad] (per state) | p99 abs theta |\n"
    "|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& r : res) {
    std::vector<std::string> mt, pt;
    for (double t : r.max_theta) mt.push_back(fmt::format("{:.3f}", t));
    for (double t : r.p99_theta) pt.push_back(fmt::format("{:.3f}", t));
    w(fmt::format("| {} | {} | {} | {} | {}{} | {} | {} | {:.4f} ({} steps) | {:.0f}% / {:.1f}% | {} | {} |\n", r.n, r.vertices,
                  r.triangles, r.hinges, r.steps, r.failure.empty() ? "" : " (failed: " + r.failure + ")", r.newton, r.assemblies,
                  r.mean_step(), r.steps, r.step_seconds > 0 ? 100 * r.linear_seconds / r.step_seconds : 0.0,
                  r.step_seconds > 0 ? 100 * r.sim_hessian_seconds / r.step_seconds : 0.0, fmt::join(mt, ", "), fmt::join(pt, ", ")));
  }

  for (int with_asm = 0; with_asm < 2; ++with_asm) {
    w(with_asm ? "\n## Bending forces + Hessian + assembly, one thread\n\n" : "\n## Bending forces + Hessian (no assembly), one thread\n\n");
    w("| n | N [ms] | S [ms] | A [ms] | S/N | A/N | N hinges/s | N triangles/s | S hinges/s | A hinges/s |\n"
      "|---|---|---|---|---|---|---|---|---|---|\n");
    for (const auto& r : res) {
      const Timing* t = with_asm ? r.fha : r.fh;
      w(fmt::format("| {} | {} | {} | {} | {:.2f} | {:.2f} | {:.3g} | {:.3g} | {:.3g} | {:.3g} |\n", r.n, ms(t[0]), ms(t[1]), ms(t[2]),
                    t[1].min / t[0].min, t[2].min / t[0].min, r.hinges / t[0].min, r.triangles / t[0].min, r.hinges / t[1].min,
                    r.hinges / t[2].min));
    }
  }

  w("\n## PSD-projected Hessian (not in the thesis), forces + Hessian, one thread\n\n"
    "P = per hinge with each hinge's 12x12 Hessian projected onto the PSD cone (`HessianMode::projected`, used by "
    "`integrator.hessian = projected` and by the adaptive Hessian's fallback): an eigen decomposition per hinge, on the "
    "9-dim complement of the translations.\n\n"
    "| n | N [ms] | S [ms] | P [ms] | P/S | P/N | P hinges/s |\n|---|---|---|---|---|---|---|\n");
  for (const auto& r : res)
    w(fmt::format("| {} | {} | {} | {} | {:.2f} | {:.2f} | {:.3g} |\n", r.n, ms(r.fh[refactored]), ms(r.fh[per_hinge]), ms(r.fh_projected),
                  r.fh_projected.min / r.fh[per_hinge].min, r.fh_projected.min / r.fh[refactored].min, r.hinges / r.fh_projected.min));

  auto speed = [](const Fit& f, int m) { return std::exp(f.ln_a[m] - f.ln_a[refactored]); };
  w("\n## Table 5.2: fit ln f = k ln(vertices) + ln a (f = min time per evaluation [ms]; common k, then ln a per method)\n\n");
  w("| quantity | thesis, cloth-sphere (forces + Jacobians + assembly) | ours, forces + Hessian + assembly | ours, forces + Hessian |\n"
    "|---|---|---|---|\n");
  w(fmt::format("| k (common) | {:.3f} | {:.3f} | {:.3f} |\n", thesis_k, fit_fha.k_common, fit_fh.k_common));
  for (int m = 0; m < num_methods; ++m)
    w(fmt::format("| k, {} alone | - | {:.3f} | {:.3f} |\n", method_label[m], fit_fha.k_own[m], fit_fh.k_own[m]));
  for (int m = 0; m < num_methods; ++m)
    w(fmt::format("| ln a, {} | {:.3f} (unit unknown) | {:.3f} | {:.3f} |\n", method_label[m], thesis_ln_a[m], fit_fha.ln_a[m],
                  fit_fh.ln_a[m]));
  w(fmt::format("| speedup of N vs S, exp(ln a_S - ln a_N) | {:.2f} | {:.2f} | {:.2f} (thesis, forces + Jacobians alone: 3-4) |\n",
                thesis_speedup_s, speed(fit_fha, per_hinge), speed(fit_fh, per_hinge)));
  w(fmt::format("| speedup of N vs A, exp(ln a_A - ln a_N) | {:.2f} | {:.2f} | {:.2f} (thesis, forces + Jacobians alone: up to ~7) |\n",
                thesis_speedup_a, speed(fit_fha, autodiff), speed(fit_fh, autodiff)));

  w("\n## Hessian agreement: ||H_a - H_b||_F / ||H_a||_F in ulp (2^-53), over every recorded state\n\n"
    "| pair | thesis typical | thesis max | ours median | ours max | states |\n|---|---|---|---|---|---|\n");
  for (int p = 0; p < 3; ++p) {
    const double mx = all_ulps[p].empty() ? 0 : *std::max_element(all_ulps[p].begin(), all_ulps[p].end());
    w(fmt::format("| {} | 1-2 | 4.9 | {:.2f} | {:.2f} | {} |\n", pair_label[p], median(all_ulps[p]), mx, all_ulps[p].size()));
  }

  w("\n## Table 5.1: share of a full time step in bending forces + Hessian + assembly\n\n"
    "Share = (Hessian assemblies per step) x (min time of forces + Hessian + assembly) / (full step time); the recording run "
    "used N, so for S and A the step time is corrected by the difference. Full step = `Simulator::step` of the recording run "
    "(one thread, direct sparse LDL^T).\n\n"
    "| method | thesis, cloth-sphere | thesis, beams | ours, min-max over resolutions | ours, largest resolution |\n|---|---|---|---|---|\n");
  const char* thesis_share[num_methods][2] = {{"4-6%", "9-12%"}, {"9-15%", "17-23%"}, {"14-22%", "26-33%"}};
  for (int m = 0; m < num_methods; ++m) {
    double lo = 1, hi = 0;
    for (const auto& r : res)
      if (r.steps > 0) lo = std::min(lo, r.share(m)), hi = std::max(hi, r.share(m));
    w(fmt::format("| {} | {} | {} | {:.1f}-{:.1f}% | {:.1f}% |\n", method_label[m], thesis_share[m][0], thesis_share[m][1], 100 * lo,
                  100 * hi, res.empty() ? 0.0 : 100 * res.back().share(m)));
  }
  w(fmt::format("\nTotal wall time {:.1f} s. Files: {}/bench_bending.jsonl, bench_bending.csv, bench_bending.md\n", wall, out.string()));
  fmt::print("{}", md);

  // ---- Files ----
  try {
    fs::create_directories(out);
    std::ofstream jl(out / "bench_bending.jsonl"), csv(out / "bench_bending.csv"), mdf(out / "bench_bending.md");
    mdf << md;
    csv << "n,vertices,triangles,hinges,method,fh_min_s,fh_median_s,fh_reps,fha_min_s,fha_median_s,fha_reps,hinges_per_s,"
           "triangles_per_s,steps,newton,assemblies,mean_step_s,bending_share,max_theta,ulp_ns_max,ulp_na_max,ulp_sa_max\n";
    for (const auto& r : res) {
      double umax[3] = {0, 0, 0};
      for (const auto& u : r.ulps)
        for (int p = 0; p < 3; ++p) umax[p] = std::max(umax[p], u[p]);
      const double max_theta = r.max_theta.empty() ? 0 : *std::max_element(r.max_theta.begin(), r.max_theta.end());
      for (int m = 0; m < num_methods; ++m) {
        Json j{{"bench", "bending"},
               {"git", git},
               {"compiler", __VERSION__},
               {"flags", build_flags()},
               {"cpu", cpu},
               {"threads", 1},
               {"scene", opt.scene},
               {"combo", combo},
               {"configurations", "hanging cloth (recorded), not cloth-sphere"},
               {"record_dt", r.dt},
               {"quick", opt.quick},
               {"n", r.n},
               {"vertices", r.vertices},
               {"triangles", r.triangles},
               {"hinges", r.hinges},
               {"method", method_key[m]},
               {"forces_hessian", {{"min_s", r.fh[m].min}, {"median_s", r.fh[m].median}, {"reps", r.fh[m].reps}}},
               {"forces_hessian_assembly", {{"min_s", r.fha[m].min}, {"median_s", r.fha[m].median}, {"reps", r.fha[m].reps}}},
               {"hinges_per_s", r.hinges / r.fh[m].min},
               {"projected_forces_hessian",
                {{"min_s", r.fh_projected.min}, {"median_s", r.fh_projected.median}, {"reps", r.fh_projected.reps}}},
               {"triangles_per_s", r.triangles / r.fh[m].min},
               {"recording", {{"steps", r.steps}, {"newton_iterations", r.newton}, {"assemblies", r.assemblies},
                              {"step_seconds_total", r.step_seconds}, {"failure", r.failure}}},
               {"bending_share", r.share(m)},
               {"max_theta", r.max_theta},
               {"ulp", {{"refactored_per_hinge", umax[0]}, {"refactored_autodiff", umax[1]}, {"per_hinge_autodiff", umax[2]}}}};
        jl << j.dump() << "\n";
        csv << fmt::format("{},{},{},{},{},{:.6e},{:.6e},{},{:.6e},{:.6e},{},{:.6e},{:.6e},{},{},{},{:.6e},{:.6e},{:.6e},{:.4f},{:.4f},{:.4f}\n",
                           r.n, r.vertices, r.triangles, r.hinges, method_key[m], r.fh[m].min, r.fh[m].median, r.fh[m].reps,
                           r.fha[m].min, r.fha[m].median, r.fha[m].reps, r.hinges / r.fh[m].min, r.triangles / r.fh[m].min, r.steps,
                           r.newton, r.assemblies, r.mean_step(), r.share(m), max_theta, umax[0], umax[1], umax[2]);
      }
    }
    Json fitj{{"bench", "bending"}, {"fit", "ln f = k ln vertices + ln a, f in ms"}, {"git", git}, {"quick", opt.quick}};
    for (int a = 0; a < 2; ++a) {
      const Fit& f = a ? fit_fha : fit_fh;
      Json j{{"k_common", f.k_common}};
      for (int m = 0; m < num_methods; ++m) j[method_key[m]] = {{"k_own", f.k_own[m]}, {"ln_a", f.ln_a[m]}, {"speedup", speed(f, m)}};
      fitj[a ? "forces_hessian_assembly" : "forces_hessian"] = j;
    }
    jl << fitj.dump() << "\n";
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: cannot write {}: {}\n", out.string(), e.what());
    return exit_config;
  }
  return exit_ok;
}

}  // namespace weft::app
