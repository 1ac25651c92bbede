#pragma once
/// \file cloth_scenes.hpp
/// Scenes of square sheets for the contact-strategy tests, built from scene JSON, and the
/// checks they share: the exact cloth-cloth intersection count (contact/verify, independent
/// of detection) and the layering of two height-field sheets.
#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

#include "contact/verify/intersection_check.hpp"
#include "framework/scene.hpp"

namespace weft::support {

/// One cloth of the scene JSON: a size x size square of n x n vertices centred at c with
/// initial velocity v (light, soft cloth: 0.1 kg/m^2, Y = 10 MPa, h = 0.5 mm).
inline Json sheet(double size, int n, const Eigen::Vector3d& c, const Eigen::Vector3d& v, bool irregular = false) {
  Json j = Json::parse(R"({"mesh": {"source": "rectangle"}, "material": {"density": 0.1, "youngs_modulus": 1e7, "thickness": 5e-4}})");
  j["mesh"]["size"] = {size, size};
  j["mesh"]["resolution"] = {n, n};
  j["mesh"]["center"] = {c.x(), c.y(), c.z()};
  j["mesh"]["tessellation"] = irregular ? "irregular" : "regular";
  j["initial_velocity"] = {v.x(), v.y(), v.z()};
  return j;
}

/// A scene of `cloths` under `combo`, dt = 1/240 s for 1 s, with `extra` JSON merged in.
inline Scene cloth_scene(const std::vector<Json>& cloths, const std::string& combo, const std::string& extra = "{}") {
  Json doc = Json::parse(R"({"time": {"dt": 0.004166666666666667, "duration": 1.0, "frame_rate": 24}})");
  doc["combo"] = combo;
  doc["cloths"] = cloths;
  doc.merge_patch(Json::parse(extra));
  return build_scene(doc, ".", "test");
}

/// Intersecting triangle pairs of the scene's mesh at positions x (exact test).
inline std::int64_t intersections(const Scene& scene, const Eigen::VectorXd& x) {
  return contact::verify::check_self_intersections(x, scene.mesh.faces()).num_pairs;
}

/// How many vertices of [b0, b1) lie below the surface of the faces with vertices in
/// [a0, a1) (a sheet that stays a height field over the xy plane), among those above its
/// triangles; `over` receives how many lie above a triangle at all.
inline int below(const Scene& scene, const Eigen::VectorXd& x, int a0, int a1, int b0, int b1, int* over = nullptr) {
  int count = 0, seen = 0;
  const Eigen::MatrixX3i& F = scene.mesh.faces();
  for (int i = b0; i < b1; ++i) {
    const Eigen::Vector3d p = x.segment<3>(3 * i);
    for (int f = 0; f < F.rows(); ++f) {
      if (F(f, 0) < a0 || F(f, 0) >= a1) continue;
      const Eigen::Vector3d a = x.segment<3>(3 * F(f, 0)), b = x.segment<3>(3 * F(f, 1)), c = x.segment<3>(3 * F(f, 2));
      const double det = (b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y());
      const double u = ((p.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (p.y() - a.y())) / det;
      const double w = ((b.x() - a.x()) * (p.y() - a.y()) - (p.x() - a.x()) * (b.y() - a.y())) / det;
      if (u < 0 || w < 0 || u + w > 1) continue;
      ++seen;
      if (p.z() < a.z() + u * (b.z() - a.z()) + w * (c.z() - a.z())) ++count;
      break;
    }
  }
  if (over) *over = seen;
  return count;
}

}  // namespace weft::support
