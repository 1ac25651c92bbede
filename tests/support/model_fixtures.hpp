#pragma once
/// \file model_fixtures.hpp
/// Scenes, states and small meshes for the energy-model tests, built in code (no files):
/// single triangles and hinges with prescribed shapes, planar grids, random patches with
/// fixed seeds, rigid motions.
#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <utility>
#include <vector>

#include "framework/scene.hpp"
#include "framework/state.hpp"
#include "framework/triangle_mesh.hpp"

namespace weft::support {

/// Portable uniform numbers from a fixed seed (std::uniform_real_distribution is not
/// specified bit for bit across standard libraries).
class Rng {
 public:
  explicit Rng(std::uint32_t seed) : g_(seed) {}
  /// Uniform in [a, b).
  double uniform(double a = 0, double b = 1) { return a + (b - a) * (static_cast<double>(g_() >> 5) / 134217728.0); }
  Eigen::Vector3d vec3(double a = -1, double b = 1) { return {uniform(a, b), uniform(a, b), uniform(a, b)}; }
  /// A random rotation (uniform unit quaternion, rejection-sampled).
  Eigen::Matrix3d rotation() {
    Eigen::Vector4d q;
    do q = Eigen::Vector4d(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
    while (q.norm() < 0.1 || q.norm() > 1);
    return Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
  }

 private:
  std::mt19937 g_;
};

/// Vertices and faces of a mesh.
struct MeshData {
  Eigen::MatrixX3d V;  ///< #V by 3
  Eigen::MatrixX3i F;  ///< #F by 3, counter-clockwise
};

/// #V by 3 -> stacked #V*3.
inline Eigen::VectorXd stack(const Eigen::MatrixX3d& V) {
  Eigen::VectorXd x(3 * V.rows());
  for (Eigen::Index i = 0; i < V.rows(); ++i) x.segment<3>(3 * i) = V.row(i).transpose();
  return x;
}

/// x_i -> R x_i + c for every vertex of a stacked vector.
inline Eigen::VectorXd rigid_motion(const Eigen::VectorXd& x, const Eigen::Matrix3d& R, const Eigen::Vector3d& c) {
  Eigen::VectorXd y(x.size());
  for (Eigen::Index i = 0; i < x.size() / 3; ++i) y.segment<3>(3 * i) = R * x.segment<3>(3 * i) + c;
  return y;
}

/// (I (x) R) g: rotate every 3-block of a stacked vector.
inline Eigen::VectorXd rotate_blocks(const Eigen::VectorXd& g, const Eigen::Matrix3d& R) {
  return rigid_motion(g, R, Eigen::Vector3d::Zero());
}

/// x + uniform noise in [-amplitude, amplitude] per coordinate.
inline Eigen::VectorXd perturb(const Eigen::VectorXd& x, double amplitude, std::uint32_t seed) {
  Rng rng(seed);
  Eigen::VectorXd y = x;
  for (Eigen::Index i = 0; i < y.size(); ++i) y[i] += rng.uniform(-amplitude, amplitude);
  return y;
}

/// A material with O(1) constants so that derivative checks are not dominated by the
/// absolute floor of the tolerances: Y = 1 Pa, nu = 0.3, h = 1 m, density 1, k = 1 J.
inline ShellMaterial unit_material() {
  ShellMaterial m;
  m.density = 1.0;
  m.youngs_modulus = 1.0;
  m.poisson_ratio = 0.3;
  m.thickness = 1.0;
  m.bending_stiffness = 1.0;
  return m;
}

/// An orthotropic material in the warp/weft convention of `ShellMaterial` (x = warp,
/// y = weft): Y = y_warp, eta = y_weft / y_warp, nu = nu_xy, G = 2 g12; density 1, k = 1 J.
inline ShellMaterial orthotropic_material(double y_warp, double y_weft, double g12, double nu, double thickness = 1.0) {
  ShellMaterial m = unit_material();
  m.model = MaterialModel::orthotropic;
  m.youngs_modulus_warp = y_warp;
  m.youngs_modulus_weft = y_weft;
  m.shear_modulus = g12;
  m.poisson_ratio = nu;
  m.thickness = thickness;
  return m;
}

/// Per face of `mesh`, the unit projection of `dir` onto the face's plane.
inline std::vector<Eigen::Vector3d> projected_warps(const MeshData& mesh, const Eigen::Vector3d& dir) {
  std::vector<Eigen::Vector3d> w(static_cast<size_t>(mesh.F.rows()));
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)), c = mesh.V.row(mesh.F(f, 2));
    const Eigen::Vector3d n = (b - a).cross(c - a).normalized();
    w[static_cast<size_t>(f)] = (dir - dir.dot(n) * n).normalized();
  }
  return w;
}

