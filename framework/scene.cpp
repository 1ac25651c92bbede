#include "framework/scene.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <functional>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include <unistd.h>

#include "framework/files.hpp"
#include "framework/mesh_generators.hpp"
#include "framework/obj_io.hpp"

namespace weft {

Checker ShellMaterial::validate(const std::string& path) const {
  Checker c(path);
  c.require(density > 0, "density", density, "> 0").require(thickness > 0, "thickness", thickness, "> 0");
  // The stiffnesses the energies use must be finite: k grows with h^3.
  if (thickness > 0 && (orthotropic() ? youngs_modulus_warp && youngs_modulus_weft : youngs_modulus > 0)) {
    const double k = bending_k(), stretch = (orthotropic() ? *youngs_modulus_warp : youngs_modulus) * thickness;
    c.require(std::isfinite(k) && std::isfinite(stretch), "thickness", thickness,
              fmt::format("a thickness whose stiffnesses are finite (here the stretching stiffness Y h = {:g} N/m and the bending "
                          "stiffness k = {:g} J overflow)",
                          stretch, k));
  }
  if (!orthotropic()) {
    c.require(youngs_modulus > 0, "youngs_modulus", youngs_modulus, "> 0")
        .require(poisson_ratio > -1 && poisson_ratio < 1, "poisson_ratio", poisson_ratio, "in (-1, 1) (2D plane stress)");
    for (const auto& [key, value] : {std::pair{"youngs_modulus_warp", youngs_modulus_warp},
                                     std::pair{"youngs_modulus_weft", youngs_modulus_weft}, std::pair{"shear_modulus", shear_modulus},
                                     std::pair{"bending_rigidity_weft", bending_rigidity_weft}})
      if (value) c.fail(fmt::format("{}.{} is only read when model = orthotropic: set model = \"orthotropic\" or remove it", path, key));
    return c;
  }
  // Positive definiteness at rest (methods/shells §3.2): Y_x > 0, eta > 0, G > 0, eta nu^2 < 1.
  for (const auto& [key, value] : {std::pair{"youngs_modulus_warp", youngs_modulus_warp},
                                   std::pair{"youngs_modulus_weft", youngs_modulus_weft}, std::pair{"shear_modulus", shear_modulus}})
    if (!value) c.fail(fmt::format("{}.{} is required when model = orthotropic", path, key));
  if (youngs_modulus_warp) c.require(*youngs_modulus_warp > 0, "youngs_modulus_warp", *youngs_modulus_warp, "Y_warp > 0");
  if (youngs_modulus_weft) c.require(*youngs_modulus_weft > 0, "youngs_modulus_weft", *youngs_modulus_weft, "Y_weft > 0");
  if (shear_modulus) c.require(*shear_modulus > 0, "shear_modulus", *shear_modulus, "G12 > 0");
  c.require(std::isfinite(poisson_ratio), "poisson_ratio", poisson_ratio, "a finite number");
  if (youngs_modulus_warp && youngs_modulus_weft && *youngs_modulus_warp > 0 && *youngs_modulus_weft > 0) {
    const double e = eta(), enu2 = e * poisson_ratio * poisson_ratio;
    c.require(enu2 < 1, "poisson_ratio", poisson_ratio,
              fmt::format("eta nu^2 < 1 with eta = youngs_modulus_weft / youngs_modulus_warp = {} (here eta nu^2 = {}; "
                          "positive definiteness at rest needs |nu| < {})",
                          e, enu2, 1.0 / std::sqrt(e)));
  }
  return c;
}

double RestStateSpec::scale(double t) const {
  if (keyframes.empty()) return 1.0;
  if (t <= keyframes.front().time) return keyframes.front().scale;
  for (size_t k = 1; k < keyframes.size(); ++k)
    if (t <= keyframes[k].time) {
      const auto &a = keyframes[k - 1], &b = keyframes[k];
      const double u = (t - a.time) / (b.time - a.time);
      return (1.0 - u) * a.scale + u * b.scale;
    }
  return keyframes.back().scale;
}

bool Scene::has_animated_rest() const {
  for (const auto& c : spec.cloths)
    if (c.rest_state.active()) return true;
  return false;
}

double triangle_area(const Eigen::Vector3d& length2) {
  if (!(length2.minCoeff() > 0) || !length2.allFinite()) return -1;
  std::array<double, 3> l = {std::sqrt(length2[0]), std::sqrt(length2[1]), std::sqrt(length2[2])};
  std::sort(l.begin(), l.end(), std::greater<>());
  const double a = l[0], b = l[1], c = l[2];
  // Kahan, "Miscalculating area and angles of a needle-like triangle": exact up to a few
  // ulps for any shape; the factor c - (a - b) is negative iff a > b + c.
  const double p = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c));
  return p >= 0 ? 0.25 * std::sqrt(p) : -1.0;
}

bool proper_triangle(const Eigen::Vector3d& length2) {
  return 2.0 * triangle_area(length2) > 1e-12 * length2.maxCoeff();
}

std::vector<unsigned char> rest_state_edges(const Scene& scene) {
  const auto& edges = scene.mesh.edges();
  std::vector<unsigned char> sel(edges.size(), 0);
  for (size_t e = 0; e < edges.size(); ++e) {
    const int f = scene.mesh.edge_faces()[e][0];
    const RestStateSpec& r = scene.spec.cloths[scene.face_cloth[f]].rest_state;
    if (!r.active()) continue;
    if (!r.has_box()) {
      sel[e] = 1;
      continue;
    }
    bool inside = true;
    for (int k = 0; k < 2; ++k) {
      const Eigen::Vector3d p = scene.mesh.rest().row(edges[e][k]);
      inside = inside && (p.array() >= r.box_min.array()).all() && (p.array() <= r.box_max.array()).all();
    }
    sel[e] = inside;
  }
  return sel;
}

