#include "apps/bench_contact.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "apps/bench_common.hpp"
#include "framework/build_info.hpp"
#include "apps/runner.hpp"
#include "contact/verify/intersection_check.hpp"
#include "framework/error.hpp"
#include "framework/params_json.hpp"
#include "framework/scene.hpp"
#include "policies/registry.hpp"

namespace weft::app {
namespace {

namespace fs = std::filesystem;


/// Sums over the counted steps of one resolution.
struct Totals {
  int steps = 0;
  double wall = 0, detection = 0, response = 0, solve = 0, contact_stage = 0, energy = 0, hessian = 0, linear_setup = 0,
         linear_solve = 0, line_search = 0;
  long long contacts = 0, obstacle_contacts = 0, proximity_contacts = 0, ccd_hits = 0, impulses = 0, impact_zones = 0,
            zone_iterations = 0, newton = 0, linear = 0;
  int contact_steps = 0;  ///< counted steps with at least one contact
  int max_contacts = 0;
  double max_penetration = 0;
  long long intersections = -1;  ///< summed over the checked steps (-1: not checked)
  std::vector<double> step_seconds;
  double per_step(double x) const { return steps ? x / steps : 0; }
  double share(double x) const { return wall > 0 ? x / wall : 0; }
  double median_step() const {
    if (step_seconds.empty()) return 0;
    std::vector<double> v = step_seconds;
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
  }
};

/// "81" -> [81, 81], "51x21" -> [51, 21]; anything else is a ConfigError.
std::array<int, 2> parse_resolution(const std::string& s) {
  auto number = [&](const std::string& t) {
    size_t used = 0;
    int n = 0;
    try {
      n = std::stoi(t, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != t.size() || n < 2)
      throw ConfigError(fmt::format("--resolutions: '{}' is neither n nor nxm with n, m >= 2 (e.g. 81 or 51x21)", s));
    return n;
  };
  const auto x = s.find('x');
  if (x == std::string::npos) {
    const int n = number(s);
    return {n, n};
  }
  return {number(s.substr(0, x)), number(s.substr(x + 1))};
}

}  // namespace

int bench_contact(const BenchContactOptions& opt) {
  const std::string data = app::data_dir();
  const std::string scene_path =
      !opt.scene.empty() ? opt.scene : (fs::path(data) / "scenes" / "drape_sphere.json").string();
  std::vector<std::string> resolutions = opt.resolutions;
  if (resolutions.empty() && opt.drape)
    for (int n = 11; n <= 81; n += 2) resolutions.push_back(std::to_string(n));
  if (resolutions.empty() && opt.quick) resolutions.push_back("11");
  if (resolutions.empty()) resolutions.push_back("");  // the scene's own
  const int skip = std::max(0, opt.skip);

  // Validate every case before any work (exit 2 with the key and value).
  std::vector<std::vector<std::string>> case_overrides;
  std::vector<int> case_steps;
  try {
    for (const std::string& res : resolutions) {
      std::vector<std::string> ov = opt.overrides;
      if (!opt.combo.empty()) ov.push_back("combo=" + opt.combo);
      if (!res.empty()) {
        const auto r = parse_resolution(res);
        ov.push_back(fmt::format("cloths.0.mesh.resolution=[{},{}]", r[0], r[1]));
      }
      const Scene scene = load_scene(scene_path, ov);
      const ComboInfo* combo = nullptr;
      for (const auto& c : combos())
        if (c.key == scene.spec.combo) combo = &c;
      if (!combo) throw ConfigError(fmt::format("unknown combination '{}' (see `weft list`)", scene.spec.combo));
      const std::string why = not_applicable_reason(*combo, scene);
      if (!why.empty()) throw ConfigError(fmt::format("{} does not apply to {}: {}", scene.spec.combo, scene_path, why));
      const int scene_steps = static_cast<int>(std::lround(scene.spec.time.duration / scene.spec.time.dt));
      const int counted = opt.steps > 0 ? opt.steps : opt.quick ? 4 : std::max(1, scene_steps - skip);
      case_overrides.push_back(ov);
      case_steps.push_back(counted);
    }
  } catch (const ConfigError& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return exit_config;
  }

  const int threads = worker_threads();
  const std::string cpu = cpu_model(), git = build_commit();
  const fs::path out = opt.out_dir.empty() ? fs::path("out/bench_contact") : fs::path(opt.out_dir);
  std::ofstream jl, csv;
  try {
    fs::create_directories(out);
    jl.open(out / "bench_contact.jsonl");
    csv.open(out / "bench_contact.csv");
    if (!jl || !csv) throw std::runtime_error("cannot open the output files");
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}: {}\n", out.string(), e.what());
    return exit_config;
  }
  Json meta = meta_record("contact", cpu, threads);
  meta.update(Json{{"scene", scene_path},
             {"overrides", opt.overrides},
             {"skip", skip},
             {"check", opt.check},
             {"quick", opt.quick}});
  jl << meta.dump() << '\n';
  csv << "scene,combo,resolution,vertices,faces,first_step,steps,seconds_per_step,median_step_s,detection_share,"
         "response_share,solve_share,contact_stage_share,energy_share,hessian_share,linear_setup_share,linear_solve_share,"
         "contacts_per_step,max_contacts,contact_steps,obstacle_contacts_per_step,proximity_contacts_per_step,"
         "ccd_hits_per_step,impulses_per_step,impact_zones_per_step,zone_iterations_per_step,newton_per_step,"
         "linear_per_step,max_penetration_m,intersections,status\n";
  csv.flush();

