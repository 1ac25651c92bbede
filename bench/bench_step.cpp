// Seconds per step of the hanging cloth at several resolutions, with the iteration counts
// and stage times that explain them. One JSON line per resolution on stdout.
//   bench_step [scene] [steps]     (default scenes/hanging_cloth.json, 48 steps)
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <thread>

#include "framework/reports.hpp"
#include "framework/scene.hpp"
#include "policies/registry.hpp"

int main(int argc, char** argv) {
  using namespace weft;
  const std::string path = argc > 1 ? argv[1] : "scenes/hanging_cloth.json";
  const int steps = argc > 2 ? std::atoi(argv[2]) : 48;
  for (int res : {11, 21, 31, 41, 61}) {
    const Scene scene = load_scene(path, {fmt::format("cloths.0.mesh.resolution=[{},{}]", res, res)});
    auto sim = make_simulator(scene);
    std::vector<double> per_step;
    StageTimes stages;
    long newton = 0, linear = 0;
    for (int k = 0; k < steps; ++k) {
      const auto t0 = std::chrono::steady_clock::now();
      const StepReport r = sim->step();
      per_step.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      if (!r.ok()) {
        fmt::print(stderr, "step {} failed: {}\n", k, r.message);
        return 3;
      }
      newton += r.newton.iterations;
      linear += r.linear.iterations;
      if (k > 0) stages += r.times;  // step 0 includes the one-off pattern analysis
    }
    std::vector<double> sorted(per_step.begin() + 1, per_step.end());
    std::sort(sorted.begin(), sorted.end());
    Json line{{"scene", path},
              {"combo", std::string(sim->combo())},
              {"vertices", scene.mesh.num_vertices()},
              {"steps", steps},
              {"first_step_seconds", per_step.front()},
              {"min_step_seconds", sorted.front()},
              {"median_step_seconds", sorted[sorted.size() / 2]},
              {"newton_per_step", double(newton) / steps},
              {"linear_iterations", linear},
              {"stage_seconds_after_first", to_json(stages)},
              {"hardware_threads", std::thread::hardware_concurrency()}};
    fmt::print("{}\n", line.dump());
  }
}
