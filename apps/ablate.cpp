#include "apps/ablate.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <sstream>

#include "apps/bench_common.hpp"
#include "apps/plots.hpp"
#include "contact/rods/rod_verify.hpp"
#include "contact/verify/intersection_check.hpp"
#include "framework/timers.hpp"
#include "policies/registry.hpp"

namespace weft::app {
namespace {

const ComboInfo* find_combo(std::string_view name) {
  for (const ComboInfo& c : combos())
    if (c.key == name) return &c;
  return nullptr;
}

bool direct(const ComboInfo& c) { return c.linear == "direct" || c.linear == "banded_lu"; }

/// The reference combination: the scene's own when it solves directly, else the
/// combination with the same energy, integrator and contact and a direct solver.
std::string default_reference(const Scene& scene) {
  const ComboInfo& own = resolve_combo(scene);
  if (direct(own)) return std::string(own.key);
  for (std::string_view solver : {"direct", "banded_lu"})
    if (const ComboInfo* c = sibling(own, solver); c && not_applicable_reason(*c, scene).empty()) return std::string(c->key);
  return std::string(own.key);
}

/// Penetrations of a state, by checks independent of the detection code: rod overlaps and
/// rod points inside obstacles (contact/rods/rod_verify.hpp), cloth-cloth triangle
/// intersections (contact/verify) and cloth vertices inside obstacles.
int penetrations(const Scene& scene, const State& s) {
  std::vector<Eigen::Vector3d> x(s.num_vertices());
  for (int i = 0; i < s.num_vertices(); ++i) x[i] = s.position(i);
  int n = 0;
  if (scene.rods.num_rods() > 0) {
    std::vector<double> radius(scene.rods.num_rods());
    for (int r = 0; r < scene.rods.num_rods(); ++r) radius[r] = scene.spec.rods[scene.rods.family[r]].material.radius;
    n += contact::rods::count_rod_overlaps(x, scene.rods.first, radius, 1e-7, 2);
    n += contact::rods::count_obstacle_penetrations(x, scene.rods.first, radius, scene.spec.obstacles, s.t, 1e-7);
    return n;
  }
  if (scene.mesh.faces().rows() > 0)
    n += static_cast<int>(contact::verify::check_self_intersections(s.x, scene.mesh.faces()).num_pairs);
  if (!scene.spec.obstacles.empty()) {  // every vertex a point of radius 0
    std::vector<int> first(x.size() + 1);
    std::iota(first.begin(), first.end(), 0);
    n += contact::rods::count_obstacle_penetrations(x, first, std::vector<double>(x.size(), 0.0), scene.spec.obstacles, s.t, 1e-7);
  }
  return n;
}

/// Diagonal of the bounding box of the initial vertices (1 m for a single point).
double scene_size(const State& s) {
  if (s.num_vertices() == 0) return 1;
  Eigen::Vector3d lo = s.position(0), hi = lo;
  for (int i = 1; i < s.num_vertices(); ++i) lo = lo.cwiseMin(s.position(i)), hi = hi.cwiseMax(s.position(i));
  const double L = (hi - lo).norm();
  return L > 0 ? L : 1;
}

double total_energy(const AnySimulator& sim) {
  const EnergyReport e = sim.energies();
  return e.kinetic + e.potential;
}

struct Trajectory {
  std::vector<Eigen::VectorXd> frames;  ///< positions at frame k (time k / frame_rate)
};

/// Runs one combination, frames compared to `ref` (null: record them into `own`).
AblateRow run_one(const std::string& scene_path, const std::vector<std::string>& ov, const Trajectory* ref, Trajectory* own,
                  double size, Json& history, bool quiet) {
  AblateRow row;
  auto sim = make_simulator(load_scene(scene_path, ov));
  row.combo = std::string(sim->combo());
  const Scene& scene = sim->scene();
  const int spf = scene.spec.time.steps_per_frame();
  row.steps_planned = static_cast<int>(std::min<long long>(scene.spec.time.num_steps(), std::numeric_limits<int>::max()));  // frame 0 is the initial state
  row.stage_seconds.assign(static_cast<int>(Stage::count_), 0.0);
  const double E0 = total_energy(*sim);
  // Energy scale: the largest kinetic energy plus magnitude of every potential term seen
  // (a sheet starting flat at rest has zero energy at t = 0).
  auto energy_scale = [&] {
    const EnergyReport e = sim->energies();
    double m = e.kinetic;
    for (const auto& [name, v] : e.terms) m += std::abs(v);
    return m;
  };
  double scale = energy_scale();
  if (own) own->frames.push_back(sim->state().x);
  double sum2 = 0;
  long count = 0;
  int worst_newton = -1;
  const auto start = std::chrono::steady_clock::now();
  for (int k = 1; k <= row.steps_planned; ++k) {
    const StepReport r = sim->step();
    row.steps = k;
    for (int s = 0; s < static_cast<int>(Stage::count_); ++s) row.stage_seconds[s] += r.times.seconds[s];
    row.newton_iterations += r.newton.iterations;
    row.linear_iterations += r.linear.iterations;
    row.contacts += r.contact.contacts;
    if (r.newton.iterations > worst_newton && !r.newton.history.empty()) {
      worst_newton = r.newton.iterations;
      Json res = Json::array();
      for (const NewtonIteration& it : r.newton.history) res.push_back(it.residual);
      res.push_back(r.newton.final_residual);
      history = {{"label", row.combo}, {"step", k}, {"residuals", res}};
    }
    if (!r.ok()) {
      row.status = fmt::format("failed at step {} ({}): {}", r.step, r.failed_stage, r.message);
      break;
    }
    if (k % spf && k != row.steps_planned) continue;
    const State& s = sim->state();
    const int frame = (k + spf - 1) / spf;  // the last frame may be shorter
    if (own) own->frames.push_back(s.x);
    if (ref && frame < static_cast<int>(ref->frames.size())) {
      const Eigen::VectorXd& xr = ref->frames[frame];
      for (int i = 0; i < s.num_vertices(); ++i) {
        const double d = (s.position(i) - xr.segment<3>(3 * i)).norm();
        sum2 += d * d;
        row.max_error = std::max(row.max_error, d / size);
        ++count;
      }
      ++row.frames_compared;
    }
    scale = std::max(scale, energy_scale());
    const int p = penetrations(scene, s);
    row.penetrations_max = std::max(row.penetrations_max, p);
    row.penetrations_end = p;
  }
  row.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  row.rms_error = count ? std::sqrt(sum2 / count) / size : 0;
  row.energy_drift = (total_energy(*sim) - E0) / std::max(scale, 1e-300);
  if (!quiet)
    fmt::print(stderr, "{}: {} ({} of {} steps, {:.2f} s), rms error {:.3g}\n", row.combo, row.status, row.steps,
               row.steps_planned, row.wall_seconds, row.rms_error);
  return row;
}

/// A row's name in tables and plots: the combination, and its sweep point if any.
std::string label(const AblateRow& r) { return r.point.empty() ? r.combo : r.combo + " " + r.point; }

/// One run's overrides: the user's, the combination's, the sweep point's, the duration.
std::vector<std::string> run_overrides(const AblateOptions& opt, const std::string& combo, const std::vector<std::string>& point) {
  std::vector<std::string> ov = opt.overrides;
  append_combo_overrides(ov, combo);
  ov.insert(ov.end(), point.begin(), point.end());
  if (opt.duration > 0) ov.push_back(fmt::format("time.duration={}", opt.duration));
  return ov;
}

/// The sweep points: the product of the sweeps' values, each point one override per sweep.
std::vector<std::vector<std::string>> sweep_points(const std::vector<std::string>& sweeps, std::vector<std::string>& problems) {
  std::vector<std::vector<std::string>> points = {{}};
  for (const std::string& sw : sweeps) {
    const size_t eq = sw.find('=');
    std::vector<std::string> values;
    if (eq != std::string::npos) {
      std::string item;
      std::stringstream ss(sw.substr(eq + 1));
      while (std::getline(ss, item, ','))
        if (!item.empty()) values.push_back(item);
    }
    if (eq == std::string::npos || eq == 0 || values.empty()) {
      problems.push_back(fmt::format("--sweep \"{}\": expected KEY=V1,V2,... (e.g. time.dt=0.01,0.005)", sw));
      continue;
    }
    std::vector<std::vector<std::string>> next;
    for (const auto& p : points)
      for (const std::string& v : values) {
        next.push_back(p);
        next.back().push_back(sw.substr(0, eq) + "=" + v);
      }
    points = std::move(next);
  }
  return points;
}

std::string csv_header() {
  std::string h = "combo,point,label,status,steps,steps_planned,frames_compared,rms_error,max_error,energy_drift,penetrations_max,"
                  "penetrations_end,newton_iterations,linear_iterations,contacts,wall_seconds";
  for (std::string_view s : stage_names) h += fmt::format(",seconds_{}", s);
  return h + "\n";
}

std::string csv_row(const AblateRow& r) {
  std::string line = fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}", r.combo, csv_field(r.point), csv_field(label(r)),
                                 csv_field(r.status == "ok" ? "ok" : r.status),
                                 r.steps, r.steps_planned, r.frames_compared, r.rms_error, r.max_error, r.energy_drift,
                                 r.penetrations_max, r.penetrations_end, r.newton_iterations, r.linear_iterations, r.contacts,
                                 r.wall_seconds);
  for (double s : r.stage_seconds) line += fmt::format(",{}", s);
  return line + "\n";
}

