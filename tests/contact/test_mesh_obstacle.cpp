// Triangle-mesh obstacles read from OBJ: the signed distance of a cube mesh equals
// the analytic box's (posed by scale, center and motion), a sphere tessellation is within its
// chordal error of the sphere, the derivatives match finite differences in face, edge and
// vertex regions (convex and reflex), the BVH finds the brute-force closest point, malformed
// files are configuration errors naming the key, and sheets dropped on a mesh box through the
// impulse and the constraint combos stay out of it and come to rest.
#include <doctest/doctest.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "contact/detection/distance.hpp"
#include "contact/mesh_distance.hpp"
#include "contact/obstacle_penalty.hpp"
#include "framework/scene.hpp"
#include "policies/registry.hpp"

using namespace weft;
using contact::Distance;
using contact::MeshClosest;
using contact::MeshDistance;
using contact::ObstaclePose;
using Eigen::Vector3d;
namespace fs = std::filesystem;

namespace {

using Faces = std::vector<std::array<int, 3>>;

/// A fresh directory under the system temp directory, removed with its files.
struct TempDir {
  fs::path path;
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  TempDir() {
    std::random_device rd;
    path = fs::temp_directory_path() / fmt::format("weft_mesh_obstacle_{}", rd());
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  void write(const std::string& name, const std::string& text) const { std::ofstream(path / name) << text; }
};

std::string obj_text(const std::vector<Vector3d>& V, const Faces& F) {
  std::string s;
  for (const auto& v : V) s += fmt::format("v {:.17g} {:.17g} {:.17g}\n", v.x(), v.y(), v.z());
  for (const auto& f : F) s += fmt::format("f {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1);
  return s;
}

// Box [offset - h, offset + h]: vertex k has the signs of bits (1, 2, 4); faces outward.
std::vector<Vector3d> box_vertices(const Vector3d& h, const Vector3d& offset = Vector3d::Zero()) {
  std::vector<Vector3d> V;
  for (int k = 0; k < 8; ++k) V.push_back(offset + Vector3d(k & 1 ? h.x() : -h.x(), k & 2 ? h.y() : -h.y(), k & 4 ? h.z() : -h.z()));
  return V;
}
const Faces box_faces = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                         {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};

Faces reversed(Faces F) {
  for (auto& f : F) std::swap(f[1], f[2]);
  return F;
}

// UV sphere of radius r about the origin: nu x (nv - 1) ring vertices plus the two poles.
std::string sphere_obj(double r, int nu, int nv) {
  std::vector<Vector3d> V{Vector3d(0, 0, -r)};
  for (int j = 1; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const double th = M_PI * j / nv, ph = 2 * M_PI * i / nu;
      V.push_back(r * Vector3d(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), -std::cos(th)));
    }
  V.push_back(Vector3d(0, 0, r));
  auto id = [&](int j, int i) { return 1 + (j - 1) * nu + (i % nu); };
  Faces F;
  for (int i = 0; i < nu; ++i) F.push_back({0, id(1, i + 1), id(1, i)});
  for (int j = 1; j + 1 < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      F.push_back({id(j, i), id(j, i + 1), id(j + 1, i + 1)});
      F.push_back({id(j, i), id(j + 1, i + 1), id(j + 1, i)});
    }
  const int top = static_cast<int>(V.size()) - 1;
  for (int i = 0; i < nu; ++i) F.push_back({top, id(nv - 1, i), id(nv - 1, i + 1)});
  return obj_text(V, F);
}

// The L polygon (0,0) (2,0) (2,1) (1,1) (1,2) (0,2) extruded over z in [0, 1]: a closed,
// non-convex prism with a reflex edge along (1, 1, z).
const std::vector<std::array<double, 2>> l_polygon = {{0, 0}, {2, 0}, {2, 1}, {1, 1}, {1, 2}, {0, 2}};
std::string l_prism_obj() {
  std::vector<Vector3d> V;
  for (int z = 0; z < 2; ++z)
    for (const auto& p : l_polygon) V.emplace_back(p[0], p[1], z);
  Faces F;
  for (int k = 1; k + 1 < 6; ++k) {  // caps: a fan from (0, 0), star-shaped about it
    F.push_back({6, 6 + k, 6 + k + 1});  // top, counter-clockwise seen from +z
    F.push_back({0, k + 1, k});          // bottom, seen from -z
  }
  for (int k = 0; k < 6; ++k) {  // sides: the polygon is counter-clockwise, so (dy, -dx) is outward
    const int a = k, b = (k + 1) % 6;
    F.push_back({a, b, 6 + b});
    F.push_back({a, 6 + b, 6 + a});
  }
  return obj_text(V, F);
}
bool inside_l_prism(const Vector3d& x) {
  const bool in_l = x.x() > 0 && x.y() > 0 && ((x.x() < 2 && x.y() < 1) || (x.x() < 1 && x.y() < 2));
  return in_l && x.z() > 0 && x.z() < 1;
}

// A scene with one tiny sheet far away and the given obstacles, files relative to `dir`.
Scene scene_with(const TempDir& dir, const std::string& obstacles) {
  Json doc = Json::parse(R"({
    "combo": "cloth_ip_impulse_direct",
    "cloths": [{"mesh": {"source": "rectangle", "size": [0.02, 0.02], "resolution": [2, 2], "center": [0, 0, 50]}}],
    "time": {"dt": 0.004166666666666667, "duration": 1.0, "frame_rate": 24}
  })");
  doc["obstacles"] = Json::parse(obstacles);
  return build_scene(doc, dir.path.string(), "test");
}

Vector3d random_in(std::mt19937& rng, const Vector3d& lo, const Vector3d& hi) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  return lo + Vector3d(u(rng), u(rng), u(rng)).cwiseProduct(hi - lo);
}