Checker check_rest_states(const Scene& scene) {
  Checker c;
  if (!scene.has_animated_rest()) return c;
  const std::vector<unsigned char> sel = rest_state_edges(scene);
  const auto& F = scene.mesh.faces();
  const auto& X = scene.mesh.rest();
  std::vector<int> selected(scene.spec.cloths.size(), 0), bad(scene.spec.cloths.size(), 0);
  for (size_t e = 0; e < sel.size(); ++e) selected[scene.face_cloth[scene.mesh.edge_faces()[e][0]]] += sel[e];
  for (size_t k = 0; k < scene.spec.cloths.size(); ++k) {
    const RestStateSpec& r = scene.spec.cloths[k].rest_state;
    if (r.active() && selected[k] == 0)
      c.fail(fmt::format("cloths.{}.rest_state: the box [{}] .. [{}] selects no edge of the cloth (both end points must be inside)", k,
                         fmt::join(r.box_min.data(), r.box_min.data() + 3, ", "), fmt::join(r.box_max.data(), r.box_max.data() + 3, ", ")));
  }
  for (int f = 0; f < scene.mesh.num_faces(); ++f) {
    const int k = scene.face_cloth[f];
    const RestStateSpec& r = scene.spec.cloths[k].rest_state;
    if (!r.active()) continue;
    Eigen::Vector3d l2;
    std::array<bool, 3> scaled{};
    for (int i = 0; i < 3; ++i) {
      // Edge i is opposite local vertex i.
      l2[i] = (X.row(F(f, (i + 2) % 3)) - X.row(F(f, (i + 1) % 3))).squaredNorm();
      scaled[i] = sel[scene.mesh.face_edges()[f][i]] != 0;
    }
    // The keyframes whose factor is smallest and largest; s(t) stays between them.
    size_t lo = 0, hi = 0;
    for (size_t q = 1; q < r.keyframes.size(); ++q) {
      if (r.keyframes[q].scale < r.keyframes[lo].scale) lo = q;
      if (r.keyframes[q].scale > r.keyframes[hi].scale) hi = q;
    }
    for (size_t q : {lo, hi}) {
      const double g = 1.0 - r.weight + r.weight * r.keyframes[q].scale;
      Eigen::Vector3d m2 = l2;
      for (int i = 0; i < 3; ++i)
        if (scaled[i]) m2[i] *= g * g;
      if (proper_triangle(m2)) continue;
      if (++bad[k] <= 10)
        c.fail(fmt::format("cloths.{}.rest_state: face {} (vertices {} {} {}) is not a proper triangle at keyframe {} (t = {} s, factor "
                           "1 - w + w s = {}): its rest lengths {:.6g} {:.6g} {:.6g} violate the triangle inequality l_i < l_j + l_k "
                           "(or collapse it); keep the box boundary away from it or reduce the change of scale",
                           k, f - scene.cloth_face_offset[k], F(f, 0), F(f, 1), F(f, 2), q, r.keyframes[q].time, g, std::sqrt(m2[0]),
                           std::sqrt(m2[1]), std::sqrt(m2[2])));
      break;
    }
  }
  for (size_t k = 0; k < bad.size(); ++k)
    if (bad[k] > 10) c.fail(fmt::format("cloths.{}.rest_state: ... and {} more faces", k, bad[k] - 10));
  return c;
}

int TimeSpec::steps_per_frame() const { return std::max(1, static_cast<int>(std::lround(1.0 / (frame_rate * dt)))); }
long long TimeSpec::num_steps() const { return std::max(1LL, std::llround(duration / dt)); }
int TimeSpec::num_frames() const {
  const long long spf = steps_per_frame();
  return static_cast<int>((num_steps() + spf - 1) / spf);
}

Eigen::VectorXd Scene::lumped_masses() const {
  Eigen::VectorXd m = Eigen::VectorXd::Zero(mesh.num_vertices());
  const auto& V = mesh.rest();
  const auto& F = mesh.faces();
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = V.row(F(f, 0)), b = V.row(F(f, 1)), c = V.row(F(f, 2));
    const double third = face_material(f).density * 0.5 * (b - a).cross(c - a).norm() / 3.0;
    for (int k = 0; k < 3; ++k) m[F(f, k)] += third;
  }
  return m;
}

State Scene::initial_state() const {
  State s;
  const int n = mesh.num_vertices();
  s.x.resize(3 * n);
  s.v.resize(3 * n);
  const Eigen::MatrixX3d& x0 = start.rows() == n ? start : mesh.rest();
  for (int i = 0; i < n; ++i) s.x.segment<3>(3 * i) = x0.row(i).transpose();
  for (size_t c = 0; c < spec.cloths.size(); ++c)
    for (int i = cloth_vertex_offset[c]; i < cloth_vertex_offset[c + 1]; ++i)
      s.v.segment<3>(3 * i) = spec.cloths[c].initial_velocity;
  s.mass = lumped_masses();
  s.dof = dof;
  for (int i = 0; i < n; ++i)
    if (dof[i] != Dof::free) s.v.segment<3>(3 * i).setZero();
  s.t = 0;
  return s;
}

void Scene::constrained_positions(double t, const State& s, Eigen::VectorXd& target) const {
  target = s.x;
  const Eigen::MatrixX3d& x0 = start.rows() == mesh.num_vertices() ? start : mesh.rest();
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    if (dof[i] == Dof::pinned) target.segment<3>(3 * i) = x0.row(i).transpose();
    else if (dof[i] == Dof::scripted) target.segment<3>(3 * i) = motions[vertex_motion[i]].apply(x0.row(i).transpose(), t);
  }
}

