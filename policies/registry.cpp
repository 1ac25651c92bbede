#include "policies/registry.hpp"

#include <map>
#include <set>

#include "framework/params_json.hpp"
#include "framework/scene.hpp"

// X(key, energy, integrator, contact, linear, description): the single table of pre-built
// combinations. Adding a row needs a policies/combos/<key>.cpp with make_<key>/docs_<key>.
#define WEFT_COMBO_TABLE(X)                                                                        \
  X(cloth_ip_direct, "membrane(stvk, isotropic) + bending(theta) + gravity", "incremental_potential", \
    "none", "direct", "cloth without contact: backward Euler as minimisation, sparse LDL^T")         \
  X(cloth_tan_ip_direct, "membrane(stvk, isotropic) + bending(tan) + gravity", "incremental_potential", \
    "none", "direct", "as cloth_ip_direct with the 2 tan(theta/2) bending energy (thesis Eq. 5.8)")  \
  X(cloth_ortho_ip_direct, "membrane(stvk, orthotropic) + bending(theta) + gravity", "incremental_potential", \
    "none", "direct", "cloth with warp/weft material constants (isotropic cloths accepted too), no contact") \
  X(cloth_ip_penalty_direct, "membrane(stvk, isotropic) + bending(theta) + gravity", "incremental_potential", \
    "obstacle_penalty", "direct", "cloth against analytic obstacles through a penalty potential (frictionless)") \
  X(cloth_ip_impulse_direct, "membrane(stvk, isotropic) + bending(theta) + gravity", "incremental_potential", \
    "impulse", "direct", "Bridson-style impulses after the solve: obstacles and self contact with friction, impact zones") \
  X(cloth_ip_impulse_sa_ppcg, "membrane(stvk, isotropic) + bending(theta) + gravity", "incremental_potential", \
    "impulse", "sa_ppcg", "as cloth_ip_impulse_direct with smoothed-aggregation PCG: impulse contact on large cloth") \
  X(cloth_ip_compliance_direct, "membrane(stvk, isotropic) + bending(theta) + gravity", "incremental_potential", \
    "linear_compliance", "direct", "linear compliance after the solve (D = A^-1): Gauss-Seidel over exact Coulomb contacts, impulse failsafe") \
  X(cloth_ip_constraints_direct, "membrane(stvk, isotropic) + bending(theta) + gravity", "incremental_potential", \
    "implicit_contact", "direct", "contact inside the solve (BW98): obstacle equality constraints released when pulling with Coulomb friction, cloth-cloth repulsion springs, impulse failsafe") \
  X(cloth_lie_constraints_diag_pcg, "membrane(stvk, isotropic) + bending(theta) + gravity", "linearly_implicit", \
    "implicit_contact", "diag_pcg", "Baraff-Witkin 1998: one linear solve per step, obstacle constraints filtered by modified PCG, repulsion springs") \
  X(cloth_ip_constraints_sa_ppcg, "membrane(stvk, isotropic) + bending(theta) + gravity", "incremental_potential", \
    "implicit_contact", "sa_ppcg", "contact inside the solve with smoothed-aggregation prefiltered PCG (the thesis' ch. 11 simulator)") \
  X(cloth_ip_barrier_direct, "membrane(stvk, isotropic) + bending(theta) + gravity", "incremental_potential", \
    "barrier", "direct", "barrier contact inside the solve (IPC / C-IPC): log barrier on point-triangle and edge-edge distances, lagged smoothed friction, CCD-bounded line search: intersection-free iterates") \
  X(cloth_ip_barrier_sa_ppcg, "membrane(stvk, isotropic) + bending(theta) + gravity", "incremental_potential", \
    "barrier", "sa_ppcg", "as cloth_ip_barrier_direct with smoothed-aggregation prefiltered PCG: barrier contact on large cloth") \
  X(cloth_root_direct, "membrane(stvk, isotropic) + bending(theta) + gravity", "backward_euler_root", "none",   \
    "direct", "backward Euler as root finding on the residual (the thesis' comparison, ch. 6)")             \
  X(cloth_lie_direct, "membrane(stvk, isotropic) + bending(theta) + gravity", "linearly_implicit", "none",     \
    "direct", "one Newton step per time step (Baraff-Witkin style linearly implicit Euler)")                \
  X(cloth_ip_diag_pcg, "membrane(stvk, isotropic) + bending(theta) + gravity", "incremental_potential", "none", \
    "diag_pcg", "as cloth_ip_direct with block-Jacobi PCG (the thesis' Diag-PCG baseline, ch. 11)")          \
  X(cloth_ip_sa_ppcg, "membrane(stvk, isotropic) + bending(theta) + gravity", "incremental_potential", "none", \
    "sa_ppcg", "as cloth_ip_direct with smoothed-aggregation prefiltered PCG (thesis ch. 11): large cloth")  \
  X(cloth_lie_sa_ppcg, "membrane(stvk, isotropic) + bending(theta) + gravity", "linearly_implicit", "none",   \
    "sa_ppcg", "Baraff-Witkin linearly implicit Euler with SA+PPCG: the thesis' chapter-11 simulator")          \
  X(rods_none, "discrete_elastic_rod + gravity", "rod_backward_euler", "none", "banded_lu",                     \
    "elastic rods without contact: per-rod backward Euler as minimisation, banded LU")                       \
  X(rods_impulse, "discrete_elastic_rod + gravity", "rod_backward_euler", "impulse", "banded_lu",             \
    "rods with the impulse response (D = M^-1): Gauss-Seidel over exact Coulomb contacts, one pass")         \
  X(rods_linear, "discrete_elastic_rod + gravity", "rod_backward_euler", "linear_compliance", "banded_lu",    \
    "rods with linear compliance (D = K^-1 at the DEL solution, frozen): one constrained Newton step")       \
  X(rods_adonis, "discrete_elastic_rod + gravity", "rod_backward_euler", "adonis", "banded_lu",               \
    "ADONIS: Gauss-Seidel inside a constrained Newton loop re-linearising the over-stretched rods (thesis ch. 8)") \
  X(rods_staggered, "discrete_elastic_rod + gravity", "rod_backward_euler", "staggered_projections", "banded_lu", \
    "nonlinear staggered projections: alternating contact and friction problems inside Newton (thesis ch. 8)")