/// Per face of `mesh`, a random unit direction in the face's plane (fixed seed).
inline std::vector<Eigen::Vector3d> random_warps(const MeshData& mesh, std::uint32_t seed) {
  Rng rng(seed);
  std::vector<Eigen::Vector3d> w(static_cast<size_t>(mesh.F.rows()));
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)), c = mesh.V.row(mesh.F(f, 2));
    const Eigen::Vector3d t1 = (b - a).normalized(), t2 = (b - a).cross(c - a).normalized().cross(t1);
    const double phi = rng.uniform(0, 2 * std::numbers::pi);
    w[static_cast<size_t>(f)] = std::cos(phi) * t1 + std::sin(phi) * t2;
  }
  return w;
}

/// A scene holding one mesh; `face_cloth[f]` picks the material of face f among `materials`
/// (one ClothSpec per material; all faces use cloth 0 when `face_cloth` is empty).
/// `face_warp` is the per-face warp direction of orthotropic materials (`Scene::face_warp`).
inline Scene make_scene(const MeshData& mesh, const std::vector<ShellMaterial>& materials, std::vector<int> face_cloth = {},
                        std::vector<Eigen::Vector3d> face_warp = {}) {
  Scene s;
  s.mesh = TriangleMesh(mesh.V, mesh.F);
  for (size_t c = 0; c < materials.size(); ++c) {
    ClothSpec cloth;
    cloth.name = "cloth" + std::to_string(c);
    cloth.material = materials[c];
    s.spec.cloths.push_back(cloth);
  }
  const int nv = s.mesh.num_vertices(), nf = s.mesh.num_faces();
  s.face_cloth = face_cloth.empty() ? std::vector<int>(nf, 0) : std::move(face_cloth);
  s.cloth_vertex_offset = {0, nv};
  s.cloth_face_offset = {0, nf};
  s.dof.assign(nv, Dof::free);
  s.vertex_motion.assign(nv, -1);
  s.face_warp = std::move(face_warp);
  return s;
}
inline Scene make_scene(const MeshData& mesh, const ShellMaterial& material = unit_material(),
                        std::vector<Eigen::Vector3d> face_warp = {}) {
  return make_scene(mesh, std::vector<ShellMaterial>{material}, {}, std::move(face_warp));
}

/// Lumped masses computed independently of `Scene::lumped_masses`: density * area / 3 per corner.
inline Eigen::VectorXd reference_masses(const Scene& s) {
  Eigen::VectorXd m = Eigen::VectorXd::Zero(s.mesh.num_vertices());
  const auto& V = s.mesh.rest();
  const auto& F = s.mesh.faces();
  for (int f = 0; f < s.mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = V.row(F(f, 0)), b = V.row(F(f, 1)), c = V.row(F(f, 2));
    const double area = 0.5 * (b - a).cross(c - a).norm();
    for (int k = 0; k < 3; ++k) m[F(f, k)] += s.face_material(f).density * area / 3.0;
  }
  return m;
}

/// A state at positions x (stacked #V*3), zero velocity, masses from `reference_masses`.
inline State make_state(const Scene& scene, const Eigen::VectorXd& x) {
  State s;
  s.x = x;
  s.v = Eigen::VectorXd::Zero(x.size());
  s.mass = reference_masses(scene);
  s.dof = scene.dof;
  return s;
}
inline State rest_state(const Scene& scene) { return make_state(scene, stack(scene.mesh.rest())); }

/// A scene, a model built on it and a state.
template <class Model>
struct Patch {
  Scene scene;
  Model model;
  State state;
};
template <class Model>
Patch<Model> make_patch(const MeshData& mesh, const Eigen::VectorXd& x, const typename Model::Params& prm = {},
                        const ShellMaterial& material = unit_material(), std::vector<Eigen::Vector3d> face_warp = {}) {
  Scene scene = make_scene(mesh, material, std::move(face_warp));
  Model model(scene, prm);
  State state = make_state(scene, x);
  return Patch<Model>{std::move(scene), std::move(model), std::move(state)};
}

/// One triangle.
inline MeshData triangle(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  MeshData m;
  m.V.resize(3, 3);
  m.V << a.transpose(), b.transpose(), c.transpose();
  m.F.resize(1, 3);
  m.F << 0, 1, 2;
  return m;
}

/// Two triangles T = (x0, x1, x2), T~ = (x3, x2, x1) sharing the hinge x1 -> x2 (methods/shells §6.1).
inline MeshData hinge(const Eigen::Vector3d& x0, const Eigen::Vector3d& x1, const Eigen::Vector3d& x2,
                      const Eigen::Vector3d& x3) {
  MeshData m;
  m.V.resize(4, 3);
  m.V << x0.transpose(), x1.transpose(), x2.transpose(), x3.transpose();
  m.F.resize(2, 3);
  m.F << 0, 1, 2, 3, 2, 1;
  return m;
}

