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
#include "contact/verify/obstacle_check.hpp"
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

/// One run of the bench: a scene, its overrides (the combination and resolution included),
/// the steps to count and to skip.
struct Case {
  std::string name;  ///< the suite's case name, or the scene's stem
  std::string scene;
  std::vector<std::string> overrides;
  int steps = 0, skip = 0;
};

/// `production` -> <data>/scenes/suites/contact_production.json; a path is taken as it is.
fs::path suite_path(const std::string& suite) {
  if (suite.find('/') == std::string::npos && suite.find('.') == std::string::npos)
    return fs::path(app::data_dir()) / "scenes" / "suites" / ("contact_" + suite + ".json");
  return suite;
}

/// A scene of a suite: absolute, or relative to weft's data directory (the source tree).
std::string suite_scene(const std::string& s) {
  const fs::path p(s);
  return p.is_absolute() ? s : (fs::path(app::data_dir()) / p).string();
}

/// The cases of a suite file (format: BenchContactOptions::suite), crossed with its
/// combinations; --combo, --steps and --skip replace the file's.
std::vector<Case> read_suite(const BenchContactOptions& opt) {
  const fs::path path = suite_path(opt.suite);
  std::ifstream in(path);
  if (!in) throw ConfigError(fmt::format("--suite: cannot read '{}' (a suite name such as 'production', or a suite file)", path.string()));
  Json doc;
  try {
    doc = Json::parse(in, nullptr, true, /*ignore_comments=*/true);
  } catch (const Json::parse_error& e) {
    throw ConfigError(fmt::format("--suite {}: not valid JSON: {}", path.string(), e.what()));
  }
  const auto where = [&](const std::string& key) { return fmt::format("--suite {}: {}", path.string(), key); };
  const auto strings = [&](const Json& j, const std::string& key) {
    if (!j.is_array() || j.empty())
      throw ConfigError(fmt::format("{} = {}: expected a non-empty array of strings", where(key), j.dump()));
    std::vector<std::string> v;
    for (const Json& e : j) {
      if (!e.is_string()) throw ConfigError(fmt::format("{} = {}: expected a non-empty array of strings", where(key), j.dump()));
      v.push_back(e.get<std::string>());
    }
    return v;
  };
  const auto count = [&](const Json& j, const std::string& key, int lo) {
    if (!j.is_number_integer() || j.get<long long>() < lo || j.get<long long>() > 1000000)
      throw ConfigError(fmt::format("{} = {}: expected an integer in [{}, 1000000]", where(key), j.dump(), lo));
    return j.get<int>();
  };
  if (!doc.is_object()) throw ConfigError(fmt::format("{}: expected an object with \"cases\"", where("(top level)")));
  for (const auto& [k, v] : doc.items())
    if (k != "description" && k != "combos" && k != "cases")
      throw ConfigError(fmt::format("{}: unknown key (valid: description, combos, cases)", where(k)));
  std::vector<std::string> combos_all;
  if (doc.contains("combos")) combos_all = strings(doc["combos"], "combos");
  if (!doc.contains("cases") || !doc["cases"].is_array() || doc["cases"].empty())
    throw ConfigError(fmt::format("{}: expected a non-empty array of cases", where("cases")));
  std::vector<Case> cases;
  for (size_t i = 0; i < doc["cases"].size(); ++i) {
    const Json& c = doc["cases"][i];
    const std::string at = fmt::format("cases.{}", i);
    if (!c.is_object()) throw ConfigError(fmt::format("{}: expected an object", where(at)));
    for (const auto& [k, v] : c.items())
      if (k != "name" && k != "scene" && k != "overrides" && k != "combos" && k != "steps" && k != "skip")
        throw ConfigError(fmt::format("{}.{}: unknown key (valid: name, scene, overrides, combos, steps, skip)", where(at), k));
    if (!c.contains("scene") || !c["scene"].is_string())
      throw ConfigError(fmt::format("{}.scene: expected a scene file (relative to {})", where(at), app::data_dir()));
    Case base;
    base.scene = suite_scene(c["scene"].get<std::string>());
    base.name = c.contains("name") && c["name"].is_string() ? c["name"].get<std::string>() : fs::path(base.scene).stem().string();
    if (c.contains("overrides")) base.overrides = strings(c["overrides"], at + ".overrides");
    base.steps = c.contains("steps") ? count(c["steps"], at + ".steps", 1) : -1;
    base.skip = c.contains("skip") ? count(c["skip"], at + ".skip", 0) : 0;
    std::vector<std::string> combos = c.contains("combos") ? strings(c["combos"], at + ".combos") : combos_all;
    if (!opt.combo.empty()) combos = {opt.combo};
    if (combos.empty()) combos.push_back("");  // the scene's
    for (const std::string& combo : combos) {
      Case k = base;
      for (const std::string& o : opt.overrides) k.overrides.push_back(o);
      if (!combo.empty()) append_combo_overrides(k.overrides, combo);
      if (opt.steps > 0) k.steps = opt.steps;
      if (opt.skip > 0) k.skip = opt.skip;
      cases.push_back(std::move(k));
    }
  }
  return cases;
}

