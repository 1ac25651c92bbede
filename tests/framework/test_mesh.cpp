#include <doctest/doctest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>
#include <set>

#include "framework/error.hpp"
#include "framework/mesh_generators.hpp"
#include "framework/obj_io.hpp"
#include "framework/triangle_mesh.hpp"

using namespace weft;

namespace {
TriangleMesh to_mesh(const MeshData& m) { return TriangleMesh(m.V, m.F); }

// Every face's normal points along +z (sheets generated in the xy plane).
int faces_facing_up(const TriangleMesh& m) {
  int n = 0;
  for (int f = 0; f < m.num_faces(); ++f) {
    const Eigen::Vector3d a = m.rest().row(m.faces()(f, 0)), b = m.rest().row(m.faces()(f, 1)), c = m.rest().row(m.faces()(f, 2));
    n += (b - a).cross(c - a).z() > 0;
  }
  return n;
}
}  // namespace

TEST_SUITE("framework") {
  TEST_CASE("rectangle: topology counts and orientation / regular and irregular") {
    for (auto t : {Tessellation::regular, Tessellation::irregular})
      for (auto res : {std::array<int, 2>{2, 2}, std::array<int, 2>{5, 3}, std::array<int, 2>{11, 11}}) {
        CAPTURE(static_cast<int>(t));
        CAPTURE(res[0]);
        CAPTURE(res[1]);
        const auto m = to_mesh(make_rectangle({1.0, 2.0}, res, t, 3));
        const int nx = res[0], ny = res[1];
        CHECK(m.num_vertices() == nx * ny);
        CHECK(m.num_faces() == 2 * (nx - 1) * (ny - 1));
        CHECK(m.num_edges() == (nx - 1) * ny + nx * (ny - 1) + (nx - 1) * (ny - 1));
        CHECK(m.num_boundary_edges() == 2 * (nx - 1) + 2 * (ny - 1));
        CHECK(m.num_hinges() == m.num_edges() - m.num_boundary_edges());
        CHECK(m.num_vertices() - m.num_edges() + m.num_faces() == 1);  // a disk
        CHECK(m.num_components() == 1);
        CHECK(faces_facing_up(m) == m.num_faces());
        CHECK(m.rest_area() == doctest::Approx(2.0).epsilon(1e-12));
      }
  }

  TEST_CASE("rectangle: irregular tessellation jitters interior vertices only / deterministically") {
    const auto r = make_rectangle({1, 1}, {9, 9}, Tessellation::regular, 1);
    const auto a = make_rectangle({1, 1}, {9, 9}, Tessellation::irregular, 1);
    const auto b = make_rectangle({1, 1}, {9, 9}, Tessellation::irregular, 1);
    const auto c = make_rectangle({1, 1}, {9, 9}, Tessellation::irregular, 2);
    CHECK((a.V - b.V).norm() == 0.0);
    CHECK((a.V - c.V).norm() > 0.0);
    int moved = 0, boundary_moved = 0;
    for (int i = 0; i < r.V.rows(); ++i) {
      const bool boundary = std::abs(std::abs(r.V(i, 0)) - 0.5) < 1e-12 || std::abs(std::abs(r.V(i, 1)) - 0.5) < 1e-12;
      const bool m = (r.V.row(i) - a.V.row(i)).norm() > 1e-12;
      moved += m;
      boundary_moved += boundary && m;
    }
    CHECK(moved == 49);  // the 7x7 interior vertices
    CHECK(boundary_moved == 0);
  }

  TEST_CASE("rectangle: irregular sheets have no folded or sliver triangles at any size or seed") {
    // 30% jitter on both ends of an edge could fold a triangle over; the generator shrinks
    // the offsets of such triangles (an inverted rest triangle is also a self-intersection).
    int shrunk = 0;
    for (int n : {31, 101, 201})
      for (int seed = 0; seed < 4; ++seed) {
        CAPTURE(n);
        CAPTURE(seed);
        const MeshData m = make_rectangle({1, 1}, {n, n}, Tessellation::irregular, seed);
        const double h = 1.0 / (n - 1), nominal = 0.5 * h * h;
        double smallest = 1e300;
        for (Eigen::Index f = 0; f < m.F.rows(); ++f) {
          const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
          smallest = std::min(smallest, 0.5 * (b - a).cross(c - a).z());
        }
        CHECK(smallest >= 0.1 * nominal * (1 - 1e-12));
        shrunk += smallest < 0.2 * nominal;  // some triangles sit at the floor: the guard acts
      }
    CHECK(shrunk > 0);
  }

  TEST_CASE("l_shape: counts / re-entrant corner and orientation") {
    const int n = 9, c = 4;  // cut at grid line 4
    const auto m = to_mesh(make_l_shape({1, 1}, {n, n}, Tessellation::regular, 1));
    CHECK(m.num_vertices() == n * n - (n - 1 - c) * (n - 1 - c));
    CHECK(m.num_faces() == 2 * ((n - 1) * (n - 1) - (n - 1 - c) * (n - 1 - c)));
    CHECK(m.num_vertices() - m.num_edges() + m.num_faces() == 1);
    CHECK(faces_facing_up(m) == m.num_faces());
    CHECK(m.rest_area() == doctest::Approx(0.75).epsilon(1e-12));
    CHECK_THROWS_AS(make_l_shape({1, 1}, {8, 9}, Tessellation::regular, 1), ConfigError);
  }

  TEST_CASE("hinges: labelling follows methods/shells §6.1") {
    const auto m = to_mesh(make_rectangle({1, 1}, {6, 5}, Tessellation::irregular, 4));
    REQUIRE(m.num_hinges() > 0);
    for (const auto& h : m.hinges()) {
      // T = (x0, x1, x2) is a cyclic rotation of face T's vertices.
      const auto fa = m.faces().row(h.face[0]), fb = m.faces().row(h.face[1]);
      bool t_ok = false, tt_ok = false;
      for (int r = 0; r < 3; ++r) {
        t_ok |= fa(r) == h.v[0] && fa((r + 1) % 3) == h.v[1] && fa((r + 2) % 3) == h.v[2];
        tt_ok |= fb(r) == h.v[3] && fb((r + 1) % 3) == h.v[2] && fb((r + 2) % 3) == h.v[1];
      }
      CHECK(t_ok);
      CHECK(tt_ok);
      CHECK(std::set<int>(h.v.begin(), h.v.end()).size() == 4);
      const auto& e = m.edges()[h.edge];
      CHECK(std::min(h.v[1], h.v[2]) == e[0]);
      CHECK(std::max(h.v[1], h.v[2]) == e[1]);
    }
  }

  TEST_CASE("vertex adjacency: symmetric and matches the edges") {
    const auto m = to_mesh(make_rectangle({1, 1}, {4, 4}, Tessellation::regular, 1));
    long total = 0;
    for (int i = 0; i < m.num_vertices(); ++i)
      for (int k = m.vertex_offsets()[i]; k < m.vertex_offsets()[i + 1]; ++k) {
        const int j = m.vertex_neighbours()[k];
        const auto first = m.vertex_neighbours().begin() + m.vertex_offsets()[j];
        const auto last = m.vertex_neighbours().begin() + m.vertex_offsets()[j + 1];
        CHECK(std::find(first, last, i) != last);
        ++total;
      }
    CHECK(total == 2 * m.num_edges());
  }

  TEST_CASE("triangle mesh: bad topology is a configuration error") {
    Eigen::MatrixX3d V(5, 3);
    V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 0, 1;
    Eigen::MatrixX3i inconsistent(2, 3);
    inconsistent << 0, 1, 2, 1, 2, 3;  // both traverse 1 -> 2
    CHECK_THROWS_WITH_AS(TriangleMesh(V, inconsistent), doctest::Contains("inconsistent orientation"), ConfigError);
    Eigen::MatrixX3i nonmanifold(3, 3);
    nonmanifold << 0, 1, 2, 2, 1, 3, 1, 2, 4;
    CHECK_THROWS_WITH_AS(TriangleMesh(V, nonmanifold), doctest::Contains("non-manifold"), ConfigError);
    Eigen::MatrixX3i out_of_range(1, 3);
    out_of_range << 0, 1, 7;
    CHECK_THROWS_WITH_AS(TriangleMesh(V, out_of_range), doctest::Contains("references vertex 7"), ConfigError);
    Eigen::MatrixX3i repeated(1, 3);
    repeated << 0, 1, 1;
    CHECK_THROWS_WITH_AS(TriangleMesh(V, repeated), doctest::Contains("repeats a vertex"), ConfigError);
  }

  TEST_CASE("obj: write then read keeps vertex order / faces and orientation") {
    const auto tmp = std::filesystem::temp_directory_path() / "weft_test_mesh.obj";
    const auto m = make_rectangle({1, 1}, {5, 4}, Tessellation::irregular, 9);
    Eigen::VectorXd x(3 * m.V.rows());
    for (int i = 0; i < m.V.rows(); ++i) x.segment<3>(3 * i) = m.V.row(i).transpose();
    write_obj(tmp.string(), x, m.F, "test");
    const auto r = read_obj(tmp.string());
    CHECK(r.V.rows() == m.V.rows());
    CHECK((r.V - m.V).norm() <= 1e-15);
    CHECK(r.F == m.F);
    CHECK(faces_facing_up(to_mesh(r)) == r.F.rows());
    std::filesystem::remove(tmp);
  }

  TEST_CASE("obj: polygons are triangulated - missing and malformed files are configuration errors") {
    const auto dir = std::filesystem::temp_directory_path();
    {
      std::ofstream f(dir / "weft_quad.obj");
      f << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
    }
    const auto q = read_obj((dir / "weft_quad.obj").string());
    CHECK(q.V.rows() == 4);
    CHECK(q.F.rows() == 2);
    CHECK_THROWS_WITH_AS(read_obj((dir / "weft_does_not_exist.obj").string()), doctest::Contains("not found"), ConfigError);
    {
      std::ofstream f(dir / "weft_nofaces.obj");
      f << "v 0 0 0\nv 1 0 0\n";
    }
    CHECK_THROWS_WITH_AS(read_obj((dir / "weft_nofaces.obj").string()), doctest::Contains("no triangle faces"), ConfigError);
    {
      std::ofstream f(dir / "weft_badindex.obj");
      f << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n";
    }
    CHECK_THROWS_AS(read_obj((dir / "weft_badindex.obj").string()), ConfigError);
  }

  TEST_CASE("generated sheets: texture coordinates are the (u v) plane coordinates") {
    auto m = make_l_shape({2, 1}, {5, 7}, Tessellation::irregular, 3);
    REQUIRE(m.has_uv());
    CHECK(m.FUV == m.F);
    CHECK((m.UV - m.V.leftCols<2>()).norm() == 0.0);
    place_sheet(m, SheetPlane::yz, {1, 2, 3});
    // Placement moves the vertices, not the texture coordinates: (u, v) -> (y, z).
    const auto dirs = texture_directions(m, 0.3);
    for (const auto& d : dirs) CHECK((d - Eigen::Vector3d(0, std::cos(0.3), std::sin(0.3))).norm() <= 1e-12);
  }

  TEST_CASE("obj: texture coordinates are read per face corner / with seams") {
    const auto dir = std::filesystem::temp_directory_path();
    {
      // Two triangles sharing the edge 1-3, with different texture coordinates on either side.
      std::ofstream f(dir / "weft_uv.obj");
      f << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
        << "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 5 5\nvt 6 6\n"
        << "f 1/1 2/2 3/3\nf 1/5 3/6 4/4\n";
    }
    const auto m = read_obj((dir / "weft_uv.obj").string());
    REQUIRE(m.has_uv());
    CHECK(m.UV.rows() == 6);
    CHECK(m.UV.row(4) == Eigen::RowVector2d(5, 5));
    CHECK(m.FUV.row(0) == Eigen::RowVector3i(0, 1, 2));
    CHECK(m.FUV.row(1) == Eigen::RowVector3i(4, 5, 3));
    // Face 0: u along x. Face 1: t(v0) = (5, 5), t(v2) = (6, 6), t(v3) = (0, 1).
    const auto d = texture_directions(m, 0.0);
    CHECK((d[0] - Eigen::Vector3d(1, 0, 0)).norm() <= 1e-15);
    {
      // Direction of increasing u on face 1: solve X = J t on its edges.
      Eigen::Matrix<double, 3, 2> X;
      Eigen::Matrix2d U;
      X << 1, 0, 1, 1, 0, 0;
      U << 1, -5, 1, -4;
      const Eigen::Vector3d ju = (X * U.inverse()).col(0).normalized();
      CHECK((d[1] - ju).norm() <= 1e-14);
    }
    {
      std::ofstream f(dir / "weft_uv_partial.obj");
      f << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 2 2\n"
        << "f 1/1 2/2 3/3\nf 1 3 4\nf 1/1 3/3 4/4\n";
    }
    // A face without texture coordinates, and a zero-area texture triangle, named.
    const auto p = read_obj((dir / "weft_uv_partial.obj").string());
    try {
      texture_directions(p, 0.0);
      FAIL("expected a ConfigError");
    } catch (const ConfigError& e) {
      const std::string what = e.what();
      CAPTURE(what);
      CHECK(what.find("face 1 has no texture coordinates") != std::string::npos);
      CHECK(what.find("face 2 has a zero-area texture triangle") != std::string::npos);
    }
    // Without vt lines: no texture coordinates at all.
    {
      std::ofstream f(dir / "weft_nouv.obj");
      f << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    }
    const auto n = read_obj((dir / "weft_nouv.obj").string());
    CHECK_FALSE(n.has_uv());
    CHECK_THROWS_WITH_AS(texture_directions(n, 0.0), doctest::Contains("no texture coordinates"), ConfigError);
    for (const char* name : {"weft_uv.obj", "weft_uv_partial.obj", "weft_nouv.obj"}) std::filesystem::remove(dir / name);
  }
}
