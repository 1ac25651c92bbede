#include <doctest/doctest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>

#include "framework/scene.hpp"

using namespace weft;

namespace {
Json base_scene() {
  return Json::parse(R"({
    "cloths": [{"mesh": {"source": "rectangle", "resolution": [5, 5]},
                "pins": [{"box_min": [-0.6, 0.4, -0.1], "box_max": [0.6, 0.6, 0.1]}]}],
    "time": {"dt": 0.01, "duration": 0.1, "frame_rate": 25}
  })");
}
std::string errors_of(const Json& doc) {
  try {
    build_scene(doc, ".", "test.json");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST_SUITE("framework") {
  TEST_CASE("scene: a valid scene builds its mesh / pins / masses and state") {
    const Scene s = build_scene(base_scene(), ".", "test.json");
    CHECK(s.mesh.num_vertices() == 25);
    int pinned = 0;
    for (auto d : s.dof) pinned += d == Dof::pinned;
    CHECK(pinned == 5);  // the top row
    const Eigen::VectorXd m = s.lumped_masses();
    CHECK(m.sum() == doctest::Approx(s.spec.cloths[0].material.density * 1.0));
    const State st = s.initial_state();
    CHECK(st.x.size() == 75);
    CHECK(st.v.isZero());
    CHECK(s.spec.time.steps_per_frame() == 4);
    CHECK(s.spec.time.num_frames() == 2);
  }

  TEST_CASE("scene: every problem is reported at once / with file and key path") {
    Json doc = base_scene();
    doc["time"]["dt"] = -1;
    doc["cloths"][0]["material"] = {{"poisson_ratio", 1.5}, {"thickness", "2 Pa"}};
    doc["cloths"][0]["mesh"]["colour"] = "red";
    doc["gravity"] = "down";
    const std::string e = errors_of(doc);
    CAPTURE(e);
    CHECK(e.find("test.json: invalid scene") == 0);
    CHECK(e.find("time.dt = -1 s is out of range: valid in (0, 1] s") != std::string::npos);
    CHECK(e.find("cloths.0.material.poisson_ratio = 1.5 is out of range: valid in (-1, 1)") != std::string::npos);
    CHECK(e.find("cloths.0.material.thickness = \"2 Pa\": unit 'Pa' is a pressure, expected a length") != std::string::npos);
    CHECK(e.find("cloths.0.mesh.colour is not a known key") != std::string::npos);
    CHECK(e.find("gravity = \"down\" has the wrong type") != std::string::npos);
  }

  TEST_CASE("scene: cross-field and selection errors") {
    Json doc = base_scene();
    doc["time"]["dt"] = 0.015;  // does not divide 1/25 s
    CHECK(errors_of(doc).find("divides the frame interval") != std::string::npos);
    doc = base_scene();
    doc["cloths"][0]["pins"][0] = {{"box_min", {5, 5, 5}}, {"box_max", {6, 6, 6}}};
    CHECK(errors_of(doc).find("selects no vertex") != std::string::npos);
    doc = base_scene();
    doc["cloths"][0]["pins"][0] = {{"vertices", {0, 99}}};
    CHECK(errors_of(doc).find("cloths.0.pins.0.vertices.1 = 99 is out of range: valid 0..24") != std::string::npos);
    doc = base_scene();
    doc["cloths"][0]["mesh"] = {{"source", "file"}, {"file", "no_such_mesh.obj"}};
    CHECK(errors_of(doc).find("no_such_mesh.obj: mesh file not found") != std::string::npos);
    doc = base_scene();
    doc.erase("cloths");
    CHECK(errors_of(doc).find("cloths is required but missing") != std::string::npos);
  }

  TEST_CASE("scene: scripted pins follow their rigid motion") {
    Json doc = base_scene();
    doc["cloths"][0]["pins"][0]["motion"] = {{"angular_velocity", {0, 0, 2 * M_PI}}, {"velocity", {0, 0, 1}}, {"start", 0.1}};
    const Scene s = build_scene(doc, ".", "test.json");
    const State st = s.initial_state();
    Eigen::VectorXd target;
    s.constrained_positions(0.05, st, target);  // before start: at rest
    int scripted = 0;
    for (int i = 0; i < s.mesh.num_vertices(); ++i) {
      if (s.dof[i] != Dof::scripted) continue;
      ++scripted;
      CHECK((target.segment<3>(3 * i) - st.x.segment<3>(3 * i)).norm() <= 1e-15);
    }
    CHECK(scripted == 5);
    s.constrained_positions(0.6, st, target);  // half a turn about z, 0.5 m up
    for (int i = 0; i < s.mesh.num_vertices(); ++i)
      if (s.dof[i] == Dof::scripted) {
        const Eigen::Vector3d x0 = st.x.segment<3>(3 * i);
        CHECK((target.segment<3>(3 * i) - Eigen::Vector3d(-x0.x(), -x0.y(), x0.z() + 0.5)).norm() <= 1e-12);
      }
  }

  TEST_CASE("scene: load_scene reads comments / applies overrides / reports malformed JSON") {
    const auto dir = std::filesystem::temp_directory_path();
    const auto path = (dir / "weft_scene_test.json").string();
    {
      std::ofstream f(path);
      f << "// a comment\n" << base_scene().dump(2);
    }
    const Scene s = load_scene(path, {"cloths.0.material.thickness=\"1 mm\"", "cloths.0.mesh.resolution=[3,4]"});
    CHECK(s.spec.cloths[0].material.thickness == doctest::Approx(1e-3));
    CHECK(s.mesh.num_vertices() == 12);
    CHECK_THROWS_WITH_AS(load_scene(path, {"cloths.0.materiel.thickness=1"}), doctest::Contains("cloths.0.materiel is not a known key"),
                         ConfigError);
    {
      std::ofstream f(path);
      f << "{\"time\": {\"dt\": 0.01,}";
    }
    CHECK_THROWS_WITH_AS(load_scene(path), doctest::Contains("malformed JSON"), ConfigError);
    std::filesystem::remove(path);
  }
}