namespace weft {

namespace combo_factories {
#define WEFT_DECLARE(key, ...)                               \
  std::unique_ptr<AnySimulator> make_##key(const Scene&); \
  std::vector<PolicyDoc> docs_##key();
WEFT_COMBO_TABLE(WEFT_DECLARE)
#undef WEFT_DECLARE
}  // namespace combo_factories

namespace {
#define WEFT_ROW(key, energy, integrator, contact, linear, description) \
  ComboInfo{#key, energy, integrator, contact, linear, description, &combo_factories::make_##key, &combo_factories::docs_##key},
const ComboInfo table[] = {WEFT_COMBO_TABLE(WEFT_ROW)};
#undef WEFT_ROW
}  // namespace

std::span<const ComboInfo> combos() { return table; }

std::string not_applicable_reason(const ComboInfo& combo, const Scene& scene) {
  const bool rod_combo = combo.energy.find("discrete_elastic_rod") != std::string_view::npos;
  if (rod_combo && scene.spec.rods.empty()) return "the scene has no rods: a rod combination simulates rods only";
  if (rod_combo && !scene.spec.cloths.empty()) return "the scene has cloths: a rod combination simulates rods only";
  if (!rod_combo && scene.spec.cloths.empty()) return "the scene has no cloths: a cloth combination would instantiate cloth models for nothing";
  if (!rod_combo && !scene.spec.rods.empty()) return "the scene has rods: a cloth combination does not simulate rods";
  if (rod_combo) {
    if (combo.contact == "none" && !scene.spec.obstacles.empty())
      return fmt::format("the scene has {} obstacle(s) but contact = none would let the rods pass through them", scene.spec.obstacles.size());
    return {};
  }
  if (combo.contact == "none" && !scene.spec.obstacles.empty())
    return fmt::format("the scene has {} obstacle(s) but contact = none would let the cloth pass through them",
                       scene.spec.obstacles.size());
  if (combo.energy.find("membrane(stvk, isotropic)") != std::string_view::npos)
    for (size_t c = 0; c < scene.spec.cloths.size(); ++c)
      if (scene.spec.cloths[c].material.orthotropic())
        return fmt::format("cloths.{}.material.model = orthotropic needs membrane(stvk, orthotropic)", c);
  if (combo.contact == "obstacle_penalty" && scene.spec.obstacles.empty())
    return "the scene has no obstacles: contact = obstacle_penalty would pay for a contact stage it does not use";
  if ((combo.contact == "impulse" || combo.contact == "implicit_contact" || combo.contact == "linear_compliance" ||
       combo.contact == "barrier") &&
      scene.spec.obstacles.empty()) {
    const Json* c = scene.solver.contains("contact") ? &scene.solver["contact"] : nullptr;
    if (c && c->is_object() && c->contains("self_contact") && (*c)["self_contact"] == false)
      return fmt::format("the scene has no obstacles and contact.self_contact = false: contact = {} would pay for a contact "
                         "stage it does not use", combo.contact);
  }
  return {};
}

std::unique_ptr<AnySimulator> make_simulator(const Scene& scene) {
  for (const auto& c : table)
    if (c.key == scene.spec.combo) {
      const std::string why = not_applicable_reason(c, scene);
      if (!why.empty()) throw ConfigError(fmt::format("{}: invalid scene", scene.path), {fmt::format("combo = \"{}\": {}", c.key, why)});
      return c.make(scene);
    }
  std::string names;
  for (const auto& c : table) names += (names.empty() ? "" : ", ") + std::string(c.key);
  throw ConfigError(fmt::format("{}: invalid scene", scene.path),
                    {fmt::format("combo = \"{}\" is not a pre-built combination: valid are {}", scene.spec.combo, names)});
}

std::string scene_reference() {
  std::string out =
      "# Scene file reference\n\n"
      "Generated by `weft keys` from the `visit` functions of the parameter structs; a test\n"
      "checks that this file is up to date. Scene files are JSON (comments allowed). Values\n"
      "are SI; any physical quantity may instead be a string with a unit, e.g. `\"20 MPa\"`,\n"
      "`\"0.3 mm\"`, `\"150 g/m^2\"`. Every key may be overridden on the command line with a\n"
      "dotted path: `weft run scene.json time.dt=0.002 cloths.0.material.thickness=\"0.5 mm\"`.\n"
      "Unknown keys are errors. `.N` stands for an array index.\n\n"
      "## Scene keys\n\n"
      "| key | type | unit | default | valid | meaning |\n|---|---|---|---|---|---|\n";
  std::vector<std::string> rows;
  SceneSpec spec{};
  DocWriter w("", rows);
  spec.visit(w);
  for (const auto& r : rows) out += r + "\n";
  out += "\n## Solver sections\n\nEach combination (`weft list`) reads the sections of its own policies.\n";
  std::set<std::pair<std::string, std::string>> seen;
  for (const auto& c : table)
    for (const auto& d : c.docs()) {
      if (!seen.insert({d.section, d.policy}).second) continue;
      out += fmt::format("\n### `{}` = {}\n\n", d.section, d.policy);
      if (d.rows.empty()) {
        out += "No parameters.\n";
        continue;
      }
      out += "| key | type | unit | default | valid | meaning |\n|---|---|---|---|---|---|\n";
      for (const auto& r : d.rows) out += r + "\n";
    }
  out += "\n## Combinations\n\n| combo | energy | integrator | contact | linear | description |\n|---|---|---|---|---|---|\n";
  for (const auto& c : table)
    out += fmt::format("| `{}` | {} | {} | {} | {} | {} |\n", c.key, c.energy, c.integrator, c.contact, c.linear, c.description);
  return out;
}

}  // namespace weft
