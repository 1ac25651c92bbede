#pragma once
/// \file scene.hpp
/// A scene: what is simulated (cloth meshes and their materials, pins and scripted
/// motion, obstacles, gravity, damping), for how long, and what is written. Loaded from
/// JSON (see docs/scene-reference.md, generated from the `visit` functions below) and
/// validated completely before any work starts. All values are SI inside weft.
#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "framework/obstacle_mesh.hpp"
#include "framework/params.hpp"
#include "framework/motion.hpp"
#include "framework/params_json.hpp"
#include "framework/rod_set.hpp"
#include "framework/state.hpp"
#include "framework/triangle_mesh.hpp"

namespace weft {

/// Constitutive model of a cloth's membrane (methods/shells §3).
enum class MaterialModel { isotropic, orthotropic };
inline constexpr std::array<std::string_view, 2> material_model_names = {"isotropic", "orthotropic"};
/// Where the warp direction of an orthotropic cloth comes from.
enum class WarpFrom { angle, uv };
inline constexpr std::array<std::string_view, 2> warp_from_names = {"angle", "uv"};
/// How the hinge bending stiffness k follows from the flexural rigidity D (see ShellMaterial::bending_k).
enum class BendingCalibration { plate, thesis };
inline constexpr std::array<std::string_view, 2> bending_calibration_names = {"plate", "thesis"};
/// Sum of a_e theta_e^2 over a triangle mesh bent into a cylinder of radius R, per A / R^2:
/// 3 on equilateral and on jittered meshes (docs/methods/shells.md §6.13), where the plate
/// energy (D / 2) integral of kappa^2 gives 1 / 2 per unit D. `plate` calibration divides D by
/// 2 x this, so that a hinge mesh bent along one direction stores the plate's energy.
inline constexpr double hinge_cylinder_factor = 3.0;

/// Thin-shell material of one cloth: isotropic (Y, nu), or orthotropic from the engineering
/// constants of a woven fabric (methods/shells §3.2).
///
/// **Warp/weft convention** (methods/shells §3.2 leaves the assignment of the structural direction
/// ahat to warp or weft to the project): the x axis of methods/shells §3.2, ahat_perp, is the **warp**; its y
/// axis, ahat, is the **weft** (in the rest plane, perpendicular to the warp). Hence
///   Y   = Y_x  = youngs_modulus_warp,      eta = Y_y / Y_x = youngs_modulus_weft / youngs_modulus_warp,
///   nu  = nu_xy = poisson_ratio: the strain ratio -eps_weft / eps_warp under uniaxial stress
///         along the warp (the weft->warp ratio is nu_yx = eta nu, by reciprocity nu_xy/Y_x = nu_yx/Y_y),
///   G   = 2 shear_modulus: the thesis' G is the Voigt entry for tensor shear strain, twice the
///         engineering shear modulus G12 (methods/shells §0 trap 4).
/// Positive definiteness at rest (methods/shells §2.3, §3.2): Y_warp > 0, Y_weft > 0, G12 > 0 and
/// eta nu^2 < 1; isotropic: Y > 0 and -1 < nu < 1 (the 2D plane-stress bound, not nu < 1/2).
struct ShellMaterial {
  MaterialModel model = MaterialModel::isotropic;
  double density = 0.15;           ///< [kg/m^2] mass per rest area
  double youngs_modulus = 2e7;     ///< [Pa] isotropic only
  std::optional<double> youngs_modulus_warp;  ///< [Pa] orthotropic: Y_x along the warp; required
  std::optional<double> youngs_modulus_weft;  ///< [Pa] orthotropic: Y_y along the weft; required
  std::optional<double> shear_modulus;        ///< [Pa] orthotropic: engineering G12 (G = 2 G12); required
  double poisson_ratio = 0.3;      ///< [-] isotropic: nu in (-1, 1); orthotropic: nu_xy (warp -> weft), eta nu^2 < 1
  double thickness = 3e-4;         ///< [m]
  std::optional<double> bending_rigidity;       ///< [N m] D (along the warp when orthotropic); default from Y and h
  std::optional<double> bending_rigidity_weft;  ///< [N m] D along the weft; default see rigidity_weft()
  BendingCalibration bending_calibration = BendingCalibration::plate;
  std::optional<double> bending_stiffness;  ///< [J] k itself; default see bending_k()
  WarpFrom warp_from = WarpFrom::angle;     ///< orthotropic: source of the warp direction
  double warp_angle = 0;           ///< [rad] orthotropic: warp angle in the sheet's (u, v) / texture plane