namespace {

/// Obstacle CCD reads a motion's single-phase fields over a step (contact/impulse.cpp,
/// contact/rods/rod_obstacle_detection.cpp); for a multi-phase motion they hold its envelope
/// (framework/motion.hpp), a sound bound only when the centre stays put and, for a sphere,
/// when the envelope's axis misses the sphere's centre unless every phase's axis hits it.
Checker check_obstacle_phases(const ObstacleSpec& o, const std::string& path) {
  Checker c(path);
  const Motion& m = o.motion;
  if (!m.multi_phase()) return c;
  for (size_t k = 0; k < m.phases.size(); ++k)
    c.require(m.phases[k].velocity.isZero(), fmt::format("phases.{}.velocity", k),
              fmt::format("[{}]", fmt::join(m.phases[k].velocity.data(), m.phases[k].velocity.data() + 3, ", ")),
              "zero for an obstacle: a multi-phase obstacle motion may only rotate about `center` (its CCD bounds the "
              "motion by one fixed centre)");
  if (o.shape != ObstacleShape::sphere) return c;
  const Eigen::Vector3d offset = o.center - m.center;
  Eigen::Vector3d fastest = Eigen::Vector3d::Zero();
  for (const MotionPhase& p : m.phases)
    if (p.angular_velocity.norm() > fastest.norm()) fastest = p.angular_velocity;
  if (offset.cross(fastest).norm() != 0) return c;
  for (size_t k = 0; k < m.phases.size(); ++k)
    c.require(offset.cross(m.phases[k].angular_velocity).norm() == 0, fmt::format("phases.{}.angular_velocity", k),
              fmt::format("[{}]", fmt::join(m.phases[k].angular_velocity.data(), m.phases[k].angular_velocity.data() + 3, ", ")),
              "an axis through the sphere's centre, as the fastest phase's (or move `center` off that axis)");
  return c;
}

}  // namespace

std::vector<std::string> cloth_output_names(const SceneSpec& s) {
  std::vector<std::string> names;
  for (size_t c = 0; c < s.cloths.size(); ++c)
    names.push_back(s.cloths.size() == 1 ? s.cloths[c].name : fmt::format("{}{}", s.cloths[c].name, c));
  return names;
}

std::string obstacle_output_name(const SceneSpec& s, size_t o) { return fmt::format("{}{}", s.obstacles[o].name, o); }

bool is_safe_name(std::string_view name) {
  if (name.empty() || name.size() > 64 || name.find("..") != std::string_view::npos) return false;
  const auto alnum = [](char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9'); };
  if (!alnum(name.front())) return false;
  for (char c : name)
    if (!alnum(c) && c != '_' && c != '-' && c != '.') return false;
  return true;
}

// Peak resident size of `weft run` per simulated vertex, measured with GNU time (2026-12-02):
// the 201 x 201 sheet (40,401 vertices) took 212 MB hanging under SA+PPCG and 224 MB dropped
// on the box under obstacle constraints (5.5 KB per vertex), 10k vertices 61 MB; the
// 1000-rod hair ball (30,000 vertices) 27 MB. With a margin: 6 KB and 1 KB per vertex.
const double SizeEstimate::cloth_bytes_per_vertex = 6000, SizeEstimate::rod_bytes_per_vertex = 1000, SizeEstimate::base_bytes = 32e6;

SizeEstimate estimate_size(const SceneSpec& s) {
  SizeEstimate e;
  for (const ClothSpec& cl : s.cloths)
    if (cl.mesh.source != MeshSource::file) e.cloth_vertices += static_cast<double>(cl.mesh.resolution[0]) * cl.mesh.resolution[1];
  for (const RodSpec& r : s.rods) e.rod_vertices += static_cast<double>(r.count) * r.vertices;
  e.bytes = SizeEstimate::base_bytes + e.cloth_vertices * SizeEstimate::cloth_bytes_per_vertex + e.rod_vertices * SizeEstimate::rod_bytes_per_vertex;
  return e;
}

double physical_memory_bytes() {
  const long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGE_SIZE);
  return pages > 0 && size > 0 ? static_cast<double>(pages) * static_cast<double>(size) : 0.0;
}