// Closest feature of the mesh obstacle `o` posed at t to x (body coordinates inside).
MeshClosest feature_at(const ObstaclePose& p, const Vector3d& x) { return p.mesh->closest(p.rotation.transpose() * (x - p.center)); }
bool same_feature(const MeshClosest& a, const MeshClosest& b) { return a.feature == b.feature && a.id == b.id; }

// A 0.2 m sheet of 9 x 9 vertices at z = 0 over a box (mesh or analytic) with its top at
// z = -0.01, overhanging it by a quarter along -x: it lands flat and drapes over one edge.
Scene drop_scene(const TempDir& dir, const std::string& combo, const std::string& obstacle, const Json& contact) {
  Json doc = Json::parse(R"({
    "cloths": [{"mesh": {"source": "rectangle", "size": [0.2, 0.2], "resolution": [9, 9]},
                "material": {"density": 0.1, "youngs_modulus": 1e7, "thickness": 5e-4}}],
    "damping": {"mass": 2.0},
    "time": {"dt": 0.004166666666666667, "duration": 1.0, "frame_rate": 24}
  })");
  doc["combo"] = combo;
  doc["obstacles"] = Json::parse("[" + obstacle + "]");
  doc["contact"] = contact;
  return build_scene(doc, dir.path.string(), "test");
}
const char* const mesh_box = R"({"shape": "mesh", "file": "box.obj", "center": [0.1, 0, -0.06], "friction": 0.5})";
const char* const analytic_box = R"({"shape": "box", "half_extents": [0.15, 0.15, 0.05], "center": [0.1, 0, -0.06], "friction": 0.5})";

struct DropRun {
  std::vector<Eigen::VectorXd> x;  // after each step
  double worst = -1e300;           // largest depth below the thickness surface [m]
  double peak_kinetic = 0, final_kinetic = 0;
  int contacts = 0;
};

/// One OpenMP thread for the small drop runs: on a loaded 2-core machine the barriers spin
/// (as in test_contact_scenes.cpp). Restores the previous count.
struct OneThread {
#ifdef _OPENMP
  int previous = omp_get_max_threads();
  OneThread() { omp_set_num_threads(1); }
  ~OneThread() { omp_set_num_threads(previous); }
#endif
};

