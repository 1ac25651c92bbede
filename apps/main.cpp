// The weft command: run scenes, list the pre-built combinations, print the scene reference.
#include <CLI/CLI.hpp>

#include <cstdlib>
#include <sstream>
#include <fmt/format.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "apps/ablate.hpp"
#include "apps/bench_bending.hpp"
#include "apps/bench_common.hpp"
#include "apps/bench_contact.hpp"
#include "apps/cli_args.hpp"
#include "apps/bench_hair.hpp"
#include "apps/bench_linear.hpp"
#include "apps/plots.hpp"
#include "apps/stability.hpp"
#include "apps/validate.hpp"
#include "apps/runner.hpp"
#include "framework/build_info.hpp"
#include "framework/scene.hpp"
#include "policies/registry.hpp"

int main(int argc, char** argv) {
  using namespace weft;
  app::reexec_with_environment(argv);  // returns unless it re-executes this program
  CLI::App app{"weft: cloth and hair simulation with frictional contact, composed from compile-time policies"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("weft ") + version() + ", built from " + build_commit());
  int threads = 0;
  std::string log_level = "info";
  app.add_option("--threads", threads,
                 "worker threads (default: OMP_NUM_THREADS, else `weft run` picks by the scene's size: one thread below "
                 "app::parallel_min_vertices vertices, every core above)")
      ->check(CLI::Range(0, app::max_threads));
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error, off")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "off"}));

  app::RunOptions run;
  auto* cmd_run = app.add_subcommand("run", "simulate a scene and write frames, statistics and a summary");
  cmd_run->add_option("scene", run.scene, "scene file (JSON)")->required();
  cmd_run->add_option("overrides", run.overrides,
                      "key=value overrides; dotted keys mirror the scene tree, e.g. time.dt=0.002 integrator.max_iterations=20");
  cmd_run->add_option("-o,--out", run.out_dir, "output directory (default: out)")
      ->check([](const std::string& v) { return v.empty() ? std::string("an empty path; give a directory (default: out)") : std::string(); });
  bool bar = false, plain = false;
  cmd_run->add_flag("--progress", bar, "always draw a progress bar");
  cmd_run->add_flag("--plain", plain, "plain progress lines (default when stderr is not a terminal)");
  cmd_run->add_flag("-q,--quiet", run.quiet, "no progress output");
  cmd_run->add_option("--checkpoint-every", run.checkpoint_every,
                      "write the state to OUT/checkpoint.wckp every N frames and at the last (also when interrupted), and "
                      "OUT/failed_step.wckp, the state at the start of a failing step; every pre-built combination, rods and cloth");
  cmd_run->add_option("--resume", run.resume,
                      "continue from a checkpoint (.wckp) to the scene's end, bitwise as if never stopped; the scene and overrides "
                      "may differ from the run that wrote it (e.g. another strategy) as long as the rods or the cloth vertices match; "
                      "a preconditioner kept across steps is rebuilt, which the run warns about");
  cmd_run->footer(
      "Exit codes: 0 success; 2 invalid scene, parameters or checkpoint (nothing written); 3 a step failed "
      "(output up to the failure kept); 128+signal when interrupted.");

  std::string list_scene;
  auto* cmd_list = app.add_subcommand("list", "list the pre-built combinations of policies");
  cmd_list->add_option("--scene", list_scene, "also say which combinations apply to this scene and why others do not");

  auto* cmd_keys = app.add_subcommand("keys", "print the scene file reference (every key, unit, default and range)");

  app::StabilityOptions stab;
  std::string vary;
  auto* cmd_stab = app.add_subcommand("stability", "classify runs over a grid: time step x one scene parameter, per combination");
  cmd_stab->add_option("scene", stab.scene, "scene file (JSON)")->required();
  cmd_stab->add_option("overrides", stab.overrides, "key=value overrides applied to every run");
  cmd_stab->add_option("--dt", stab.dts, "time steps [s], e.g. --dt 0.004167 0.0417")->required();
  cmd_stab->add_option("--vary", vary, "KEY=V1,V2,...: a dotted scene key and its values, e.g. cloths.0.material.youngs_modulus=1e6,1e9,1e11");
  cmd_stab->add_option("--combos", stab.combos, "combinations to compare (default: the scene's)");
  cmd_stab->add_option("--duration", stab.duration, "simulated time per run [s] (default: the scene's)")->check(CLI::PositiveNumber);
  cmd_stab->add_option("--strain", stab.strain_threshold, "edge strain above which a run is 'excessive strain' (default 0.5)")
      ->check(CLI::PositiveNumber);
  cmd_stab->add_option("-o,--out", stab.out_dir, "output directory for stability.csv, stability_map.txt and stability_meta.json (the build, machine and command)");
  cmd_stab->add_flag("-q,--quiet", stab.quiet, "no per-run lines");
  bool stab_no_plots = false;
  cmd_stab->add_flag("--no-plots", stab_no_plots, "no stability_map.png/.svg");

  app::BenchBendingOptions bench_bending;
  auto* cmd_bench = app.add_subcommand("bench", "benchmarks");
  cmd_bench->require_subcommand(1);
  auto* cmd_bench_bending = cmd_bench->add_subcommand(
      "bending", "hinge-bending forces and Hessians: refactored vs per hinge vs autodiff (thesis Tables 5.1, 5.2)");
  cmd_bench_bending->add_option("--out", bench_bending.out_dir, "output directory (default: out/bench_bending)");
  cmd_bench_bending->add_flag("--quick", bench_bending.quick, "reduced run: 4 resolutions, 1 recorded state, short timings");
  cmd_bench_bending->add_option("--scene", bench_bending.scene, "hanging-cloth scene (default: the source tree's scenes/hanging_cloth.json)");
  cmd_bench_bending->add_option("--budget", bench_bending.budget, "timing budget per resolution and method [s] (default 0.2, quick 0.02)")
      ->check(CLI::NonNegativeNumber);
  cmd_bench_bending->add_option("--max-reps", bench_bending.max_reps, "repetitions per timing at most (at least 3)")->check(CLI::PositiveNumber);
  cmd_bench_bending->add_option("--record-dt", bench_bending.record_dt, "time step of the recording runs [s]")->check(CLI::PositiveNumber);
  cmd_bench_bending->add_option("--record-time", bench_bending.record_time, "simulated time of the recording runs [s]")
      ->check(CLI::PositiveNumber);
  cmd_bench_bending->add_option("--states", bench_bending.states, "recorded states per resolution")->check(CLI::PositiveNumber);
  cmd_bench_bending->add_option("--resolutions", bench_bending.resolutions, "n of the n x n grids (default 11 13 ... 81)")
      ->check(CLI::Range(3, 1000));

  app::BenchLinearOptions bench_linear;
  auto* cmd_bench_linear = cmd_bench->add_subcommand(
      "linear", "linear solvers on the cloth systems of thesis Table 11.1: direct, Diag-PCG, SA+PPCG, ... (methods/multigrid §10)");
  cmd_bench_linear->add_option("--examples", bench_linear.examples, "pinned drooping re-entrant dropHorizontal dropVertical (default: all)");
  cmd_bench_linear->add_option("--tessellations", bench_linear.tessellations, "regular irregular (default: both)");
  cmd_bench_linear->add_option("--sizes", bench_linear.sizes, "grid intervals m, (m+1)^2 vertices (default: 30 40 60 80 100 150 200 300 400 600 800 1000)")
      ->check(CLI::Range(4, 4000));
  cmd_bench_linear->add_option("--max-vertices", bench_linear.max_vertices, "skip sizes with more vertices")->check(CLI::PositiveNumber);
  cmd_bench_linear->add_option("--solvers", bench_linear.solvers,
                               "solvers to compare (default: all available; see --list-solvers); sa_ppcg:KEY=VALUE[:KEY=VALUE...] "
                               "adds SA+PPCG with those linear.preconditioner settings, e.g. sa_ppcg:theta=0.25");
  cmd_bench_linear->add_flag("--list-solvers", bench_linear.list_solvers, "print the solvers of this build and exit");
  cmd_bench_linear->add_option("--sa", bench_linear.sa_settings,
                               "KEY=VALUE settings of the SA preconditioner of sa_ppcg and sa_mpcg, the keys of a scene's "
                               "linear.preconditioner (weft keys), e.g. --sa cycle_gamma=2 cycle_gamma_levels=1");
  cmd_bench_linear->add_option("--steps", bench_linear.steps, "steps per case before the cap (default: the thesis's frames at 30 fps)")
      ->check(CLI::PositiveNumber);
  cmd_bench_linear->add_option("--step-budget", bench_linear.step_budget, "cap: steps <= max(2, budget / vertices) (default 4e6)")
      ->check(CLI::PositiveNumber);
  cmd_bench_linear->add_option("--max-iterations", bench_linear.max_iterations, "CG iteration limit (default 20000)")->check(CLI::PositiveNumber);
  cmd_bench_linear->add_option("--tolerance", bench_linear.tolerance, "relative M^-1-norm residual (default 1e-5, thesis)")
      ->check(CLI::Range(1e-14, 0.5));
  cmd_bench_linear->add_option("--out", bench_linear.out_dir, "output directory (default: out/bench_linear)");
  cmd_bench_linear->add_flag("--quick", bench_linear.quick, "reduced run: m = 30 (961 vertices), 2 steps");
  cmd_bench_linear->add_option("--threads", bench_linear.threads, "OpenMP threads (default: all)")->check(CLI::NonNegativeNumber);

  app::BenchContactOptions bench_contact;
  auto* cmd_bench_contact = cmd_bench->add_subcommand(
      "contact", "cloth contact: seconds per step and the shares of detection, response and solve per resolution");
  cmd_bench_contact->add_option("scene", bench_contact.scene, "scene file (default: the source tree's scenes/drape_sphere.json)");
  cmd_bench_contact->add_option("overrides", bench_contact.overrides, "key=value overrides applied to every run");
  cmd_bench_contact->add_option("--combo", bench_contact.combo, "combination (default: the scene's)");
  cmd_bench_contact->add_option("--resolutions", bench_contact.resolutions,
                                "cloths.0.mesh.resolution per run: n (n x n) or nxm, e.g. 41 81 or 51x21 (default: the scene's)");
  cmd_bench_contact->add_flag("--drape", bench_contact.drape, "the thesis' 36 drape resolutions n = 11, 13, ..., 81");
  cmd_bench_contact->add_option("--steps", bench_contact.steps, "counted steps per resolution (default: the scene's duration)")
      ->check(CLI::PositiveNumber);
  cmd_bench_contact->add_option("--skip", bench_contact.skip, "leading steps run but not counted (default 0)")
      ->check(CLI::NonNegativeNumber);
  cmd_bench_contact->add_flag("--check", bench_contact.check, "exact cloth-cloth intersection check after every step (untimed)");
  cmd_bench_contact->add_flag("--quick", bench_contact.quick, "reduced run: resolution 11 unless given, 4 steps");
  cmd_bench_contact->add_option("--suite", bench_contact.suite,
                                "run a suite of scenes, each checked after every step: 'production' (the 40k-vertex scenes), "
                                "'shrunk' (the same at small sizes) or a suite file");
  cmd_bench_contact->add_option("--out", bench_contact.out_dir, "output directory (default: out/bench_contact)");

  app::BenchHairOptions bench_hair;
  auto* cmd_bench_hair = cmd_bench->add_subcommand(
      "hair", "hair-ball stability study (thesis Figure 9.12): success, run time, contacts, Newton iterations per strategy and dt");
  cmd_bench_hair->add_option("scene", bench_hair.scene, "hair-ball scene (default: the source tree's scenes/hairball_1000.json)");
  cmd_bench_hair->add_option("overrides", bench_hair.overrides, "key=value overrides applied to every run");
  cmd_bench_hair->add_option("--strategies", bench_hair.strategies,
                             "rod combinations (default: rods_impulse rods_linear rods_adonis; rods_staggered also applies)");
  cmd_bench_hair->add_option("--dt", bench_hair.dts, "time steps [s] (default: 0.1 0.01 0.005 0.001)")->check(CLI::PositiveNumber);
  cmd_bench_hair->add_option("--duration", bench_hair.duration, "simulated time per run [s] (default: the scene's)")
      ->check(CLI::PositiveNumber);
  cmd_bench_hair->add_option("--strain", bench_hair.strain_threshold, "edge strain above which a run fails (default 0.5)")
      ->check(CLI::PositiveNumber);
  cmd_bench_hair->add_flag("--quick", bench_hair.quick, "reduced run: 8 rods, dt 0.01 and 0.005, 0.02 s");
  cmd_bench_hair->add_flag("--resume", bench_hair.resume, "keep --out's bench_hair.csv and skip the runs it holds");
  cmd_bench_hair->add_option("--out", bench_hair.out_dir, "output directory (default: out/bench_hair)");

  app::AblateOptions ablate;
  bool ablate_no_plots = false, ablate_loose_reference = false;
  auto* cmd_ablate = app.add_subcommand(
      "ablate", "one scene under several combinations, each measured against a reference run: error, energy drift, "
                "penetrations, iterations, time per stage; CSV, JSON and plots");
  cmd_ablate->add_option("scene", ablate.scene, "scene file (JSON)")->required();
  cmd_ablate->add_option("overrides", ablate.overrides, "key=value overrides applied to every run, the reference included");
  cmd_ablate->add_option("--combos", ablate.combos, "combinations to compare, or 'applicable' for every one that applies")->required();
  cmd_ablate->add_option("--reference", ablate.reference,
                         "reference combination (default: the scene's, or the same policies with a direct solver)");
  cmd_ablate->add_option("--reference-substeps", ablate.reference_substeps, "reference time step = scene dt / this (default 4)")
      ->check(CLI::PositiveNumber);
  cmd_ablate->add_flag("--loose-reference", ablate_loose_reference, "keep the reference's Newton tolerances (default: tightened)");
  cmd_ablate->add_option("--sweep", ablate.sweeps,
                         "KEY=V1,V2,...: run every combination at each value (repeatable: the product of the sweeps), all against one "
                         "reference: a work-precision diagram, e.g. --sweep time.dt=0.01,0.005,0.0025")
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  cmd_ablate->add_option("--duration", ablate.duration, "simulated time per run [s] (default: the scene's)")->check(CLI::PositiveNumber);
  cmd_ablate->add_option("-o,--out", ablate.out_dir, "output directory (default: out-ablate)");
  cmd_ablate->add_flag("--no-plots", ablate_no_plots, "tables only");
  cmd_ablate->add_flag("-q,--quiet", ablate.quiet, "no per-run lines");

  app::ValidateOptions validate;
  bool validate_no_plots = false;
  auto* cmd_validate = app.add_subcommand(
      "validate", "reference problems with closed-form or exact answers (membrane stretch, cantilever elastica of strips and rods, incline, a helical rod at rest): "
                  "a table of reference, measured, error and pass; CSV, JSON, report.md; exit 4 when one misses");
  cmd_validate->add_option("overrides", validate.overrides, "key=value overrides applied to every problem's scene (cloths.* to the cloth problems, rods.* to the rod problems)");
  cmd_validate->add_flag("--quick", validate.quick, "the reduced suite (coarse meshes), as the default tests run it");
  cmd_validate->add_option("--only", validate.only, "problems whose name starts with this (repeatable), e.g. cantilever/tan");
  cmd_validate->add_option("-o,--out", validate.out_dir, "output directory (default: out-validate)");
  cmd_validate->add_flag("--no-plots", validate_no_plots, "tables only");
  cmd_validate->add_flag("-q,--quiet", validate.quiet, "no per-problem lines");

  auto* cmd_render = app.add_subcommand(
      "render", "frames of a `weft run` output directory to PNG with POV-Ray, an animated GIF or MP4, or a side-by-side "
                "of two runs (scripts/weft_render.py; `weft render --help` for its options)");
  cmd_render->set_help_flag();  // --help goes to the renderer, which documents the options
  cmd_render->allow_extras();
  cmd_render->prefix_command();

  app.footer("See README.md and docs/scene-reference.md.");
  try {
    app.parse(app::overrides_out_of_lists(argc, argv));
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);  // prints the message (or the help) as CLI11 does
    return rc == 0 ? 0 : app::exit_config;
  }
  spdlog::set_level(spdlog::level::from_str(log_level));
  spdlog::set_pattern("[%H:%M:%S] %v");
  spdlog::set_default_logger(spdlog::stderr_color_mt("weft"));
  spdlog::set_pattern("[%H:%M:%S] %v");