namespace {

/// A count of vertices for a message: "25,010,001".
std::string grouped(double n) {
  std::string d = fmt::format("{:.0f}", n), out;
  for (size_t i = 0; i < d.size(); ++i) {
    if (i > 0 && (d.size() - i) % 3 == 0) out += ',';
    out += d[i];
  }
  return out;
}

/// Refuse a scene too large for the counters or for this machine's memory, naming the keys
/// that set its size, before any mesh is built.
void check_size(const SceneSpec& s, Checker& c) {
  const SizeEstimate e = estimate_size(s);
  std::vector<std::string> keys;
  for (size_t k = 0; k < s.cloths.size(); ++k)
    if (s.cloths[k].mesh.source != MeshSource::file)
      keys.push_back(fmt::format("cloths.{}.mesh.resolution = [{}, {}]", k, s.cloths[k].mesh.resolution[0], s.cloths[k].mesh.resolution[1]));
  for (size_t k = 0; k < s.rods.size(); ++k) keys.push_back(fmt::format("rods.{}.count = {} x vertices = {}", k, s.rods[k].count, s.rods[k].vertices));
  const std::string from = fmt::format("{}", fmt::join(keys, ", "));
  const double n = e.cloth_vertices + e.rod_vertices;
  if (n > SizeEstimate::max_vertices) {
    c.fail(fmt::format("{}: {} vertices in all; valid: at most {} (the index arrays are 32-bit)", from, grouped(n), grouped(SizeEstimate::max_vertices)));
    return;
  }
  const double ram = physical_memory_bytes();
  if (ram > 0 && e.bytes > ram)
    c.fail(fmt::format("{}: {} vertices need about {:.1f} GB of memory (estimate: {:.0f} bytes per cloth vertex, {:.0f} per rod vertex) "
                       "and this machine has {:.1f} GB; valid: a scene of at most about {} cloth vertices here",
                       from, grouped(n), e.bytes / 1e9, SizeEstimate::cloth_bytes_per_vertex, SizeEstimate::rod_bytes_per_vertex,
                       ram / 1e9, grouped(std::floor((ram - SizeEstimate::base_bytes) / SizeEstimate::cloth_bytes_per_vertex))));
}

void validate_spec(const SceneSpec& s, std::vector<std::string>& errors) {
  Checker c;
  check_size(s, c);
  const auto check_name = [&](const std::string& key, const std::string& name) {
    c.require(is_safe_name(name), key, Json(name).dump(),
              "1-64 characters of A-Z a-z 0-9 _ - . starting with a letter or digit (it names output files)");
  };
  for (size_t k = 0; k < s.cloths.size(); ++k) check_name(fmt::format("cloths.{}.name", k), s.cloths[k].name);
  for (size_t k = 0; k < s.obstacles.size(); ++k) check_name(fmt::format("obstacles.{}.name", k), s.obstacles[k].name);
  {  // two parts must not write the same files
    std::vector<std::pair<std::string, std::string>> bases;  // (file base, key)
    const std::vector<std::string> cloth_bases = cloth_output_names(s);
    for (size_t k = 0; k < cloth_bases.size(); ++k) bases.emplace_back(cloth_bases[k], fmt::format("cloths.{}.name", k));
    if (!s.rods.empty()) bases.emplace_back("rods", "rods");
    for (size_t k = 0; k < s.obstacles.size(); ++k) bases.emplace_back(obstacle_output_name(s, k), fmt::format("obstacles.{}.name", k));
    for (size_t a = 0; a < bases.size(); ++a)
      for (size_t b = a + 1; b < bases.size(); ++b)
        if (bases[a].first == bases[b].first)
          c.fail(fmt::format("{} and {}: both would write the output files {}_*.obj/.vtp; give them different names", bases[a].second,
                             bases[b].second, bases[a].first));
  }
  const double frame = 1.0 / s.time.frame_rate;
  const double ratio = frame / s.time.dt;
  c.require(s.time.dt <= frame * (1 + 1e-12), "time.dt", s.time.dt,
            fmt::format("<= the frame interval 1/frame_rate = {} s", frame));
  if (s.time.dt <= frame)
    c.require(std::abs(ratio - std::round(ratio)) <= 1e-6 * ratio, "time.dt", s.time.dt,
              fmt::format("divides the frame interval {} s (e.g. {} or {} s)", frame, frame / std::floor(ratio),
                          frame / std::ceil(ratio)));
  if (s.cloths.empty() && s.rods.empty()) c.fail("cloths, rods: a scene needs at least one cloth or one rod family");
  if (!s.rods.empty())
    c.require(s.time.max_subdivisions == 0, "time.max_subdivisions", s.time.max_subdivisions,
              "0 for rod scenes (step subdivision is a cloth failsafe; the rod stability studies count failed steps)");
  c.require(s.time.duration >= s.time.dt, "time.duration", s.time.duration, fmt::format(">= time.dt = {} s", s.time.dt));
  // Counts: steps per frame, frames and steps must fit the counters (and a run be finite);
  // the duration must be a whole number of steps, so that the run ends where asked.
  if (ratio > TimeSpec::max_steps_per_frame)
    c.fail(fmt::format("time.dt = {} s: {:.3g} steps per frame of {} s; valid: at most {:.0e} steps per frame (time.dt >= {:.3g} s)",
                       s.time.dt, ratio, frame, static_cast<double>(TimeSpec::max_steps_per_frame),
                       frame / static_cast<double>(TimeSpec::max_steps_per_frame)));
  const double steps = s.time.duration / s.time.dt, frames = s.time.duration * s.time.frame_rate;
  if (frames > TimeSpec::max_frames)
    c.fail(fmt::format("time.duration = {} s: {:.3g} frames at frame_rate = {} /s; valid: at most {:.0e} frames (time.duration <= {:.6g} s)",
                       s.time.duration, frames, s.time.frame_rate, static_cast<double>(TimeSpec::max_frames),
                       static_cast<double>(TimeSpec::max_frames) / s.time.frame_rate));
  else if (steps > TimeSpec::max_steps)
    c.fail(fmt::format("time.duration = {} s: {:.3g} steps of time.dt = {} s; valid: at most {:.0e} steps (time.duration <= {:.6g} s)",
                       s.time.duration, steps, s.time.dt, static_cast<double>(TimeSpec::max_steps),
                       static_cast<double>(TimeSpec::max_steps) * s.time.dt));
  else if (steps >= 1 && std::abs(steps - std::round(steps)) > 1e-6 * steps)
    c.fail(fmt::format("time.duration = {} s is {:.6g} steps of time.dt = {} s; valid: a whole number of steps, e.g. {:.9g} or {:.9g} s",
                       s.time.duration, steps, s.time.dt, std::floor(steps) * s.time.dt, std::ceil(steps) * s.time.dt));
  for (size_t k = 0; k < s.cloths.size(); ++k) {
    const auto& cl = s.cloths[k];
    const std::string p = fmt::format("cloths.{}", k);
    if (cl.mesh.source == MeshSource::file)
      c.require(!cl.mesh.file.empty(), p + ".mesh.file", "\"\"", "a path to an OBJ file when mesh.source = file");
    if (cl.mesh.source == MeshSource::l_shape)
      c.require(cl.mesh.resolution[0] % 2 == 1 && cl.mesh.resolution[1] % 2 == 1, p + ".mesh.resolution",
                fmt::format("[{}, {}]", cl.mesh.resolution[0], cl.mesh.resolution[1]), "odd numbers for an l_shape");
    c.merge(cl.material.validate(p + ".material"));
    if (cl.material.orthotropic() && cl.material.warp_from == WarpFrom::angle && cl.mesh.source == MeshSource::file)
      c.fail(fmt::format("{}.material.warp_from = \"angle\": an OBJ mesh (mesh.source = file) has no sheet axes; use warp_from = "
                         "\"uv\" (the warp then follows the texture u axis, rotated by warp_angle)",
                         p));
    const RestStateSpec& rs = cl.rest_state;
    for (size_t q = 1; q < rs.keyframes.size(); ++q)
      c.require(rs.keyframes[q].time > rs.keyframes[q - 1].time, fmt::format("{}.rest_state.keyframes.{}.time", p, q),
                rs.keyframes[q].time, fmt::format("> keyframes.{}.time = {} (strictly increasing)", q - 1, rs.keyframes[q - 1].time));
    const bool box_given = rs.box_min.array().isFinite().any() || rs.box_max.array().isFinite().any();
    if (rs.active() && box_given && !rs.has_box())
      c.fail(fmt::format("{}.rest_state: give both box_min and box_max, with box_min <= box_max", p));
    for (size_t q = 0; q < cl.pins.size(); ++q) {
      const auto& pin = cl.pins[q];
      const std::string pp = fmt::format("{}.pins.{}", p, q);
      if (pin.vertices.empty() && !pin.has_box()) c.fail(pp + ": give `vertices` or a box (`box_min` <= `box_max`)");
      c.merge(pin.motion.validate(pp + ".motion"));
    }
  }
  for (size_t k = 0; k < s.obstacles.size(); ++k) {
    const auto& o = s.obstacles[k];
    const std::string p = fmt::format("obstacles.{}", k);
    if (o.shape == ObstacleShape::plane)
      c.require(o.normal.norm() > 1e-12, p + ".normal", fmt::format("[{}]", fmt::join(o.normal.data(), o.normal.data() + 3, ", ")),
                "a nonzero vector");
    if (o.shape == ObstacleShape::mesh) c.require(!o.file.empty(), p + ".file", "\"\"", "a path to an OBJ file when shape = mesh");
    c.require(o.center.cwiseAbs().maxCoeff() <= max_coordinate, p + ".center", fmt::format("[{}]", fmt::join(o.center.data(), o.center.data() + 3, ", ")),
              fmt::format("within {:.0e} m of the origin", max_coordinate));
    if (o.shape == ObstacleShape::sphere) c.require(o.radius <= max_coordinate, p + ".radius", o.radius, fmt::format("<= {:.0e} m", max_coordinate));
    if (o.shape == ObstacleShape::box)
      c.require(o.half_extents.cwiseAbs().maxCoeff() <= max_coordinate, p + ".half_extents",
                fmt::format("[{}]", fmt::join(o.half_extents.data(), o.half_extents.data() + 3, ", ")), fmt::format("<= {:.0e} m", max_coordinate));
    c.merge(o.motion.validate(p + ".motion"));
    c.merge(check_obstacle_phases(o, p + ".motion"));
  }
  for (size_t k = 0; k < s.rods.size(); ++k) {
    const RodSpec& r = s.rods[k];
    const std::string p = fmt::format("rods.{}", k);
    c.merge(r.motion.validate(p + ".motion"));
    // Lengths in meters, within the extent of a mesh; edges long enough for the rod model.
    const double edge = r.length / (r.vertices - 1);
    c.require(r.length <= max_coordinate, p + ".length", r.length, fmt::format("<= {:.0e} m", max_coordinate));
    c.require(!(r.length <= max_coordinate) || edge >= 1e-9, p + ".length", r.length,
              fmt::format("rest edges of at least 1 nm: length / (vertices - 1) = {:.3g} m here", edge));
    c.require(r.material.radius <= max_coordinate, p + ".material.radius", r.material.radius, fmt::format("<= {:.0e} m", max_coordinate));
    c.require(r.spacing * r.count <= max_coordinate, p + ".spacing", r.spacing,
              fmt::format("spacing x count <= {:.0e} m (here {:.3g} m)", max_coordinate, r.spacing * r.count));
    for (const auto& [key, v] : {std::pair{"root", r.root}, std::pair{"sphere_center", r.sphere_center}})
      c.require(v.cwiseAbs().maxCoeff() <= max_coordinate, p + "." + key, fmt::format("[{}]", fmt::join(v.data(), v.data() + 3, ", ")),
                fmt::format("within {:.0e} m of the origin", max_coordinate));
    c.require(r.sphere_radius <= max_coordinate, p + ".sphere_radius", r.sphere_radius, fmt::format("<= {:.0e} m", max_coordinate));
  }
  errors.insert(errors.end(), c.violations().begin(), c.violations().end());
}

MeshData make_mesh(const MeshSpec& m, const std::string& base_dir) {
  MeshData d;
  switch (m.source) {
    case MeshSource::rectangle:
      d = make_rectangle(m.size, m.resolution, m.tessellation, m.seed);
      place_sheet(d, m.plane, m.center);
      break;
    case MeshSource::l_shape:
      d = make_l_shape(m.size, m.resolution, m.tessellation, m.seed);
      place_sheet(d, m.plane, m.center);
      break;
    case MeshSource::file: {
      const std::filesystem::path p = std::filesystem::path(m.file).is_absolute() ? std::filesystem::path(m.file)
                                                                                   : std::filesystem::path(base_dir) / m.file;
      d = read_obj(p.lexically_normal().string());
      d.V *= m.scale;
      d.V.rowwise() += m.translate.transpose();
      break;
    }
  }
  return d;
}

}  // namespace

