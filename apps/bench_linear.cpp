#include "apps/bench_linear.hpp"

#include <fmt/format.h>
#include <malloc.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "apps/bench_linear_systems.hpp"
#include "apps/bench_common.hpp"
#include "framework/build_info.hpp"
#include "apps/runner.hpp"
#include "framework/params_json.hpp"
#include "linear/sa_amg.hpp"

namespace weft::app {
namespace {

using namespace benchlin;
namespace fs = std::filesystem;

constexpr int thesis_m[12] = {30, 40, 60, 80, 100, 150, 200, 300, 400, 600, 800, 1000};
constexpr double fps = 30.0;  // the thesis's frame rate is not stated (methods/multigrid §10.1)

// Thesis Table 11.1 (methods/multigrid §10.3): SA+PPCG speedup vs Diag-PCG and vs PARDISO, per
// tessellation (0 regular, 1 irregular), size (thesis_m order) and example.
constexpr double thesis_vs_diag[2][12][5] = {
    {{0.39, 0.58, 0.55, 0.57, 0.53}, {0.45, 0.63, 0.60, 0.57, 0.51}, {0.40, 0.50, 0.54, 0.62, 0.35}, {0.43, 0.53, 0.50, 0.65, 0.35},
     {0.54, 0.66, 0.72, 0.77, 0.40}, {0.85, 1.03, 1.02, 1.07, 0.50}, {1.07, 1.35, 1.36, 1.40, 0.60}, {2.23, 2.87, 2.67, 2.27, 2.35},
     {3.89, 5.01, 4.87, 3.64, 1.14}, {5.48, 7.10, 6.38, 4.70, 2.29}, {7.12, 9.28, 8.84, 6.09, 3.46}, {9.20, 11.64, 10.89, 7.53, 3.01}},
    {{0.43, 0.49, 0.51, 0.52, 0.56}, {0.46, 0.52, 0.62, 0.60, 0.54}, {0.43, 0.46, 0.55, 0.56, 0.38}, {0.46, 0.50, 0.56, 0.69, 0.44},
     {0.56, 0.61, 0.67, 0.89, 0.53}, {0.81, 0.87, 0.97, 1.13, 0.57}, {1.22, 1.19, 1.43, 1.33, 0.76}, {2.32, 2.51, 2.36, 2.20, 1.29},
     {3.78, 4.20, 4.22, 3.26, 2.03}, {5.32, 5.98, 6.13, 4.63, 2.63}, {7.02, 7.84, 7.72, 5.93, 2.39}, {8.97, 9.82, 9.59, 5.74, 2.81}}};
constexpr double thesis_vs_pardiso[2][12][5] = {
    {{0.76, 0.72, 0.72, 0.61, 0.61}, {1.06, 0.99, 0.95, 0.75, 0.80}, {1.31, 1.18, 1.17, 0.96, 0.94}, {1.51, 1.35, 1.31, 1.14, 1.04},
     {1.78, 1.57, 1.53, 1.37, 1.06}, {2.23, 1.89, 1.86, 1.69, 1.14}, {2.29, 2.03, 2.01, 1.89, 1.18}, {2.27, 2.07, 1.95, 1.92, 1.11},
     {2.14, 1.95, 1.92, 1.84, 0.77}, {2.21, 2.01, 1.76, 1.85, 1.32}, {2.26, 2.10, 1.96, 1.89, 1.53}, {2.40, 2.20, 2.04, 2.13, 1.80}},
    {{0.87, 0.80, 0.80, 0.64, 0.71}, {1.17, 1.12, 1.04, 0.94, 1.01}, {1.61, 1.45, 1.39, 1.21, 1.06}, {1.86, 1.65, 1.72, 1.44, 1.32},
     {2.06, 1.87, 1.93, 1.74, 1.42}, {2.49, 2.11, 2.20, 2.13, 1.43}, {2.61, 2.21, 2.32, 2.23, 1.56}, {2.54, 2.21, 2.33, 2.19, 1.39},
     {2.45, 2.18, 2.16, 2.10, 1.39}, {2.49, 2.22, 2.21, 2.13, 1.57}, {2.56, 2.24, 2.19, 2.21, 1.68}, {2.73, 2.56, 2.47, 2.08, 1.71}}};

// ---- memory ----
/// Resets the kernel's peak-RSS mark of this process (Linux >= 4.0); false if unsupported.
bool reset_peak_rss() {
  std::ofstream f("/proc/self/clear_refs");
  if (!f) return false;
  f << "5";
  return static_cast<bool>(f.flush());
}
/// A "Key:  N kB" line of a /proc/self file in MB (-1: unavailable).
double proc_kb_line_mb(const char* file, const char* key) {
  std::ifstream f(file);
  std::string line;
  while (std::getline(f, line))
    if (line.rfind(key, 0) == 0) return std::atof(line.c_str() + std::strlen(key)) / 1024.0;
  return -1;
}
/// A "VmXXX:  N kB" line of /proc/self/status in MB (-1: unavailable).
double proc_status_mb(const char* key) { return proc_kb_line_mb("/proc/self/status", key); }
double rusage_peak_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss / 1024.0;  // kB on Linux
}

// ---- bandwidth ----
/// STREAM-like triad a = b + s c over 3 arrays of `n` doubles (first-touch initialised by the
/// same threads), best of `reps`; bytes = 3 * 8 * n per triad (no write-allocate counted).
double stream_triad_gbs(std::size_t n, int reps) {
  std::unique_ptr<double[]> a(new double[n]), b(new double[n]), c(new double[n]);
  const long long nn = static_cast<long long>(n);
#pragma omp parallel for schedule(static)
  for (long long i = 0; i < nn; ++i) a[i] = 0, b[i] = 1.0, c[i] = 2.0;
  double best = 1e300;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = Clock::now();
    const double s = 3.0 + r;
#pragma omp parallel for schedule(static)
    for (long long i = 0; i < nn; ++i) a[i] = b[i] + s * c[i];
    best = std::min(best, seconds_since(t0));
  }
  volatile double sink = a[n / 2];
  (void)sink;
  return 3.0 * 8.0 * static_cast<double>(n) / best / 1e9;
}

