#pragma once
/// \file bench_contact.hpp
/// `weft bench contact`: where the time of a cloth-contact step goes.
/// Runs one scene under its (or a given) combination at several resolutions for a window of
/// steps and reports, per resolution: vertices, seconds per step, the shares of the step's
/// wall time spent in contact detection (ContactReport::detection_seconds: BVH refits,
/// proximity and CCD queries), in the contact response (response_seconds: impulses, impact
/// zones) and in the implicit solve (StageTimes energy + hessian + linear_setup +
/// linear_solve + line_search), contacts per step, CCD hits, impact zones, Newton and
/// linear iterations. Writes bench_contact.csv and bench_contact.jsonl (one line per step
/// and one per resolution) to --out; a resolution is written as soon as it is done.
///
/// With a suite (`--suite production`, or a suite file) it runs the suite's cases instead, each
/// under each of its combinations, checks every step for cloth-cloth intersections and
/// obstacle crossings (untimed), and adds per run the 95th percentile and the largest step
/// time, linear iterations per Newton iteration, the steps with an intersection or a crossing,
/// the deepest penetration and whether the run completed. A suite file is JSON (comments
/// allowed): {"description": "...", "combos": [combo, ...], "cases": [{"name", "scene" (relative
/// to weft's data directory or absolute), "overrides": ["key=value", ...], "combos", "steps",
/// "skip"}, ...]}; a case's combos replace the file's, and --combo, --steps, --skip and the
/// command line's overrides apply to every case.
#include <string>
#include <vector>

namespace weft::app {

struct BenchContactOptions {
  std::string scene;                    ///< "" = <source dir>/scenes/drape_sphere.json
  std::vector<std::string> overrides;   ///< key=value applied to every run
  std::string combo;                    ///< "" = the scene's combination
  std::vector<std::string> resolutions; ///< "n" (n x n) or "nxm" for cloths.0.mesh.resolution; empty: the scene's
  bool drape = false;                   ///< the thesis' 36 drape resolutions n = 11, 13, ..., 81 (default scene drape_sphere.json)
  int steps = -1;                       ///< steps per resolution (< 0: the scene's duration; quick: 4)
  int skip = 0;                         ///< leading steps run but not counted (e.g. the fall before contact)
  bool check = false;                   ///< exact intersection check after every step (untimed, counted in the output)
  bool quick = false;                   ///< tiny run for tests: resolution 11 unless given, 4 steps
  std::string suite;                    ///< "" = one scene; a name (<data>/scenes/suites/contact_<name>.json) or a suite file
  std::string out_dir;                  ///< "" = out/bench_contact
};

/// Runs the benchmark; prints a Markdown table to stdout. Returns an exit code.
int bench_contact(const BenchContactOptions& options);

}  // namespace weft::app