/// The q-quantile (0..1) of v by linear interpolation (0 when empty).
double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const double at = q * static_cast<double>(v.size() - 1);
  const size_t i = static_cast<size_t>(at);
  if (i + 1 >= v.size()) return v.back();
  return v[i] + (at - static_cast<double>(i)) * (v[i + 1] - v[i]);
}

}  // namespace

int bench_contact(const BenchContactOptions& given) {
  BenchContactOptions opt = given;
  // A suite names its scenes, so after --suite the first key=value reaches the scene positional.
  if (!opt.suite.empty() && opt.scene.find('=') != std::string::npos) {
    opt.overrides.insert(opt.overrides.begin(), opt.scene);
    opt.scene.clear();
  }
  const std::string data = app::data_dir();
  const bool suite = !opt.suite.empty();
  const bool check = opt.check || suite;  // a suite always checks
  // Validate every case before any work (exit 2 with the key and value).
  std::vector<Case> cases;
  try {
    if (suite) {
      if (!opt.scene.empty() || !opt.resolutions.empty() || opt.drape)
        throw ConfigError("--suite: the suite file names its scenes and sizes; drop the scene, --resolutions and --drape");
      cases = read_suite(opt);
    } else {
      const std::string scene_path =
          !opt.scene.empty() ? opt.scene : (fs::path(data) / "scenes" / "drape_sphere.json").string();
      std::vector<std::string> resolutions = opt.resolutions;
      if (resolutions.empty() && opt.drape)
        for (int n = 11; n <= 81; n += 2) resolutions.push_back(std::to_string(n));
      if (resolutions.empty() && opt.quick) resolutions.push_back("11");
      if (resolutions.empty()) resolutions.push_back("");  // the scene's own
      for (const std::string& res : resolutions) {
        Case k;
        k.name = fs::path(scene_path).stem().string();
        k.scene = scene_path;
        k.overrides = opt.overrides;
        if (!opt.combo.empty()) append_combo_overrides(k.overrides, opt.combo);
        if (!res.empty()) {
          const auto r = parse_resolution(res);
          k.overrides.push_back(fmt::format("cloths.0.mesh.resolution=[{},{}]", r[0], r[1]));
        }
        k.steps = opt.steps;
        k.skip = std::max(0, opt.skip);
        cases.push_back(std::move(k));
      }
    }
    for (Case& k : cases) {
      const Scene scene = load_scene(k.scene, k.overrides);
      const ComboInfo& combo = resolve_combo(scene);
      const std::string why = not_applicable_reason(combo, scene);
      if (!why.empty()) throw ConfigError(fmt::format("{} does not apply to {}: {}", combo.key, k.scene, why));
      if (scene.mesh.num_faces() == 0) throw ConfigError(fmt::format("{}: bench contact needs a cloth scene", k.scene));
      const int scene_steps = static_cast<int>(std::lround(scene.spec.time.duration / scene.spec.time.dt));
      if (k.steps <= 0) k.steps = opt.quick ? 4 : std::max(1, scene_steps - k.skip);
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
  meta.update(Json{{"scene", suite ? suite_path(opt.suite).string() : cases.front().scene},
                   {"suite", opt.suite},
                   {"overrides", opt.overrides},
                   {"skip", cases.front().skip},
                   {"check", check},
                   {"quick", opt.quick}});
  jl << meta.dump() << '\n';
  csv << "scene,combo,resolution,vertices,faces,first_step,steps,seconds_per_step,median_step_s,detection_share,"
         "response_share,solve_share,contact_stage_share,energy_share,hessian_share,linear_setup_share,linear_solve_share,"
         "contacts_per_step,max_contacts,contact_steps,obstacle_contacts_per_step,proximity_contacts_per_step,"
         "ccd_hits_per_step,impulses_per_step,impact_zones_per_step,zone_iterations_per_step,newton_per_step,"
         "linear_per_step,max_penetration_m,intersections,status,case,p95_step_s,max_step_s,max_newton,"
         "linear_per_newton,line_search_share,intersecting_steps,obstacle_crossing_steps,max_obstacle_crossings,"
         "deepest_obstacle_penetration_m,min_gap_m,completed,subdivided_steps\n";
  csv.flush();

  const std::string title = suite ? suite_path(opt.suite).stem().string() : cases.front().name;
  fmt::print("# weft bench contact: {}\n\nHardware: {} ({} hardware threads, {} OpenMP threads); git {}; {}\n\n", title, cpu,
             std::thread::hardware_concurrency(), threads, git, build_flags());
  if (suite)
    fmt::print("Suite {}: {} runs, every step checked for cloth-cloth intersections and obstacle crossings (untimed).\n\n",
               suite_path(opt.suite).string(), cases.size());
  else
    fmt::print("Shares are of the summed wall time of the counted steps {}..{} of each run (steps 1..{} run, not counted).\n\n",
               cases.front().skip + 1, cases.front().skip + cases.front().steps, cases.front().skip);
  if (suite) {
    fmt::print("| case | combo | vertices | steps | s/step | p95 | max | Newton/step | linear/Newton | contacts/step | solve "
               "| detection | cloth-cloth | obstacle crossings | deepest | substepped | completed |\n");
    fmt::print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n");
  } else {
    fmt::print("| resolution | vertices | s/step | detection | response | solve | contacts/step | CCD hits/step | impact zones/step "
               "| Newton/step | linear it./step | intersections | status |\n");
    fmt::print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n");
  }
  std::fflush(stdout);

  int exit_code = exit_ok;
  const auto t_all = Clock::now();
  for (const Case& k : cases) {
    const Scene scene = load_scene(k.scene, k.overrides);
    const std::string res_label =
        fmt::format("{}x{}", scene.spec.cloths[0].mesh.resolution[0], scene.spec.cloths[0].mesh.resolution[1]);
    auto sim = make_simulator(scene);
    Totals tot;
    if (check) tot.intersections = 0;
    int intersecting_steps = 0, crossing_steps = 0, max_newton = 0, subdivided = 0;
    std::int64_t max_crossings = 0;
    double deepest_obstacle = 0, min_gap = 0;
    std::string status = "ok";
    const int total_steps = k.skip + k.steps;
    for (int s = 1; s <= total_steps; ++s) {
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
      std::int64_t inter = -1, crossings = -1;
      double depth = 0;
      if (check) {
        inter = contact::verify::check_self_intersections(sim->state().x, scene.mesh.faces()).num_pairs;
        tot.intersections += inter;
        const contact::verify::ObstacleCheckReport o =
            contact::verify::check_obstacles(sim->state().x, scene.mesh.faces(), scene.spec.obstacles, sim->state().t);
        crossings = o.crossing_triangles;
        depth = o.deepest;
        if (s > k.skip) {
          intersecting_steps += inter > 0;
          crossing_steps += crossings > 0;
          max_crossings = std::max(max_crossings, crossings);
          deepest_obstacle = std::max(deepest_obstacle, depth);
        }
      }
      const ContactReport& cr = r.contact;
      const StageTimes& st = r.times;
      const double solve = st[Stage::energy] + st[Stage::hessian] + st[Stage::linear_setup] + st[Stage::linear_solve] +
                           st[Stage::line_search];
      Json rec{{"record", "step"},
               {"case", k.name},
               {"combo", std::string(sim->combo())},
               {"resolution", res_label},
               {"step", r.step},
               {"counted", s > k.skip},
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
               {"intersections", inter}};
      if (check) {
        rec["obstacle_crossings"] = crossings;
        rec["obstacle_depth"] = depth;
      }
      if (cr.barrier_pairs > 0) {
        rec["barrier_pairs"] = cr.barrier_pairs;
        rec["min_gap"] = cr.min_gap;
      }
      jl << rec.dump() << std::endl;  // every step: an interrupted long run keeps what it measured
      if (s <= k.skip) continue;
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
      max_newton = std::max(max_newton, r.newton.iterations);
      if (r.ok() && r.substeps > 1) ++subdivided;  // retried as substeps (time.max_subdivisions)
      tot.max_penetration = std::max(tot.max_penetration, cr.max_penetration);
      if (cr.barrier_pairs > 0 && (min_gap == 0 || cr.min_gap < min_gap)) min_gap = cr.min_gap;
    }
    const bool completed = status == "ok";
    const double p95 = quantile(tot.step_seconds, 0.95);
    const double max_step = tot.step_seconds.empty() ? 0 : *std::max_element(tot.step_seconds.begin(), tot.step_seconds.end());
    const double linear_per_newton = tot.newton > 0 ? static_cast<double>(tot.linear) / static_cast<double>(tot.newton) : 0;
    const int V = sim->state().num_vertices();
    const int F = static_cast<int>(scene.mesh.faces().rows());
    const std::string scene_name = fs::path(k.scene).stem().string();
    csv << fmt::format(
        "{},{},{},{},{},{},{},{:.6e},{:.6e},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.2f},{},{},{:.2f},{:.2f},"
        "{:.3f},{:.2f},{:.3f},{:.3f},{:.3f},{:.2f},{:.3e},{},{},{},{:.6e},{:.6e},{},{:.2f},{:.4f},{},{},{},{:.3e},{:.3e},{},{}\n",
        scene_name, sim->combo(), res_label, V, F, k.skip + 1, tot.steps, tot.per_step(tot.wall), tot.median_step(),
        tot.share(tot.detection), tot.share(tot.response), tot.share(tot.solve), tot.share(tot.contact_stage),
        tot.share(tot.energy), tot.share(tot.hessian), tot.share(tot.linear_setup), tot.share(tot.linear_solve),
        tot.per_step(tot.contacts), tot.max_contacts, tot.contact_steps, tot.per_step(tot.obstacle_contacts),
        tot.per_step(tot.proximity_contacts), tot.per_step(tot.ccd_hits), tot.per_step(tot.impulses),
        tot.per_step(tot.impact_zones), tot.per_step(tot.zone_iterations), tot.per_step(tot.newton), tot.per_step(tot.linear),
        tot.max_penetration, tot.intersections, csv_field(status), csv_field(k.name), p95, max_step, max_newton,
        linear_per_newton, tot.share(tot.line_search), check ? std::to_string(intersecting_steps) : "-1",
        check ? std::to_string(crossing_steps) : "-1", check ? std::to_string(max_crossings) : "-1", deepest_obstacle, min_gap,
        completed ? 1 : 0, subdivided);
    csv.flush();
    jl << Json{{"record", "resolution"},
               {"case", k.name},
               {"scene", scene_name},
               {"combo", std::string(sim->combo())},
               {"overrides", k.overrides},
               {"resolution", res_label},
               {"vertices", V},
               {"faces", F},
               {"first_step", k.skip + 1},
               {"steps", tot.steps},
               {"seconds_per_step", tot.per_step(tot.wall)},
               {"median_step_s", tot.median_step()},
               {"p95_step_s", p95},
               {"max_step_s", max_step},
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
               {"max_newton", max_newton},
               {"linear_per_step", tot.per_step(tot.linear)},
               {"linear_per_newton", linear_per_newton},
               {"max_penetration", tot.max_penetration},
               {"intersections", tot.intersections},
               {"intersecting_steps", check ? intersecting_steps : -1},
               {"obstacle_crossing_steps", check ? crossing_steps : -1},
               {"max_obstacle_crossings", check ? max_crossings : -1},
               {"deepest_obstacle_penetration", deepest_obstacle},
               {"min_gap", min_gap},
               {"completed", completed},
               {"subdivided_steps", subdivided},
               {"status", status}}
              .dump()
       << '\n';
    jl.flush();
    if (suite)
      fmt::print("| {} | {} | {} | {} | {:.4g} | {:.4g} | {:.4g} | {:.2f} | {:.1f} | {:.1f} | {:.1f}% | {:.1f}% | {} | {} | {:.3g} m | {} | {} |\n",
                 k.name, sim->combo(), V, tot.steps, tot.per_step(tot.wall), p95, max_step, tot.per_step(tot.newton),
                 linear_per_newton, tot.per_step(tot.contacts), 100 * tot.share(tot.solve), 100 * tot.share(tot.detection),
                 intersecting_steps, crossing_steps, deepest_obstacle, subdivided, completed ? "yes" : status);
    else
      fmt::print("| {} | {} | {:.4g} | {:.1f}% | {:.1f}% | {:.1f}% | {:.1f} | {:.2f} | {:.2f} | {:.2f} | {:.1f} | {} | {} |\n",
                 res_label, V, tot.per_step(tot.wall), 100 * tot.share(tot.detection), 100 * tot.share(tot.response),
                 100 * tot.share(tot.solve), tot.per_step(tot.contacts), tot.per_step(tot.ccd_hits),
                 tot.per_step(tot.impact_zones), tot.per_step(tot.newton), tot.per_step(tot.linear),
                 check ? std::to_string(tot.intersections) : "not checked", status);
    std::fflush(stdout);
  }
  if (suite)
    fmt::print("\ncloth-cloth: counted steps with an intersecting triangle pair (exact test); obstacle crossings: counted steps "
               "with a cloth triangle crossing an obstacle; deepest: the deepest cloth point inside an obstacle.\n");
  fmt::print("\nTotal wall time {:.1f} s. Files: {}/bench_contact.csv, bench_contact.jsonl\n", seconds_since(t_all),
             out.string());
  return exit_code;
}

}  // namespace weft::app