DropRun drop(const Scene& scene, int steps, double thickness) {
  const OneThread one;
  auto sim = make_simulator(scene);
  DropRun r;
  for (int k = 0; k < steps; ++k) {
    const StepReport rep = sim->step();
    REQUIRE_MESSAGE(rep.ok(), "step ", k + 1, ": ", rep.message);
    const State& s = sim->state();
    const ObstaclePose p = ObstaclePose::at(scene.spec.obstacles[0], s.t);
    for (int i = 0; i < s.num_vertices(); ++i)
      if (s.is_free(i)) r.worst = std::max(r.worst, thickness - p.distance(s.position(i)).phi);
    r.x.push_back(s.x);
    r.contacts += rep.contact.contacts;
    r.final_kinetic = sim->energies().kinetic;
    r.peak_kinetic = std::max(r.peak_kinetic, r.final_kinetic);
  }
  return r;
}

void write_box(const TempDir& dir) { dir.write("box.obj", obj_text(box_vertices(Vector3d(0.15, 0.15, 0.05)), box_faces)); }

// The first `steps` steps: the sheet lands (about step 11) and starts draping over the edge.
void drop_on_mesh_box(const std::string& combo, double thickness, int steps) {
  const TempDir dir;
  write_box(dir);
  const DropRun mesh = drop(drop_scene(dir, combo, mesh_box, {{"thickness", thickness}}), steps, thickness);
  const double moved = (mesh.x.back() - mesh.x.front()).cwiseAbs().maxCoeff();
  MESSAGE(combo << ": depth below the thickness " << mesh.worst << " m over " << steps << " steps, " << mesh.contacts << " contacts");
  CHECK(mesh.contacts > 0);
  CHECK(moved > 0.01);  // it fell and draped
  CHECK(mesh.worst <= 1e-9);
}

// 1 s: the sheet comes to rest on the mesh box, along the same path as on the analytic box
// (their signed distances agree to rounding; `agree` is the spread the solver's own
// tolerances and the trajectory's round-off allow: with contact constraints and friction the
// largest difference over the run was 8.2e-6 to 2.1e-5 m, and the motion itself moved by
// 7e-6 m, over ten orders of the matrix assembly, colouring chunks of 1 to 128 elements).
void rest_on_mesh_box(const std::string& combo, double thickness, double agree) {
  const TempDir dir;
  write_box(dir);
  const int steps = 240;
  const DropRun mesh = drop(drop_scene(dir, combo, mesh_box, {{"thickness", thickness}}), steps, thickness);
  const DropRun box = drop(drop_scene(dir, combo, analytic_box, {{"thickness", thickness}}), steps, thickness);
  double diff = 0;
  for (int k = 0; k < steps; ++k) diff = std::max(diff, (mesh.x[k] - box.x[k]).cwiseAbs().maxCoeff());
  const double moved = (mesh.x.back() - mesh.x.front()).cwiseAbs().maxCoeff();
  MESSAGE(combo << ": depth below the thickness " << mesh.worst << " m, kinetic energy peak " << mesh.peak_kinetic << " J, after 1 s "
                << mesh.final_kinetic << " J; max difference to the analytic box " << diff << " m (motion " << moved << " m)");
  CHECK(mesh.contacts > 0);
  CHECK(moved > 0.01);
  CHECK(mesh.worst <= 1e-9);
  CHECK(mesh.final_kinetic <= 1e-3 * mesh.peak_kinetic);
  CHECK(diff <= agree);
}

}  // namespace

