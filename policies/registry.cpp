#include "policies/registry.hpp"

#include <algorithm>
#include <array>
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
  X(cloth_ip_diag_ppcg, "membrane(stvk, isotropic) + bending(theta) + gravity", "incremental_potential", "none", \
    "diag_ppcg", "as cloth_ip_direct with prefiltered PCG and block Jacobi of the prefiltered matrix")        \
  X(cloth_ip_sa_mpcg, "membrane(stvk, isotropic) + bending(theta) + gravity", "incremental_potential", "none", \
    "sa_mpcg", "as cloth_ip_sa_ppcg with SA built from the unfiltered matrix inside modified PCG (the ablation of thesis Fig. 11.8)") \
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

// The combinations of the optional back ends, in the table only when built with them.
#ifdef WEFT_WITH_CHOLMOD
#define WEFT_CHOLMOD_COMBOS(X)                                                                                    \
  X(cloth_ip_cholmod, "membrane(stvk, isotropic) + bending(theta) + gravity", "incremental_potential", "none",  \
    "cholmod", "as cloth_ip_direct with CHOLMOD's supernodal Cholesky (-DWEFT_WITH_CHOLMOD=ON)")                  \
  X(cloth_ip_barrier_cholmod, "membrane(stvk, isotropic) + bending(theta) + gravity", "incremental_potential",  \
    "barrier", "cholmod", "as cloth_ip_barrier_direct with CHOLMOD's supernodal Cholesky (-DWEFT_WITH_CHOLMOD=ON)")
#else
#define WEFT_CHOLMOD_COMBOS(X)
#endif
#ifdef WEFT_WITH_PETSC
#define WEFT_PETSC_COMBOS(X)                                                                                     \
  X(cloth_ip_petsc_gamg, "membrane(stvk, isotropic) + bending(theta) + gravity", "incremental_potential", "none", \
    "petsc_gamg", "as cloth_ip_sa_ppcg with PETSc CG + GAMG on the prefiltered matrix (-DWEFT_WITH_PETSC=ON)")
#else
#define WEFT_PETSC_COMBOS(X)
#endif
#define WEFT_ALL_COMBOS(X) WEFT_COMBO_TABLE(X) WEFT_CHOLMOD_COMBOS(X) WEFT_PETSC_COMBOS(X)

