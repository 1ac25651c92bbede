#pragma once
/// \file registry.hpp
/// The pre-built combinations, selectable by name at run time (`weft list`, the scene's
/// "combo" key). Generated from one table (registry.cpp), so the names, the help text
/// and the factories cannot drift apart.
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "framework/any_simulator.hpp"
#include "framework/scene.hpp"

namespace weft {

/// The reference rows of one policy's parameters (for docs/scene-reference.md).
struct PolicyDoc {
  std::string section;  ///< "energy", "integrator", "contact" or "linear"
  std::string policy;   ///< the policy's name
  std::vector<std::string> rows;
};

struct ComboInfo {
  std::string_view key;          ///< the name used in scenes and on the command line
  std::string_view energy, integrator, contact, linear;
  std::string_view description;
  /// Build a simulator for a validated scene; reads the solver sections strictly.
  std::unique_ptr<AnySimulator> (*make)(const Scene&);
  /// Reference rows of every policy of the combination.
  std::vector<PolicyDoc> (*docs)();
};

/// All pre-built combinations, in table order.
std::span<const ComboInfo> combos();

/// Why `combo` cannot run `scene` ("" if it can).
std::string not_applicable_reason(const ComboInfo& combo, const Scene& scene);

/// The combination that runs `scene`: `scene.spec.combo`, or with `linear.solver` given
/// (`scene.linear_solver`) its pre-built sibling of the same energy, integrator and contact
/// with that solver. Throws ConfigError naming the key, the value and the valid ones: an
/// unknown combo or solver, a back end this build lacks (with its CMake option), or a
/// family without that solver (listing the solvers it has).
const ComboInfo& resolve_combo(const Scene& scene);

/// The combination of `own`'s energy, integrator and contact with linear solver `linear`
/// (nullptr: none is pre-built).
const ComboInfo* sibling(const ComboInfo& own, std::string_view linear);

/// `linear.solver = auto`: below this many cloth vertices a sparse direct solver, from it on
/// SA+PPCG (bench/results/linear-choice: where the two cross on the shipped scenes).
inline constexpr int auto_iterative_min_vertices = 400;
/// The solver `auto` picks for `combo` on `scene`: by size, among the pre-built siblings.
std::string_view auto_linear_solver(const ComboInfo& combo, const Scene& scene);

/// Overrides that select exactly the combination `key`: "combo=KEY" and, for a pre-built
/// one, its own `linear.solver`, so that a scene's `linear.solver` does not swap the solver of
/// a combination named on the command line (`--combo`, `--combos`).
void append_combo_overrides(std::vector<std::string>& overrides, std::string_view key);

/// The simulator for `resolve_combo(scene)`. Throws ConfigError naming the scene file when the
/// combination is unknown (listing the available ones), does not apply to the scene, or
/// its parameters are invalid (all violations at once).
std::unique_ptr<AnySimulator> make_simulator(const Scene& scene);

/// The scene reference document (Markdown), generated from the `visit` functions.
std::string scene_reference();

}  // namespace weft
