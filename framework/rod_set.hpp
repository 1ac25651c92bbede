#pragma once
/// \file rod_set.hpp
/// Elastic rods (hair) in a scene: how the scene file describes them (`RodSpec`) and the
/// rod set built from it (`RodSet`): per rod, the rest configuration in the interleaved DoF
/// layout of discrete elastic rods, q = (x0, theta0, x1, theta1, ..., theta_{V-2}, x_{V-1})
/// (n = 4V - 1; x_i at 4i, the twist of edge j at 4j + 3), its material and which DoFs
/// follow a scripted root.
///
/// Units are SI. The thesis' rod experiments are stated in cgs; scenes convert at the
/// boundary (the unit suffixes of framework/units.hpp, e.g. "37 um", "3.9e9 dyn/cm^2").
#include <Eigen/Core>

#include <array>
#include <string>
#include <string_view>
#include <vector>

#include "framework/motion.hpp"
#include "framework/params.hpp"

namespace weft {

/// How a rod's root is held.
enum class RodRoot {
  free,    ///< nothing held (a dropped rod)
  vertex,  ///< the root vertex and the first twist follow the root motion (a pinned end)
  edge,    ///< the first two vertices and the first twist follow it (a clamped end: the root tangent is prescribed)
};
inline constexpr std::array<std::string_view, 3> rod_root_names = {"free", "vertex", "edge"};

/// How rods are generated.
enum class RodShape {
  straight,     ///< `count` parallel straight rods from `root` along `direction`, spaced by `spacing` along `spread`
  helix,        ///< like straight, each a helix of `curl_radius` and `curl_pitch` about `direction`
  sphere_hair,  ///< `count` rods rooted on a sphere (`sphere_center`, `sphere_radius`), area-uniformly over the cap within `coverage_angle` of `direction`, growing along the normal; helices about the normal with a random phase when `curl_radius` > 0; no two rods closer than `clearance` at rest
};
inline constexpr std::array<std::string_view, 3> rod_shape_names = {"straight", "helix", "sphere_hair"};

/// Cross-section and material of a rod (circular cross-section).
struct RodMaterialSpec {
  double radius = 50e-6;     ///< [m]
  double youngs_modulus = 1e9;  ///< [Pa]
  double shear_modulus = 3.4e8;  ///< [Pa]
  double density = 1300;     ///< [kg/m^3]
  double viscosity = 0;      ///< [Pa s] internal (viscous-thread) damping; 0: none
  template <class V>
  void visit(V& v) {
    v.field("radius", radius, {Unit::length, Range::gt(0), "radius of the circular cross-section"});
    v.field("youngs_modulus", youngs_modulus, {Unit::pressure, Range::gt(0), "Young's modulus (stretching, bending)"});
    v.field("shear_modulus", shear_modulus, {Unit::pressure, Range::gt(0), "shear modulus (twisting)"});
    v.field("density", density, {Unit::density, Range::gt(0), "volumetric mass density"});
    v.field("viscosity", viscosity, {Unit::viscosity, Range::ge(0), "internal viscosity of the viscous-thread terms (0: none)"});
  }
};

/// One entry of the scene's "rods" list: a family of rods with one material.
struct RodSpec {
  std::string name = "rods";
  RodShape shape = RodShape::straight;
  int count = 1;                       ///< rods in the family
  int vertices = 30;                   ///< vertices per rod (>= 3)
  double length = 0.2;                 ///< [m] arc length of each rod at rest
  Eigen::Vector3d root{0, 0, 0};       ///< [m] root of the first rod (straight, helix)
  Eigen::Vector3d direction{0, 0, -1}; ///< growth direction (straight, helix) or the cap axis (sphere_hair); normalised
  Eigen::Vector3d spread{1, 0, 0};     ///< straight, helix: the roots are spaced along this direction
  double spacing = 0.01;               ///< [m] distance between neighbouring roots (straight, helix)
  double curl_radius = 0;              ///< [m] helix radius of a curly rest shape (0: straight)
  double curl_pitch = 0.02;            ///< [m] rise per turn of the helix
  Eigen::Vector3d sphere_center{0, 0, 0};
  double sphere_radius = 0.09;         ///< [m]
  double coverage_angle = 1.5707963267948966;  ///< [rad] sphere_hair: half-angle of the seeded cap (pi/2: half the sphere)
  int seed = 1;                        ///< sphere_hair: random seed of the root positions
  double clearance = 0;                ///< [m] sphere_hair: smallest gap at rest between the surfaces of two rods (no rod is ever seeded inside the scalp)
  RodRoot root_held = RodRoot::edge;   ///< how the roots are held
  Motion motion;                       ///< motion of the held roots (rigid, like an obstacle's)
  Eigen::Vector3d initial_velocity = Eigen::Vector3d::Zero();  ///< [m/s]
  RodMaterialSpec material;
  template <class V>
  void visit(V& v) {
    v.field("name", name, {Unit::none, Range::any(), "name used in output files"});
    v.choice("shape", shape, rod_shape_names, "generator: straight rods, helices, or hair rooted on a sphere");
    v.field("count", count, {Unit::none, Range::closed(1, 1000000), "number of rods"});
    v.field("vertices", vertices, {Unit::none, Range::closed(3, 100000), "vertices per rod"});
    v.field("length", length, {Unit::length, Range::gt(0), "rest arc length of each rod"});
    v.field("root", root, {Unit::length, Range::any(), "root of the first rod (straight, helix)"});
    v.field("direction", direction, {Unit::none, Range::any(), "growth direction (straight, helix) or cap axis (sphere_hair); nonzero"});
    v.field("spread", spread, {Unit::none, Range::any(), "straight, helix: roots are spaced along this direction"});
    v.field("spacing", spacing, {Unit::length, Range::ge(0), "straight, helix: distance between neighbouring roots"});
    v.field("curl_radius", curl_radius, {Unit::length, Range::ge(0), "radius of a helical (curly) rest shape; 0: straight"});
    v.field("curl_pitch", curl_pitch, {Unit::length, Range::gt(0), "rise per turn of the helical rest shape"});
    v.field("sphere_center", sphere_center, {Unit::length, Range::any(), "sphere_hair: centre of the scalp sphere"});
    v.field("sphere_radius", sphere_radius, {Unit::length, Range::gt(0), "sphere_hair: radius of the scalp sphere"});
    v.field("coverage_angle", coverage_angle,
            {Unit::angle, Range::open_closed(0, 3.141592653589793), "sphere_hair: half-angle of the seeded cap about `direction`"});
    v.field("seed", seed, {Unit::none, Range::ge(0), "sphere_hair: random seed of the roots"});
    v.field("clearance", clearance,
            {Unit::length, Range::ge(0),
             "sphere_hair: smallest gap at rest between the surfaces of two rods of the family; a rod that would come closer to one "
             "placed before it, or enter the scalp, is drawn again (phase, then root)"});
    v.choice("root_held", root_held, rod_root_names, "free, a pinned root vertex, or a clamped root edge");
    v.section("motion", motion);
    v.field("initial_velocity", initial_velocity, {Unit::velocity, Range::any(), "initial velocity of every vertex"});
    v.section("material", material);
  }
};

/// The rods of a scene, all families concatenated. Vertex i of rod r is global centreline
/// vertex `first[r] + i`.
struct RodSet {
  std::vector<Eigen::VectorXd> rest;   ///< per rod: rest q (4V-1), twists 0
  std::vector<int> first;              ///< #rods+1 vertex offsets
  std::vector<int> family;             ///< per rod: index into SceneSpec::rods
  std::vector<RodRoot> root_held;      ///< per rod
  std::vector<int> motion;             ///< per rod: index into `motions`, -1 when the root is static or free
  std::vector<Motion> motions;
  int num_rods() const { return static_cast<int>(rest.size()); }
  int num_vertices() const { return first.empty() ? 0 : first.back(); }
  int rod_vertices(int r) const { return first[r + 1] - first[r]; }
};

struct SceneSpec;
/// Generate every family's rods. Throws ConfigError naming the key of a family that cannot
/// be generated (e.g. a sphere_hair cap too small for `count` roots).
RodSet build_rods(const SceneSpec& spec);

/// Number of held vertices at a rod's root.
inline int held_vertices(RodRoot r) { return r == RodRoot::free ? 0 : r == RodRoot::vertex ? 1 : 2; }

}  // namespace weft