  bool orthotropic() const { return model == MaterialModel::orthotropic; }
  /// eta = Y_weft / Y_warp (1 for isotropic materials).
  double eta() const {
    return orthotropic() ? youngs_modulus_weft.value_or(0) / youngs_modulus_warp.value_or(0) : 1.0;
  }
  /// Flexural rigidity D [N m] for curvature along the warp (isotropic: in every direction):
  /// `bending_rigidity` if given, else the Kirchhoff plate's Y h^3 / (12 (1 - nu^2)),
  /// orthotropic Y_warp h^3 / (12 (1 - nu_xy nu_yx)) with nu_xy nu_yx = eta nu^2.
  double rigidity_warp() const {
    if (bending_rigidity) return *bending_rigidity;
    const double h3 = thickness * thickness * thickness;
    if (orthotropic()) return youngs_modulus_warp.value_or(0) * h3 / (12.0 * (1.0 - eta() * poisson_ratio * poisson_ratio));
    return youngs_modulus * h3 / (12.0 * (1.0 - poisson_ratio * poisson_ratio));
  }
  /// Flexural rigidity along the weft: `bending_rigidity_weft` if given, else `bending_rigidity`
  /// if given (bending as stiff both ways), else the plate's Y_weft h^3 / (12 (1 - eta nu^2)) for
  /// orthotropic and rigidity_warp() for isotropic materials.
  double rigidity_weft() const {
    if (bending_rigidity_weft) return *bending_rigidity_weft;
    if (bending_rigidity || !orthotropic()) return rigidity_warp();
    const double h3 = thickness * thickness * thickness;
    return youngs_modulus_weft.value_or(0) * h3 / (12.0 * (1.0 - eta() * poisson_ratio * poisson_ratio));
  }
  /// k = D / (this): `plate` 2 x hinge_cylinder_factor = 6, so that the hinge energy of a sheet
  /// bent along one direction is the plate's (D / 2) kappa^2 per area (docs/methods/shells.md
  /// §6.13); `thesis` 2, the thesis' k = D / 2 (its Eq. 5.11), which makes such bending three
  /// times too stiff.
  double bending_divisor() const { return bending_calibration == BendingCalibration::plate ? 2.0 * hinge_cylinder_factor : 2.0; }
  /// Hinge bending stiffness k [J] of a hinge whose bending direction (in-plane, across the
  /// hinge edge) makes cos_warp with the warp: `bending_stiffness` if given, else
  /// D(phi) / bending_divisor() with Huber's directional rigidity of an orthotropic plate,
  ///   D(phi) = (sqrt(D_warp) cos^2 phi + sqrt(D_weft) sin^2 phi)^2,
  /// which is D for isotropic materials and D_warp / D_weft along the warp / the weft.
  double bending_k(double cos_warp) const {
    if (bending_stiffness) return *bending_stiffness;
    const double c2 = cos_warp * cos_warp, r = std::sqrt(rigidity_warp()) * c2 + std::sqrt(rigidity_weft()) * (1.0 - c2);
    return r * r / bending_divisor();
  }
  /// k without a direction: `bending_stiffness` if given, else sqrt(D_warp D_weft) / bending_divisor().
  double bending_k() const {
    if (bending_stiffness) return *bending_stiffness;
    return std::sqrt(rigidity_warp() * rigidity_weft()) / bending_divisor();
  }
  /// Cross-field and stability checks (every violation at once), keys prefixed by `path`
  /// (e.g. "cloths.0.material"): the inequalities above, the orthotropic constants required
  /// for model = orthotropic and absent for model = isotropic, thickness > 0.
  Checker validate(const std::string& path) const;