#ifdef _OPENMP
  if (threads > 0) omp_set_num_threads(threads);
#endif
  run.threads_given = threads > 0 || std::getenv("OMP_NUM_THREADS") != nullptr;

  if (*cmd_run) {
    run.progress = bar ? 1 : plain ? 0 : -1;
    return app::run_scene(run);
  }
  if (*cmd_list) {
    std::optional<Scene> scene;
    if (!list_scene.empty()) {
      try {
        scene = load_scene(list_scene);
      } catch (const ConfigError& e) {
        fmt::print(stderr, "error: {}\n", e.what());
        return app::exit_config;
      }
    }
    for (const auto& c : combos()) {
      fmt::print("{}\n  energy:     {}\n  integrator: {}\n  contact:    {}\n  linear:     {}\n  {}\n", c.key, c.energy,
                 c.integrator, c.contact, c.linear, c.description);
      if (scene) {
        const std::string why = not_applicable_reason(c, *scene);
        fmt::print("  applies to {}: {}\n", list_scene, why.empty() ? "yes" : "no, " + why);
      }
    }
    return 0;
  }
  if (*cmd_bench_bending) return app::bench_bending(bench_bending);
  if (*cmd_bench_linear) return app::bench_linear(bench_linear);
  if (*cmd_bench_contact) return app::bench_contact(bench_contact);
  if (*cmd_bench_hair) return app::bench_hair(bench_hair);
  if (*cmd_stab) {
    if (!vary.empty()) {
      const auto eq = vary.find('=');
      if (eq == std::string::npos || eq == 0) {
        fmt::print(stderr, "error: --vary {} is not of the form KEY=V1,V2,...\n", vary);
        return app::exit_config;
      }
      stab.vary_key = vary.substr(0, eq);
      std::string rest = vary.substr(eq + 1), item;
      std::stringstream ss(rest);
      while (std::getline(ss, item, ',')) stab.vary_values.push_back(item);
    }
    stab.plots = !stab_no_plots;
    return app::run_stability(stab);
  }
  if (*cmd_ablate) {
    ablate.plots = !ablate_no_plots;
    ablate.reference_tighten = !ablate_loose_reference;
    return app::run_ablate(ablate);
  }
  if (*cmd_validate) {
    validate.plots = !validate_no_plots;
    return app::run_validate(validate);
  }
  if (*cmd_render) return app::run_python_tool("weft_render.py", cmd_render->remaining());
  if (*cmd_keys) {
    fmt::print("{}", scene_reference());
    return 0;
  }
  return 0;
}
