// Cloth checkpoints (framework/checkpoint.hpp, Simulator::save / restore): for every
// pre-built cloth combination, a run stopped after k steps, written to a file and resumed in
// a fresh simulator ends bitwise where the run that never stopped ends. The contact scenes
// carry state from step to step (obstacle contacts with their friction modes and anchors,
// released pairs, cloth-cloth springs made afresh); the guard shows that dropping the saved
// contact state changes the result. A step that fails leaves the simulator at its start.
#include <doctest/doctest.h>

#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

#include "contact/no_contact.hpp"
#include "framework/checkpoint.hpp"
#include "policies/presets.hpp"
#include "policies/registry.hpp"
#include "tests/support/rod_fixtures.hpp"

using namespace weft;

namespace {

std::string scene_path(const std::string& name) { return support::source_path("scenes/" + name); }

std::string scratch(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("weft_cloth_checkpoint_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

// Two coarse sheets dropped on a sphere just below the lower one: obstacle contacts with
// friction (stick and slide), cloth-cloth contact where the strategy has it (the penalty
// strategy takes only obstacles, and only a thickness).
Scene sheets(const std::string& combo, std::vector<std::string> extra = {}) {
  std::vector<std::string> o = {"cloths.0.mesh.resolution=[9,9]", "cloths.1.mesh.resolution=[7,7]",
                                "cloths.1.mesh.center=[0.03,0.02,0.0045]", "obstacles.0.center=[0,0,-0.2018]",
                                "cloths.0.initial_velocity=[0,0,-1]", "cloths.1.initial_velocity=[0,0,-1]", "time.duration=0.2",
                                "combo=" + combo};
  o.insert(o.end(), extra.begin(), extra.end());
  return load_scene(scene_path("sheets_on_sphere.json"), o);
}
Scene sheet_on_sphere(const std::string& combo) {
  Json doc = Json::parse(R"({
    "cloths": [{"mesh": {"source": "rectangle", "size": [0.6, 0.6], "resolution": [9, 9], "center": [0, 0, 0]}, "initial_velocity": [0, 0, -1],
                "material": {"density": "100 g/m^2", "youngs_modulus": "20 MPa", "poisson_ratio": 0.3, "thickness": "0.5 mm"}}],
    "obstacles": [{"shape": "sphere", "center": [0, 0, -0.2018], "radius": 0.2, "friction": 0}],
    "contact": {"thickness": "3 mm", "stiffness": 1e7},
    "time": {"dt": 0.004166666666666667, "duration": 0.2, "frame_rate": 24}})");
  doc["combo"] = combo;
  return build_scene(doc, ".", "test");
}
// A coarse hanging sheet (no contact).
Scene hanging(const std::string& combo) {
  return load_scene(scene_path("hanging_cloth.json"), {"cloths.0.mesh.resolution=[9,9]", "time.duration=0.1", "combo=" + combo});
}
Scene orthotropic(const std::string& combo) {
  return load_scene(scene_path("orthotropic_sheet.json"), {"cloths.0.mesh.resolution=[9,9]", "time.duration=0.1", "combo=" + combo});
}

// The first of the scenes above this combination applies to. SA rebuilds its hierarchy at
// every setup here (the default keeps it between setups, which a resumed run rebuilds: a
// named caveat, tested below).
Scene scene_for(const ComboInfo& c) {
  for (Scene (*make)(const std::string&) : {+[](const std::string& k) { return sheets(k); }, &sheet_on_sphere, &hanging, &orthotropic}) {
    Scene s = make(std::string(c.key));
    if (!not_applicable_reason(c, s).empty()) continue;
    if (c.linear.find("sa_") != std::string_view::npos) s.solver["linear"]["preconditioner"]["reuse"] = "none";
    try {
      (void)make_simulator(s);  // the scene's solver sections fit this combination
      return s;
    } catch (const ConfigError&) {
    }
  }
  FAIL("no test scene for combination " << c.key);
  return {};
}

// A contact policy that keeps state between steps and does not save it.
struct Unsaved : contact::NoContact {
  using NoContact::NoContact;
  static constexpr bool stateless = false;
};
static_assert(!Simulator<ClothTheta, integrators::IncrementalPotential, Unsaved, linear::Direct>::checkpointable);
static_assert(Simulator<ClothTheta, integrators::IncrementalPotential, contact::NoContact, linear::Direct>::checkpointable);
static_assert(Simulator<ClothTheta, integrators::IncrementalPotential, contact::ImplicitContact, linear::SaPpcg>::checkpointable);

struct Run {
  Eigen::VectorXd x, v;
  double t = 0, kinetic = 0, potential = 0;
  int contacts = 0;
  int solves = 0;  ///< linear solves (shifted attempts included) from the checkpoint on
};

// `steps` steps of a fresh simulator, or of one restored from `from`.
Run run(const Scene& scene, int steps, const Checkpoint* from = nullptr, std::string* file = nullptr, int save_at = -1) {
  auto sim = make_simulator(scene);
  if (from) sim->restore(*from);
  Run r;
  for (int k = 0; k < steps; ++k) {
    if (k == save_at) write_checkpoint(*file, sim->checkpoint());
    const StepReport rep = sim->step();
    REQUIRE_MESSAGE(rep.ok(), rep.message);
    r.contacts += rep.contact.contacts;
    if (k >= save_at) r.solves += rep.linear.solves;  // the steps a resumed run repeats
  }
  r.x = sim->state().x, r.v = sim->state().v, r.t = sim->state().t;
  const EnergyReport e = sim->energies();
  r.kinetic = e.kinetic, r.potential = e.potential;
  return r;
}

}  // namespace

TEST_SUITE("contact") {
  TEST_CASE("cloth: a run resumed from a checkpoint file ends bitwise where the uninterrupted run ends for every cloth combination") {
    int tested = 0;
    for (const ComboInfo& c : combos()) {
      if (c.energy.find("discrete_elastic_rod") != std::string_view::npos) continue;
      CAPTURE(c.key);
      const Scene scene = scene_for(c);
      std::string file = scratch(std::string(c.key) + ".wckp");
      const Run straight = run(scene, 24, nullptr, &file, 16);  // writes the checkpoint before step 17
      const Checkpoint ck = read_checkpoint(file);
      CHECK(ck.header["kind"] == "cloth");
      CHECK(ck.header["step"] == 16);
      CHECK(ck.header["combo"] == std::string(c.key));
      CHECK(ck.header["resume_caveats"].empty());
      const Run resumed = run(scene, 8, &ck);
      MESSAGE(c.key << ": " << straight.contacts << " contacts over 24 steps, " << ck.arrays.size() << " arrays"
                    << (ck.has("integrator.shift_hint") ? ", shift hint " + std::to_string(ck.get_scalar("integrator.shift_hint")) : ""));
      if (c.contact != "none") CHECK(straight.contacts > 0);
      CHECK(resumed.t == straight.t);
      CHECK(resumed.x == straight.x);  // bitwise
      CHECK(resumed.v == straight.v);
      CHECK(resumed.kinetic == straight.kinetic);
      CHECK(resumed.potential == straight.potential);
      CHECK(resumed.solves == straight.solves);  // the same work, not only the same result
      ++tested;
    }
    CHECK(tested >= 15);
  }

  TEST_CASE("cloth: the guard of the bitwise comparison: a checkpoint without its contact state resumes differently") {
    // Obstacle constraints with friction: the contacts a step hands the next (modes, anchors,
    // normal forces) change the next steps. Without them the resumed run starts as if the
    // sheets had just arrived, and ends elsewhere.
    const Scene scene = sheets("cloth_ip_constraints_direct");
    std::string file = scratch("guard.wckp");
    const Run straight = run(scene, 24, nullptr, &file, 16);
    Checkpoint ck = read_checkpoint(file);
    const auto& contacts = ck.get("contact.contacts");
    REQUIRE(contacts.size() >= 13 * 2);  // state worth saving
    int sticking = 0;
    for (size_t k = 2; k < contacts.size(); k += 13) sticking += contacts[k] == 1;
    MESSAGE((contacts.size() / 13) << " obstacle contacts saved, " << sticking << " sticking");
    CHECK(run(scene, 8, &ck).x == straight.x);
    Checkpoint bare;
    bare.header = ck.header;
    for (const auto& [name, values] : ck.arrays)
      if (name.rfind("contact.", 0) != 0) bare.put(name, values);
    CHECK(run(scene, 8, &bare).x != straight.x);
  }

  TEST_CASE("cloth: the guard for the integrator's state: without its shift hint a resumed run factorises more often") {
    // Impulses after an incremental-potential step: the Hessian goes indefinite in the
    // collisions, and the Levenberg-Marquardt shift that last worked is where the next
    // step's search for a positive definite K + tau M~ starts. Here the shifts found are the
    // same from either start (powers of 10 of min_shift), so the hint changes the work done,
    // and the resumed run must repeat that work too.
    const Scene scene = sheets("cloth_ip_impulse_direct");
    std::string file = scratch("guard_shift.wckp");
    const Run straight = run(scene, 24, nullptr, &file, 8);
    Checkpoint ck = read_checkpoint(file);
    REQUIRE(ck.get_scalar("integrator.shift_hint") > 0);
    const Run resumed = run(scene, 16, &ck);
    CHECK(resumed.x == straight.x);
    CHECK(resumed.solves == straight.solves);
    Checkpoint bare;
    bare.header = ck.header;
    for (const auto& [name, values] : ck.arrays)
      if (name != "integrator.shift_hint") bare.put(name, values);
    const Run cold = run(scene, 16, &bare);
    MESSAGE("linear solves over steps 9-24: " << straight.solves << " straight, " << resumed.solves << " resumed, " << cold.solves
                                              << " resumed without the shift hint");
    CHECK(cold.solves > straight.solves);
  }

  TEST_CASE("cloth: every pre-built combination writes checkpoints and a kept preconditioner is named as a caveat") {
    for (const ComboInfo& c : combos()) {  // the rod combinations: test_rod_checkpoint.cpp
      if (c.energy.find("discrete_elastic_rod") != std::string_view::npos) continue;
      CAPTURE(c.key);
      CHECK(make_simulator(scene_for(c))->checkpoint_unsupported().empty());
    }
    auto frozen = make_simulator(load_scene(scene_path("hanging_cloth.json"),
                                            {"cloths.0.mesh.resolution=[9,9]", "combo=cloth_ip_sa_ppcg", "linear.setup=once_per_pattern"}));
    REQUIRE(frozen->step().ok());
    const Json caveats = frozen->checkpoint().header["resume_caveats"];
    REQUIRE(caveats.size() == 1);
    CHECK(caveats[0].get<std::string>().find("once_per_pattern") != std::string::npos);
    // The default SA settings keep the hierarchy between setups.
    auto kept = make_simulator(load_scene(scene_path("hanging_cloth.json"), {"cloths.0.mesh.resolution=[9,9]", "combo=cloth_ip_sa_ppcg"}));
    REQUIRE(kept->checkpoint().header["resume_caveats"].size() == 1);
    CHECK(kept->checkpoint().header["resume_caveats"][0].get<std::string>().find("linear.preconditioner.reuse") != std::string::npos);
  }

  TEST_CASE("cloth: a checkpoint that does not fit is refused naming what differs and the simulator stays as it was") {
    auto sim = make_simulator(sheets("cloth_ip_constraints_direct"));
    for (int k = 0; k < 3; ++k) REQUIRE(sim->step().ok());
    const Checkpoint good = sim->checkpoint();
    const Eigen::VectorXd x = sim->state().x;
    const auto refused = [&](Checkpoint c, const std::string& what) {
      CAPTURE(what);
      try {
        sim->restore(c);
        FAIL("restored");
      } catch (const ConfigError& e) {
        CHECK(std::string(e.what()).find(what) != std::string::npos);
      }
      CHECK(sim->state().x == x);
      CHECK(sim->state().t == good.header["time"].get<double>());
    };
    Checkpoint c = good;
    c.header["vertices"] = 5;
    refused(c, "checkpoint holds 5 vertices; this scene's mesh has 130");
    c = good;
    c.header["kind"] = "rods";
    refused(c, "checkpoint holds a 'rods' state; this combination simulates cloth");
    // A contact array cut short: the policies are put back before the error.
    c = Checkpoint{};
    c.header = good.header;
    for (const auto& [name, values] : good.arrays) {
      std::vector<double> v = values;
      if (name == "contact.contacts") v.pop_back();
      c.put(name, v);
    }
    refused(c, "checkpoint array 'contact.contacts' has");
    c = Checkpoint{};
    c.header = good.header;
    for (const auto& [name, values] : good.arrays) {
      std::vector<double> v = values;
      if (name == "contact.contacts") v[0] = 1e6;
      c.put(name, v);
    }
    refused(c, "is not a pair of this scene (130 vertices, 1 obstacles)");
    // After the refusals the simulator continues as the one that never saw them.
    auto twin = make_simulator(sheets("cloth_ip_constraints_direct"));
    for (int k = 0; k < 5; ++k) REQUIRE(twin->step().ok());
    for (int k = 0; k < 2; ++k) REQUIRE(sim->step().ok());
    CHECK(sim->state().x == twin->state().x);
  }

  TEST_CASE("cloth: a step that fails leaves the simulator at its start with its contact state") {
    // One Newton iteration cannot converge: step 5 fails. The failed attempt moved the contact
    // set (begin_step); the simulator puts it back, so a checkpoint taken now is the step's start.
    const Scene good = sheets("cloth_ip_constraints_direct");
    const Scene failing = sheets("cloth_ip_constraints_direct", {"integrator.max_iterations=1"});
    auto a = make_simulator(good), b = make_simulator(failing);
    for (int k = 0; k < 4; ++k) REQUIRE(a->step().ok());
    const Checkpoint at4 = a->checkpoint();
    b->restore(at4);
    const StepReport r = b->step();
    REQUIRE_FALSE(r.ok());
    CHECK(r.step == 5);
    CHECK(b->state().x == a->state().x);
    CHECK(b->state().v == a->state().v);
    CHECK(b->state().t == a->state().t);
    const Checkpoint after = b->checkpoint();
    for (const auto& [name, values] : at4.arrays) {
      CAPTURE(name);
      CHECK(after.get(name) == values);
    }
  }
}

TEST_SUITE("contact") {
  TEST_CASE("cloth: a step retried as two half steps (time.max_subdivisions) starts from the step's contact state") {
    // With at most 6 Newton iterations some step of the sheets in contact fails at dt and
    // converges as two steps of dt/2 (the first such step is found, not assumed). The retry
    // must be the two half steps a run at dt/2 takes from the same state: the contact set the
    // failed attempt detected is undone first.
    const double dt = sheets("cloth_ip_constraints_direct").spec.time.dt;
    const std::string half_dt = fmt::format("time.dt={:.17g}", dt / 2);
    auto a = make_simulator(sheets("cloth_ip_constraints_direct"));
    auto retried = make_simulator(sheets("cloth_ip_constraints_direct", {"integrator.max_iterations=6", "time.max_subdivisions=1"}));
    auto halves = make_simulator(sheets("cloth_ip_constraints_direct", {"integrator.max_iterations=6", half_dt}));
    Checkpoint start;
    StepReport r;
    int steps = 0;
    for (; steps < 48; ++steps) {
      start = a->checkpoint();
      if (start.get("contact.contacts").size() >= 13) {
        retried->restore(start);
        r = retried->step();
        if (r.ok() && r.subdivisions == 1) break;  // the full step failed, its halves converged
      }
      REQUIRE(a->step().ok());
    }
    REQUIRE_MESSAGE(steps < 48, "no step in contact that fails at dt and converges as two half steps");
    MESSAGE("step " << steps + 1 << " retried as two half steps");
    halves->restore(start);
    for (int k = 0; k < 2; ++k) REQUIRE(halves->step().ok());
    CHECK(retried->state().t == halves->state().t);
    CHECK(retried->state().x == halves->state().x);
    CHECK(retried->state().v == halves->state().v);
    const Checkpoint x = retried->checkpoint(), y = halves->checkpoint();
    CHECK(x.get("contact.contacts") == y.get("contact.contacts"));
  }
}