Scene build_scene(const Json& doc, const std::string& base_dir, const std::string& origin) {
  const std::string header = fmt::format("{}: invalid scene", origin);
  std::vector<std::string> errors;
  if (!doc.is_object()) throw ConfigError(header, {"the document must be a JSON object"});

  Scene scene;
  scene.path = origin;
  Json rest = doc;
  scene.solver = Json::object();
  for (const char* k : {"energy", "integrator", "contact", "linear"})
    if (rest.contains(k)) {
      scene.solver[k] = rest[k];
      rest.erase(k);
    }
  if (scene.solver.contains("linear") && scene.solver["linear"].is_object() && scene.solver["linear"].contains("solver")) {
    const Json& v = scene.solver["linear"]["solver"];
    if (v.is_string() && !v.get<std::string>().empty())
      scene.linear_solver = v.get<std::string>();
    else
      errors.push_back(fmt::format("linear.solver = {}: a solver name is expected (see `weft list`)", v.dump()));
    scene.solver["linear"].erase("solver");
    if (scene.solver["linear"].empty()) scene.solver.erase("linear");  // rods read no linear section
  }
  {
    JsonReader r(rest, "", errors);
    scene.spec.visit(r);
    r.finish();
  }
  if (!errors.empty()) throw ConfigError(header, errors);
  // Keys with a default that the chosen material model does not read (unknown keys are
  // errors; so are keys that would be silently ignored).
  for (size_t c = 0; c < scene.spec.cloths.size(); ++c) {
    const Json& cj = rest.at("cloths").at(c);
    if (!cj.contains("material")) continue;
    const Json& mj = cj.at("material");
    const bool ortho = scene.spec.cloths[c].material.orthotropic();
    for (const char* key : ortho ? std::vector<const char*>{"youngs_modulus"} : std::vector<const char*>{"warp_from", "warp_angle"})
      if (mj.contains(key))
        errors.push_back(ortho ? fmt::format("cloths.{}.material.{} is not read when model = orthotropic: give youngs_modulus_warp and "
                                             "youngs_modulus_weft",
                                             c, key)
                               : fmt::format("cloths.{}.material.{} is only read when model = orthotropic", c, key));
  }
  // Obstacle keys the shape does not read.
  for (size_t k = 0; k < scene.spec.obstacles.size(); ++k) {
    const Json& oj = rest.at("obstacles").at(k);
    const bool mesh = scene.spec.obstacles[k].shape == ObstacleShape::mesh;
    for (const char* key : mesh ? std::vector<const char*>{"radius", "half_extents", "normal"} : std::vector<const char*>{"file", "scale"})
      if (oj.contains(key))
        errors.push_back(mesh ? fmt::format("obstacles.{}.{} is not read when shape = mesh (the OBJ file gives the surface)", k, key)
                              : fmt::format("obstacles.{}.{} is only read when shape = mesh", k, key));
  }
  validate_spec(scene.spec, errors);
  if (!errors.empty()) throw ConfigError(header, errors);
  // Multi-phase motions: the single-phase fields carry the envelope (framework/motion.hpp).
  for (ClothSpec& cl : scene.spec.cloths)
    for (PinSpec& pin : cl.pins) pin.motion.set_envelope();
  for (ObstacleSpec& o : scene.spec.obstacles) o.motion.set_envelope();
  for (RodSpec& f : scene.spec.rods) f.motion.set_envelope();

  // Meshes, concatenated.
  std::vector<MeshData> parts;
  for (size_t c = 0; c < scene.spec.cloths.size(); ++c) {
    const MeshSpec& m = scene.spec.cloths[c].mesh;
    const std::string key = m.source == MeshSource::file ? fmt::format("cloths.{}.mesh.file = \"{}\"", c, m.file) : fmt::format("cloths.{}.mesh", c);
    try {
      parts.push_back(make_mesh(m, base_dir));
      const MeshData& d = parts.back();
      if (const std::string bad = check_extent(d.V); !bad.empty())
        errors.push_back(fmt::format("{}: {} (after mesh.scale and mesh.translate)", key, bad));
      // A vertex in no face has no mass: it cannot be simulated.
      std::vector<unsigned char> used(static_cast<size_t>(d.V.rows()), 0);
      for (Eigen::Index f = 0; f < d.F.rows(); ++f)
        for (int k = 0; k < 3; ++k)
          if (d.F(f, k) >= 0 && d.F(f, k) < d.V.rows()) used[static_cast<size_t>(d.F(f, k))] = 1;
      if (const auto n = std::count(used.begin(), used.end(), 0); n > 0)
        errors.push_back(fmt::format("{}: {} vertices belong to no face, the first is vertex {} (0-based; line 'v' number {} of the file); "
                                     "valid: every vertex in a triangle (remove unused vertices)",
                                     key, n, std::find(used.begin(), used.end(), 0) - used.begin(), std::find(used.begin(), used.end(), 0) - used.begin() + 1));
    } catch (const ConfigError& e) {
      errors.push_back(fmt::format("{}: {}", key, e.what()));
    }
  }
  // Mesh obstacles: read and checked once, shared by every copy of the spec.
  for (size_t k = 0; k < scene.spec.obstacles.size(); ++k) {
    ObstacleSpec& o = scene.spec.obstacles[k];
    if (o.shape != ObstacleShape::mesh) continue;
    const std::filesystem::path p = std::filesystem::path(o.file).is_absolute() ? std::filesystem::path(o.file)
                                                                                 : std::filesystem::path(base_dir) / o.file;
    try {
      o.mesh = load_obstacle_mesh(p.lexically_normal().string(), o.scale, fmt::format("obstacles.{}.file = \"{}\"", k, o.file));
    } catch (const ConfigError& e) {
      if (e.violations().empty()) errors.emplace_back(e.what());
      errors.insert(errors.end(), e.violations().begin(), e.violations().end());
    }
  }
  if (!errors.empty()) throw ConfigError(header, errors);
  Eigen::Index nv = 0, nf = 0;
  for (const auto& p : parts) nv += p.V.rows(), nf += p.F.rows();
  Eigen::MatrixX3d V(nv, 3);
  Eigen::MatrixX3i F(nf, 3);
  scene.cloth_vertex_offset = {0};
  scene.cloth_face_offset = {0};
  for (size_t c = 0; c < parts.size(); ++c) {
    const int v0 = scene.cloth_vertex_offset.back(), f0 = scene.cloth_face_offset.back();
    V.middleRows(v0, parts[c].V.rows()) = parts[c].V;
    F.middleRows(f0, parts[c].F.rows()) = parts[c].F.array() + v0;
    scene.cloth_vertex_offset.push_back(v0 + static_cast<int>(parts[c].V.rows()));
    scene.cloth_face_offset.push_back(f0 + static_cast<int>(parts[c].F.rows()));
    scene.face_cloth.insert(scene.face_cloth.end(), parts[c].F.rows(), static_cast<int>(c));
  }
  if (nv > 0) try {
      scene.mesh = TriangleMesh(V, F);
    } catch (const ConfigError& e) {
      // Name the cloth (and its file): the parts are disjoint, so each one's own mesh fails.
      for (size_t c = 0; c < parts.size(); ++c) try {
          TriangleMesh own(parts[c].V, parts[c].F);
        } catch (const ConfigError& part) {
          const MeshSpec& m = scene.spec.cloths[c].mesh;
          errors.push_back(fmt::format("cloths.{}.mesh{}: {} (indices 0-based, within the cloth)", c,
                                       m.source == MeshSource::file ? fmt::format(".file = \"{}\"", m.file) : std::string(), part.what()));
        }
      if (errors.empty()) errors.emplace_back(e.what());
      throw ConfigError(header, errors);
    }
  try {
    scene.rods = build_rods(scene.spec);
  } catch (const ConfigError& e) {
    throw ConfigError(header, e.violations().empty() ? std::vector<std::string>{e.what()} : e.violations());
  }
  // Initial positions: the rest positions, or a second OBJ of the same mesh.
  scene.start = V;
  for (size_t c = 0; c < parts.size(); ++c) {
    const MeshSpec& m = scene.spec.cloths[c].mesh;
    if (m.initial_file.empty()) continue;
    const auto path = std::filesystem::path(m.initial_file).is_absolute() ? std::filesystem::path(m.initial_file)
                                                                           : std::filesystem::path(base_dir) / m.initial_file;
    try {
      MeshData init = read_obj(path.lexically_normal().string());
      if (init.V.rows() != parts[c].V.rows() || init.F != parts[c].F) {
        errors.push_back(fmt::format("cloths.{}.mesh.initial_file = \"{}\" has {} vertices and {} faces: it must be the same "
                                     "mesh as the rest state ({} vertices, {} faces, same faces)",
                                     c, m.initial_file, init.V.rows(), init.F.rows(), parts[c].V.rows(), parts[c].F.rows()));
        continue;
      }
      init.V *= m.scale;
      init.V.rowwise() += m.translate.transpose();
      if (const std::string bad = check_extent(init.V); !bad.empty()) {
        errors.push_back(fmt::format("cloths.{}.mesh.initial_file = \"{}\": {} (after mesh.scale and mesh.translate)", c, m.initial_file, bad));
        continue;
      }
      scene.start.middleRows(scene.cloth_vertex_offset[c], init.V.rows()) = init.V;
    } catch (const ConfigError& e) {
      errors.push_back(fmt::format("cloths.{}.mesh.initial_file: {}", c, e.what()));
    }
  }
  // Warp directions of orthotropic cloths, per face (methods/shells §10.2: a 3D unit vector in the
  // rest plane). Generated sheets carry their (u, v) coordinates as texture coordinates, so
  // both sources go through `texture_directions`.
  scene.face_warp.assign(static_cast<size_t>(nf), Eigen::Vector3d::Zero());
  for (size_t c = 0; c < parts.size(); ++c) {
    const ShellMaterial& m = scene.spec.cloths[c].material;
    if (!m.orthotropic()) continue;
    const std::string key = fmt::format("cloths.{}.material.warp_from = \"{}\"", c, enum_name(m.warp_from, warp_from_names));
    try {
      const auto dirs = texture_directions(parts[c], m.warp_angle);
      std::copy(dirs.begin(), dirs.end(), scene.face_warp.begin() + scene.cloth_face_offset[c]);
    } catch (const ConfigError& e) {
      if (e.violations().empty()) errors.push_back(fmt::format("{}: {}", key, e.what()));
      for (const auto& v : e.violations()) errors.push_back(fmt::format("{}: {}", key, v));
    }
  }
  for (int f = 0; f < scene.mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = V.row(F(f, 0)), b = V.row(F(f, 1)), c = V.row(F(f, 2));
    if ((b - a).cross(c - a).norm() <= 1e-14 * std::max(1e-300, (b - a).squaredNorm() + (c - a).squaredNorm())) {
      errors.push_back(fmt::format("cloths.{}.mesh: face {} has zero rest area", scene.face_cloth[f],
                                   f - scene.cloth_face_offset[scene.face_cloth[f]]));
      if (errors.size() > 10) break;
    }
  }

  // Pins and scripted vertices.
  scene.dof.assign(nv, Dof::free);
  scene.vertex_motion.assign(nv, -1);
  for (size_t c = 0; c < scene.spec.cloths.size(); ++c) {
    const auto& cl = scene.spec.cloths[c];
    const int v0 = scene.cloth_vertex_offset[c], v1 = scene.cloth_vertex_offset[c + 1];
    for (size_t q = 0; q < cl.pins.size(); ++q) {
      const auto& pin = cl.pins[q];
      const std::string p = fmt::format("cloths.{}.pins.{}", c, q);
      std::vector<int> ids;
      for (size_t k = 0; k < pin.vertices.size(); ++k) {
        if (pin.vertices[k] >= v1 - v0)
          errors.push_back(fmt::format("{}.vertices.{} = {} is out of range: valid 0..{}", p, k, pin.vertices[k], v1 - v0 - 1));
        else
          ids.push_back(v0 + pin.vertices[k]);
      }
      if (pin.has_box()) {
        int found = 0;
        for (int i = v0; i < v1; ++i) {
          const Eigen::Vector3d r = V.row(i);
          if ((r.array() >= pin.box_min.array()).all() && (r.array() <= pin.box_max.array()).all()) ids.push_back(i), ++found;
        }
        if (found == 0) errors.push_back(fmt::format("{}: the box [{}] .. [{}] selects no vertex of the cloth", p,
                                                     fmt::join(pin.box_min.data(), pin.box_min.data() + 3, ", "),
                                                     fmt::join(pin.box_max.data(), pin.box_max.data() + 3, ", ")));
      }
      const bool scripted = !pin.motion.is_static();
      if (scripted) scene.motions.push_back(pin.motion);
      for (int i : ids) {
        scene.dof[i] = scripted ? Dof::scripted : Dof::pinned;
        scene.vertex_motion[i] = scripted ? static_cast<int>(scene.motions.size()) - 1 : -1;
      }
    }
  }
  {
    const Checker rc = check_rest_states(scene);
    errors.insert(errors.end(), rc.violations().begin(), rc.violations().end());
  }
  if (!errors.empty()) throw ConfigError(header, errors);
  for (auto& o : scene.spec.obstacles)
    if (o.shape == ObstacleShape::plane) o.normal.normalize();
  return scene;
}

