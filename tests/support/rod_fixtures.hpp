#pragma once
/// \file rod_fixtures.hpp
/// Shared set-up of the rod scene tests: a scene built from JSON rod families, and the
/// concrete simulator behind an AnySimulator.
#include <doctest/doctest.h>

#include <cstdlib>
#include <string>
#include <vector>

#include "framework/checkpoint.hpp"
#include "policies/registry.hpp"

namespace weft::support {

/// A rod scene: `rods` families, `combo`, time step dt for `duration` (a frame per step),
/// no output files, `extra` merged in (obstacles, gravity, contact parameters).
inline Scene rod_scene(const std::string& combo, const Json& rods, double dt, double duration, const Json& extra = Json::object()) {
  Json doc = Json::parse(R"({"output": {"obj": false, "vtp": false}})");
  doc["combo"] = combo;
  doc["rods"] = rods;
  doc["time"] = {{"dt", dt}, {"duration", duration}, {"frame_rate", 1.0 / dt}};
  doc.merge_patch(extra);
  return build_scene(doc, ".", "test");
}

/// Overrides of scenes/whip.json for the Figure 9.2 sweeps (bench/rods/figure_9_2.sh): the
/// handle starts 0.3 rad before the wall and gravity is off, so the whip turns in the wall's
/// plane; with `near_wall` the wall's edge is also 7 cm from the axis, so that every run
/// strikes it (bench/results/rods/figure_9_2_near_wall/).
inline std::vector<std::string> whip_sweep_overrides(bool near_wall = false) {
  std::vector<std::string> o = {"gravity=[0,0,0]", "rods.0.root=[0.0477668,-0.0147760,0]", "rods.0.direction=[0.9553365,-0.2955202,0]"};
  if (near_wall) o.push_back("obstacles.0.center=[0.17,0,0]");
  return o;
}

/// The simulator of combination Sim inside `s` (std::bad_cast for another combination).
template <class Sim>
Sim& as(AnySimulator& s) {
  return dynamic_cast<SimulatorAdapter<Sim>&>(s).simulator();
}

/// A file of the source tree (WEFT_SOURCE_DIR, which CTest sets), e.g. "scenes/whip.json".
inline std::string source_path(const std::string& relative) {
  const char* root = std::getenv("WEFT_SOURCE_DIR");
  REQUIRE(root);
  return std::string(root) + "/" + relative;
}

/// `sim` continued from tests/data/checkpoints/`name`: a state recorded by `weft run`
/// (`--checkpoint-every`, or failed_step.wckp); the directory's README says from which run.
inline void resume_from_fixture(AnySimulator& sim, const std::string& name) {
  sim.restore(read_checkpoint(source_path("tests/data/checkpoints/" + name)));
}

}  // namespace weft::support
