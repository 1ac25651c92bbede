#include "apps/bench_hair.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <sys/wait.h>
#include <unistd.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "apps/bench_common.hpp"
#include "framework/build_info.hpp"
#include "apps/runner.hpp"
#include "apps/stability.hpp"
#include "framework/error.hpp"
#include "framework/params_json.hpp"
#include "framework/scene.hpp"
#include "linear/lapack_info.hpp"
#include "policies/registry.hpp"
#include "policies/rod_presets.hpp"

namespace weft::app {
namespace {

namespace fs = std::filesystem;
using contact::rods::GroupStats;


/// The per-group statistics of the last step of a rod simulator with contact groups (null
/// for other simulators): the strategy's own record, updated by every step.
template <class Sim>
const std::vector<GroupStats>* groups_if(AnySimulator& s) {
  auto* a = dynamic_cast<SimulatorAdapter<Sim>*>(&s);
  return a ? &a->simulator().contact().last_groups() : nullptr;
}
const std::vector<GroupStats>* group_stats(AnySimulator& s) {
  if (auto* g = groups_if<RodsImpulse>(s)) return g;
  if (auto* g = groups_if<RodsLinear>(s)) return g;
  if (auto* g = groups_if<RodsAdonis>(s)) return g;
  return groups_if<RodsStaggered>(s);
}

/// One run: a strategy at one time step.
struct Run {
  std::string scene, strategy;
  int rods = 0;
  double dt = 0, duration = 0;
  Stability outcome = Stability::stable;
  int steps = 0, steps_planned = 0;
  double wall = 0;
  double contacts_mean = 0, rod_contacts_mean = 0, obstacle_contacts_mean = 0;
  int contacts_max = 0;
  double groups_mean = 0;
  int groups_max = 0, largest_group = 0;
  double newton_mean = 0, newton_weighted = 0;  ///< outer iterations per group: plain and contact-weighted means
  int newton_max = 0;
  double gs_sweeps_per_step = 0, relinearized_per_step = 0;
  int capped_groups = 0, redetections = 0, gs_unconverged = 0;
  double max_strain = 0;
  std::string message;