  template <class V>
  void visit(V& v) {
    v.choice("model", model, material_model_names,
             "membrane material: isotropic (youngs_modulus, poisson_ratio) or orthotropic (warp/weft constants)");
    v.field("density", density, {Unit::area_density, Range::gt(0), "mass per rest area"});
    v.field("youngs_modulus", youngs_modulus,
            {Unit::pressure, Range::gt(0), "isotropic: Young's modulus Y of the sheet material (not read when orthotropic)"});
    v.field("youngs_modulus_warp", youngs_modulus_warp,
            {Unit::pressure, Range::gt(0), "orthotropic (required): Young's modulus along the warp (x axis of methods/shells §3.2, ahat_perp)"});
    v.field("youngs_modulus_weft", youngs_modulus_weft,
            {Unit::pressure, Range::gt(0), "orthotropic (required): Young's modulus along the weft (y axis of methods/shells §3.2, ahat)"});
    v.field("shear_modulus", shear_modulus,
            {Unit::pressure, Range::gt(0), "orthotropic (required): engineering in-plane shear modulus G12 (the thesis' G = 2 G12)"});
    // The isotropic bound is a field range; an orthotropic nu_xy is bounded only together with
    // eta (eta nu^2 < 1, checked by `validate`), so its range depends on `model`, read above.
    v.field("poisson_ratio", poisson_ratio,
            {Unit::none, orthotropic() ? Range::any() : Range::open(-1, 1),
             "isotropic: Poisson ratio, -1 < nu < 1 (2D plane stress); orthotropic: nu_xy = -strain_weft / strain_warp "
             "under uniaxial stress along the warp, (Y_weft / Y_warp) nu^2 < 1"});
    v.field("thickness", thickness, {Unit::length, Range::gt(0), "shell thickness h"});
    v.field("bending_rigidity", bending_rigidity,
            {Unit::energy, Range::gt(0),
             "flexural rigidity D per unit width (along the warp when orthotropic), e.g. a measured KES-F B; default the plate's "
             "Y h^3 / (12 (1 - nu^2)), orthotropic Y_warp h^3 / (12 (1 - eta nu^2))"});
    v.field("bending_rigidity_weft", bending_rigidity_weft,
            {Unit::energy, Range::gt(0),
             "flexural rigidity D along the weft; default bending_rigidity if given, else Y_weft h^3 / (12 (1 - eta nu^2)) "
             "(orthotropic) or the isotropic D"});
    v.choice("bending_calibration", bending_calibration, bending_calibration_names,
             "hinge stiffness k from D: plate (k = D / 6: a sheet bent along one direction stores the plate energy) or thesis "
             "(k = D / 2, the thesis' Eq. 5.11, three times too stiff in such bending)");
    v.field("bending_stiffness", bending_stiffness,
            {Unit::energy, Range::ge(0), "hinge bending stiffness k itself (overrides bending_rigidity and bending_calibration)"});
    v.choice("warp_from", warp_from, warp_from_names,
             "orthotropic: warp direction from `warp_angle` in the generated sheet's (u, v) plane (angle), or per face from the "
             "OBJ texture coordinates: the rest-triangle image of the texture direction at `warp_angle` from the u axis (uv)");
    v.field("warp_angle", warp_angle,
            {Unit::angle, Range::any(), "orthotropic: warp angle from the sheet's first axis (angle) or from the texture u axis (uv)"});
  }
};

/// One keyframe of an animated rest state.
struct RestKeyframe {
  double time = 0;   ///< [s]
  double scale = 1;  ///< [-] rest-length scale factor s
  template <class V>
  void visit(V& v) {
    v.field("time", time, {Unit::time, Range::ge(0), "keyframe time", true});
    v.field("scale", scale, {Unit::none, Range::gt(0), "rest-length scale factor s at that time", true});
  }
};

/// Animated rest state of one cloth (methods/shells §5): every selected edge has the rest length
///   lbar_e(t) = lbar_e (1 - w + w s(t)),
/// with s(t) piecewise linear through the keyframes (strictly increasing times) and constant
/// before the first and after the last. Edges are selected when both end points' rest
/// positions lie in [box_min, box_max], or all edges of the cloth without a box. Only the
/// membrane follows it: masses and bending rest data (rest angles, hinge weights) stay those
/// of the mesh. With a box, triangles on its boundary have some edges scaled and others not;
/// the scene is rejected at load if any triangle would violate the triangle inequalities (or
/// become degenerate) at an extreme keyframe scale. The feasible factors of a triangle form an
/// interval, so checking the extremes covers every time.
struct RestStateSpec {
  std::vector<RestKeyframe> keyframes;  ///< empty: the rest state is static
  double weight = 1.0;                  ///< [-] w, blend between the mesh (0) and the script (1)
  Eigen::Vector3d box_min = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d box_max = Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity());