Json to_json(const AblateRow& r) {
  Json stages = Json::object();
  for (size_t s = 0; s < r.stage_seconds.size(); ++s) stages[std::string(stage_names[s])] = r.stage_seconds[s];
  return {{"combo", r.combo}, {"point", r.point}, {"status", r.status}, {"steps", r.steps}, {"steps_planned", r.steps_planned},
          {"frames_compared", r.frames_compared}, {"rms_error", r.rms_error}, {"max_error", r.max_error},
          {"energy_drift", r.energy_drift}, {"penetrations_max", r.penetrations_max}, {"penetrations_end", r.penetrations_end},
          {"newton_iterations", r.newton_iterations}, {"linear_iterations", r.linear_iterations}, {"contacts", r.contacts},
          {"wall_seconds", r.wall_seconds}, {"stage_seconds", stages}};
}

}  // namespace

int run_ablate(const AblateOptions& opt, std::vector<AblateRow>* out_rows) {
  // Everything is validated before any run: the scene, every combination, the reference.
  std::vector<std::string> names;
  std::vector<std::vector<std::string>> points;
  std::string reference;
  std::vector<std::string> ref_ov;
  try {
    const Scene scene = load_scene(opt.scene, opt.overrides);
    std::vector<std::string> problems;
    if (opt.combos.size() == 1 && opt.combos[0] == "applicable") {
      for (const ComboInfo& c : combos())
        if (not_applicable_reason(c, scene).empty()) names.emplace_back(c.key);
    } else {
      for (const std::string& n : opt.combos) {
        const ComboInfo* c = find_combo(n);
        if (!c) problems.push_back(fmt::format("--combos: \"{}\" is not a pre-built combination (weft list)", n));
        else if (const std::string why = not_applicable_reason(*c, scene); !why.empty())
          problems.push_back(fmt::format("--combos: \"{}\" does not apply to this scene: {}", n, why));
        else names.push_back(n);
      }
    }
    if (names.empty() && problems.empty()) problems.push_back("--combos: no combination to run");
    points = sweep_points(opt.sweeps, problems);
    if (opt.reference_substeps < 1) problems.push_back(fmt::format("--reference-substeps = {} must be >= 1", opt.reference_substeps));
    if (!problems.empty()) throw ConfigError(fmt::format("{}: cannot ablate", opt.scene), problems);
    double smallest_dt = scene.spec.time.dt;
    for (const std::string& n : names)
      for (const auto& point : points)
        smallest_dt = std::min(smallest_dt, make_simulator(load_scene(opt.scene, run_overrides(opt, n, point)))->scene().spec.time.dt);
    reference = opt.reference.empty() ? default_reference(scene) : opt.reference;
    ref_ov = opt.overrides;
    append_combo_overrides(ref_ov, reference);
    if (opt.duration > 0) ref_ov.push_back(fmt::format("time.duration={}", opt.duration));
    ref_ov.push_back(fmt::format("time.dt={}", smallest_dt / opt.reference_substeps));
    make_simulator(load_scene(opt.scene, ref_ov));
    // Tight tolerances where the reference's policies have them (each kept only if accepted).
    if (opt.reference_tighten)
      for (const char* t : {"integrator.relative_tolerance=1e-10", "integrator.length_tolerance=1e-12", "integrator.tolerance=1e-12",
                            "integrator.max_iterations=1000"}) {
        std::vector<std::string> trial = ref_ov;
        trial.emplace_back(t);
        try {
          make_simulator(load_scene(opt.scene, trial));
          ref_ov = std::move(trial);
        } catch (const ConfigError&) {
        }
      }
  } catch (const ConfigError& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 2;
  }

  std::filesystem::create_directories(opt.out_dir);
  const std::filesystem::path dir(opt.out_dir);
  std::ofstream csv((dir / "ablate.csv").string());
  std::ofstream hist((dir / "histories.jsonl").string());
  csv << csv_header();
  Json doc = {{"scene", opt.scene}, {"overrides", opt.overrides}, {"sweeps", opt.sweeps}};
  doc["reference"] = {{"combo", reference}, {"overrides", ref_ov}};
  auto write_json = [&](const std::vector<AblateRow>& rows) {
    Json r = Json::array();
    for (const AblateRow& row : rows) r.push_back(to_json(row));
    doc["rows"] = r;
    std::ofstream((dir / "ablate.json").string()) << doc.dump(2) << "\n";
  };

  Trajectory ref;
  const State s0 = make_simulator(load_scene(opt.scene, ref_ov))->state();
  const double size = scene_size(s0);
  doc["scene_size_m"] = size;
  Json ref_hist;
  AblateRow ref_row = run_one(opt.scene, ref_ov, nullptr, &ref, size, ref_hist, opt.quiet);
  doc["reference"]["status"] = ref_row.status;
  doc["reference"]["wall_seconds"] = ref_row.wall_seconds;
  if (ref_row.status != "ok") {
    write_json({});
    fmt::print(stderr, "error: the reference run {} {}\n", reference, ref_row.status);
    return 3;
  }
  std::vector<AblateRow> rows;
  for (const std::string& n : names)
    for (const auto& point : points) {
      Json h;
      AblateRow row = run_one(opt.scene, run_overrides(opt, n, point), &ref, nullptr, size, h, opt.quiet);
      row.point = fmt::format("{}", fmt::join(point, " "));
      if (!h.is_null()) h["label"] = label(row);
      rows.push_back(std::move(row));
      csv << csv_row(rows.back());
      csv.flush();
      if (!h.is_null()) hist << h.dump() << "\n" << std::flush;
      write_json(rows);
    }
  csv.close();
  hist.close();

  fmt::print("ablation of {} against {} (dt / {}{}); errors are vertex distances / scene size {:.3g} m\n\n", opt.scene, reference,
             opt.reference_substeps, opt.reference_tighten ? ", tight tolerances" : "", size);
  fmt::print("| combination | status | RMS error | max error | energy drift | penetrations (max) | Newton it. | linear it. | wall [s] |"
             " contact [s] |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const AblateRow& r : rows)
    fmt::print("| {} | {} | {:.3e} | {:.3e} | {:.2e} | {} | {} | {} | {:.3f} | {:.3f} |\n", label(r), r.status, r.rms_error, r.max_error,
               r.energy_drift, r.penetrations_max, r.newton_iterations, r.linear_iterations, r.wall_seconds,
               r.stage_seconds[static_cast<int>(Stage::contact)]);
  fmt::print("\ntables: {}, {}\n", (dir / "ablate.csv").string(), (dir / "ablate.json").string());
  if (opt.plots) {
    const std::string csv_path = (dir / "ablate.csv").string(), hist_path = (dir / "histories.jsonl").string();
    // One curve per combination through its sweep points (a single point each without sweeps).
    bool written = plot("pareto", csv_path, opt.out_dir, {"--x", "wall_seconds", "--y", "rms_error", "--label", "combo", "--point", "point"}) ==
                   PlotOutcome::written;
    written = plot("stages", csv_path, opt.out_dir, {"--label", "label"}) == PlotOutcome::written && written;
    if (std::filesystem::file_size(hist_path) > 0) written = plot("histories", hist_path, opt.out_dir) == PlotOutcome::written && written;
    if (written) fmt::print(stderr, "plots: {}/{{pareto,stages,histories}}.{{png,svg}}\n", opt.out_dir);
  }
  if (out_rows) *out_rows = std::move(rows);
  return 0;
}

}  // namespace weft::app