  bool ok() const { return outcome == Stability::stable; }
};

constexpr const char* csv_header =
    "scene,rods,strategy,dt,duration,outcome,success,steps,steps_planned,wall_s,s_per_step,contacts_mean,contacts_max,"
    "rod_contacts_mean,obstacle_contacts_mean,groups_mean,groups_max,largest_group,newton_per_group_mean,"
    "newton_per_group_weighted,newton_per_group_max,gs_sweeps_per_step,relinearized_per_step,capped_groups,"
    "gs_unconverged_steps,redetections,max_strain,message";

std::string to_csv(const Run& r) {
  return fmt::format("{},{},{},{},{},{},{},{},{},{:.3f},{:.4e},{:.2f},{},{:.2f},{:.2f},{:.2f},{},{},{:.4f},{:.4f},{},{:.2f},{:.3f},{},{},{},{:.4e},{}",
                     r.scene, r.rods, r.strategy, r.dt, r.duration, to_string(r.outcome), r.ok() ? 1 : 0, r.steps, r.steps_planned,
                     r.wall, r.steps ? r.wall / r.steps : 0.0, r.contacts_mean, r.contacts_max, r.rod_contacts_mean,
                     r.obstacle_contacts_mean, r.groups_mean, r.groups_max, r.largest_group, r.newton_mean, r.newton_weighted,
                     r.newton_max, r.gs_sweeps_per_step, r.relinearized_per_step, r.capped_groups, r.gs_unconverged, r.redetections,
                     r.max_strain, csv_field(r.message));
}

/// A row written by to_csv (for --resume); false if it does not parse.
bool from_csv(const std::string& line, Run& r) {
  std::vector<std::string> f;
  size_t pos = 0;
  const int fields = 28;
  while (static_cast<int>(f.size()) < fields - 1) {
    const size_t c = line.find(',', pos);
    if (c == std::string::npos) return false;
    f.push_back(line.substr(pos, c - pos));
    pos = c + 1;
  }
  std::string msg = line.substr(pos);
  if (msg.size() >= 2 && msg.front() == '"' && msg.back() == '"') msg = msg.substr(1, msg.size() - 2);
  try {
    r.scene = f[0];
    r.rods = std::stoi(f[1]);
    r.strategy = f[2];
    r.dt = std::stod(f[3]);
    r.duration = std::stod(f[4]);
    r.outcome = Stability::invalid;
    for (Stability s : {Stability::stable, Stability::diverged, Stability::not_converged, Stability::excessive_strain})
      if (f[5] == to_string(s)) r.outcome = s;
    r.steps = std::stoi(f[7]);
    r.steps_planned = std::stoi(f[8]);
    r.wall = std::stod(f[9]);
    r.contacts_mean = std::stod(f[11]);
    r.contacts_max = std::stoi(f[12]);
    r.rod_contacts_mean = std::stod(f[13]);
    r.obstacle_contacts_mean = std::stod(f[14]);
    r.groups_mean = std::stod(f[15]);
    r.groups_max = std::stoi(f[16]);
    r.largest_group = std::stoi(f[17]);
    r.newton_mean = std::stod(f[18]);
    r.newton_weighted = std::stod(f[19]);
    r.newton_max = std::stoi(f[20]);
    r.gs_sweeps_per_step = std::stod(f[21]);
    r.relinearized_per_step = std::stod(f[22]);
    r.capped_groups = std::stoi(f[23]);
    r.gs_unconverged = std::stoi(f[24]);
    r.redetections = std::stoi(f[25]);
    r.max_strain = std::stod(f[26]);
  } catch (const std::exception&) {
    return false;
  }
  r.message = msg;
  return true;
}

std::string duration_text(double s) {
  if (s < 60) return fmt::format("{:.1f} s", s);
  const long t = std::lround(s);
  if (t < 3600) return fmt::format("{}m{:02}s", t / 60, t % 60);
  return fmt::format("{}h{:02}m", t / 3600, (t % 3600) / 60);
}

std::string dt_text(double dt) { return dt >= 1e-3 ? fmt::format("{:g} ms", dt * 1e3) : fmt::format("{:g} us", dt * 1e6); }

/// The thesis' stability study (methods/rod-contact §14.2): wall time to completion, "✗" = failed.
constexpr const char* thesis_table =
    "| rods | method | 100 ms | 10 ms | 5 ms | 1 ms | 0.1 ms |\n"
    "|---|---|---|---|---|---|---|\n"
    "| 1K | ADONIS | ✗ | 3h42m | 3h28m | 4h09m | 10h58m |\n"
    "| 1K | Linear | ✗ | ✗ | ✗ | 6h38m | 11h09m |\n"
    "| 1K | Impulse | ✗ | ✗ | ✗ | ✗ | 13h27m |\n"
    "| 2K | ADONIS | ✗ | 6h29m | 3h46m | 5h11m | 23h49m |\n"
    "| 2K | Linear | ✗ | ✗ | ✗ | 8h30m | 23h35m |\n"
    "| 2K | Impulse | ✗ | ✗ | ✗ | ✗ | 28h51m |\n"
    "| 4K | ADONIS | ✗ | 43h55m | 21h47m | 19h40m | 55h19m |\n"
    "| 4K | Linear | ✗ | ✗ | ✗ | ✗ | 55h37m |\n"
    "| 4K | Impulse | ✗ | ✗ | ✗ | ✗ | 76h34m |\n";

/// The Markdown report of every run so far.
std::string report(const std::string& title, const std::vector<std::string>& strategies, const std::vector<double>& dts,
                   const std::vector<Run>& runs) {
  std::string md = title;
  md += "\n## Success and wall time (the layout of the thesis' table)\n\n";
  md += "✓ = completed without failure, ✗ = failed (the reason and step in the table below), blank = not run yet.\n\n";
  md += "| strategy |";
  for (double dt : dts) md += fmt::format(" {} |", dt_text(dt));
  md += "\n|---|";
  for (size_t i = 0; i < dts.size(); ++i) md += "---|";
  md += "\n";
  for (const std::string& s : strategies) {
    md += fmt::format("| {} |", s);
    for (double dt : dts) {
      auto it = std::find_if(runs.begin(), runs.end(), [&](const Run& r) { return r.strategy == s && r.dt == dt; });
      if (it == runs.end()) md += " |";
      else if (it->ok()) md += fmt::format(" ✓ {} |", duration_text(it->wall));
      else md += fmt::format(" ✗ {} (step {} of {}) |", to_string(it->outcome), it->steps, it->steps_planned);
    }
    md += "\n";
  }
  md += "\n## Thesis (methods/rod-contact §14.2): full runs on a 4-core Xeon X5650 2.67 GHz, wall time to completion\n\n";
  md += thesis_table;
  md += "\n## Per run\n\n";
  md += "Contacts: rod-rod plus rod-sphere, per step after the response. Newton: constrained Newton (outer) iterations "
        "per contact group of the step's last solve (mean over the groups of all steps; weighted by the group's contacts; "
        "largest). GS: Gauss-Seidel sweeps per step, summed over the groups.\n\n";
  md += "| strategy | dt | outcome | steps | wall | s/step | contacts/step mean | max | groups/step | largest group | "
        "Newton/group mean | weighted | max | GS sweeps/step | re-linearised/step | capped | max strain | message |\n";
  md += "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n";
  for (const Run& r : runs)
    md += fmt::format("| {} | {} | {} | {}/{} | {} | {:.3g} | {:.1f} | {} | {:.1f} | {} | {:.3f} | {:.3f} | {} | {:.1f} | {:.2f} | {} | {:.3g} | {} |\n",
                      r.strategy, dt_text(r.dt), r.ok() ? "✓" : std::string("✗ ") + to_string(r.outcome), r.steps, r.steps_planned,
                      duration_text(r.wall), r.steps ? r.wall / r.steps : 0.0, r.contacts_mean, r.contacts_max, r.groups_mean,
                      r.largest_group, r.newton_mean, r.newton_weighted, r.newton_max, r.gs_sweeps_per_step,
                      r.relinearized_per_step, r.capped_groups, r.max_strain, r.message);
  return md;
}


/// The child of one run: steps the scene, appends one JSON line per step (with the run id
/// = its pid) and an end record to `jsonl`; its stderr goes to `err`. Returns the exit code.
int simulate(const std::string& scene_path, const std::string& strategy, double dt, const std::vector<std::string>& overrides,
             int steps, double strain_threshold, const fs::path& jsonl, const fs::path& err) {
  const int id = static_cast<int>(getpid());
  if (std::freopen(err.c_str(), "a", stderr)) std::setvbuf(stderr, nullptr, _IONBF, 0);  // an abort flushes nothing
  fmt::print(stderr, "run {}: {} at dt = {}\n", id, strategy, dt);
  std::ofstream jl(jsonl, std::ios::app);
  Stability outcome = Stability::stable;
  std::string message;
  int done = 0;
  try {
    const Scene scene = load_scene(scene_path, overrides);
    auto sim = make_simulator(scene);
    const std::vector<GroupStats>* groups = group_stats(*sim);
    for (int k = 1; k <= steps; ++k) {
      const auto t0 = Clock::now();
      const StepReport r = sim->step();
      const double wall = seconds_since(t0);
      done = k;
      if (!r.ok()) {
        outcome = r.message.find("non-finite") != std::string::npos ? Stability::diverged : Stability::not_converged;
        message = fmt::format("step {}: {}: {}", r.step, r.failed_stage, r.message);
        break;
      }
      const double energy = r.energy.kinetic + r.energy.potential;
      if (!sim->state().x.allFinite() || !std::isfinite(energy)) {
        outcome = Stability::diverged;
        message = fmt::format("step {}: non-finite state or energy", r.step);
        break;
      }
      const double strain = max_edge_strain(scene, sim->state());
      const ContactReport& cr = r.contact;
      long long outer = 0, wnum = 0, wden = 0;
      int gmax = 0;
      if (groups)
        for (const GroupStats& g : *groups) {
          outer += g.outer;
          wnum += static_cast<long long>(g.contacts) * g.outer;
          wden += g.contacts;
          gmax = std::max(gmax, g.outer);
        }
      const long long ng = groups ? static_cast<long long>(groups->size()) : 0;
      jl << Json{{"record", "step"},
                 {"run", id},
                 {"strategy", strategy},
                 {"dt", dt},
                 {"step", r.step},
                 {"t", r.time},
                 {"wall_s", wall},
                 {"detection_s", cr.detection_seconds},
                 {"response_s", cr.response_seconds},
                 {"contacts", cr.contacts},
                 {"rod_contacts", cr.rod_contacts},
                 {"obstacle_contacts", cr.obstacle_contacts},
                 {"groups", ng},
                 {"largest_group", cr.largest_group},
                 {"outer_sum", outer},
                 {"outer_weighted_sum", wnum},
                 {"group_contacts", wden},
                 {"newton_mean", ng ? static_cast<double>(outer) / ng : 0.0},
                 {"newton_weighted", wden ? static_cast<double>(wnum) / wden : 0.0},
                 {"newton_max", gmax},
                 {"gs_sweeps", cr.gs_sweeps},
                 {"gs_residual", cr.gs_residual},
                 {"gs_unconverged", cr.gs_unconverged},
                 {"relinearized", cr.relinearized},
                 {"sp_alternations", cr.sp_alternations},
                 {"capped_groups", cr.capped_groups},
                 {"redetections", cr.redetections},
                 {"del_newton", r.newton.iterations},
                 {"max_stretch", cr.max_stretch},
                 {"strain", strain}}
                .dump()
         << std::endl;  // every step: an interrupted run keeps what it measured
      if (strain > strain_threshold) {
        outcome = Stability::excessive_strain;
        message = fmt::format("step {}: edge strain {:.3g} > {}", r.step, strain, strain_threshold);
        break;
      }
    }
  } catch (const std::exception& e) {  // outside the parallel regions
    outcome = Stability::not_converged;
    message = fmt::format("step {}: {}", done + 1, e.what());
    done += 1;
  }
  jl << Json{{"record", "end"}, {"run", id}, {"outcome", to_string(outcome)}, {"steps", done}, {"message", message}}.dump() << std::endl;
  return 0;
}

/// Sums the step lines of run `id` in `jsonl`, and its end record's outcome (the outcome
/// stays `stable` and the message empty without one: the caller handles an aborted run).
Run collect(const fs::path& jsonl, int id) {
  Run run;
  long long contacts = 0, rod_contacts = 0, obstacle_contacts = 0, groups = 0, outer = 0, wnum = 0, wden = 0, sweeps = 0, relin = 0;
  int summed = 0;
  std::ifstream in(jsonl);
  std::string line;
  while (std::getline(in, line)) {
    Json j;
    try {
      j = Json::parse(line);
    } catch (const std::exception&) {
      continue;
    }
    if (!j.contains("run") || j.at("run") != id) continue;
    if (j.at("record") == "end") {
      for (Stability s : {Stability::stable, Stability::diverged, Stability::not_converged, Stability::excessive_strain})
        if (j.at("outcome") == to_string(s)) run.outcome = s;
      run.message = j.at("message");
      run.steps = j.at("steps");
      continue;
    }
    if (j.at("record") != "step") continue;
    ++summed;
    run.steps = j.at("step");
    contacts += j.at("contacts").get<long long>();
    rod_contacts += j.at("rod_contacts").get<long long>();
    obstacle_contacts += j.at("obstacle_contacts").get<long long>();
    run.contacts_max = std::max(run.contacts_max, j.at("contacts").get<int>());
    groups += j.at("groups").get<long long>();
    run.groups_max = std::max(run.groups_max, j.at("groups").get<int>());
    run.largest_group = std::max(run.largest_group, j.at("largest_group").get<int>());
    outer += j.at("outer_sum").get<long long>();
    wnum += j.at("outer_weighted_sum").get<long long>();
    wden += j.at("group_contacts").get<long long>();
    run.newton_max = std::max(run.newton_max, j.at("newton_max").get<int>());
    sweeps += j.at("gs_sweeps").get<long long>();
    relin += j.at("relinearized").get<long long>();
    run.capped_groups += j.at("capped_groups").get<int>();
    run.redetections += j.at("redetections").get<int>();
    run.gs_unconverged += j.at("gs_unconverged").get<int>() > 0;
    run.max_strain = std::max(run.max_strain, j.at("strain").get<double>());
  }
  const double n = std::max(1, summed);
  run.contacts_mean = contacts / n;
  run.rod_contacts_mean = rod_contacts / n;
  run.obstacle_contacts_mean = obstacle_contacts / n;
  run.groups_mean = groups / n;
  run.newton_mean = groups ? static_cast<double>(outer) / groups : 0;
  run.newton_weighted = wden ? static_cast<double>(wnum) / wden : 0;
  run.gs_sweeps_per_step = sweeps / n;
  run.relinearized_per_step = relin / n;
  return run;
}

}  // namespace

int bench_hair(const BenchHairOptions& opt) {
  const std::string data = app::data_dir();
  const std::string scene_path =
      !opt.scene.empty() ? opt.scene : (fs::path(data) / "scenes" / "hairball_1000.json").string();
  const std::vector<std::string> strategies =
      !opt.strategies.empty() ? opt.strategies : std::vector<std::string>{"rods_impulse", "rods_linear", "rods_adonis"};
  const std::vector<double> dts = !opt.dts.empty() ? opt.dts
                                  : opt.quick      ? std::vector<double>{0.01, 0.005}
                                                   : std::vector<double>{0.1, 0.01, 0.005, 0.001};
  const double duration = opt.duration > 0 ? opt.duration : opt.quick ? 0.02 : 0;

  // Validate every run before any work (exit 2 with the key and value).
  struct Case {
    std::string strategy;
    double dt;
    std::vector<std::string> overrides;
    int steps;
  };
  std::vector<Case> cases;
  std::string scene_name = fs::path(scene_path).stem().string();
  int rods = 0, vertices = 0;
  double scene_duration = 0;
  try {
    for (double dt : dts)  // the large (cheap) steps first: a long campaign reports them early
      for (const std::string& s : strategies) {
        if (!(dt > 0)) throw ConfigError(fmt::format("--dt {}: time steps must be > 0", dt));
        std::vector<std::string> ov = opt.overrides;
        if (opt.quick) ov.push_back("rods.0.count=8");
        append_combo_overrides(ov, s);
        ov.push_back(fmt::format("time.dt={}", dt));
        ov.push_back(fmt::format("time.frame_rate={}", 1.0 / dt));  // one step per frame: any dt divides it
        ov.push_back(whole_steps_duration(scene_path, opt.overrides, dt, duration));
        const Scene scene = load_scene(scene_path, ov);
        const std::string why = not_applicable_reason(resolve_combo(scene), scene);
        if (!why.empty()) throw ConfigError(fmt::format("{} does not apply to {}: {}", s, scene_path, why));
        rods = scene.rods.num_rods();
        vertices = rods ? scene.rods.rod_vertices(0) : 0;
        scene_duration = scene.spec.time.duration;
        cases.push_back({s, dt, ov, std::max(1, static_cast<int>(std::lround(scene.spec.time.duration / dt)))});
      }
  } catch (const ConfigError& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return exit_config;
  }

  const fs::path out = opt.out_dir.empty() ? fs::path("out/bench_hair") : fs::path(opt.out_dir);
  std::vector<Run> runs;
  if (opt.resume && fs::exists(out / "bench_hair.csv")) {
    std::ifstream in(out / "bench_hair.csv");
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line)) {
      Run r;
      if (from_csv(line, r)) runs.push_back(r);
    }
  }
  const int threads = worker_threads();
  const std::string cpu = cpu_model(), git = build_commit();
  std::ofstream jl, csv;
  try {
    fs::create_directories(out);
    const bool append = opt.resume && !runs.empty();
    if (!append) std::ofstream(out / "bench_hair.jsonl", std::ios::trunc);
    jl.open(out / "bench_hair.jsonl", std::ios::app);  // the runs' children append their steps to it too
    csv.open(out / "bench_hair.csv", append ? std::ios::app : std::ios::trunc);
    if (!jl || !csv) throw std::runtime_error("cannot open the output files");
    if (!append) csv << csv_header << '\n';
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}: {}\n", out.string(), e.what());
    return exit_config;
  }
  csv.flush();
  Json meta = meta_record("hair", cpu, threads);
  meta.update(Json{{"scene", scene_path},
             {"rods", rods},
             {"overrides", opt.overrides},
             {"strategies", strategies},
             {"dts", dts},
             {"duration", duration > 0 ? duration : scene_duration},
             {"strain_threshold", opt.strain_threshold},
             {"quick", opt.quick}});
  jl << meta.dump() << std::endl;

  const std::string title = fmt::format(
      "# weft bench hair: {} ({} rods of {} vertices)\n\nHardware: {} ({} hardware threads, {} OpenMP threads); git {}; {}; LAPACK {}\n\n"
      "Each run simulates {} s (the thesis' runs are longer; its duration is not stated). Failure: a failed step, a "
      "non-finite state or energy, or an edge strain |l / l_rest - 1| > {} (the classification of `weft stability`).\n",
      scene_name, rods, vertices, cpu, std::thread::hardware_concurrency(), threads, git, build_flags(), linear::lapack_library(),
      duration > 0 ? duration : scene_duration, opt.strain_threshold);
  fmt::print("{}\n", title);
  fmt::print("| strategy | dt | outcome | steps | wall | s/step | contacts/step | max | groups/step | Newton/group | weighted | max "
             "| GS sweeps/step | max strain |\n|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  std::fflush(stdout);

  for (const Case& c : cases) {
    if (std::any_of(runs.begin(), runs.end(), [&](const Run& r) { return r.strategy == c.strategy && r.dt == c.dt; })) continue;
    // Each run in a child process: a broken invariant inside the contact solve (an exception
    // thrown in a parallel region) ends only that run, which is then a failure with its message.
    jl.flush();
    csv.flush();
    std::fflush(stdout);
    std::fflush(stderr);
    const fs::path err_path = out / "bench_hair.stderr";  // the runs' stderr, appended
    const auto t_run = Clock::now();
    const pid_t pid = fork();
    if (pid < 0) {
      fmt::print(stderr, "error: fork failed\n");
      return exit_failed;
    }
    if (pid == 0) _exit(simulate(scene_path, c.strategy, c.dt, c.overrides, c.steps, opt.strain_threshold, out / "bench_hair.jsonl",
                                 err_path));
    int status = 0;
    waitpid(pid, &status, 0);
    Run run = collect(out / "bench_hair.jsonl", pid);
    run.scene = scene_name;
    run.strategy = c.strategy;
    run.rods = rods;
    run.dt = c.dt;
    run.duration = c.steps * c.dt;
    run.steps_planned = c.steps;
    run.wall = seconds_since(t_run);
    if (!(WIFEXITED(status) && WEXITSTATUS(status) == 0)) {
      // No end record: the child died. Its last stderr line says why.
      std::ifstream in(err_path);
      std::string line, last;
      while (std::getline(in, line))
        if (!line.empty()) last = line;
      run.outcome = Stability::not_converged;
      run.message = fmt::format("step {}: the run aborted ({}): {}", run.steps + 1,
                                WIFSIGNALED(status) ? fmt::format("signal {}", WTERMSIG(status)) : fmt::format("exit {}", WEXITSTATUS(status)),
                                last);
      run.steps += 1;  // the step that aborted
    }
    csv << to_csv(run) << '\n';
    csv.flush();
    jl << Json{{"record", "run"},
               {"run", pid},
               {"strategy", run.strategy},
               {"dt", run.dt},
               {"outcome", to_string(run.outcome)},
               {"steps", run.steps},
               {"steps_planned", run.steps_planned},
               {"wall_s", run.wall},
               {"contacts_mean", run.contacts_mean},
               {"contacts_max", run.contacts_max},
               {"groups_mean", run.groups_mean},
               {"newton_per_group_mean", run.newton_mean},
               {"newton_per_group_weighted", run.newton_weighted},
               {"newton_per_group_max", run.newton_max},
               {"gs_sweeps_per_step", run.gs_sweeps_per_step},
               {"max_strain", run.max_strain},
               {"message", run.message}}
              .dump()
       << std::endl;
    fmt::print("| {} | {} | {} | {}/{} | {} | {:.3g} | {:.1f} | {} | {:.1f} | {:.3f} | {:.3f} | {} | {:.1f} | {:.3g} |\n", run.strategy,
               dt_text(run.dt), run.ok() ? "✓" : std::string("✗ ") + to_string(run.outcome), run.steps, run.steps_planned,
               duration_text(run.wall), run.steps ? run.wall / run.steps : 0.0, run.contacts_mean, run.contacts_max, run.groups_mean,
               run.newton_mean, run.newton_weighted, run.newton_max, run.gs_sweeps_per_step, run.max_strain);
    std::fflush(stdout);
    runs.push_back(run);
    std::ofstream(out / "bench_hair.md") << report(title, strategies, dts, runs);
  }
  std::ofstream(out / "bench_hair.md") << report(title, strategies, dts, runs);
  fmt::print("\n{}", report("", strategies, dts, runs).substr(0));
  fmt::print("\nFiles: {}/bench_hair.csv, bench_hair.jsonl, bench_hair.md\n", out.string());
  return exit_ok;
}

}  // namespace weft::app