  bool active() const { return !keyframes.empty(); }
  bool has_box() const { return (box_min.array() <= box_max.array()).all(); }
  /// s(t), piecewise linear; 1 without keyframes.
  double scale(double t) const;
  /// The rest-length factor 1 - w + w s(t) of selected edges.
  double factor(double t) const { return 1.0 - weight + weight * scale(t); }
  template <class V>
  void visit(V& v) {
    v.list("keyframes", keyframes, "(time, scale) keyframes of the rest-length scale s(t), strictly increasing times", 1);
    v.field("weight", weight, {Unit::none, Range::closed(0, 1), "blend weight w: lbar(t) = lbar (1 - w + w s(t))"});
    v.field("box_min", box_min,
            {Unit::length, Range::any(), "select edges whose end points' rest positions are in [box_min, box_max] (default: all)"});
    v.field("box_max", box_max, {Unit::length, Range::any(), "upper corner of the selection box"});
  }
};


/// How a cloth mesh is made.
enum class MeshSource { rectangle, l_shape, file };
inline constexpr std::array<std::string_view, 3> mesh_source_names = {"rectangle", "l_shape", "file"};
enum class Tessellation { regular, irregular };
inline constexpr std::array<std::string_view, 2> tessellation_names = {"regular", "irregular"};
/// The plane a generated sheet lies in (the first two axes span it).
enum class SheetPlane { xy, xz, yz };
inline constexpr std::array<std::string_view, 3> sheet_plane_names = {"xy", "xz", "yz"};

struct MeshSpec {
  MeshSource source = MeshSource::rectangle;
  // generators
  Eigen::Vector2d size{1.0, 1.0};          ///< [m] extent along the plane's two axes
  std::array<int, 2> resolution{21, 21};   ///< vertices along each axis
  Tessellation tessellation = Tessellation::regular;
  int seed = 1;                            ///< irregular tessellation
  SheetPlane plane = SheetPlane::xy;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  ///< [m] centre of the generated sheet
  // file
  std::string file;                        ///< OBJ path, relative to the scene file
  double scale = 1.0;                      ///< applied to file vertices (e.g. 0.01 for cm)
  Eigen::Vector3d translate = Eigen::Vector3d::Zero();  ///< [m] applied after scaling
  std::string initial_file;                ///< optional OBJ with the initial positions (same mesh)

  template <class V>
  void visit(V& v) {
    v.choice("source", source, mesh_source_names, "generator or OBJ file");
    v.field("size", size, {Unit::length, Range::gt(0), "rectangle / L-shape extent (the L removes one quadrant)"});
    v.field("resolution", resolution, {Unit::none, Range::closed(2, 5000), "vertices per side"});
    v.choice("tessellation", tessellation, tessellation_names, "regular grid, or jittered vertices with random diagonals");
    v.field("seed", seed, {Unit::none, Range::ge(0), "random seed of the irregular tessellation"});
    v.choice("plane", plane, sheet_plane_names, "plane of a generated sheet");
    v.field("center", center, {Unit::length, Range::any(), "centre of a generated sheet"});
    v.field("file", file, {Unit::none, Range::any(), "OBJ file (source = file), relative to the scene file"});
    v.field("scale", scale, {Unit::none, Range::gt(0), "scale applied to OBJ vertices"});
    v.field("translate", translate, {Unit::length, Range::any(), "translation applied to OBJ vertices after scaling"});
    v.field("initial_file", initial_file,
            {Unit::none, Range::any(),
             "OBJ with the initial positions (same vertices and faces; scale and translate apply); the mesh gives the rest state"});
  }
};

/// A set of vertices that do not move freely: selected by id and/or by a box around the
/// rest positions. Static unless a motion is given.
struct PinSpec {
  std::vector<int> vertices;                 ///< vertex ids within the cloth
  Eigen::Vector3d box_min = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d box_max = Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity());
  Motion motion;
  bool has_box() const { return (box_min.array() <= box_max.array()).all(); }
  template <class V>
  void visit(V& v) {
    v.field("vertices", vertices, {Unit::none, Range::ge(0), "vertex ids (0-based, within this cloth)"});
    v.field("box_min", box_min, {Unit::length, Range::any(), "select rest positions inside [box_min, box_max]"});
    v.field("box_max", box_max, {Unit::length, Range::any(), "upper corner of the selection box"});
    v.section("motion", motion);
  }
};