void apply_override(Json& doc, const std::string& assignment) {
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw ConfigError(fmt::format("override '{}' is not of the form key=value (e.g. time.dt=0.002)", assignment));
  const std::string key = assignment.substr(0, eq), text = assignment.substr(eq + 1);
  Json value;
  try {
    value = Json::parse(text);
  } catch (const Json::parse_error&) {
    value = text;
  } catch (const Json::exception&) {  // out_of_range: a number beyond a double, e.g. 1e999
    throw ConfigError(fmt::format("override '{}': {} is not a finite number (valid: a double, |x| < 1.8e308)", assignment, text));
  }
  Json* node = &doc;
  std::stringstream ss(key);
  std::string part, walked;
  std::vector<std::string> parts;
  while (std::getline(ss, part, '.')) parts.push_back(part);
  for (size_t i = 0; i < parts.size(); ++i) {
    const std::string& p = parts[i];
    if (p.empty()) throw ConfigError(fmt::format("override '{}': empty key component", assignment));
    walked += (walked.empty() ? "" : ".") + p;
    const bool last = i + 1 == parts.size();
    if (node->is_array()) {
      char* end = nullptr;
      const long idx = std::strtol(p.c_str(), &end, 10);
      if (*end != '\0' || idx < 0 || idx >= static_cast<long>(node->size()))
        throw ConfigError(fmt::format("override '{}': {} is not an index of an array of {} entries", assignment, walked, node->size()));
      node = &(*node)[static_cast<size_t>(idx)];
    } else {
      if (node->is_null()) *node = Json::object();
      if (!node->is_object())
        throw ConfigError(fmt::format("override '{}': {} is a value, not a section", assignment, walked));
      node = &(*node)[p];
    }
    if (last) *node = value;
  }
}

