// What a cloth step's snapshot costs against the step (Simulator::step copies the state and
// the policies' arrays before every step, to leave a failed step at its start). The
// snapshot is private; `checkpoint()` does the same copies plus a small JSON header, so its
// time bounds the snapshot's. Built as the scratch programs of bench/results (README).
#include <chrono>
#include <cstdio>

#include "policies/registry.hpp"

using namespace weft;
using clk = std::chrono::steady_clock;

int main(int argc, char** argv) {
  const int n = argc > 1 ? std::atoi(argv[1]) : 201;
  const std::string res = "cloths.0.mesh.resolution=[" + std::to_string(n) + "," + std::to_string(n) + "]";
  for (const char* combo : {"cloth_ip_sa_ppcg", "cloth_ip_constraints_sa_ppcg"}) {
    const bool contact = std::string(combo).find("constraints") != std::string::npos;
    Scene s = contact ? load_scene("/work/main/scenes/drape_sphere.json",
                                   {res, "combo=" + std::string(combo), "contact.cloth_friction=0", "contact.self_contact=false",
                                    "obstacles.0.center=[0,0,-0.302]", "obstacles.0.friction=0.3"})
                      : load_scene("/work/main/scenes/hanging_cloth.json", {res, "combo=" + std::string(combo)});
    auto sim = make_simulator(s);
    double step_s = 0, ck_s = 0;
    int steps = 0, newton = 0, contacts = 0;
    size_t values = 0;
    for (int k = 0; k < 10; ++k) {
      auto t0 = clk::now();
      const StepReport r = sim->step();
      auto t1 = clk::now();
      const Checkpoint c = sim->checkpoint();
      auto t2 = clk::now();
      if (!r.ok()) { std::printf("step %d failed: %s\n", k + 1, r.message.c_str()); break; }
      step_s += std::chrono::duration<double>(t1 - t0).count();
      ck_s += std::chrono::duration<double>(t2 - t1).count();
      ++steps, newton += r.newton.iterations, contacts += r.contact.contacts;
      values = 0;
      for (const auto& [name, a] : c.arrays) values += a.size();
    }
    std::printf("%s %dx%d (%d vertices): %d steps, %.1f Newton iterations/step, %.0f contacts/step; step %.4f s, checkpoint copy %.6f s "
                "(%zu values, %.2f MB): %.3f%% of a step\n",
                combo, n, n, n * n, steps, double(newton) / steps, double(contacts) / steps, step_s / steps, ck_s / steps, values,
                values * 8e-6, 100 * ck_s / step_s);
  }
}