struct ClothSpec {
  std::string name = "cloth";
  MeshSpec mesh;
  ShellMaterial material;
  std::vector<PinSpec> pins;
  Eigen::Vector3d initial_velocity = Eigen::Vector3d::Zero();  ///< [m/s]
  RestStateSpec rest_state;        ///< animated rest state (methods/shells §5); static when it has no keyframes
  template <class V>
  void visit(V& v) {
    v.field("name", name, {Unit::none, Range::any(), "name used in output files"});
    v.section("mesh", mesh);
    v.section("material", material);
    v.list("pins", pins, "pinned or scripted vertex sets");
    v.field("initial_velocity", initial_velocity, {Unit::velocity, Range::any(), "initial velocity of every vertex"});
    v.section("rest_state", rest_state);
  }
};

enum class ObstacleShape { sphere, box, plane, mesh };
inline constexpr std::array<std::string_view, 4> obstacle_shape_names = {"sphere", "box", "plane", "mesh"};

/// A scripted rigid obstacle: an analytic sphere, box or plane, or a triangle mesh read
/// from an OBJ file. A mesh's body coordinates are the OBJ's, scaled by `scale` about the
/// OBJ origin; `center` places that origin, and `motion` moves the body rigidly. The inside
/// of a mesh is well defined when it is closed and its faces are counter-clockwise seen from
/// outside; an open mesh has an inside only near its surface (framework/obstacle_mesh.hpp).
struct ObstacleSpec {
  ObstacleShape shape = ObstacleShape::sphere;
  std::string name = "obstacle";
  Eigen::Vector3d center = Eigen::Vector3d::Zero();       ///< [m] sphere/box centre, a point on a plane, a mesh's OBJ origin
  double radius = 0.5;                                    ///< [m] sphere
  Eigen::Vector3d half_extents{0.5, 0.5, 0.5};            ///< [m] box
  Eigen::Vector3d normal{0, 0, 1};                        ///< plane normal (normalised on load)
  std::string file;                                       ///< mesh: OBJ path, relative to the scene file
  double scale = 1.0;                                     ///< mesh: uniform scale of the OBJ vertices, > 0
  double friction = 0.0;                                  ///< Coulomb coefficient
  Motion motion;
  /// Mesh: the surface in body coordinates, loaded by `build_scene` (scenes built in code set
  /// it with `load_obstacle_mesh` or `make_obstacle_mesh`); shared by copies of the spec.
  std::shared_ptr<const ObstacleMesh> mesh;
  template <class V>
  void visit(V& v) {
    v.choice("shape", shape, obstacle_shape_names, "obstacle shape: sphere, box, plane, or a triangle mesh from an OBJ file", true);
    v.field("name", name, {Unit::none, Range::any(), "name used in output files"});
    v.field("center", center,
            {Unit::length, Range::any(), "sphere/box centre, a point on the plane, or where a mesh's OBJ origin is placed"});
    v.field("radius", radius, {Unit::length, Range::gt(0), "sphere radius"});
    v.field("half_extents", half_extents, {Unit::length, Range::gt(0), "box half extents"});
    v.field("normal", normal, {Unit::none, Range::any(), "plane normal (nonzero; normalised)"});
    v.field("file", file,
            {Unit::none, Range::any(),
             "mesh (required): OBJ file of the surface, relative to the scene file; closed with faces counter-clockwise seen "
             "from outside for a well-defined inside (an open mesh has an inside only near its surface); no zero-area faces, "
             "at most two faces per edge"});
    v.field("scale", scale, {Unit::none, Range::gt(0), "mesh: uniform scale of the OBJ vertices about the OBJ origin"});
    v.field("friction", friction, {Unit::none, Range::ge(0), "Coulomb friction coefficient"});
    v.section("motion", motion);
  }
};