  const std::string scene_name = fs::path(scene_path).stem().string();
  fmt::print("# weft bench contact: {}\n\nHardware: {} ({} hardware threads, {} OpenMP threads); git {}; {}\n\n", scene_name, cpu,
             std::thread::hardware_concurrency(), threads, git, build_flags());
  fmt::print("Shares are of the summed wall time of the counted steps {}..{} of each run (steps 1..{} run, not counted).\n\n",
             skip + 1, skip + case_steps.front(), skip);
  fmt::print("| resolution | vertices | s/step | detection | response | solve | contacts/step | CCD hits/step | impact zones/step "
             "| Newton/step | linear it./step | intersections | status |\n");
  fmt::print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n");
  std::fflush(stdout);

  int exit_code = exit_ok;
  const auto t_all = Clock::now();
  for (size_t c = 0; c < resolutions.size(); ++c) {
    const Scene scene = load_scene(scene_path, case_overrides[c]);
    const std::string res_label =
        fmt::format("{}x{}", scene.spec.cloths[0].mesh.resolution[0], scene.spec.cloths[0].mesh.resolution[1]);
    auto sim = make_simulator(scene);
    Totals tot;
    if (opt.check) tot.intersections = 0;
    std::string status = "ok";
    const int total_steps = skip + case_steps[c];
    for (int k = 1; k <= total_steps; ++k) {
      const auto t0 = Clock::now();
      const StepReport r = sim->step();
      const double wall = seconds_since(t0);
      if (!r.ok()) {
        status = fmt::format("step {} failed in {}: {}", r.step, r.failed_stage, r.message);
        exit_code = exit_failed;
        break;
      }
      if (!sim->state().x.allFinite()) {
        status = fmt::format("step {}: non-finite positions", r.step);
        exit_code = exit_failed;
        break;
      }
      std::int64_t inter = -1;
      if (opt.check) {
        inter = contact::verify::check_self_intersections(sim->state().x, scene.mesh.faces()).num_pairs;
        tot.intersections += inter;
      }
      const ContactReport& cr = r.contact;
      const StageTimes& st = r.times;
      const double solve = st[Stage::energy] + st[Stage::hessian] + st[Stage::linear_setup] + st[Stage::linear_solve] +
                           st[Stage::line_search];
      jl << Json{{"record", "step"},
                 {"resolution", res_label},
                 {"step", r.step},
                 {"counted", k > skip},
                 {"wall_s", wall},
                 {"detection_s", cr.detection_seconds},
                 {"response_s", cr.response_seconds},
                 {"solve_s", solve},
                 {"contact_stage_s", st[Stage::contact]},
                 {"contacts", cr.contacts},
                 {"obstacle_contacts", cr.obstacle_contacts},
                 {"proximity_contacts", cr.proximity_contacts},
                 {"ccd_hits", cr.ccd_hits},
                 {"impulses", cr.impulses},
                 {"impact_zones", cr.impact_zones},
                 {"zone_iterations", cr.zone_iterations},
                 {"newton", r.newton.iterations},
                 {"linear", r.linear.iterations},
                 {"max_penetration", cr.max_penetration},
                 {"intersections", inter}}
                .dump()
         << std::endl;  // every step: an interrupted long run keeps what it measured
      if (k <= skip) continue;
      ++tot.steps;
      tot.step_seconds.push_back(wall);
      tot.wall += wall;
      tot.detection += cr.detection_seconds;
      tot.response += cr.response_seconds;
      tot.solve += solve;
      tot.contact_stage += st[Stage::contact];
      tot.energy += st[Stage::energy];
      tot.hessian += st[Stage::hessian];
      tot.linear_setup += st[Stage::linear_setup];
      tot.linear_solve += st[Stage::linear_solve];
      tot.line_search += st[Stage::line_search];
      tot.contacts += cr.contacts;
      tot.max_contacts = std::max(tot.max_contacts, cr.contacts);
      tot.contact_steps += cr.contacts > 0;
      tot.obstacle_contacts += cr.obstacle_contacts;
      tot.proximity_contacts += cr.proximity_contacts;
      tot.ccd_hits += cr.ccd_hits;
      tot.impulses += cr.impulses;
      tot.impact_zones += cr.impact_zones;
      tot.zone_iterations += cr.zone_iterations;
      tot.newton += r.newton.iterations;
      tot.linear += r.linear.iterations;
      tot.max_penetration = std::max(tot.max_penetration, cr.max_penetration);
    }
    const int V = sim->state().num_vertices();
    const int F = static_cast<int>(scene.mesh.faces().rows());
    csv << fmt::format(
        "{},{},{},{},{},{},{},{:.6e},{:.6e},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.2f},{},{},{:.2f},{:.2f},"
        "{:.3f},{:.2f},{:.3f},{:.3f},{:.3f},{:.2f},{:.3e},{},\"{}\"\n",
        scene_name, scene.spec.combo, res_label, V, F, skip + 1, tot.steps, tot.per_step(tot.wall), tot.median_step(),
        tot.share(tot.detection), tot.share(tot.response), tot.share(tot.solve), tot.share(tot.contact_stage),
        tot.share(tot.energy), tot.share(tot.hessian), tot.share(tot.linear_setup), tot.share(tot.linear_solve),
        tot.per_step(tot.contacts), tot.max_contacts, tot.contact_steps, tot.per_step(tot.obstacle_contacts),
        tot.per_step(tot.proximity_contacts), tot.per_step(tot.ccd_hits), tot.per_step(tot.impulses),
        tot.per_step(tot.impact_zones), tot.per_step(tot.zone_iterations), tot.per_step(tot.newton), tot.per_step(tot.linear),
        tot.max_penetration, tot.intersections, status);
    csv.flush();
    jl << Json{{"record", "resolution"},
               {"scene", scene_name},
               {"combo", scene.spec.combo},
               {"resolution", res_label},
               {"vertices", V},
               {"faces", F},
               {"first_step", skip + 1},
               {"steps", tot.steps},
               {"seconds_per_step", tot.per_step(tot.wall)},
               {"median_step_s", tot.median_step()},
               {"detection_share", tot.share(tot.detection)},
               {"response_share", tot.share(tot.response)},
               {"solve_share", tot.share(tot.solve)},
               {"stage_shares",
                {{"energy", tot.share(tot.energy)},
                 {"hessian", tot.share(tot.hessian)},
                 {"linear_setup", tot.share(tot.linear_setup)},
                 {"linear_solve", tot.share(tot.linear_solve)},
                 {"line_search", tot.share(tot.line_search)},
                 {"contact", tot.share(tot.contact_stage)}}},
               {"contacts_per_step", tot.per_step(tot.contacts)},
               {"max_contacts", tot.max_contacts},
               {"contact_steps", tot.contact_steps},
               {"ccd_hits_per_step", tot.per_step(tot.ccd_hits)},
               {"impact_zones_per_step", tot.per_step(tot.impact_zones)},
               {"newton_per_step", tot.per_step(tot.newton)},
               {"linear_per_step", tot.per_step(tot.linear)},
               {"max_penetration", tot.max_penetration},
               {"intersections", tot.intersections},
               {"status", status}}
              .dump()
       << '\n';
    jl.flush();
    fmt::print("| {} | {} | {:.4g} | {:.1f}% | {:.1f}% | {:.1f}% | {:.1f} | {:.2f} | {:.2f} | {:.2f} | {:.1f} | {} | {} |\n",
               res_label, V, tot.per_step(tot.wall), 100 * tot.share(tot.detection), 100 * tot.share(tot.response),
               100 * tot.share(tot.solve), tot.per_step(tot.contacts), tot.per_step(tot.ccd_hits),
               tot.per_step(tot.impact_zones), tot.per_step(tot.newton), tot.per_step(tot.linear),
               opt.check ? std::to_string(tot.intersections) : "not checked", status);
    std::fflush(stdout);
  }
  fmt::print("\nTotal wall time {:.1f} s. Files: {}/bench_contact.csv, bench_contact.jsonl\n", seconds_since(t_all),
             out.string());
  return exit_code;
}

}  // namespace weft::app