TEST_SUITE("contact") {
  TEST_CASE("mesh obstacle: a sheet dropped on a mesh box with impulses stays out of it") {
    drop_on_mesh_box("cloth_ip_impulse_direct", 1e-3, 36);
  }

  TEST_CASE("mesh obstacle: a sheet dropped on a mesh box with constraints stays out of it") {
    drop_on_mesh_box("cloth_ip_constraints_direct", 2e-3, 48);
  }

  TEST_CASE("mesh obstacle: the penalty combo drops a sheet on a mesh box as on the analytic box") {
    // Frictionless: the exact Hessian of the penalty uses the edge Hessian of phi where the
    // sheet bends over the box's edge.
    TempDir dir;
    write_box(dir);
    const Json contact = {{"stiffness", 1e6}, {"thickness", 2e-3}};
    const std::string mesh = R"({"shape": "mesh", "file": "box.obj", "center": [0.1, 0, -0.06]})";
    const std::string box = R"({"shape": "box", "half_extents": [0.15, 0.15, 0.05], "center": [0.1, 0, -0.06]})";
    const int steps = 48;
    const DropRun m = drop(drop_scene(dir, "cloth_ip_penalty_direct", mesh, contact), steps, 2e-3);
    const DropRun b = drop(drop_scene(dir, "cloth_ip_penalty_direct", box, contact), steps, 2e-3);
    double diff = 0;
    for (int k = 0; k < steps; ++k) diff = std::max(diff, (m.x[k] - b.x[k]).cwiseAbs().maxCoeff());
    MESSAGE("penalty: deepest " << m.worst << " m into the 2 mm layer; max difference to the analytic box " << diff << " m");
    CHECK(m.contacts > 0);
    CHECK(m.worst > 0);     // the penalty lets it into the layer ...
    CHECK(m.worst < 2e-3);  // ... but not through the surface
    CHECK(diff <= 1e-9);
  }

  TEST_CASE("mesh obstacle: a cube OBJ posed by scale and center and motion matches the analytic box") {
    TempDir dir;
    // Body box half extents (0.3, 0.2, 0.1), from an OBJ at half the size (scale 2).
    dir.write("cube.obj", obj_text(box_vertices(Vector3d(0.15, 0.1, 0.05)), box_faces));
    // Off-origin OBJ: a cube around (1, 0.5, 0) at scale 0.5 is the box of half extent 0.05
    // around center + (0.5, 0.25, 0).
    dir.write("offset.obj", obj_text(box_vertices(Vector3d(0.1, 0.1, 0.1), Vector3d(1, 0.5, 0)), box_faces));
    const std::string motion =
        R"("motion": {"velocity": [0.3, -0.1, 0.2], "angular_velocity": [0.5, 1.0, -0.7], "center": [0, 0.1, 0.2], "start": 0.1, "end": 2})";
    struct Case {
      const char* name;
      std::string mesh, box;
      Vector3d half;
    };
    const Case cases[] = {
        {"moving cube", R"({"shape": "mesh", "file": "cube.obj", "scale": 2, "center": [0.1, -0.2, 0.3], )" + motion + "}",
         R"({"shape": "box", "half_extents": [0.3, 0.2, 0.1], "center": [0.1, -0.2, 0.3], )" + motion + "}", Vector3d(0.3, 0.2, 0.1)},
        {"offset cube", R"({"shape": "mesh", "file": "offset.obj", "scale": 0.5, "center": [-0.2, 0.1, 0.4]})",
         R"({"shape": "box", "half_extents": [0.05, 0.05, 0.05], "center": [0.3, 0.35, 0.4]})", Vector3d(0.05, 0.05, 0.05)},
    };
    for (const Case& c : cases) {
      CAPTURE(c.name);
      const Scene scene = scene_with(dir, "[" + c.mesh + ", " + c.box + "]");
      REQUIRE(scene.spec.obstacles[0].mesh);
      CHECK(scene.spec.obstacles[0].mesh->closed());
      std::mt19937 rng(5);
      int inside = 0, faces = 0, edges_or_vertices = 0;
      for (double t : {0.0, 0.05, 0.7, 3.0}) {
        CAPTURE(t);
        const ObstaclePose pm = ObstaclePose::at(scene.spec.obstacles[0], t), pb = ObstaclePose::at(scene.spec.obstacles[1], t);
        for (int k = 0; k < 500; ++k) {
          const Vector3d y = random_in(rng, -2 * c.half, 2 * c.half);
          const Vector3d x = pb.center + pb.rotation * y;
          CAPTURE(y.transpose());
          const Distance dm = pm.distance(x), db = pb.distance(x);
          CHECK(std::abs(dm.phi - db.phi) <= 1e-12);
          CHECK((dm.grad - db.grad).norm() <= 1e-12);
          CHECK((dm.hess - db.hess).norm() <= 1e-9 * (1 + db.hess.norm()));
          const auto outside = ((y.cwiseAbs() - c.half).array() > 0).count();
          inside += db.phi < 0;
          faces += outside == 1;
          edges_or_vertices += outside >= 2;
        }
      }
      CHECK(inside >= 50);  // every kind of region is sampled
      CHECK(faces >= 200);
      CHECK(edges_or_vertices >= 200);
    }
  }

  TEST_CASE("mesh obstacle: a sphere tessellation is within its chordal error of the analytic sphere") {
    TempDir dir;
    const double r = 0.2;
    dir.write("sphere.obj", sphere_obj(r, 32, 16));
    const Scene scene = scene_with(dir, R"([{"shape": "mesh", "file": "sphere.obj", "center": [0.3, 0, 0.1]},
                                            {"shape": "sphere", "radius": 0.2, "center": [0.3, 0, 0.1]}])");
    const ObstacleMesh& m = *scene.spec.obstacles[0].mesh;
    REQUIRE(m.closed());
    // Chordal error: the deepest point of the faces below the sphere (every vertex is on it).
    double eps = 0;
    for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
      const auto pt = contact::detection::point_triangle_distance(Vector3d::Zero(), m.V.row(m.F(f, 0)).transpose(),
                                                                  m.V.row(m.F(f, 1)).transpose(), m.V.row(m.F(f, 2)).transpose());
      eps = std::max(eps, r - std::sqrt(pt.distance_squared));
    }
    REQUIRE(eps > 1e-4 * r);
    REQUIRE(eps < 0.02 * r);
    const ObstaclePose pm = ObstaclePose::at(scene.spec.obstacles[0], 0), ps = ObstaclePose::at(scene.spec.obstacles[1], 0);
    std::mt19937 rng(9);
    double worst = 0;
    int inside = 0;
    for (int k = 0; k < 4000; ++k) {
      const Vector3d x = ps.center + random_in(rng, Vector3d::Constant(-2 * r), Vector3d::Constant(2 * r));
      CAPTURE(x.transpose());
      const Distance dm = pm.distance(x), ds = ps.distance(x);
      // The polyhedron lies inside the ball, within eps of the sphere: phi_sphere <= phi_mesh <= phi_sphere + eps.
      CHECK(dm.phi - ds.phi >= -1e-15);
      CHECK(dm.phi - ds.phi <= eps * (1 + 1e-12));
      worst = std::max(worst, dm.phi - ds.phi);
      inside += dm.phi < 0;
      if (std::abs(ds.phi) > 0.25 * r) CHECK(dm.grad.dot(ds.grad) >= 0.99);  // nearly radial away from the surface
    }
    CHECK(inside > 100);
    CHECK(worst > 0.5 * eps);  // the bound is attained, not a loose one
  }

  TEST_CASE("mesh obstacle: gradient and Hessian match central differences in face and edge and vertex regions") {
    TempDir dir;
    dir.write("l.obj", l_prism_obj());
    dir.write("sphere.obj", sphere_obj(0.5, 12, 7));
    const Scene scene = scene_with(dir, R"([{"shape": "mesh", "file": "l.obj", "center": [0.1, 0.2, -0.3],
                                             "motion": {"angular_velocity": [0.3, -0.2, 0.4], "velocity": [0.1, 0, 0]}},
                                            {"shape": "mesh", "file": "sphere.obj", "center": [0, 0, 0]}])");
    const Vector3d lo[2] = {Vector3d(-0.6, -0.6, -0.6), Vector3d(-1, -1, -1)}, hi[2] = {Vector3d(2.6, 2.6, 1.6), Vector3d(1, 1, 1)};
    // Explicit points (body coordinates of the L): beside the reflex edge inside and outside,
    // at a convex vertex, along a convex edge, over a face.
    const std::vector<Vector3d> explicit_points = {Vector3d(0.9, 0.9, 0.5), Vector3d(1.3, 1.2, 0.5), Vector3d(2.3, -0.2, 1.4),
                                                   Vector3d(2.2, 0.5, 1.3), Vector3d(0.5, 0.5, 1.4), Vector3d(1.1, 1.05, 1.2)};
    const double h = 1e-6;
    for (int o = 0; o < 2; ++o) {
      CAPTURE(o);
      const ObstaclePose p = ObstaclePose::at(scene.spec.obstacles[o], 0.8);
      const ObstacleMesh& m = *scene.spec.obstacles[o].mesh;
      std::mt19937 rng(17);
      int checked[3] = {0, 0, 0}, reflex_inside = 0;
      for (int k = 0; k < 1500; ++k) {
        const Vector3d y = o == 0 && k < static_cast<int>(explicit_points.size()) ? explicit_points[k] : random_in(rng, lo[o], hi[o]);
        const Vector3d x = p.center + p.rotation * y;
        CAPTURE(y.transpose());
        const Distance d = p.distance(x);
        // The BVH finds the brute-force closest distance.
        const MeshClosest q = feature_at(p, x);
        double brute = 1e300;
        for (Eigen::Index f = 0; f < m.F.rows(); ++f)
          brute = std::min(brute, contact::detection::point_triangle_distance(y, m.V.row(m.F(f, 0)).transpose(), m.V.row(m.F(f, 1)).transpose(),
                                                                               m.V.row(m.F(f, 2)).transpose())
                                      .distance_squared);
        CHECK(std::abs(q.distance_squared - brute) <= 1e-14 * (1 + brute));
        CHECK(std::abs(std::abs(d.phi) - std::sqrt(brute)) <= 1e-12);
        if (o == 0) CHECK((d.phi < 0) == inside_l_prism(y));  // the sign of a non-convex closed mesh
        if (std::abs(d.phi) < 0.02) continue;  // near the surface the derivatives of edges and vertices blow up
        bool smooth = true;
        for (int a = 0; a < 3 && smooth; ++a)
          for (double sg : {-1.0, 1.0}) smooth = smooth && same_feature(q, feature_at(p, x + sg * h * Vector3d::Unit(a)));
        if (!smooth) continue;  // straddles a region boundary, where the Hessian jumps
        Vector3d g_fd;
        Eigen::Matrix3d H_fd;
        for (int a = 0; a < 3; ++a) {
          const Vector3d e = h * Vector3d::Unit(a);
          const Distance dp = p.distance(x + e), dn = p.distance(x - e);
          g_fd[a] = (dp.phi - dn.phi) / (2 * h);
          H_fd.col(a) = (dp.grad - dn.grad) / (2 * h);
        }
        CHECK((d.grad - g_fd).norm() <= 1e-7);
        CHECK(std::abs(d.grad.norm() - 1) <= 1e-12);
        CHECK((d.hess - H_fd).norm() <= 1e-5 * (1 + d.hess.norm()));
        CHECK((d.hess - d.hess.transpose()).norm() <= 1e-12 * (1 + d.hess.norm()));
        ++checked[static_cast<int>(q.feature)];
        if (q.feature != MeshClosest::Feature::face) REQUIRE(d.hess.norm() > 0);
        if (o == 0 && q.feature == MeshClosest::Feature::edge && d.phi < 0) ++reflex_inside;  // only reflex edges are closest from inside
      }
      MESSAGE("obstacle " << o << ": checked " << checked[0] << " face, " << checked[1] << " edge, " << checked[2] << " vertex points");
      CHECK(checked[0] >= 20);
      CHECK(checked[1] >= 20);
      CHECK(checked[2] >= 20);
      if (o == 0) CHECK(reflex_inside >= 1);
    }
  }

  TEST_CASE("mesh obstacle: an open mesh is signed by its face normals near the surface") {
    TempDir dir;
    // A unit square in z = 0, normals +z, as two triangles.
    dir.write("square.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n");
    const Scene scene = scene_with(dir, R"([{"shape": "mesh", "file": "square.obj"}])");
    CHECK(!scene.spec.obstacles[0].mesh->closed());
    CHECK(scene.spec.obstacles[0].mesh->boundary_edges == 4);
    const ObstaclePose p = ObstaclePose::at(scene.spec.obstacles[0], 0);
    const Distance above = p.distance(Vector3d(0.3, 0.6, 0.01)), below = p.distance(Vector3d(0.6, 0.3, -0.02));
    CHECK(above.phi == doctest::Approx(0.01).epsilon(1e-12));
    CHECK(below.phi == doctest::Approx(-0.02).epsilon(1e-12));
    CHECK((above.grad - Vector3d::UnitZ()).norm() <= 1e-15);
    CHECK((below.grad - Vector3d::UnitZ()).norm() <= 1e-15);
    // Beside a boundary edge, above and below the plane: the distance to the edge, signed by the face normal.
    const Distance out_above = p.distance(Vector3d(1.03, 0.5, 0.04)), out_below = p.distance(Vector3d(1.03, 0.5, -0.04));
    CHECK(out_above.phi == doctest::Approx(0.05).epsilon(1e-12));
    CHECK(out_below.phi == doctest::Approx(-0.05).epsilon(1e-12));
    // On the diagonal (a flat interior edge) and at the surface: the face branch.
    const Distance diag = p.distance(Vector3d(0.5, 0.5, 0.1)), on = p.distance(Vector3d(0.25, 0.75, 0));
    CHECK(diag.phi == doctest::Approx(0.1).epsilon(1e-12));
    CHECK(diag.hess.norm() == 0.0);
    CHECK(std::abs(on.phi) <= 1e-16);
    CHECK((on.grad - Vector3d::UnitZ()).norm() <= 1e-15);
  }

  TEST_CASE("mesh obstacle: malformed files and keys are configuration errors naming the key") {
    TempDir dir;
    const std::string cube = obj_text(box_vertices(Vector3d(0.1, 0.1, 0.1)), box_faces);
    dir.write("vertices_only.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
    dir.write("infinite.obj", "v 1e999 0 0\n" + cube.substr(cube.find('\n') + 1));
    dir.write("collinear.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n");
    dir.write("inward.obj", obj_text(box_vertices(Vector3d(0.1, 0.1, 0.1)), reversed(box_faces)));
    dir.write("flipped.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 4 3\n");
    dir.write("fin.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n");
    dir.write("cube.obj", cube);
    struct Case {
      std::string obstacle;
      std::vector<std::string> expected;  // substrings of the message
    };
    const Case cases[] = {
        {R"({"shape": "mesh", "file": "missing.obj"})", {"obstacles.0.file = \"missing.obj\"", "not found"}},
        {R"({"shape": "mesh", "file": "vertices_only.obj"})", {"obstacles.0.file = \"vertices_only.obj\"", "no triangle faces"}},
        {R"({"shape": "mesh", "file": "infinite.obj"})", {"obstacles.0.file = \"infinite.obj\"", "infinite.obj:1:", "not finite"}},
        {R"({"shape": "mesh", "file": "collinear.obj"})", {"obstacles.0.file = \"collinear.obj\"", "face 1", "zero area"}},
        {R"({"shape": "mesh", "file": "inward.obj"})", {"obstacles.0.file = \"inward.obj\"", "point inwards"}},
        {R"({"shape": "mesh", "file": "flipped.obj"})", {"obstacles.0.file = \"flipped.obj\"", "same direction"}},
        {R"({"shape": "mesh", "file": "fin.obj"})", {"obstacles.0.file = \"fin.obj\"", "more than two faces"}},
        {R"({"shape": "mesh"})", {"obstacles.0.file", "a path to an OBJ file"}},
        {R"({"shape": "mesh", "file": "cube.obj", "scale": 0})", {"obstacles.0.scale"}},
        {R"({"shape": "mesh", "file": "cube.obj", "radius": 0.1})", {"obstacles.0.radius is not read when shape = mesh"}},
        {R"({"shape": "sphere", "file": "cube.obj"})", {"obstacles.0.file is only read when shape = mesh"}},
    };
    for (const Case& c : cases) {
      CAPTURE(c.obstacle);
      CHECK_THROWS_AS(scene_with(dir, "[" + c.obstacle + "]"), ConfigError);
      for (const auto& e : c.expected) CHECK_THROWS_WITH(scene_with(dir, "[" + c.obstacle + "]"), doctest::Contains(e.c_str()));
    }
    CHECK_NOTHROW(scene_with(dir, R"([{"shape": "mesh", "file": "cube.obj", "scale": 3}])"));
    ObstacleSpec bare;
    bare.shape = ObstacleShape::mesh;
    bare.file = "cube.obj";
    CHECK_THROWS_WITH_AS(ObstaclePose::at(bare, 0), doctest::Contains("has no geometry"), ConfigError);
  }
}

TEST_SUITE("slow") {
  TEST_CASE("mesh obstacle: a sheet dropped on a mesh box comes to rest as on the analytic box with impulses") {
    rest_on_mesh_box("cloth_ip_impulse_direct", 1e-3, 1e-12);
  }

  TEST_CASE("mesh obstacle: a sheet dropped on a mesh box comes to rest as on the analytic box with constraints") {
    rest_on_mesh_box("cloth_ip_constraints_direct", 2e-3, 5e-5);
  }
}