struct TimeSpec {
  double dt = 1.0 / 240.0;       ///< [s]
  double duration = 2.0;         ///< [s]
  double frame_rate = 24.0;      ///< [1/s] frames written per simulated second
  int max_subdivisions = 0;      ///< cloth: a failed step is retried as 2 half steps, recursively, this deep (0: it fails)
  int steps_per_frame() const;
  /// Steps of the run: duration / dt, a whole number (validated).
  long long num_steps() const;
  /// Frames after the initial one: the last frame ends at t = duration, so it is shorter
  /// than 1 / frame_rate when the duration is not a whole number of frames.
  int num_frames() const;
  /// The time of frame k.
  double frame_time(int k) const { return static_cast<double>(std::min<long long>(static_cast<long long>(k) * steps_per_frame(), num_steps())) * dt; }
  static constexpr long long max_steps_per_frame = 10'000'000, max_frames = 10'000'000, max_steps = 1'000'000'000'000;
  template <class V>
  void visit(V& v) {
    v.field("dt", dt, {Unit::time, Range::open_closed(0, 1), "time step; must divide the frame interval"});
    v.field("duration", duration,
            {Unit::time, Range::gt(0),
             "simulated time: a whole number of steps; when it is not a whole number of frames the last frame is shorter and "
             "holds the state at t = duration"});
    v.field("frame_rate", frame_rate, {Unit::frequency, Range::open_closed(0, 10000), "frames per simulated second"});
    v.field("max_subdivisions", max_subdivisions,
            {Unit::none, Range::closed(0, 10),
             "cloth: a step that fails (Newton or the contact response does not converge, a non-finite state) is retried "
             "from its start as two steps of dt/2, recursively down to dt/2^max_subdivisions; the step report counts the "
             "substeps and keeps the first failure. 0: the step fails (rods: must be 0, a stability study counts failures)"});
  }
};

struct DampingSpec {
  double mass = 0.0;  ///< [1/s] drag -c M v (air damping), treated implicitly
  template <class V>
  void visit(V& v) {
    v.field("mass", mass, {Unit::frequency, Range::ge(0), "mass-proportional damping c (force -c M v)"});
  }
};

struct OutputSpec {
  bool obj = true;      ///< one OBJ per frame
  bool vtp = true;      ///< one VTK PolyData per frame plus a .pvd series
  bool stats = true;    ///< per-step statistics as JSON lines
  int every = 1;        ///< write every n-th frame
  template <class V>
  void visit(V& v) {
    v.field("obj", obj, {Unit::none, Range::any(), "write frames as OBJ"});
    v.field("vtp", vtp, {Unit::none, Range::any(), "write frames as VTK .vtp with a .pvd series"});
    v.field("stats", stats, {Unit::none, Range::any(), "write per-step statistics (stats.jsonl)"});
    v.field("every", every, {Unit::none, Range::ge(1), "write every n-th frame"});
  }
};

/// The scene file's own keys (the solver sections are read by the chosen combination).
struct SceneSpec {
  std::string combo = "cloth_ip_direct";
  std::string description;
  std::vector<ClothSpec> cloths;
  std::vector<RodSpec> rods;
  std::vector<ObstacleSpec> obstacles;
  Eigen::Vector3d gravity{0, 0, -9.81};
  TimeSpec time;
  DampingSpec damping;
  OutputSpec output;
  template <class V>
  void visit(V& v) {
    v.field("combo", combo, {Unit::none, Range::any(), "pre-built combination of policies (`weft list`)"});
    v.field("description", description, {Unit::none, Range::any(), "free text"});
    v.list("cloths", cloths, "cloth sheets (a scene has at least one cloth or one rod family)");
    v.list("rods", rods, "families of elastic rods (hair)");
    v.list("obstacles", obstacles, "scripted rigid obstacles: analytic shapes or triangle meshes");
    v.field("gravity", gravity, {Unit::acceleration, Range::any(), "gravitational acceleration"});
    v.section("time", time);
    v.section("damping", damping);
    v.section("output", output);
  }
};

/// A loaded, validated scene: the spec plus everything derived from it.
/// The base names of a scene's output files, as `weft run` writes them: each cloth's (its name, with
/// its index appended when there are several), "rods", and each obstacle's (name + index).
/// Frame k of a part is <base>_<kkkk>.obj / .vtp.
std::vector<std::string> cloth_output_names(const SceneSpec& s);
std::string obstacle_output_name(const SceneSpec& s, size_t obstacle);

/// A name that is safe as a file name on every platform weft writes to: 1-64 characters of
/// A-Z a-z 0-9 _ - . starting with a letter or digit (no path separator, no "..", nothing XML
/// must escape).
bool is_safe_name(std::string_view name);

/// What a scene will need before its meshes are built: the vertices of its generated
/// sheets and rod families (OBJ meshes are bounded by their files), and the memory a run of
/// that many vertices takes, from peak resident sizes measured with the default solvers.
struct SizeEstimate {
  double cloth_vertices = 0, rod_vertices = 0;
  double bytes = 0;
  static const double cloth_bytes_per_vertex, rod_bytes_per_vertex, base_bytes;  // measured: framework/scene.cpp
  /// Simulated vertices index arrays of int (4 DoFs per rod vertex, 9 per Hessian block).
  static constexpr double max_vertices = 200'000'000;
};
SizeEstimate estimate_size(const SceneSpec& s);
/// The machine's physical memory [bytes] (0: unknown).
double physical_memory_bytes();

