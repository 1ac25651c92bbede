#pragma once
/// \file rod_fixtures.hpp
/// Shared set-up of the rod scene tests: a scene built from JSON rod families, and the
/// concrete simulator behind an AnySimulator.
#include <string>

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

/// The simulator of combination Sim inside `s` (std::bad_cast for another combination).
template <class Sim>
Sim& as(AnySimulator& s) {
  return dynamic_cast<SimulatorAdapter<Sim>&>(s).simulator();
}

}  // namespace weft::support
