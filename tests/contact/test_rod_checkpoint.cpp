// Rod checkpoints (framework/checkpoint.hpp, RodSimulator::save / restore): a run stopped
// after k steps, written to a file and resumed in a fresh simulator ends bitwise where the
// run that never stopped ends, for each of the four contact strategies, on a small hair ball
// with rod-rod and rod-sphere contacts, scripted roots and a turning sphere. A checkpoint of
// other rods is refused naming what differs, and leaves the simulator as it was.
#include <doctest/doctest.h>

#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

#include "framework/checkpoint.hpp"
#include "policies/registry.hpp"
#include "tests/support/rod_fixtures.hpp"

using namespace weft;

namespace {

std::string scene_path(const std::string& name) { return support::source_path("scenes/" + name); }

std::unique_ptr<AnySimulator> small_ball(const std::string& combo, int rods = 24) {
  return make_simulator(load_scene(scene_path("hairball_250.json"),
                                   {"rods.0.count=" + std::to_string(rods), "time.duration=0.1", "rods.0.motion.phases.0.start=0",
                                    "obstacles.0.motion.phases.0.start=0", "combo=" + combo}));
}

std::string scratch(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("weft_rod_checkpoint_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

}  // namespace

TEST_SUITE("rods") {
  TEST_CASE("rods: a run resumed from a checkpoint file ends bitwise where the uninterrupted run ends for every strategy") {
    for (const std::string combo : {"rods_impulse", "rods_linear", "rods_adonis", "rods_staggered"}) {
      CAPTURE(combo);
      auto straight = small_ball(combo), first = small_ball(combo);
      int contacts = 0;
      for (int k = 0; k < 5; ++k) REQUIRE(first->step().ok());
      const std::string file = scratch(combo + ".wckp");
      write_checkpoint(file, first->checkpoint());
      first.reset();
      for (int k = 0; k < 10; ++k) {
        const StepReport r = straight->step();
        REQUIRE_MESSAGE(r.ok(), r.message);
        if (k >= 5) contacts += r.contact.rod_contacts + r.contact.obstacle_contacts;
      }
      auto resumed = small_ball(combo);
      const Checkpoint c = read_checkpoint(file);
      CHECK(c.header["step"] == 5);
      CHECK(c.header["combo"] == combo);
      resumed->restore(c);
      CHECK(resumed->state().t == 5 * resumed->scene().spec.time.dt);
      StepReport last;
      for (int k = 0; k < 5; ++k) {
        last = resumed->step();
        REQUIRE_MESSAGE(last.ok(), last.message);
      }
      MESSAGE(combo << ": " << contacts << " contacts over steps 6-10");
      CHECK(contacts > 0);  // the resumed steps do resolve contacts
      CHECK(last.step == 10);
      CHECK(resumed->state().t == straight->state().t);
      CHECK(resumed->state().x == straight->state().x);  // bitwise
      CHECK(resumed->state().v == straight->state().v);
      const EnergyReport a = resumed->energies(), b = straight->energies();
      CHECK(a.kinetic == b.kinetic);
      CHECK(a.potential == b.potential);  // twist and bending energies read the restored frames
    }
  }

  TEST_CASE("rods: the guard of the bitwise comparison: restoring a state one step off differs") {
    auto a = small_ball("rods_adonis"), b = small_ball("rods_adonis");
    for (int k = 0; k < 3; ++k) REQUIRE(a->step().ok());
    const Checkpoint at3 = a->checkpoint();
    REQUIRE(a->step().ok());
    b->restore(at3);
    REQUIRE(b->step().ok());
    CHECK(b->state().x == a->state().x);
    REQUIRE(a->step().ok());  // a is one step further
    REQUIRE(b->step().ok());
    b->restore(at3);
    REQUIRE(b->step().ok());
    CHECK(b->state().x != a->state().x);
  }

  TEST_CASE("rods: a checkpoint replays a step with another strategy from the same state") {
    auto adonis = small_ball("rods_adonis");
    for (int k = 0; k < 4; ++k) REQUIRE(adonis->step().ok());
    auto staggered = small_ball("rods_staggered");
    staggered->restore(adonis->checkpoint());
    CHECK(staggered->state().x == adonis->state().x);
    const StepReport r = staggered->step();
    REQUIRE_MESSAGE(r.ok(), r.message);
    CHECK(r.step == 5);
    CHECK(staggered->state().t == 5 * staggered->scene().spec.time.dt);
  }

  TEST_CASE("rods: a checkpoint of other rods is refused naming the difference and the state stays as it was") {
    auto small = small_ball("rods_adonis", 8);
    REQUIRE(small->step().ok());
    const Checkpoint c8 = small->checkpoint();
    auto other = small_ball("rods_adonis", 12);
    const Eigen::VectorXd x0 = other->state().x;
    CHECK_THROWS_WITH_AS(other->restore(c8), "checkpoint holds 8 rod(s); this scene has 12", ConfigError);
    CHECK(other->state().x == x0);
    CHECK(other->state().t == 0);
    // Same rod count, other vertex count.
    auto finer = make_simulator(load_scene(scene_path("hairball_250.json"), {"rods.0.count=8", "rods.0.vertices=20", "combo=rods_adonis"}));
    CHECK_THROWS_WITH_AS(finer->restore(c8), "checkpoint rod 0 has 119 DoFs; this scene's rod 0 has 79 (20 vertices)", ConfigError);
    // A damaged array is named.
    Checkpoint cut = c8;
    cut.arrays[2].second.pop_back();
    CHECK_THROWS_WITH_AS(small->restore(cut), "checkpoint array 'tangent' holds 695 values; this scene needs 696", ConfigError);
    Checkpoint cloth = c8;
    cloth.header["kind"] = "cloth";
    CHECK_THROWS_WITH_AS(small->restore(cloth), "checkpoint holds a 'cloth' state; this combination simulates rods", ConfigError);
  }
}
