#include "apps/stability.hpp"

#include "apps/bench_common.hpp"
#include "apps/plots.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>

#include "framework/scene.hpp"
#include "framework/writers.hpp"
#include "policies/registry.hpp"

namespace weft::app {

const char* to_string(Stability s) {
  switch (s) {
    case Stability::stable: return "stable";
    case Stability::diverged: return "diverged";
    case Stability::not_converged: return "not_converged";
    case Stability::excessive_strain: return "excessive_strain";
    case Stability::invalid: return "invalid";
  }
  return "?";
}

double max_edge_strain(const Scene& scene, const State& s) {
  double m = 0;
  const RodSet& rods = scene.rods;  // rod edges: vertices i, i + 1 of each rod (rest in the interleaved layout)
  for (int r = 0; r < rods.num_rods(); ++r)
    for (int i = 0; i + 1 < rods.rod_vertices(r); ++i) {
      const double l0 = (rods.rest[r].segment<3>(4 * i + 4) - rods.rest[r].segment<3>(4 * i)).norm();
      const double l = (s.position(rods.first[r] + i + 1) - s.position(rods.first[r] + i)).norm();
      m = std::max(m, std::abs(l / l0 - 1.0));
    }
  for (const auto& e : scene.mesh.edges()) {
    const double l0 = (scene.mesh.rest().row(e[0]) - scene.mesh.rest().row(e[1])).norm();
    const double l = (s.position(e[0]) - s.position(e[1])).norm();
    m = std::max(m, std::abs(l / l0 - 1.0));
  }
  return m;
}

namespace {

char symbol(Stability s) {
  switch (s) {
    case Stability::stable: return '.';
    case Stability::diverged: return 'D';
    case Stability::not_converged: return 'N';
    case Stability::excessive_strain: return 'S';
    case Stability::invalid: return '?';
  }
  return '?';
}

StabilityResult run_cell(const StabilityOptions& opt, const std::string& combo, double dt, const std::string& value) {
  StabilityResult res;
  res.combo = combo;
  res.dt = dt;
  res.value = value;
  std::vector<std::string> ov = opt.overrides;
  const auto start = std::chrono::steady_clock::now();
  std::unique_ptr<AnySimulator> sim;
  try {
    ov.push_back(whole_steps_duration(opt.scene, opt.overrides, dt, opt.duration));  // the duration on this dt's grid
    ov.push_back(fmt::format("time.dt={}", dt));
    // dt <= 1/frame_rate makes any dt valid; the scene caps the frame rate (10^4 /s), and no
    // frame is written here, so steps below 1 ms run at 1000 frames per second.
    ov.push_back(fmt::format("time.frame_rate={}", std::min(1.0 / dt, 1000.0)));
    if (!combo.empty()) append_combo_overrides(ov, combo);
    if (!opt.vary_key.empty()) ov.push_back(opt.vary_key + "=" + value);
    sim = make_simulator(load_scene(opt.scene, ov));
  } catch (const ConfigError& e) {
    res.outcome = Stability::invalid;
    res.message = e.what();
    return res;
  }
  res.combo = std::string(sim->combo());
  const Scene& scene = sim->scene();
  res.steps_planned = static_cast<int>(std::lround(scene.spec.time.duration / dt));
  const EnergyReport e0 = sim->energies();
  const double E0 = e0.kinetic + e0.potential;
  // Energy scale: the initial kinetic energy plus the magnitude of every potential term.
  double scale = e0.kinetic;
  for (const auto& [n, v] : e0.terms) scale += std::abs(v);
  scale = std::max(scale, 1e-12);
  bool scripted = false;
  for (const auto& o : scene.spec.obstacles) scripted |= !o.motion.is_static();
  for (const auto& c : scene.spec.cloths)
    for (const auto& p : c.pins) scripted |= !p.motion.is_static();
  for (const auto& f : scene.spec.rods) scripted |= f.root_held != RodRoot::free && !f.motion.is_static();
  long newton = 0;
  for (int k = 0; k < res.steps_planned; ++k) {
    const StepReport r = sim->step();
    res.steps = k + 1;
    newton += r.newton.iterations;
    res.newton_max = std::max(res.newton_max, r.newton.iterations);
    res.contact_steps += r.contact.contacts > 0;
    if (!r.ok()) {
      const bool nan = r.message.find("non-finite") != std::string::npos;
      res.outcome = nan ? Stability::diverged : Stability::not_converged;
      res.message = fmt::format("step {}: {}: {}", r.step, r.failed_stage, r.message);
      break;
    }
    const double E = r.energy.kinetic + r.energy.potential;
    res.energy_ratio = (E - E0) / scale;
    // A scripted motion (a whipping handle, a moving obstacle) feeds energy in: there only a
    // non-finite energy counts as a blow-up.
    if (!std::isfinite(E) || (!scripted && E > E0 + opt.energy_growth * scale)) {
      res.outcome = Stability::diverged;
      res.message = fmt::format("step {}: total energy rose by {:.3g} of its scale", r.step, res.energy_ratio);
      break;
    }
    res.max_strain = std::max(res.max_strain, max_edge_strain(scene, sim->state()));
    if (res.max_strain > opt.strain_threshold) {
      res.outcome = Stability::excessive_strain;
      res.message = fmt::format("step {}: edge strain {:.3g} > {}", r.step, res.max_strain, opt.strain_threshold);
      break;
    }
  }
  res.newton_mean = res.steps ? static_cast<double>(newton) / res.steps : 0;
  res.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return res;
}

}  // namespace

int run_stability(const StabilityOptions& opt, std::vector<StabilityResult>* out) {
  // Validate the scene and every combination before any run.
  try {
    const Scene scene = load_scene(opt.scene, opt.overrides);
    for (const auto& c : opt.combos) {
      if (c.empty()) continue;
      std::vector<std::string> ov = opt.overrides;
      append_combo_overrides(ov, c);
      make_simulator(load_scene(opt.scene, ov));
    }
  } catch (const ConfigError& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 2;
  }
  if (opt.dts.empty()) {
    fmt::print(stderr, "error: --dt needs at least one time step\n");
    return 2;
  }
  std::vector<std::string> values = opt.vary_values;
  if (opt.vary_key.empty()) values = {""};
  std::vector<std::string> combos = opt.combos.empty() ? std::vector<std::string>{""} : opt.combos;

  std::filesystem::create_directories(opt.out_dir);
  {
    // What made this sweep: the build, the machine and the command, beside its table.
    Json meta = meta_record("stability", cpu_model(), worker_threads());
    meta["scene"] = opt.scene;
    meta["overrides"] = opt.overrides;
    meta["combos"] = opt.combos;
    meta["dts"] = opt.dts;
    meta["vary"] = {{"key", opt.vary_key}, {"values", opt.vary_values}};
    meta["duration"] = opt.duration;
    meta["strain_threshold"] = opt.strain_threshold;
    std::ofstream((std::filesystem::path(opt.out_dir) / "stability_meta.json").string()) << meta.dump(1) << "\n";
  }
  const std::string csv_path = (std::filesystem::path(opt.out_dir) / "stability.csv").string();
  std::ofstream csv(csv_path);
  csv << "combo,dt,key,value,outcome,steps,steps_planned,max_strain,energy_change,newton_mean,newton_max,wall_seconds,contact_steps,"
         "message\n";
  std::vector<StabilityResult> all;
  for (const auto& combo : combos)
    for (double dt : opt.dts)
      for (const auto& v : values) {
        StabilityResult r = run_cell(opt, combo, dt, v);
        csv << fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n", r.combo, r.dt, opt.vary_key, csv_field(r.value),
                           to_string(r.outcome), r.steps, r.steps_planned, r.max_strain, r.energy_ratio, r.newton_mean,
                           r.newton_max, r.wall_seconds, r.contact_steps, csv_field(r.message));
        csv.flush();
        if (!opt.quiet)
          fmt::print(stderr, "{} dt={} {}={}: {} ({} of {} steps, {:.1f} s)\n", r.combo, r.dt, opt.vary_key, r.value,
                     to_string(r.outcome), r.steps, r.steps_planned, r.wall_seconds);
        all.push_back(std::move(r));
      }
  // The map: one block per combination, dt down, values across. When some run of the sweep
  // had contacts, a stable run without any is `o`: it did not test the contact method.
  const bool any_contact = std::any_of(all.begin(), all.end(), [](const StabilityResult& r) { return r.contact_steps > 0; });
  auto cell = [&](const StabilityResult& r) {
    return any_contact && r.outcome == Stability::stable && r.contact_steps == 0 ? 'o' : symbol(r.outcome);
  };
  std::string map;
  size_t k = 0;
  for (size_t c = 0; c < combos.size(); ++c) {
    map += fmt::format("{}  (. stable, {}D diverged, N not converged, S excessive strain, ? invalid)\n", all[k].combo,
                       any_contact ? "o stable without any contact, " : "");
    map += fmt::format("{:>12} | {}\n", "dt \\ " + (opt.vary_key.empty() ? std::string("-") : opt.vary_key),
                       fmt::join(values, " "));
    for (size_t i = 0; i < opt.dts.size(); ++i) {
      std::string row;
      for (size_t j = 0; j < values.size(); ++j, ++k) row += std::string(std::max<size_t>(1, values[j].size()) - 1, ' ') + cell(all[k]) + " ";
      map += fmt::format("{:>12} | {}\n", fmt::format("{:.4g}", opt.dts[i]), row);
    }
    map += "\n";
  }
  std::ofstream((std::filesystem::path(opt.out_dir) / "stability_map.txt").string()) << map;
  fmt::print("{}", map);
  fmt::print("table: {}\n", csv_path);
  csv.close();
  if (opt.plots && plot("stability", csv_path, opt.out_dir) == PlotOutcome::written)
    fmt::print("map: {}/stability_map.{{png,svg}}\n", opt.out_dir);
  if (out) *out = std::move(all);
  return 0;
}

}  // namespace weft::app