/// Bytes one BlockCsr product y = A x moves at least: values 72 per block, column index 4 per
/// block, row pointer 4 per row, x read once and y written once (3 * 8 per row each).
double spmv_bytes(const BlockCsr& A) {
  return 76.0 * A.num_blocks() + 4.0 * (A.block_rows() + 1) + 48.0 * A.block_rows();
}
/// Bytes the system matrix A holds (values, column indices, row pointers, diagonal positions):
/// what every solver's user pays before any solver memory (the matrix is shared, not owned).
std::size_t matrix_bytes(const BlockCsr& A) {
  const std::size_t n = static_cast<std::size_t>(A.block_rows());
  return sizeof(double) * A.values().capacity() + sizeof(int) * (A.col().capacity() + A.row_ptr().capacity() + n);
}
/// Best time of y = A x over repetitions (at least 3, about 0.1 s).
double spmv_seconds(const BlockCsr& A) {
  Eigen::VectorXd x = Eigen::VectorXd::Ones(A.rows()), y(A.rows());
  A.multiply(x, y);  // warm-up
  double best = 1e300, total = 0;
  for (int r = 0; r < 200 && (r < 3 || total < 0.1); ++r) {
    const auto t0 = Clock::now();
    A.multiply(x, y);
    const double t = seconds_since(t0);
    best = std::min(best, t), total += t;
  }
  return best;
}

// ---- results ----
struct SolverStats {
  std::string key, label;
  bool direct = false;
  int solves = 0, failures = 0, analyses = 0;
  std::vector<double> setup, solve, total, prefilter;  // per solve [s]
  double iterations = 0;      // sum
  double rate = 0;            // sum over iterative solves
  int rate_count = 0;
  double energy = 0, energy_max = 0;  // own ||x - x*||_A / ||x*||_A
  int energy_count = 0;
  double violation_max = 0, relres_max = 0;
  std::size_t memory_max = 0;
  int levels = 0;
  double operator_complexity = 0;
  std::vector<weft::linear::SaLevelStats> hierarchy;  // of the first setup (multigrid only)
  std::map<std::string, double> setup_split;    // summed over the setups (multigrid only)
  std::string message;  // first failure
  static double mean(const std::vector<double>& v) { return v.empty() ? 0 : std::accumulate(v.begin(), v.end(), 0.0) / v.size(); }
  static double median(std::vector<double> v) {
    if (v.empty()) return 0;
    std::sort(v.begin(), v.end());
    return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
  }
  double mean_total() const { return mean(total); }
  double mean_iterations() const { return solves ? iterations / solves : 0; }
  double mean_rate() const { return rate_count ? rate / rate_count : 0; }
  double mean_energy() const { return energy_count ? energy / energy_count : -1; }
  /// Seconds per setup by phase (every solve has its setup).
  std::map<std::string, double> mean_setup_split() const {
    std::map<std::string, double> out;
    for (const auto& [phase, seconds] : setup_split) out[phase] = solves > 0 ? seconds / solves : 0.0;
    return out;
  }
};

struct CaseResult {
  Example example = Example::pinned;
  Tessellation tessellation = Tessellation::regular;
  int m = 0, vertices = 0, faces = 0, steps_planned = 0, steps_done = 0;
  long long box_contacts = 0, springs = 0;  // sums over steps
  int max_box_contacts = 0, max_springs = 0, pattern_changes = 0, pinned = 0, projected = 0, released = 0;
  double assembly_seconds = 0, detect_seconds = 0, wall_seconds = 0;  // sums / total
  double rss_before_mb = 0, assembly_peak_mb = -1, case_peak_mb = -1, process_peak_mb = 0;
  double assembly_huge_mb = -1;  ///< AnonHugePages after the first assembly (heap_pages in the meta record)
  double spmv_gbs = 0, spmv_mbytes = 0;
  int blocks = 0;
  std::size_t matrix_bytes = 0;  // A of the last step
  std::string reference, failure;
  std::vector<SolverStats> solvers;
  const SolverStats* find(const std::string& key) const {
    for (const auto& s : solvers)
      if (s.key == key && s.solves > 0) return &s;
    return nullptr;
  }
};

int thesis_index(int m) {
  for (int k = 0; k < 12; ++k)
    if (thesis_m[k] == m) return k;
  return -1;
}

std::optional<Example> parse_example(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), ::tolower);
  s.erase(std::remove_if(s.begin(), s.end(), [](char c) { return c == '-' || c == '_'; }), s.end());
  if (s == "pinned") return Example::pinned;
  if (s == "drooping") return Example::drooping;
  if (s == "reentrant") return Example::reentrant;
  if (s == "drophorizontal") return Example::drop_horizontal;
  if (s == "dropvertical") return Example::drop_vertical;
  return std::nullopt;
}

std::string tess_name(Tessellation t) { return std::string(tessellation_names[static_cast<int>(t)]); }
std::string ex_name(Example e) { return std::string(example_names[static_cast<int>(e)]); }

