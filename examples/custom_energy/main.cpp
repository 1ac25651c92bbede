// Composing a simulator in C++ with a custom energy (examples/custom_energy/edge_springs.hpp):
// mass-spring cloth = EdgeSprings + the library's gravity, backward Euler as incremental
// potential minimisation, no contact, sparse direct solves. Hangs the demo sheet from two
// corners until it settles and prints how the energy went.
//   custom_energy [SCENE] (default: weft's scenes/hanging_cloth.json)
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "contact/no_contact.hpp"
#include "edge_springs.hpp"
#include "framework/simulator.hpp"
#include "integrators/incremental_potential.hpp"
#include "linear/direct.hpp"
#include "models/energy_sum.hpp"
#include "models/gravity.hpp"

using MassSpringCloth = weft::models::EnergySum<EdgeSprings, weft::models::Gravity>;
using Sim = weft::Simulator<MassSpringCloth, weft::integrators::IncrementalPotential, weft::contact::NoContact, weft::linear::Direct>;

int main(int argc, char** argv) {
  const std::string path = argc > 1 ? argv[1] : WEFT_SCENES_DIR "/hanging_cloth.json";
  const weft::Scene scene = weft::load_scene(path, {"cloths.0.mesh.resolution=[11,11]", "time.duration=6", "time.dt=0.020833333333333332"});
  Sim::Params prm;
  std::get<0>(prm.energy.terms).stiffness = 200;  // N/m
  Sim sim(scene, prm);
  const int steps = static_cast<int>(std::lround(scene.spec.time.duration / scene.spec.time.dt));
  double kinetic = 0, peak = 0;
  for (int k = 1; k <= steps; ++k) {
    const weft::StepReport r = sim.step();
    if (!r.ok()) {
      fmt::print(stderr, "step {} failed in {}: {}\n", k, r.failed_stage, r.message);
      return 1;
    }
    kinetic = r.energy.kinetic;
    peak = std::max(peak, kinetic);
    if (k % 60 == 0) fmt::print("t = {:.2f} s: kinetic {:.3e} J, springs {:.3e} J, {} Newton iterations\n", r.time, kinetic,
                                 r.energy.terms.at(0).second, r.newton.iterations);
  }
  // Air drag (1/s) and backward Euler's numerical damping take the swing out of it.
  const bool settled = kinetic < 1e-3 * peak;
  fmt::print("{} after {} steps: kinetic energy {:.2e} J, {:.1e} of its peak\n", settled ? "settled" : "still moving", steps,
             kinetic, kinetic / peak);
  return settled ? 0 : 2;
}