struct Scene {
  SceneSpec spec;
  std::string path;                 ///< scene file ("" if built in code)
  Json solver;                      ///< the "energy", "integrator", "contact", "linear" sections
  /// `linear.solver`: the linear solver of the Newton systems, chosen among the pre-built
  /// siblings of `spec.combo` (policies/registry.hpp, `resolve_combo`); "" keeps the combo's
  /// own. Taken out of `solver["linear"]`, whose keys are the chosen solver's parameters.
  std::string linear_solver;
  TriangleMesh mesh;                ///< all cloths, concatenated (empty without cloths)
  RodSet rods;                      ///< all rods, generated from `spec.rods`
  std::vector<int> cloth_vertex_offset;  ///< #cloths+1: vertex range of each cloth
  std::vector<int> cloth_face_offset;    ///< #cloths+1: face range of each cloth
  std::vector<int> face_cloth;      ///< #F: cloth index of each face (material = cloths[c].material)
  /// #F: unit warp direction (x axis of methods/shells §3.2, ahat_perp) in the rest plane of each face of an
  /// orthotropic cloth, zero for isotropic cloths. May be empty when no cloth is orthotropic
  /// (scenes built in code fill it themselves).
  std::vector<Eigen::Vector3d> face_warp;
  std::vector<Dof> dof;             ///< #V
  /// #V by 3 initial positions; equal to the rest positions unless a cloth gives
  /// `mesh.initial_file`. Pins hold, and scripted motions move, these positions.
  Eigen::MatrixX3d start;
  std::vector<int> vertex_motion;   ///< #V: index into `motions` for scripted vertices, else -1
  std::vector<Motion> motions;

  const ShellMaterial& face_material(int f) const { return spec.cloths[face_cloth[f]].material; }
  /// True if some cloth has an animated rest state.
  bool has_animated_rest() const;
  /// Lumped masses: each triangle gives density * area / 3 to each of its vertices [kg].
  Eigen::VectorXd lumped_masses() const;
  /// Initial state (rest positions, initial velocities, masses, dofs).
  State initial_state() const;
  /// Prescribed positions of non-free vertices at time t (free entries: current x).
  void constrained_positions(double t, const State& s, Eigen::VectorXd& target) const;
};

/// Area of a triangle given its squared edge lengths (Heron's formula in Kahan's stable
/// form), or -1 when the lengths violate the triangle inequalities (or are not positive).
double triangle_area(const Eigen::Vector3d& length2);
/// A triangle that is not degenerate up to rounding: 2 area > 1e-12 max_i l_i^2 (the same
/// relative threshold as the zero-area check of rest faces).
bool proper_triangle(const Eigen::Vector3d& length2);

/// Animated rest state, edge selection: #E flags, 1 when edge e's rest length follows its
/// cloth's `rest_state` (both end points in the box, or every edge of the cloth without one).
std::vector<unsigned char> rest_state_edges(const Scene& scene);
/// Animated rest state, mesh-level checks: each box selects at least one edge, and every face
/// of an animated cloth stays a proper triangle (`proper_triangle`) at both extreme factors
/// 1 - w + w s over the keyframes. Keys are named "cloths.N.rest_state".
Checker check_rest_states(const Scene& scene);

/// Build a scene from a parsed JSON document. `base_dir` resolves relative mesh paths.
/// Throws ConfigError listing every problem, each prefixed with `origin` (the file).
Scene build_scene(const Json& doc, const std::string& base_dir, const std::string& origin);

/// Parse a scene file (comments allowed), apply `key=value` overrides (dotted keys that
/// mirror the JSON tree), and build it. Throws ConfigError.
Scene load_scene(const std::string& path, const std::vector<std::string>& overrides = {});

/// Apply one `a.b.c=value` override to a JSON document. The value is parsed as JSON when
/// possible (numbers, true/false, arrays), else taken as a string. Throws ConfigError for
/// a malformed override; unknown keys are caught by the strict reader afterwards.
void apply_override(Json& doc, const std::string& assignment);

}  // namespace weft