/// The hinge of methods/shells §6.1 / §9 item 24: x0 = (1/2, 1, 0), x1 = 0, x2 = (1, 0, 0),
/// x3 = (1/2, -cos phi, -sin phi); theta = +phi, unit hinge edge, total area 1.
inline MeshData known_hinge(double phi) {
  return hinge({0.5, 1, 0}, {0, 0, 0}, {1, 0, 0}, {0.5, -std::cos(phi), -std::sin(phi)});
}

/// A random well-shaped hinge with dihedral angle `phi` (theta = +phi), then a random rigid
/// motion. `wing_height` scales the altitude of x0 (1e-3 gives a near-degenerate triangle).
inline MeshData random_hinge(std::uint32_t seed, double phi, double wing_height = -1) {
  Rng rng(seed);
  const double L = rng.uniform(0.8, 1.2);
  const double a = rng.uniform(0.25, 0.75) * L, b = wing_height > 0 ? wing_height * L : rng.uniform(0.5, 1.0);
  const double c = rng.uniform(0.25, 0.75) * L, d = rng.uniform(0.5, 1.0);
  MeshData m = hinge({a, b, 0}, {0, 0, 0}, {L, 0, 0}, {c, -d * std::cos(phi), -d * std::sin(phi)});
  const Eigen::Matrix3d R = rng.rotation();
  const Eigen::Vector3d t = rng.vec3();
  for (int i = 0; i < 4; ++i) m.V.row(i) = (R * m.V.row(i).transpose() + t).transpose();
  return m;
}

/// Planar nx by ny vertex grid over [0, lx] x [0, ly] in the xy plane, alternating diagonals,
/// faces counter-clockwise about +z.
inline MeshData grid(int nx, int ny, double lx, double ly) {
  MeshData m;
  m.V.resize(nx * ny, 3);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) m.V.row(j * nx + i) << lx * i / (nx - 1), ly * j / (ny - 1), 0.0;
  m.F.resize(2 * (nx - 1) * (ny - 1), 3);
  int f = 0;
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i) {
      const int v00 = j * nx + i, v10 = v00 + 1, v01 = v00 + nx, v11 = v01 + 1;
      if ((i + j) % 2 == 0) {
        m.F.row(f++) << v00, v10, v11;
        m.F.row(f++) << v00, v11, v01;
      } else {
        m.F.row(f++) << v00, v10, v01;
        m.F.row(f++) << v10, v11, v01;
      }
    }
  return m;
}

/// A 4 by 4 vertex grid with unit spacing, jittered in plane (well-shaped: all angles above
/// 15 degrees); `curved` adds a smooth random height field (non-flat rest angles up to about
/// 1 rad) and a random rigid motion.
inline MeshData random_patch(std::uint32_t seed, bool curved) {
  Rng rng(seed);
  MeshData m = grid(4, 4, 3.0, 3.0);
  const double kx = rng.uniform(0.6, 1.2), ky = rng.uniform(0.6, 1.2), p = rng.uniform(0, 6.28), amp = rng.uniform(0.5, 0.8);
  for (Eigen::Index i = 0; i < m.V.rows(); ++i) {
    m.V(i, 0) += rng.uniform(-0.12, 0.12);
    m.V(i, 1) += rng.uniform(-0.12, 0.12);
    if (curved) m.V(i, 2) = amp * std::sin(kx * m.V(i, 0) + p) * std::cos(ky * m.V(i, 1)) + rng.uniform(-0.15, 0.15);
  }
  if (curved) {
    const Eigen::Matrix3d R = rng.rotation();
    const Eigen::Vector3d t = rng.vec3();
    for (Eigen::Index i = 0; i < m.V.rows(); ++i) m.V.row(i) = (R * m.V.row(i).transpose() + t).transpose();
  }
  return m;
}

/// Smallest interior angle of any face of the mesh at positions x [rad].
inline double min_angle(const MeshData& mesh, const Eigen::VectorXd& x) {
  double lo = std::numbers::pi;
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d a = x.segment<3>(3 * mesh.F(f, k)), b = x.segment<3>(3 * mesh.F(f, (k + 1) % 3)),
                            c = x.segment<3>(3 * mesh.F(f, (k + 2) % 3));
      const Eigen::Vector3d u = (b - a).normalized(), v = (c - a).normalized();
      lo = std::min(lo, std::acos(std::clamp(u.dot(v), -1.0, 1.0)));
    }
  return lo;
}

}  // namespace weft::support
