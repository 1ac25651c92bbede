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
std::string errors_of(const Json& doc, const std::string& base_dir = ".") {
  try {
    build_scene(doc, base_dir, "test.json");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}
bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

/// base_scene() with an orthotropic material: Y_warp 20 MPa, Y_weft 10 MPa, G12 1 MPa, nu 0.3.
Json orthotropic_scene() {
  Json doc = base_scene();
  doc["cloths"][0]["material"] = Json::parse(R"({"model": "orthotropic", "youngs_modulus_warp": "20 MPa",
      "youngs_modulus_weft": "10 MPa", "shear_modulus": "1 MPa", "poisson_ratio": 0.3, "thickness": "0.3 mm"})");
  return doc;
}

/// A parallelogram sheet X(u, v) = u a + v b, a = (2, 0, 0), b = (1, 1, 0) (a sheared, not
/// conformal, texture map), two triangles; texture coordinates optional.
std::string write_parallelogram_obj(const std::string& name, bool with_uv) {
  const auto path = (std::filesystem::temp_directory_path() / name).string();
  std::ofstream f(path);
  f << "v 0 0 0\nv 2 0 0\nv 3 1 0\nv 1 1 0\n";
  if (with_uv) f << "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";
  else f << "f 1 2 3\nf 1 3 4\n";
  return path;
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
    CHECK(s.spec.time.num_steps() == 10);
    CHECK(s.spec.time.num_frames() == 3);  // 0.04 and 0.08 s, and a shorter last frame at 0.1 s
    CHECK(s.spec.time.frame_time(3) == doctest::Approx(0.1));
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
    CHECK(errors_of(doc).find("cloths, rods: a scene needs at least one cloth or one rod family") != std::string::npos);
  }

  TEST_CASE("scene: names that would leave the output directory or break its XML or collide are refused") {
    for (const char* bad : {"../../evil", "a/b", "a<&\"b", ".hidden", "", "x..y"}) {
      Json doc = base_scene();
      doc["cloths"][0]["name"] = bad;
      const std::string e = errors_of(doc);
      CAPTURE(bad);
      CHECK(contains(e, "cloths.0.name"));
      CHECK(contains(e, "it names output files"));
    }
    Json doc = base_scene();
    doc["cloths"][0]["name"] = "sheet-1.a_B";
    CHECK(errors_of(doc).empty());
    // One cloth named like the first obstacle's output (name + index) would overwrite its frames.
    doc["cloths"][0]["name"] = "table0";
    doc["obstacles"] = Json::parse(R"([{"shape": "plane", "name": "table", "center": [0, 0, -1]}])");
    CHECK(contains(errors_of(doc), "cloths.0.name and obstacles.0.name: both would write the output files table0_*"));
    doc["obstacles"][0]["name"] = "../table";
    CHECK(contains(errors_of(doc), "obstacles.0.name"));
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

  TEST_CASE("scene: numbers beyond a double and paths that are not scene files are configuration errors") {
    const auto dir = std::filesystem::temp_directory_path() / "weft_scene_overflow";
    std::filesystem::create_directories(dir);
    const auto path = (dir / "scene.json").string();
    {
      std::ofstream f(path);
      f << base_scene().dump(2);
    }
    CHECK_THROWS_WITH_AS(load_scene(path, {"time.dt=1e999"}), doctest::Contains("time.dt=1e999': 1e999 is not a finite number"),
                         ConfigError);
    {
      Json doc = base_scene();
      std::ofstream f(path);
      f << doc.dump(2).replace(doc.dump(2).find("0.01"), 4, "-1e999");
    }
    CHECK_THROWS_WITH_AS(load_scene(path), doctest::Contains("a number is not finite"), ConfigError);
    CHECK_THROWS_WITH_AS(load_scene(dir.string()), doctest::Contains("not a regular file (a directory)"), ConfigError);
    CHECK_THROWS_WITH_AS(load_scene((dir / "none.json").string()), doctest::Contains("scene file not found"), ConfigError);
    std::filesystem::remove_all(dir);
  }

  TEST_CASE("scene: an orthotropic material builds with the warp from the sheet axes") {
    Json doc = orthotropic_scene();
    doc["cloths"][0]["mesh"]["plane"] = "xz";
    doc["cloths"][0]["mesh"]["tessellation"] = "irregular";
    doc["cloths"][0].erase("pins");
    doc["cloths"][0]["material"]["warp_angle"] = "30 deg";
    const Scene s = build_scene(doc, ".", "test.json");
    const ShellMaterial& m = s.spec.cloths[0].material;
    CHECK(m.orthotropic());
    CHECK(m.youngs_modulus_warp.value() == doctest::Approx(2e7));
    CHECK(m.youngs_modulus_weft.value() == doctest::Approx(1e7));
    CHECK(m.shear_modulus.value() == doctest::Approx(1e6));
    CHECK(m.eta() == doctest::Approx(0.5));
    // bending (plate calibration): sqrt(D_warp D_weft) / 6 = sqrt(Y_warp Y_weft) h^3 / (72 (1 - eta nu^2))
    CHECK(m.bending_k() == doctest::Approx(std::sqrt(2e14) * 2.7e-11 / (72 * (1 - 0.5 * 0.09))).epsilon(1e-12));
    REQUIRE(s.face_warp.size() == static_cast<size_t>(s.mesh.num_faces()));
    const Eigen::Vector3d expected(std::cos(M_PI / 6), 0, std::sin(M_PI / 6));  // (u, v) -> (x, z)
    for (const auto& w : s.face_warp) CHECK((w - expected).norm() <= 1e-12);
    // Isotropic cloths get no direction.
    const Scene iso = build_scene(base_scene(), ".", "test.json");
    for (const auto& w : iso.face_warp) CHECK(w.isZero());
  }

  TEST_CASE("scene: orthotropic stability violations name the key and the inequality / all at once") {
    struct Case {
      const char* key;
      Json value;
      const char* message;
    };
    const Case cases[] = {
        {"youngs_modulus_warp", -1, "cloths.0.material.youngs_modulus_warp = -1 Pa is out of range: valid > 0 Pa"},
        {"youngs_modulus_weft", 0, "cloths.0.material.youngs_modulus_weft = 0 Pa is out of range: valid > 0 Pa"},
        {"shear_modulus", -5, "cloths.0.material.shear_modulus = -5 Pa is out of range: valid > 0 Pa"},
        {"poisson_ratio", 1.5, "cloths.0.material.poisson_ratio = 1.5 violates 'eta nu^2 < 1 with eta = youngs_modulus_weft / "
                               "youngs_modulus_warp = 0.5 (here eta nu^2 = 1.125"},
    };
    for (const auto& c : cases) {
      CAPTURE(c.key);
      Json doc = orthotropic_scene();
      doc["cloths"][0]["material"][c.key] = c.value;
      const std::string e = errors_of(doc);
      CAPTURE(e);
      CHECK(contains(e, c.message));
    }
    // A Poisson ratio above 1 is stable when eta nu^2 < 1.
    Json ok = orthotropic_scene();
    ok["cloths"][0]["material"]["youngs_modulus_weft"] = "1 MPa";  // eta = 0.05
    ok["cloths"][0]["material"]["poisson_ratio"] = 2.0;             // eta nu^2 = 0.2
    CHECK(errors_of(ok).empty());
    // Missing constants, and keys the chosen model does not read, all reported at once.
    Json doc = orthotropic_scene();
    doc["cloths"][0]["material"].erase("shear_modulus");
    doc["cloths"][0]["material"]["youngs_modulus"] = "5 MPa";
    doc["cloths"][0]["material"]["poisson_ratio"] = 2.0;  // eta nu^2 = 2
    const std::string e = errors_of(doc);
    CAPTURE(e);
    CHECK(contains(e, "cloths.0.material.shear_modulus is required when model = orthotropic"));
    CHECK(contains(e, "cloths.0.material.youngs_modulus is not read when model = orthotropic"));
    CHECK(contains(e, "cloths.0.material.poisson_ratio = 2 violates 'eta nu^2 < 1"));
    Json iso = base_scene();
    iso["cloths"][0]["material"] = {{"youngs_modulus_warp", 1e6}, {"warp_angle", 0.3}};
    const std::string ei = errors_of(iso);
    CAPTURE(ei);
    CHECK(contains(ei, "cloths.0.material.youngs_modulus_warp is only read when model = orthotropic"));
    CHECK(contains(ei, "cloths.0.material.warp_angle is only read when model = orthotropic"));
    iso["cloths"][0]["material"] = {{"model", "anisotropic"}};
    CHECK(contains(errors_of(iso), "cloths.0.material.model = \"anisotropic\" is not a valid choice: valid are isotropic, orthotropic"));
  }

  TEST_CASE("scene: warp_from uv follows the OBJ texture coordinates on each face") {
    const std::string path = write_parallelogram_obj("weft_uv_sheet.obj", true);
    Json doc = orthotropic_scene();
    doc["cloths"][0]["mesh"] = {{"source", "file"}, {"file", path}};
    doc["cloths"][0].erase("pins");
    doc["cloths"][0]["material"]["warp_from"] = "uv";
    for (double angle : {0.0, M_PI / 2, M_PI / 4}) {
      CAPTURE(angle);
      doc["cloths"][0]["material"]["warp_angle"] = angle;
      const Scene s = build_scene(doc, ".", "test.json");
      // The image of the texture direction (cos, sin) under X = u a + v b (not the gradient of u).
      const Eigen::Vector3d expected =
          (std::cos(angle) * Eigen::Vector3d(2, 0, 0) + std::sin(angle) * Eigen::Vector3d(1, 1, 0)).normalized();
      REQUIRE(s.face_warp.size() == 2);
      for (const auto& w : s.face_warp) CHECK((w - expected).norm() <= 1e-14);
    }
    // warp_from = angle needs sheet axes; an OBJ without vt lines has no texture directions.
    doc["cloths"][0]["material"]["warp_from"] = "angle";
    CHECK(contains(errors_of(doc), "cloths.0.material.warp_from = \"angle\": an OBJ mesh (mesh.source = file) has no sheet axes"));
    doc["cloths"][0]["material"]["warp_from"] = "uv";
    doc["cloths"][0]["mesh"]["file"] = write_parallelogram_obj("weft_nouv_sheet.obj", false);
    CHECK(contains(errors_of(doc), "cloths.0.material.warp_from = \"uv\": the mesh has no texture coordinates"));
    // An isotropic cloth on the same OBJ needs none.
    Json iso = base_scene();
    iso["cloths"][0]["mesh"] = {{"source", "file"}, {"file", doc["cloths"][0]["mesh"]["file"]}};
    iso["cloths"][0].erase("pins");
    CHECK(errors_of(iso).empty());
    // Generated sheets carry their (u, v) coordinates as texture coordinates: uv = angle.
    Json gen = orthotropic_scene();
    gen["cloths"][0]["material"]["warp_angle"] = 0.4;
    const Scene a = build_scene(gen, ".", "test.json");
    gen["cloths"][0]["material"]["warp_from"] = "uv";
    const Scene b = build_scene(gen, ".", "test.json");
    for (size_t f = 0; f < a.face_warp.size(); ++f) CHECK((a.face_warp[f] - b.face_warp[f]).norm() <= 1e-14);
    std::filesystem::remove(path);
    std::filesystem::remove(std::filesystem::temp_directory_path() / "weft_nouv_sheet.obj");
  }

  TEST_CASE("scene: rest_state keyframes / box and weight are read and validated") {
    Json doc = base_scene();
    doc["cloths"][0]["rest_state"] = Json::parse(R"({"keyframes": [{"time": 0, "scale": 1}, {"time": "500 ms", "scale": 1.2}],
        "weight": 0.5, "box_min": [-0.6, -0.6, -1], "box_max": [0.05, 0.05, 1]})");
    const Scene s = build_scene(doc, ".", "test.json");
    const RestStateSpec& r = s.spec.cloths[0].rest_state;
    CHECK(s.has_animated_rest());
    CHECK(r.keyframes[1].time == doctest::Approx(0.5));
    CHECK(r.factor(0.25) == doctest::Approx(1.05));
    // Edges with both end points in the lower-left quarter of the 5x5 grid (spacing 0.25): 3x3 vertices.
    const auto sel = rest_state_edges(s);
    int n = 0;
    for (auto e : sel) n += e;
    CHECK(n == 3 * 2 + 3 * 2 + 4);  // 6 horizontal, 6 vertical, 4 diagonals
    CHECK_FALSE(build_scene(base_scene(), ".", "test.json").has_animated_rest());

    auto error_with = [&](const char* json) {
      Json d = base_scene();
      d["cloths"][0]["rest_state"] = Json::parse(json);
      return errors_of(d);
    };
    CHECK(contains(error_with(R"({"weight": 0.5})"), "cloths.0.rest_state.keyframes is required but missing"));
    CHECK(contains(error_with(R"({"keyframes": [{"time": 0, "scale": 0}]})"),
                   "cloths.0.rest_state.keyframes.0.scale = 0 is out of range: valid > 0"));
    CHECK(contains(error_with(R"({"keyframes": [{"time": 0}]})"), "cloths.0.rest_state.keyframes.0.scale is required but missing"));
    CHECK(contains(error_with(R"({"keyframes": [{"time": 0, "scale": 1}], "weight": 1.5})"),
                   "cloths.0.rest_state.weight = 1.5 is out of range: valid in [0, 1]"));
    CHECK(contains(error_with(R"({"keyframes": [{"time": 1, "scale": 1}, {"time": 0.5, "scale": 1.1}]})"),
                   "cloths.0.rest_state.keyframes.1.time = 0.5 violates '> keyframes.0.time = 1 (strictly increasing)'"));
    CHECK(contains(error_with(R"({"keyframes": [{"time": 0, "scale": 1}], "box_min": [0, 0, 0]})"),
                   "cloths.0.rest_state: give both box_min and box_max"));
    CHECK(contains(error_with(R"({"keyframes": [{"time": 0, "scale": 1}], "box_min": [5, 5, 5], "box_max": [6, 6, 6]})"),
                   "cloths.0.rest_state: the box [5, 5, 5] .. [6, 6, 6] selects no edge"));
    // Triangles on the box boundary torn apart at the largest keyframe scale.
    const std::string torn = error_with(R"({"keyframes": [{"time": 0, "scale": 1}, {"time": 1, "scale": 3}, {"time": 2, "scale": 1}],
                                           "box_min": [-0.6, -0.6, -1], "box_max": [0.05, 0.05, 1]})");
    CAPTURE(torn);
    CHECK(contains(torn, "cloths.0.rest_state: face"));
    CHECK(contains(torn, "at keyframe 1 (t = 1 s, factor 1 - w + w s = 3)"));
    CHECK(contains(torn, "violate the triangle inequality"));
    // The same script on every edge (no box) is a uniform scaling: fine.
    CHECK(error_with(R"({"keyframes": [{"time": 0, "scale": 1}, {"time": 1, "scale": 3}]})").empty());
  }
}
