// methods/integration-and-contact E2 / thesis §6.5: the folded hinge, one step at dt = 1/240, 5/240, 10/240 s,
// solved to a relative residual of 1e-10 by root finding and by incremental-potential
// minimisation with each globalisation. Prints iterations side by side with the thesis and
// an independent high-precision reference (methods/integration-and-contact §16, E2), and writes every convergence history as JSON lines.
//   bench_hinge [scenes/hinge.json] [histories.jsonl]
#include <fmt/format.h>

#include <fstream>

#include "framework/reports.hpp"
#include "framework/scene.hpp"
#include "policies/registry.hpp"

int main(int argc, char** argv) {
  using namespace weft;
  const std::string path = argc > 1 ? argv[1] : "scenes/hinge.json";
  std::ofstream hist(argc > 2 ? argv[2] : "hinge_histories.jsonl");
  struct Variant { const char* label; const char* combo; std::vector<std::string> ov; };
  const std::vector<Variant> variants = {
      {"root finding, backtracking on 1/2|f|^2", "cloth_root_direct", {"integrator.line_search=backtracking"}},
      {"root finding, pure Newton", "cloth_root_direct", {"integrator.line_search=full_step"}},
      {"minimisation, pure Newton (s = 1)", "cloth_ip_direct", {"integrator.line_search=full_step", "integrator.hessian=exact"}},
      {"minimisation, adaptive + backtracking", "cloth_ip_direct", {"integrator.line_search=backtracking"}},
      {"minimisation, adaptive + More-Thuente", "cloth_ip_direct", {"integrator.line_search=more_thuente"}},
      {"minimisation, adaptive + Hager-Zhang", "cloth_ip_direct", {"integrator.line_search=hager_zhang"}},
      {"minimisation, projected + backtracking", "cloth_ip_direct", {"integrator.hessian=projected"}},
      {"minimisation, trust region (exact)", "cloth_ip_direct", {"integrator.globalization=trust_region", "integrator.trust_radius=1e-3"}},
  };
  fmt::print("| variant | dt = 1/240 | dt = 5/240 | dt = 10/240 |\n|---|---|---|---|\n");
  for (const auto& v : variants) {
    std::string row = fmt::format("| {} |", v.label);
    for (int k : {1, 5, 10}) {
      const double dt = k / 240.0;
      std::vector<std::string> ov = {fmt::format("combo={}", v.combo), fmt::format("time.dt={}", dt),
                                     fmt::format("time.frame_rate={}", 1 / dt), "integrator.relative_tolerance=1e-10",
                                     "integrator.length_tolerance=0", "integrator.max_iterations=400"};
      ov.insert(ov.end(), v.ov.begin(), v.ov.end());
      auto sim = make_simulator(load_scene(path, ov));
      const StepReport r = sim->step();
      Json line = to_json(r.newton);
      line["variant"] = v.label;
      line["dt"] = dt;
      hist << line.dump() << "\n";
      row += r.ok() ? fmt::format(" {} |", r.newton.iterations)
                    : fmt::format(" fails: {} after {} (|f|/|f0| = {:.1e}) |", to_string(r.status), r.newton.iterations,
                                  r.newton.final_residual / r.newton.initial_residual);
    }
    fmt::print("{}\n", row);
  }
  fmt::print("\nmethods/integration-and-contact E2 reference (mpmath, 30-40 digits): pure Newton 27 / 26 / 23; Armijo on E_inc with |eig| clamp"
             " 85-91 / 195-204 / >300; with shift K + mu M 82 / >200 / >200; backtracking on |f|^2 162 / stalls / stalls.\n"
             "thesis (Mathematica, Figs. 6.2-6.3): minimisation 2-5x fewer iterations than root finding, which needed 50-digit"
             " arithmetic.\n");
}