Scene load_scene(const std::string& path, const std::vector<std::string>& overrides) {
  require_regular_file(path, "scene file", "a scene file (JSON)");
  std::ifstream in(path);
  if (!in) throw ConfigError(fmt::format("{}: scene file not readable", path));
  Json doc;
  // Keys given twice in one object: nlohmann keeps the last silently; a scene is refused.
  std::vector<std::set<std::string>> open_keys;
  std::vector<std::string> duplicates;
  const Json::parser_callback_t keys = [&](int, Json::parse_event_t event, Json& parsed) {
    if (event == Json::parse_event_t::object_start) open_keys.emplace_back();
    else if (event == Json::parse_event_t::object_end && !open_keys.empty()) open_keys.pop_back();
    else if (event == Json::parse_event_t::key && !open_keys.empty() && !open_keys.back().insert(parsed.get<std::string>()).second &&
             duplicates.size() < 10)
      duplicates.push_back(fmt::format("key \"{}\" is given twice in the same object (the scene must say what it means once)", parsed.get<std::string>()));
    return true;
  };
  try {
    doc = Json::parse(in, keys, true, /*ignore_comments=*/true);
  } catch (const Json::parse_error& e) {
    throw ConfigError(fmt::format("{}: malformed JSON: {}", path, e.what()));
  } catch (const Json::exception& e) {  // out_of_range: a number beyond a double
    throw ConfigError(fmt::format("{}: a number is not finite (valid: a double, |x| < 1.8e308): {}", path, e.what()));
  }
  if (!duplicates.empty()) throw ConfigError(fmt::format("{}: invalid scene", path), duplicates);
  if (!doc.is_object()) throw ConfigError(fmt::format("{}: invalid scene", path), {"the document must be a JSON object"});
  std::vector<std::string> errors;
  for (const auto& o : overrides) {
    try {
      apply_override(doc, o);
    } catch (const ConfigError& e) {
      errors.emplace_back(e.what());
    }
  }
  if (!errors.empty()) throw ConfigError(fmt::format("{}: invalid overrides", path), errors);
  const auto dir = std::filesystem::path(path).parent_path().string();
  // A key set on the command line is named as such: the scene file does not hold it.
  const std::string origin = overrides.empty() ? path : fmt::format("{} with the overrides {}", path, fmt::join(overrides, " "));
  Scene scene = build_scene(doc, dir.empty() ? "." : dir, origin);
  scene.path = path;
  return scene;
}

}  // namespace weft