/// One (example, tessellation, size): simulate, solve each step's system with every solver.
CaseResult run_case(const ExampleConfig& cfg, const std::vector<SolverEntry>& entries, int steps, bool reference_is_direct) {
  CaseResult r;
  r.example = cfg.example;
  r.tessellation = cfg.tessellation;
  r.m = cfg.m;
  r.steps_planned = steps;
  r.reference = entries.front().key;
  malloc_trim(0);  // give freed heap back, so that RSS before the case is this case's baseline
  const bool peak_reset = reset_peak_rss();
  r.rss_before_mb = proc_status_mb("VmRSS:");
  const auto wall0 = Clock::now();
  LinearBenchSimulation sim(cfg);
  r.vertices = sim.num_vertices();
  r.faces = sim.num_faces();
  std::vector<std::unique_ptr<AnySolver>> solvers;
  for (const auto& e : entries) {
    solvers.push_back(e.make());
    SolverStats s;
    s.key = e.key, s.label = e.label, s.direct = e.direct;
    r.solvers.push_back(s);
  }
  const int n = sim.num_vertices();
  std::vector<Eigen::VectorXd> xs(entries.size(), Eigen::VectorXd::Zero(3 * n));
  Eigen::VectorXd x_ref, e, Ae;
  double ref_norm = 0;
  for (int step = 1; step <= steps; ++step) {
    StepCounts c = sim.build_system();
    if (step == 1 && peak_reset) r.assembly_peak_mb = proc_status_mb("VmHWM:");
    if (step == 1) r.assembly_huge_mb = proc_kb_line_mb("/proc/self/smaps_rollup", "AnonHugePages:");
    r.assembly_seconds += c.assembly_seconds;
    r.detect_seconds += c.detect_seconds;
    r.box_contacts += c.box_contacts, r.max_box_contacts = std::max(r.max_box_contacts, c.box_contacts);
    r.springs += c.springs, r.max_springs = std::max(r.max_springs, c.springs);
    r.pattern_changes += c.pattern_changed ? 1 : 0;
    r.pinned = c.pinned;
    const SolveContext ctx = sim.context();
    const BlockCsr& A = sim.A();
    bool have_ref = false;
    for (size_t k = 0; k < solvers.size(); ++k) {
      AnySolver& sol = *solvers[k];
      SolverStats& st = r.solvers[k];
      Eigen::VectorXd& x = xs[k];
      x.setZero(3 * n);
      Status status = Status::success;
      std::string msg;
      auto t0 = Clock::now();
      if (c.pattern_changed) {
        status = sol.analyze_pattern(A);
        ++st.analyses;
        if (status != Status::success) msg = "analyze_pattern failed";
      }
      sol.set_context(ctx);
      sol.begin_step();
      if (status == Status::success) {
        status = sol.factorize(A);
        if (status != Status::success) msg = "factorize failed";
      }
      const double setup = seconds_since(t0);
      if (k > 0) sol.set_reference(have_ref ? &x_ref : nullptr);
      t0 = Clock::now();
      LinearReport rep = sol.solve(sim.b(), x);
      const double solve = seconds_since(t0);
      if (status == Status::success) status = rep.status;
      if (msg.empty() && status != Status::success) msg = rep.message;
      const bool ok = status == Status::success && x.allFinite();
      ++st.solves;
      st.setup.push_back(setup), st.solve.push_back(solve), st.total.push_back(setup + solve);
      st.prefilter.push_back(rep.prefilter_seconds);
      st.iterations += rep.iterations;
      if (!st.direct && rep.iterations > 0) st.rate += rep.convergence_rate, ++st.rate_count;
      st.memory_max = std::max(st.memory_max, rep.memory_bytes);
      st.levels = std::max(st.levels, rep.levels);
      st.operator_complexity = std::max(st.operator_complexity, rep.operator_complexity);
      if (st.hierarchy.empty()) st.hierarchy = sol.hierarchy();
      for (const auto& [phase, seconds] : sol.setup_split()) st.setup_split[phase] += seconds;
      st.relres_max = std::max(st.relres_max, rep.relative_residual);
      if (!ok) {
        if (st.failures++ == 0) st.message = fmt::format("step {}: {} ({})", step, msg.empty() ? "non-finite solution" : msg, to_string(status));
      }
      if (x.allFinite()) st.violation_max = std::max(st.violation_max, sim.constraints().violation(x));
      if (k == 0) {
        if (ok && reference_is_direct) {
          x_ref = x;
          A.multiply(x_ref, Ae);
          ref_norm = std::sqrt(std::max(0.0, x_ref.dot(Ae)));
          have_ref = ref_norm > 0;
        }
      } else if (have_ref && x.allFinite()) {
        e = x - x_ref;
        A.multiply(e, Ae);
        const double err = std::sqrt(std::max(0.0, e.dot(Ae))) / ref_norm;
        st.energy += err, st.energy_max = std::max(st.energy_max, err), ++st.energy_count;
      }
    }
    if (r.solvers.front().failures > 0) {
      r.failure = fmt::format("the reference solver {} failed: {}", r.reference, r.solvers.front().message);
      break;
    }
    try {
      sim.advance(xs.front(), c);
    } catch (const std::exception& ex) {
      r.failure = fmt::format("step {}: {}", step, ex.what());
      break;
    }
    r.projected += c.projected, r.released += c.released;
    ++r.steps_done;
  }
  r.wall_seconds = seconds_since(wall0);
  r.blocks = sim.A().num_blocks();
  r.matrix_bytes = matrix_bytes(sim.A());
  const double bytes = spmv_bytes(sim.A());
  r.spmv_mbytes = bytes / 1e6;
  r.spmv_gbs = bytes / spmv_seconds(sim.A()) / 1e9;
  r.case_peak_mb = peak_reset ? proc_status_mb("VmHWM:") : -1;
  r.process_peak_mb = rusage_peak_mb();
  return r;
}