namespace weft {

namespace combo_factories {
#define WEFT_DECLARE(key, ...)                               \
  std::unique_ptr<AnySimulator> make_##key(const Scene&); \
  std::vector<PolicyDoc> docs_##key();
WEFT_ALL_COMBOS(WEFT_DECLARE)
#undef WEFT_DECLARE
}  // namespace combo_factories

namespace {
#define WEFT_ROW(key, energy, integrator, contact, linear, description) \
  ComboInfo{#key, energy, integrator, contact, linear, description, &combo_factories::make_##key, &combo_factories::docs_##key},
const ComboInfo table[] = {WEFT_ALL_COMBOS(WEFT_ROW)};
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

namespace {

/// The values of `linear.solver`, with the CMake option of those that are optional back ends.
struct SolverName {
  std::string_view name, cmake_option;
};
constexpr SolverName solver_names[] = {{"auto", ""},         {"direct", ""},   {"cholmod", "WEFT_WITH_CHOLMOD"},
                                       {"diag_pcg", ""},     {"diag_ppcg", ""}, {"sa_ppcg", ""},
                                       {"sa_mpcg", ""},      {"petsc_gamg", "WEFT_WITH_PETSC"}, {"banded_lu", ""}};

bool same_family(const ComboInfo& a, const ComboInfo& b) {
  return a.energy == b.energy && a.integrator == b.integrator && a.contact == b.contact;
}

}  // namespace

const ComboInfo* sibling(const ComboInfo& own, std::string_view linear) {
  for (const auto& c : table)
    if (same_family(c, own) && c.linear == linear) return &c;
  return nullptr;
}

std::string_view auto_linear_solver(const ComboInfo& combo, const Scene& scene) {
  const bool large = scene.mesh.num_vertices() >= auto_iterative_min_vertices;
  const std::array<std::string_view, 2> order = large ? std::array<std::string_view, 2>{"sa_ppcg", "direct"}
                                                      : std::array<std::string_view, 2>{"direct", "sa_ppcg"};
  for (std::string_view pick : order)
    if (sibling(combo, pick)) return pick;
  return combo.linear;
}

const ComboInfo& resolve_combo(const Scene& scene) {
  const std::string header = fmt::format("{}: invalid scene", scene.path);
  const ComboInfo* own = nullptr;
  for (const auto& c : table)
    if (c.key == scene.spec.combo) own = &c;
  if (!own) {
    std::string names;
    for (const auto& c : table) names += (names.empty() ? "" : ", ") + std::string(c.key);
    throw ConfigError(header, {fmt::format("combo = \"{}\" is not a pre-built combination: valid are {}", scene.spec.combo, names)});
  }
  if (scene.linear_solver.empty()) return *own;
  const SolverName* known = nullptr;
  for (const auto& n : solver_names)
    if (n.name == scene.linear_solver) known = &n;
  if (!known) {
    std::string names;
    for (const auto& n : solver_names) names += (names.empty() ? "" : ", ") + std::string(n.name);
    throw ConfigError(header, {fmt::format("linear.solver = \"{}\" is not a linear solver: valid are {}", scene.linear_solver, names)});
  }
  const std::string_view want = known->name == "auto" ? auto_linear_solver(*own, scene) : known->name;
  if (const ComboInfo* c = sibling(*own, want)) return *c;
  std::string have;
  for (const auto& c : table)
    if (same_family(c, *own)) have += fmt::format("{}{} ({})", have.empty() ? "" : ", ", c.linear, c.key);
  // A back end this build lacks: no combination at all has it (else the family lacks it).
  const bool missing_backend =
      !known->cmake_option.empty() && std::none_of(std::begin(table), std::end(table), [&](const ComboInfo& c) { return c.linear == want; });
  throw ConfigError(header, {missing_backend
                                 ? fmt::format("linear.solver = \"{}\": this build has no {} back end; configure with -D{}=ON "
                                               "(`./scripts/test.sh --backends` builds one in build/backends)",
                                               want, want, known->cmake_option)
                                 : fmt::format("linear.solver = \"{}\": no pre-built combination has the energy, integrator and "
                                               "contact of combo = \"{}\" with this solver; the pre-built ones are {}",
                                               want, own->key, have)});
}

void append_combo_overrides(std::vector<std::string>& overrides, std::string_view key) {
  overrides.push_back(fmt::format("combo={}", key));
  for (const auto& c : table)
    if (c.key == key) overrides.push_back(fmt::format("linear.solver={}", c.linear));
}

std::unique_ptr<AnySimulator> make_simulator(const Scene& scene) {
  const ComboInfo& c = resolve_combo(scene);
  const std::string why = not_applicable_reason(c, scene);
  if (!why.empty()) throw ConfigError(fmt::format("{}: invalid scene", scene.path), {fmt::format("combo = \"{}\": {}", c.key, why)});
  return c.make(scene);
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
  {
    std::string names;
    for (const auto& n : solver_names) names += fmt::format("{}`{}`", names.empty() ? "" : ", ", n.name);
    out += fmt::format(
        "\n`linear.solver` (string; default: the combination's own) swaps the linear solver: the scene runs the\n"
        "pre-built combination with the same energy, integrator and contact and this solver (the\n"
        "Combinations table below). Valid: {}. `auto` takes a sparse direct solver below {} cloth\n"
        "vertices and SA+PPCG from there on, among the solvers the family has. `cholmod` and\n"
        "`petsc_gamg` need a build with `-DWEFT_WITH_CHOLMOD=ON` or `-DWEFT_WITH_PETSC=ON`; a scene\n"
        "that asks for a solver the build or the family lacks is refused (exit 2) with the list of\n"
        "those it has. The other keys of `linear` are the chosen solver's.\n",
        names, auto_iterative_min_vertices);
  }
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