/// The hierarchy as the jsonl records it: one object per level, finest first.
Json hierarchy_json(const std::vector<weft::linear::SaLevelStats>& levels) {
  Json out = Json::array();
  for (const weft::linear::SaLevelStats& l : levels)
    out.push_back({{"nodes", l.rows}, {"block_size", l.block_size}, {"blocks", l.nnz_blocks}, {"special", l.special},
                   {"aggregates", l.aggregates}, {"max_aggregate", l.max_aggregate}, {"sheet_splits", l.sheet_splits}, {"sheet_merges", l.sheet_merges}, {"reordered", l.reordered}, {"p_blocks", l.nnz_p}, {"restriction_chunks", l.restriction_chunks}, {"lambda", l.lambda}, {"mode_correction", l.mode_correction}, {"p_truncated", l.truncated}});
  return out;
}

std::string fmt_ms(double s) { return fmt::format("{:.3g}", 1e3 * s); }
std::string fmt_speedup(double v) { return std::isfinite(v) && v > 0 ? fmt::format("{:.2f}", v) : "-"; }

}  // namespace

int bench_linear(const BenchLinearOptions& opt) {
  const SolverSettings settings{opt.tolerance, opt.max_iterations, opt.sa_settings};
  std::vector<SolverEntry> all;
  try {
    all = available_solvers(settings);
  } catch (const ConfigError& e) {  // a bad --sa setting, named with its valid range
    fmt::print(stderr, "error: {}\n", e.what());
    return exit_config;
  }
  auto has = [&](const std::string& key) {
    return std::any_of(all.begin(), all.end(), [&](const SolverEntry& e) { return e.key == key; });
  };
  if (opt.list_solvers) {
    for (const auto& e : all) fmt::print("{:<11} {:<12} {}\n", e.key, e.label, e.description);
    return exit_ok;
  }

  // ---- configuration ----
  std::vector<std::string> errors;
  std::vector<Example> examples;
  if (opt.examples.empty())
    examples = {Example::pinned, Example::drooping, Example::reentrant, Example::drop_horizontal, Example::drop_vertical};
  for (const auto& s : opt.examples) {
    if (auto e = parse_example(s)) examples.push_back(*e);
    else errors.push_back(fmt::format("--examples: unknown example '{}' (pinned, drooping, re-entrant, dropHorizontal, dropVertical)", s));
  }
  std::vector<Tessellation> tess;
  if (opt.tessellations.empty()) tess = {Tessellation::regular, Tessellation::irregular};
  for (const auto& s : opt.tessellations) {
    if (s == "regular") tess.push_back(Tessellation::regular);
    else if (s == "irregular") tess.push_back(Tessellation::irregular);
    else errors.push_back(fmt::format("--tessellations: unknown tessellation '{}' (regular, irregular)", s));
  }
  std::vector<int> sizes = opt.sizes;
  if (sizes.empty()) {
    if (opt.quick) sizes = {30};
    else sizes.assign(std::begin(thesis_m), std::end(thesis_m));
  }
  for (int m : sizes)
    if (m < 4 || m % 2) errors.push_back(fmt::format("--sizes: m = {} must be even and >= 4 ((m+1)^2 vertices)", m));
  if (opt.max_vertices > 0)
    sizes.erase(std::remove_if(sizes.begin(), sizes.end(), [&](int m) { return 1LL * (m + 1) * (m + 1) > opt.max_vertices; }),
                sizes.end());
  std::sort(sizes.begin(), sizes.end());
  sizes.erase(std::unique(sizes.begin(), sizes.end()), sizes.end());
  if (sizes.empty()) errors.push_back("no size left: raise --max-vertices or pass --sizes");
  std::vector<SolverEntry> chosen;
  if (opt.solvers.empty()) {
    for (const auto& e : all)
      if (!(e.key == "direct" && has("cholmod"))) chosen.push_back(e);  // CHOLMOD replaces the slower simplicial LDL^T
  } else {
    for (const auto& key : opt.solvers) {
      if (key.find(':') != std::string::npos) {  // sa_ppcg with its own settings
        try {
          if (std::none_of(chosen.begin(), chosen.end(), [&](const SolverEntry& e) { return e.key == key; }))
            chosen.push_back(sa_ppcg_with(settings, key));
        } catch (const ConfigError& e) {
          errors.push_back(fmt::format("--solvers: {}", e.what()));
        }
        continue;
      }
      auto it = std::find_if(all.begin(), all.end(), [&](const SolverEntry& e) { return e.key == key; });
      if (it == all.end()) {
        std::string avail;
        for (const auto& e : all) avail += (avail.empty() ? "" : ", ") + e.key;
        errors.push_back(fmt::format("--solvers: '{}' is not available in this build (available: {})", key, avail));
      } else if (std::none_of(chosen.begin(), chosen.end(), [&](const SolverEntry& e) { return e.key == key; })) {
        chosen.push_back(*it);
      }
    }
  }
  if (chosen.empty()) errors.push_back("--solvers: no solver selected");
  if (!errors.empty()) {
    for (const auto& e : errors) fmt::print(stderr, "error: {}\n", e);
    return exit_config;
  }
  // The reference (first, advances the simulation, gives x*): the first direct solver.
  auto ref_it = std::find_if(chosen.begin(), chosen.end(), [](const SolverEntry& e) { return e.direct; });
  const bool reference_is_direct = ref_it != chosen.end();
  if (reference_is_direct) std::rotate(chosen.begin(), ref_it, ref_it + 1);
  const std::string direct_key = reference_is_direct ? chosen.front().key : "";

#ifdef _OPENMP
  if (opt.threads > 0) omp_set_num_threads(opt.threads);
  const int threads = omp_get_max_threads();
#else
  const int threads = 1;
#endif
  const int hw_threads = static_cast<int>(std::thread::hardware_concurrency());
  const std::string cpu = cpu_model(), git = build_commit();
  const fs::path out = opt.out_dir.empty() ? fs::path("out/bench_linear") : fs::path(opt.out_dir);
  const int steps_per_frame = static_cast<int>(std::lround(1.0 / fps / 2e-3));

  const bool cholmod = direct_key == "cholmod";
  const std::string direct_label = !reference_is_direct ? "none selected"
                                   : cholmod ? "CHOLMOD supernodal Cholesky (SuiteSparse)"
                                             : "Eigen SimplicialLDLT (AMD ordering)";

  // ---- bandwidth ----
  const std::size_t stream_n = opt.quick ? (std::size_t{1} << 22) : (std::size_t{1} << 24);
  const double stream_gbs = stream_triad_gbs(stream_n, opt.quick ? 3 : 10);
  fmt::print(stderr, "bench linear: STREAM-like triad {:.2f} GB/s ({} threads, 3 x {} MB)\n", stream_gbs, threads,
             stream_n * 8 / (1 << 20));

  // ---- files: the meta record first, then each case as soon as it is done (a long run that is
  // interrupted keeps what it measured) ----
  std::ofstream jl, csv;
  try {
    fs::create_directories(out);
    jl.open(out / "bench_linear.jsonl");
    csv.open(out / "bench_linear.csv");
    if (!jl || !csv) throw std::runtime_error("cannot open the output files");
    Json meta = meta_record("linear", cpu, threads);
    meta.update(Json{{"quick", opt.quick},
              {"direct_solver", direct_label}, {"reference", chosen.front().key}, {"tolerance", opt.tolerance},
              {"max_iterations", opt.max_iterations}, {"dt", 2e-3}, {"fps", fps}, {"steps_per_frame", steps_per_frame},
              {"step_budget", opt.step_budget}, {"stream_triad_gbs", stream_gbs}, {"stream_array_mb", stream_n * 8 / (1 << 20)},
              {"contact_model", "simple analytic box contact (top face; normal constraints, post-step projection)"},
              {"sizes", sizes}, {"sa_settings", opt.sa_settings}});
    jl << meta.dump() << "\n";
    csv << "example,tessellation,m,vertices,solver,solves,failures,analyses,mean_iterations,mean_rate,mean_setup_s,mean_solve_s,"
           "mean_total_s,median_total_s,mean_prefilter_s,mean_energy_error,max_energy_error,max_constraint_violation,"
           "max_relative_residual,memory_bytes,matrix_bytes,levels,operator_complexity,steps,mean_box_contacts,max_box_contacts,mean_springs,"
           "max_springs,pattern_changes,assembly_mean_s,assembly_peak_rss_mb,case_peak_rss_mb,process_peak_rss_mb,spmv_gbs,"
           "spmv_pct_stream,failure\n";
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: cannot write {}: {}\n", out.string(), e.what());
    return exit_config;
  }
  auto write_case = [&](const CaseResult& r) {
      const int sd = std::max(1, r.steps_done);
      Json cj{{"example", ex_name(r.example)},
              {"tessellation", tess_name(r.tessellation)},
              {"m", r.m},
              {"vertices", r.vertices},
              {"faces", r.faces},
              {"steps", r.steps_done},
              {"steps_planned", r.steps_planned},
              {"pinned", r.pinned},
              {"box_contacts_mean", double(r.box_contacts) / sd},
              {"box_contacts_max", r.max_box_contacts},
              {"springs_mean", double(r.springs) / sd},
              {"springs_max", r.max_springs},
              {"pattern_changes", r.pattern_changes},
              {"projected", r.projected},
              {"released", r.released},
              {"assembly_mean_s", r.assembly_seconds / sd},
              {"detect_mean_s", r.detect_seconds / sd},
              {"rss_before_mb", r.rss_before_mb},
              {"assembly_peak_rss_mb", r.assembly_peak_mb},
              {"assembly_huge_pages_mb", r.assembly_huge_mb},
              {"case_peak_rss_mb", r.case_peak_mb},
              {"process_peak_rss_mb", r.process_peak_mb},
              {"spmv_gbs", r.spmv_gbs},
              {"spmv_mbytes", r.spmv_mbytes},
              {"blocks", r.blocks},
              {"matrix_bytes", r.matrix_bytes},
              {"wall_seconds", r.wall_seconds},
              {"reference", r.reference},
              {"failure", r.failure}};
      for (const auto& s : r.solvers) {
        Json j{{"record", "solver"},
               {"case", cj},
               {"solver", s.key},
               {"label", s.label},
               {"solves", s.solves},
               {"failures", s.failures},
               {"analyses", s.analyses},
               {"mean_iterations", s.mean_iterations()},
               {"mean_rate", s.mean_rate()},
               {"mean_setup_s", SolverStats::mean(s.setup)},
               {"mean_solve_s", SolverStats::mean(s.solve)},
               {"mean_total_s", s.mean_total()},
               {"median_total_s", SolverStats::median(s.total)},
               {"min_total_s", s.total.empty() ? 0 : *std::min_element(s.total.begin(), s.total.end())},
               {"mean_prefilter_s", SolverStats::mean(s.prefilter)},
               {"mean_energy_error", s.mean_energy()},
               {"max_energy_error", s.energy_count ? s.energy_max : -1},
               {"max_constraint_violation", s.violation_max},
               {"max_relative_residual", s.relres_max},
               {"memory_bytes", s.memory_max},
               {"memory_with_matrix_bytes", s.memory_max + r.matrix_bytes},
               {"levels", s.levels},
               {"operator_complexity", s.operator_complexity},
               {"hierarchy", hierarchy_json(s.hierarchy)},
               {"mean_setup_split_s", s.mean_setup_split()},
               {"message", s.message}};
        jl << j.dump() << "\n";
        csv << fmt::format("{},{},{},{},{},{},{},{},{:.3f},{:.5f},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.3e},{:.3e},{:.3e},{:.3e},{},{},{},"
                           "{:.3f},{},{:.2f},{},{:.2f},{},{},{:.6e},{:.1f},{:.1f},{:.1f},{:.3f},{:.1f},\"{}\"\n",
                           ex_name(r.example), tess_name(r.tessellation), r.m, r.vertices, s.key, s.solves, s.failures, s.analyses,
                           s.mean_iterations(), s.mean_rate(), SolverStats::mean(s.setup), SolverStats::mean(s.solve), s.mean_total(),
                           SolverStats::median(s.total), SolverStats::mean(s.prefilter), s.mean_energy(),
                           s.energy_count ? s.energy_max : -1.0, s.violation_max, s.relres_max, s.memory_max, r.matrix_bytes, s.levels,
                           s.operator_complexity, r.steps_done, double(r.box_contacts) / sd, r.max_box_contacts,
                           double(r.springs) / sd, r.max_springs, r.pattern_changes, r.assembly_seconds / sd, r.assembly_peak_mb,
                           r.case_peak_mb, r.process_peak_mb, r.spmv_gbs, 100 * r.spmv_gbs / stream_gbs, s.message.empty() ? r.failure : s.message);
      }
    jl.flush();
    csv.flush();
  };

  // ---- runs ----
  std::vector<CaseResult> results;
  const auto wall0 = Clock::now();
  for (int m : sizes)
    for (Tessellation t : tess)
      for (Example ex : examples) {
        ExampleConfig cfg;
        cfg.example = ex, cfg.tessellation = t, cfg.m = m;
        const long long nv = 1LL * (m + 1) * (m + 1);
        int steps = opt.steps > 0 ? opt.steps : thesis_frames[static_cast<int>(ex)] * steps_per_frame;
        const int cap = std::max(2, static_cast<int>(opt.step_budget / static_cast<double>(nv)));
        steps = opt.quick ? std::min(steps, 2) : std::min(steps, cap);
        try {
          results.push_back(run_case(cfg, chosen, steps, reference_is_direct));
        } catch (const std::exception& e) {
          CaseResult r;
          r.example = ex, r.tessellation = t, r.m = m, r.steps_planned = steps;
          r.failure = e.what();
          results.push_back(r);
        }
        const CaseResult& r = results.back();
        write_case(r);
        std::string line;
        for (const auto& s : r.solvers)
          line += fmt::format(" {} {:.1f} its {:.3g} ms;", s.key, s.mean_iterations(), 1e3 * s.mean_total());
        fmt::print(stderr, "bench linear: {} {} m={} ({} vertices): {} steps in {:.1f} s;{}{}\n", ex_name(ex), tess_name(t), m,
                   r.vertices, r.steps_done, r.wall_seconds, line, r.failure.empty() ? "" : " FAILED: " + r.failure);
      }
  const double wall = seconds_since(wall0);

  // ---- Markdown ----
  std::string md;
  auto w = [&md](const std::string& s) { md += s; };
  w("# weft bench linear: thesis Table 11.1 (methods/multigrid §10)\n\n");
  w(fmt::format("Hardware: {}; {} hardware threads; {} OpenMP threads used; heap pages {}. Compiler: {} `{}`; git {}.{}\n\n", cpu,
                hw_threads, threads, huge_pages_status(), __VERSION__, build_flags(), git,
                opt.quick ? " **--quick: reduced run (m = 30, 2 steps).**" : ""));
  w(fmt::format("Direct solver: **{}**{} -- a stand-in for the thesis's MKL PARDISO, which is faster (PARDISO is not available "
                "here), so the 'vs direct' speedups are not the thesis's 'vs PARDISO'.\n\n",
                direct_label, cholmod ? "" : " (CHOLMOD not compiled in: -DWEFT_WITH_CHOLMOD=ON)"));
  if (!opt.sa_settings.empty())
    w(fmt::format("SA preconditioner settings (`--sa`, sa_ppcg and sa_mpcg): **{}**; the other keys at their defaults.\n\n",
                  fmt::join(opt.sa_settings, " ")));
  w(fmt::format(
      "Setup: 1 m x 1 m cotton-like sheet (0.15 kg/m^2, Y = 20 MPa, nu = 0.3, h = 0.3 mm), StVK isotropic membrane + theta hinge "
      "bending, gravity, dt = 2 ms. One Baraff-Witkin linearly implicit step per time step: A = M + dt^2 H (PSD-projected element "
      "Hessians) [+ dt^2 K_springs], pinned rows and columns decoupled (diagonal tr(A_ii)/3, as in the simulator), "
      "b = dt M v - dt^2 (grad V - f_gravity) [+ dt^2 f_springs]; unknown d = dt v_new; zero initial "
      "guess; tolerance {:g} on the relative M^-1-norm residual (M = the solver's preconditioner); iteration limit {}. Every solver "
      "solves the same system each step; the simulation advances with the reference solver (`{}`), which also gives x* for the "
      "energy error ||x - x*||_A / ||x*||_A. Steps: the thesis's frames (10 / 15 / 25) at 30 fps ({} steps per frame; the thesis "
      "does not state its frame rate), capped at max(2, {:.3g} / vertices){}. Times are means per solve (setup = analyze_pattern "
      "when the pattern changed + factorize; total = setup + solve).\n\n",
      opt.tolerance, opt.max_iterations, chosen.front().key, steps_per_frame, opt.step_budget, opt.steps > 0 ? fmt::format(" (--steps {})", opt.steps) : ""));
  w("Examples: pinned = whole boundary pinned; drooping = the two sides u = +-0.5 pinned (the thesis does not say which two); "
    "re-entrant = L-shape (the (+u, +v) quadrant removed: about 3/4 of the vertices), the two edges meeting at the re-entrant "
    "corner pinned; dropHorizontal = flat sheet meeting the top of a box (0.8 m x 0.8 m footprint, 0.3 m x 0.3 m square hole in the "
    "middle of the top) at 1 m/s, started at the moment of impact; dropVertical = same box, the sheet pre-buckled as if dropped "
    "from vertical: its lower half folded into an accordion of ~10 cm horizontal layers 4/pi mesh spacings apart (closer than the "
    "repulsion distance 1.5 spacings), its upper half vertical, falling at 1 m/s. **Contact is a simple analytic box contact** "
    "(top face only): a vertex at the top, inside the footprint and outside the hole, not moving up, gets the normal constraint "
    "n = +z, value top - z; after the step, vertices that crossed the top are projected onto it with zero normal velocity; a "
    "contact whose constraint force pulls is released (BW98). **Cloth-cloth repulsion** (dropVertical): springs k/2 (h - d)^2, "
    "k = Y h_thickness = 6000 N/m, between vertices closer than h whose rest distance exceeds 3h, found by a spatial hash, added "
    "implicitly into A (new blocks: the solvers re-run analyze_pattern when the spring set changes); separating spring pairs lose "
    "their relative normal velocity after the step.\n\n");

  w(fmt::format("## Memory bandwidth\n\nSTREAM-like triad (a = b + s c, 3 arrays of {} MB, best of {}, {} threads, 24 bytes per "
                "element): **{:.2f} GB/s**. BlockCsr SpMV y = A x on the last system of each case, best of repeated products; byte "
                "model: 72 per block (values) + 4 per block (column index) + 4 per block row (row pointer) + 48 per block row (x "
                "read once, y written once).\n\n",
                stream_n * 8 / (1 << 20), opt.quick ? 3 : 10, threads, stream_gbs));
  w("| example | tessellation | vertices | blocks | bytes per SpMV [MB] | SpMV [GB/s] | % of triad |\n|---|---|---|---|---|---|---|\n");
  for (const auto& r : results)
    if (r.blocks > 0)
      w(fmt::format("| {} | {} | {} | {} | {:.2f} | {:.2f} | {:.0f}% |\n", ex_name(r.example), tess_name(r.tessellation), r.vertices,
                    r.blocks, r.spmv_mbytes, r.spmv_gbs, 100 * r.spmv_gbs / stream_gbs));

  w("\n## Cases\n\nContacts and springs are means over the steps (max in parentheses). Assembly = gradient + projected element "
    "Hessians + gather + springs + mass, mean per step. Peak RSS: the kernel's high-water mark reset before each case "
    "(VmHWM after the first assembly, and after the whole case); the process peak is getrusage's ru_maxrss (never reset).\n\n");
  w("| example | tessellation | m | vertices | steps | box contacts | springs | pattern changes | assembly [ms] | RSS before "
    "[MB] | assembly peak RSS [MB] | case peak RSS [MB] | process peak RSS [MB] | wall [s] | failure |\n"
    "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& r : results) {
    const int sd = std::max(1, r.steps_done);
    w(fmt::format("| {} | {} | {} | {} | {} / {} | {:.1f} ({}) | {:.1f} ({}) | {} | {:.3g} | {:.0f} | {:.0f} | {:.0f} | {:.0f} | "
                  "{:.1f} | {} |\n",
                  ex_name(r.example), tess_name(r.tessellation), r.m, r.vertices, r.steps_done, r.steps_planned,
                  double(r.box_contacts) / sd, r.max_box_contacts, double(r.springs) / sd, r.max_springs, r.pattern_changes,
                  1e3 * r.assembly_seconds / sd, r.rss_before_mb, r.assembly_peak_mb, r.case_peak_mb, r.process_peak_mb,
                  r.wall_seconds, r.failure));
  }

  w("\n## Solvers per case\n\n| example | tessellation | vertices | solver | solves | failed | mean its | mean rate | setup [ms] "
    "| solve [ms] | total [ms] | median total [ms] | prefilter [ms] | energy error (mean / max) | max constraint violation | max "
    "rel. residual | memory [MB] | levels | op. complexity |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& r : results)
    for (const auto& s : r.solvers)
      w(fmt::format("| {} | {} | {} | {} | {} | {} | {:.1f} | {} | {} | {} | {} | {} | {} | {} | {:.1e} | {:.1e} | {:.1f} | {} | {} |\n",
                    ex_name(r.example), tess_name(r.tessellation), r.vertices, s.label, s.solves, s.failures, s.mean_iterations(),
                    s.rate_count ? fmt::format("{:.3f}", s.mean_rate()) : "-", fmt_ms(SolverStats::mean(s.setup)),
                    fmt_ms(SolverStats::mean(s.solve)), fmt_ms(s.mean_total()), fmt_ms(SolverStats::median(s.total)),
                    fmt_ms(SolverStats::mean(s.prefilter)),
                    s.energy_count ? fmt::format("{:.1e} / {:.1e}", s.mean_energy(), s.energy_max) : (s.key == r.reference ? "reference" : "-"),
                    s.violation_max, s.relres_max, s.memory_max / 1e6, s.levels ? std::to_string(s.levels) : "-",
                    s.operator_complexity > 0 ? fmt::format("{:.2f}", s.operator_complexity) : "-"));

  // Memory: what a user pays to solve with each solver.
  w("\n## Memory per solver\n\nA = the system matrix every solver is given (values, column indices, row pointers, diagonal "
    "positions; shared, not owned by any solver). Own = the largest memory the solver reported owning after a setup "
    "(LinearReport::memory_bytes: preconditioner or factor, work vectors, prefiltered copies). A + own is the memory a user pays "
    "to solve with that solver alone; the ratio compares it with Diag-PCG's on the same case. (The case peak RSS above also "
    "holds the simulation, the assembly and every selected solver.)\n\n"
    "| example | tessellation | vertices | A [MB] | solver | own [MB] | A + own [MB] | (A + own) / Diag-PCG's |\n"
    "|---|---|---|---|---|---|---|---|\n");
  for (const auto& r : results) {
    const SolverStats* dg = r.find("diag_pcg");
    const double base = dg ? static_cast<double>(r.matrix_bytes + dg->memory_max) : 0.0;
    for (const auto& s : r.solvers) {
      if (s.solves == 0) continue;
      const double total = static_cast<double>(r.matrix_bytes + s.memory_max);
      w(fmt::format("| {} | {} | {} | {:.1f} | {} | {:.1f} | {:.1f} | {} |\n", ex_name(r.example), tess_name(r.tessellation),
                    r.vertices, r.matrix_bytes / 1e6, s.label, s.memory_max / 1e6, total / 1e6,
                    base > 0 ? fmt::format("{:.2f}", total / base) : "-"));
    }
  }

  // Multigrid hierarchies: what the setup built, level by level.
  bool any_hierarchy = false;
  for (const auto& r : results)
    for (const auto& s : r.solvers) any_hierarchy = any_hierarchy || !s.hierarchy.empty();
  if (any_hierarchy) {
    w("\n## Multigrid hierarchies\n\nThe first setup of each multigrid solver, finest level first: nodes (block rows; 3 "
      "unknowns on level 0, 6 below), stored blocks of A_l per row, coarsening ratio n_l / n_(l+1), prolongator blocks per "
      "row, and the smoother's bound lambda of D^-1 A_l. Setup split: mean milliseconds per setup by phase.\n\n"
      "| example | tessellation | vertices | solver | level | nodes | blocks / row | ratio | P blocks / row | lambda |\n"
      "|---|---|---|---|---|---|---|---|---|---|\n");
    for (const auto& r : results)
      for (const auto& s : r.solvers)
        for (size_t l = 0; l < s.hierarchy.size(); ++l) {
          const weft::linear::SaLevelStats& h = s.hierarchy[l];
          const double rows = std::max(1, h.rows);
          w(fmt::format("| {} | {} | {} | {} | {} | {} | {:.1f} | {} | {} | {:.2f} |\n", ex_name(r.example),
                        tess_name(r.tessellation), r.vertices, s.label, l, h.rows, h.nnz_blocks / rows,
                        h.aggregates > 0 ? fmt::format("{:.2f}", rows / h.aggregates) : "-",
                        h.nnz_p > 0 ? fmt::format("{:.2f}", h.nnz_p / rows) : "-", h.lambda));
        }
    w("\n| example | tessellation | vertices | solver | setup split [ms] |\n|---|---|---|---|---|\n");
    for (const auto& r : results)
      for (const auto& s : r.solvers) {
        if (s.setup_split.empty()) continue;
        std::string parts;
        for (const auto& [phase, seconds] : s.mean_setup_split())
          parts += fmt::format("{}{} {}", parts.empty() ? "" : ", ", phase, fmt_ms(seconds));
        w(fmt::format("| {} | {} | {} | {} | {} |\n", ex_name(r.example), tess_name(r.tessellation), r.vertices, s.label, parts));
      }
  }

  // Table 11.1
  w(fmt::format("\n## Table 11.1: SA+PPCG speedup, ours (thesis)\n\nEach cell: T(Diag-PCG) / T(SA+PPCG) and T(direct) / "
                "T(SA+PPCG) with T the mean total (setup + solve) time per solve; in parentheses the thesis's vs Diag-PCG / vs "
                "PARDISO. Ours 'direct' = {}. '-' = not measured (solver not selected or not available in this build).\n",
                direct_label));
  for (Tessellation t : tess) {
    w(fmt::format("\n### {} tessellation\n\n| m | vertices |", tess_name(t)));
    for (Example ex : examples) w(fmt::format(" {} |", ex_name(ex)));
    w("\n|---|---|");
    for (size_t k = 0; k < examples.size(); ++k) w("---|");
    w("\n");
    for (int m : sizes) {
      w(fmt::format("| {} | {} |", m, (m + 1) * (m + 1)));
      for (Example ex : examples) {
        const CaseResult* c = nullptr;
        for (const auto& r : results)
          if (r.m == m && r.tessellation == t && r.example == ex) c = &r;
        const SolverStats *sa = c ? c->find("sa_ppcg") : nullptr, *dg = c ? c->find("diag_pcg") : nullptr,
                          *dr = c && !direct_key.empty() ? c->find(direct_key) : nullptr;
        const double vs_diag = sa && dg ? dg->mean_total() / sa->mean_total() : NAN;
        const double vs_direct = sa && dr ? dr->mean_total() / sa->mean_total() : NAN;
        const int ti = thesis_index(m), ei = static_cast<int>(ex), tt = static_cast<int>(t);
        const std::string thesis = ti >= 0 ? fmt::format(" ({:.2f} / {:.2f})", thesis_vs_diag[tt][ti][ei], thesis_vs_pardiso[tt][ti][ei]) : "";
        w(fmt::format(" {} / {}{} |", fmt_speedup(vs_diag), fmt_speedup(vs_direct), thesis));
      }
      w("\n");
    }
  }
  w(fmt::format("\nTotal wall time {:.1f} s. Files: {}/bench_linear.jsonl, bench_linear.csv, bench_linear.md\n", wall, out.string()));
  fmt::print("{}", md);
  {
    std::ofstream mdf(out / "bench_linear.md");
    mdf << md;
    if (!mdf) {
      fmt::print(stderr, "error: cannot write {}\n", (out / "bench_linear.md").string());
      return exit_config;
    }
  }

  const bool failed = std::any_of(results.begin(), results.end(), [](const CaseResult& r) { return !r.failure.empty(); });
  return failed ? exit_failed : exit_ok;
}

}  // namespace weft::app
