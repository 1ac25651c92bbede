#include "apps/validate.hpp"

#include <Eigen/Cholesky>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numbers>

#include "apps/bench_common.hpp"
#include "apps/plots.hpp"
#include "apps/references.hpp"
#include "framework/build_info.hpp"
#include "framework/error.hpp"
#include "policies/registry.hpp"

namespace weft::app {

namespace {

namespace fs = std::filesystem;

/// What a run leaves for the measurement: the scene, every step's time and centre of mass,
/// the final positions.
struct Record {
  std::vector<double> t;
  std::vector<Eigen::Vector3d> com;
  Eigen::VectorXd x0, x;  ///< positions at the start and at the end
};

struct Problem {
  std::string name, description, scene;
  std::vector<std::string> overrides;
  bool quick = false;
  std::string quantity, unit, source;
  double tolerance = 0;
  bool absolute = false;
  std::function<double(const Scene&)> reference;
  std::function<double(const Scene&, const Record&)> measure;
};

/// Rest x range of cloth 0 and its grid spacing along x (generated rectangles).
struct Strip {
  double x0, x1, dx;
};
Strip strip(const Scene& s) {
  const auto& X = s.mesh.rest();
  const double x0 = X.col(0).minCoeff(), x1 = X.col(0).maxCoeff();
  return {x0, x1, (x1 - x0) / (s.spec.cloths[0].mesh.resolution[0] - 1)};
}

/// Cantilever: the scene clamps the vertices of the first 1.5 grid spacings (the first two
/// columns), so the free length runs from the second column to the tip.
double cantilever_length(const Scene& s) {
  const Strip g = strip(s);
  return g.x1 - g.x0 - g.dx;
}
double cantilever_reference(const Scene& s) {
  const ShellMaterial& m = s.spec.cloths[0].material;
  const double L = cantilever_length(s), w = m.density * s.spec.gravity.norm();
  return reference::cantilever_elastica(w * L * L * L / m.rigidity_warp()).drop * L;
}
double cantilever_drop(const Scene& s, const Record& r) {
  const auto& X = s.mesh.rest();
  const Strip g = strip(s);
  double drop = 0;
  int n = 0;
  for (Eigen::Index i = 0; i < X.rows(); ++i)
    if (X(i, 0) > g.x1 - 1e-9 * (g.x1 - g.x0)) drop += X(i, 2) - r.x[3 * i + 2], ++n;
  return n ? drop / n : 0.0;
}

/// Rod cantilever: the root edge is clamped. The discrete curvature at vertex 1 stands for the
/// arc from the middle of the clamped edge to the middle of the next one (the rod's Voronoi
/// length: Bergou et al. 2008, "Discrete Elastic Rods", integrated curvature), so the rod bends from the middle of the clamped edge: the
/// free length is L - l_e / 2 (with L - l_e the drop is 4.5 % above the elastica at 41 vertices
/// and converges as 1 / n; with L - l_e / 2 it is within 0.2 % at 21 vertices).
double rod_cantilever_length(const Scene& s) {
  const RodSpec& r = s.spec.rods.at(0);
  return r.length * (1.0 - 0.5 / (r.vertices - 1));
}
double rod_cantilever_reference(const Scene& s) {
  const RodMaterialSpec& m = s.spec.rods.at(0).material;
  const double area = std::numbers::pi * m.radius * m.radius, bending = m.youngs_modulus * area * m.radius * m.radius / 4.0;
  const double L = rod_cantilever_length(s), w = m.density * area * s.spec.gravity.norm();
  return reference::cantilever_elastica(w * L * L * L / bending).drop * L;
}
double rod_tip_drop(const Scene& s, const Record& r) {
  const Eigen::Index tip = 3 * (s.spec.rods.at(0).vertices - 1) + 2;
  return r.x0[tip] - r.x[tip];
}
/// Quarter ring (a flat helix of the scene's curl radius) clamped by its root edge, loaded by
/// its weight along its axis: the free arc starts at the middle of the clamped edge, as for
/// the straight rod.
double rod_ring_reference(const Scene& s) {
  const RodSpec& r = s.spec.rods.at(0);
  const RodMaterialSpec& m = r.material;
  const double area = std::numbers::pi * m.radius * m.radius, r2 = m.radius * m.radius;
  const double phi = r.length * (1.0 - 0.5 / (r.vertices - 1)) / r.curl_radius;
  return reference::arc_cantilever_deflection(phi, r.curl_radius, m.density * area * s.spec.gravity.norm(),
                                              m.youngs_modulus * area * r2 / 4.0, m.shear_modulus * area * r2 / 2.0);
}

/// Largest distance of a vertex from where it started.
double largest_displacement(const Scene&, const Record& r) {
  double d = 0;
  for (Eigen::Index i = 0; i + 2 < r.x.size(); i += 3) d = std::max(d, (r.x.segment<3>(i) - r.x0.segment<3>(i)).norm());
  return d;
}

/// Uniaxial strip: the lateral and axial stretch at mid-length, from the vertex columns
/// nearest the middle and one spacing to each side.
struct Midspan {
  double axial, lateral;
};
Midspan midspan(const Scene& s, const Record& r) {
  const auto& X = s.mesh.rest();
  const Strip g = strip(s);
  const double mid = 0.5 * (g.x0 + g.x1);
  auto column = [&](double x, auto&& f) {
    for (Eigen::Index i = 0; i < X.rows(); ++i)
      if (std::abs(X(i, 0) - x) < 0.25 * g.dx) f(i);
  };
  auto mean_x = [&](double x) {
    double sum = 0, rest = 0;
    int n = 0;
    column(x, [&](Eigen::Index i) { sum += r.x[3 * i], rest += X(i, 0), ++n; });
    return std::pair{sum / n, rest / n};
  };
  const auto [xl, rl] = mean_x(mid - g.dx);
  const auto [xr, rr] = mean_x(mid + g.dx);
  double ylo = 1e300, yhi = -1e300, rlo = 1e300, rhi = -1e300;
  column(mid, [&](Eigen::Index i) {
    ylo = std::min(ylo, r.x[3 * i + 1]), yhi = std::max(yhi, r.x[3 * i + 1]);
    rlo = std::min(rlo, X(i, 1)), rhi = std::max(rhi, X(i, 1));
  });
  return {(xr - xl) / (rr - rl), (yhi - ylo) / (rhi - rlo)};
}

/// Incline (gravity tilted against a plane of normal z): the slope angle and the downhill unit vector.
double incline_angle(const Scene& s) { return std::atan2(s.spec.gravity.head<2>().norm(), -s.spec.gravity.z()); }
Eigen::Vector3d downhill(const Scene& s) {
  const Eigen::Vector2d g = s.spec.gravity.head<2>();
  return g.norm() > 0 ? Eigen::Vector3d(g.x(), g.y(), 0).normalized() : Eigen::Vector3d::UnitX();
}
double obstacle_friction(const Scene& s) { return s.spec.obstacles.at(0).friction; }
/// Acceleration of the downhill distance of the centre of mass: least-squares parabola over
/// the steps after `settle` seconds.
double slide_acceleration(const Scene& s, const Record& r, double settle) {
  const Eigen::Vector3d d = downhill(s);
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (size_t k = 0; k < r.t.size(); ++k) {
    if (r.t[k] < settle) continue;
    const Eigen::Vector3d phi(1.0, r.t[k], 0.5 * r.t[k] * r.t[k]);
    A += phi * phi.transpose();
    b += phi * r.com[k].dot(d);
  }
  const Eigen::LDLT<Eigen::Matrix3d> f(A);
  return f.info() == Eigen::Success && f.isPositive() && A(0, 0) >= 3 ? f.solve(b)[2] : 0.0;
}
/// Downhill distance covered by the centre of mass after `settle` seconds.
double slide_distance(const Scene& s, const Record& r, double settle) {
  const Eigen::Vector3d d = downhill(s);
  for (size_t k = 0; k < r.t.size(); ++k)
    if (r.t[k] >= settle) return (r.com.back() - r.com[k]).dot(d);
  return 0.0;
}

constexpr const char* elastica_source =
    "inextensible elastica of a clamped strip under its own weight, D = Y h^3 / 12 (1 - nu^2) (Frisch-Fay 1962, Flexible "
    "Bars, ch. 3; solved by shooting)";

std::vector<Problem> suite() {
  std::vector<Problem> p;
  p.push_back({"membrane/uniaxial", "isotropic StVK strip stretched to 1.2 x its length, free sides: lateral contraction at mid-length",
               "scenes/validation/uniaxial_strip.json", {}, true, "1 - lateral stretch", "-",
               "St. Venant-Kirchhoff in uniaxial stress, E_yy = -nu E_xx (docs/methods/shells.md §3.1)", 0.02, false, nullptr,
               nullptr});
  p.back().reference = nullptr;  // needs the measured axial stretch: see measure
  // Cantilevers: the 16 mm beam of the thesis' beam scenes, damped to rest.
  struct Mesh {
    const char* tess;
    int nx, ny;
    bool quick;
  };
  for (const char* energy : {"theta", "tan"})
    for (const Mesh m : {Mesh{"regular", 31, 4, true}, Mesh{"regular", 61, 6, false}, Mesh{"regular", 88, 9, false},
                         Mesh{"regular", 98, 14, false}, Mesh{"irregular", 31, 4, false}, Mesh{"irregular", 61, 6, false},
                         Mesh{"irregular", 88, 9, false}, Mesh{"irregular", 98, 14, false}}) {
      const bool quick = m.quick || (std::string(energy) == "tan" && std::string(m.tess) == "irregular" && m.nx == 31);
      Problem c{fmt::format("cantilever/{}/{}-{}x{}", energy, m.tess, m.nx, m.ny),
                fmt::format("1 m x 0.1 m strip, h = 16 mm, Y = 100 MPa, clamped at one end, at rest under gravity ({} bending, {} "
                            "{} x {} mesh)",
                            energy, m.tess, m.nx, m.ny),
                "scenes/validation/cantilever.json",
                {fmt::format("cloths.0.mesh.tessellation={}", m.tess), fmt::format("cloths.0.mesh.resolution=[{},{}]", m.nx, m.ny),
                 fmt::format("cloths.0.pins.0.box_max=[{:.9g},0.051,0.001]", -0.5 + 1.5 / (m.nx - 1))},
                quick, "tip drop", "m", elastica_source, 0.05, false, cantilever_reference, cantilever_drop};
      if (std::string(energy) == "tan") c.overrides.emplace_back("combo=cloth_tan_ip_direct");
      p.push_back(std::move(c));
    }
  // Rods: the discrete elastic rod against the elastica, and a curved rest shape that must hold.
  for (const int n : {21, 41, 81})
    p.push_back({fmt::format("rod/cantilever-{}", n),
                 fmt::format("straight rod, 25 cm, r = 0.5 mm, Y = 1 GPa, root edge clamped, at rest under gravity ({} vertices)", n),
                 "scenes/validation/rod_cantilever.json", {fmt::format("rods.0.vertices={}", n)}, n == 21, "tip drop", "m",
                 "inextensible elastica of a clamped rod under its own weight, EI = Y pi r^4 / 4 (Frisch-Fay 1962, Flexible Bars, "
                 "ch. 3; solved by shooting)",
                 0.01, false, rod_cantilever_reference, rod_tip_drop});
  for (const int n : {21, 41, 81})
    p.push_back({fmt::format("rod/ring-{}", n),
                 fmt::format("quarter ring of radius 5 cm, r = 1 mm, root edge clamped, bent out of its plane by its weight: "
                             "bending and torsion together ({} vertices)", n),
                 "scenes/validation/rod_ring.json", {fmt::format("rods.0.vertices={}", n)}, n == 21, "tip deflection", "m",
                 "circular-arc cantilever loaded normal to its plane, q R^4 [(1 - cos phi)^2 / 2 EI + (phi - sin phi)^2 / 2 GJ], "
                 "EI = Y pi r^4 / 4, GJ = G pi r^4 / 2 (Castigliano; Roark's Formulas for Stress and Strain, ch. 9)",
                 0.01, false, rod_ring_reference, rod_tip_drop});
  p.push_back({"rod/helix-at-rest", "helix of radius 1 cm and pitch 2 cm in its rest shape, root edge clamped, no gravity: "
               "largest displacement after 1 s", "scenes/validation/rod_helix.json", {}, true, "largest displacement", "m",
               "a rod in its rest shape stores no energy and feels no force: it stays where it is", 1e-9, true,
               [](const Scene&) { return 0.0; }, largest_displacement});
  constexpr double settle = 0.1;
  for (const double mu : {0.5, 0.6}) {
    const bool slides = mu < 0.55;
    p.push_back({slides ? "rod/incline/slide" : "rod/incline/stick",
                 fmt::format("rod across a plane inclined by 30 degrees, ADONIS contact, mu = {} {} tan 30: {}", mu, slides ? "<" : ">",
                             slides ? "downhill acceleration" : "downhill distance after 0.1 s"),
                 "scenes/validation/rod_incline.json", {fmt::format("obstacles.0.friction={}", mu)}, true,
                 slides ? "acceleration" : "slide distance", slides ? "m/s^2" : "m",
                 slides ? "Coulomb friction on an incline, a = g (sin alpha - mu cos alpha)"
                        : "Coulomb friction on an incline: no sliding when mu > tan alpha",
                 slides ? 0.05 : 1e-3, !slides,
                 [slides](const Scene& s) {
                   return slides ? reference::incline_acceleration(s.spec.gravity.norm(), incline_angle(s), obstacle_friction(s)) : 0.0;
                 },
                 [=](const Scene& s, const Record& r) { return slides ? slide_acceleration(s, r, settle) : slide_distance(s, r, settle); }});
  }
  p.push_back({"incline/slide", "sheet on a plane inclined by 30 degrees, mu = 0.5 < tan 30: downhill acceleration",
               "scenes/incline_sheet.json", {"obstacles.0.friction=0.5"}, true, "acceleration", "m/s^2",
               "Coulomb friction on an incline, a = g (sin alpha - mu cos alpha)", 0.05, false,
               [](const Scene& s) { return reference::incline_acceleration(s.spec.gravity.norm(), incline_angle(s), obstacle_friction(s)); },
               [=](const Scene& s, const Record& r) { return slide_acceleration(s, r, settle); }});
  p.push_back({"incline/stick", "the same sheet with mu = 0.6 > tan 30: it stays where it lands (downhill distance after 0.1 s)",
               "scenes/incline_sheet.json", {"obstacles.0.friction=0.6"}, true, "slide distance", "m",
               "Coulomb friction on an incline: no sliding when mu > tan alpha", 1e-3, true,
               [](const Scene&) { return 0.0; }, [=](const Scene& s, const Record& r) { return slide_distance(s, r, settle); }});
  return p;
}

/// The problem's own overrides, then the user's: those of cloths (`cloths.`) reach only the
/// problems of cloths and those of rods (`rods.`) only the problems of rods, so that one
/// override can be given to the whole suite.
std::vector<std::string> scene_overrides(const Problem& pb, const std::vector<std::string>& user) {
  std::vector<std::string> ov;
  for (const std::string& o : pb.overrides)
    if (o.rfind("combo=", 0) == 0) append_combo_overrides(ov, o.substr(6));
    else ov.push_back(o);
  const bool rods = pb.name.rfind("rod/", 0) == 0;
  for (const std::string& o : user)
    if (!(rods ? o.rfind("cloths.", 0) == 0 : o.rfind("rods.", 0) == 0)) ov.push_back(o);
  return ov;
}

/// Runs one problem's scene to its end and measures it.
ValidationRow run_problem(const Problem& pb, const std::vector<std::string>& user_ov, bool quiet) {
  ValidationRow row{pb.name, pb.quantity, pb.unit, pb.source};
  row.tolerance = pb.tolerance;
  row.absolute = pb.absolute;
  const auto start = std::chrono::steady_clock::now();
  auto sim = make_simulator(load_scene(fs::path(data_dir()) / pb.scene, scene_overrides(pb, user_ov)));
  const Scene& scene = sim->scene();
  Record rec;
  auto note = [&] {
    const State& s = sim->state();
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    double m = 0;
    for (int i = 0; i < s.num_vertices(); ++i) c += s.mass[i] * s.position(i), m += s.mass[i];
    rec.t.push_back(s.t);
    rec.com.push_back(c / m);
  };
  note();
  rec.x0 = sim->state().x;
  const long long steps = scene.spec.time.num_steps();
  for (long long k = 1; k <= steps; ++k) {
    const StepReport r = sim->step();
    row.steps = static_cast<int>(k);
    if (!r.ok()) {
      row.status = fmt::format("failed at step {} ({}): {}", r.step, r.failed_stage, r.message);
      break;
    }
    note();
  }
  rec.x = sim->state().x;
  row.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (row.status == "ok") {
    if (pb.name == "membrane/uniaxial") {
      const Midspan m = midspan(scene, rec);
      row.reference = 1.0 - reference::stvk_uniaxial_lateral_stretch(m.axial, scene.spec.cloths[0].material.poisson_ratio);
      row.measured = 1.0 - m.lateral;
    } else {
      row.reference = pb.reference(scene);
      row.measured = pb.measure(scene, rec);
    }
    row.error = pb.absolute ? std::abs(row.measured - row.reference) : std::abs(row.measured - row.reference) / std::abs(row.reference);
    row.pass = std::isfinite(row.error) && row.error <= row.tolerance;
  }
  if (!quiet)
    fmt::print(stderr, "{}: {} ({} steps, {:.1f} s)\n", row.problem, row.status == "ok" ? (row.pass ? "pass" : "MISSED") : row.status,
               row.steps, row.seconds);
  return row;
}

std::string csv_row(const ValidationRow& r) {
  return fmt::format("{},{},{},{:.9g},{:.9g},{:.6g},{:.6g},{},{},{},{},{:.3f},{}\n", csv_field(r.problem), csv_field(r.quantity),
                     csv_field(r.unit), r.reference, r.measured, r.error, r.tolerance, r.absolute ? "absolute" : "relative",
                     r.pass ? "pass" : "fail", csv_field(r.status), r.steps, r.seconds, csv_field(r.source));
}

std::string error_text(const ValidationRow& r) {
  return r.absolute ? fmt::format("{:.3g} {}", r.error, r.unit) : fmt::format("{:.2f} %", 100 * r.error);
}
std::string tolerance_text(const ValidationRow& r) {
  return r.absolute ? fmt::format("{:.3g} {}", r.tolerance, r.unit) : fmt::format("{:.3g} %", 100 * r.tolerance);
}

}  // namespace

std::vector<std::string> validation_problems(bool quick) {
  std::vector<std::string> names;
  for (const Problem& p : suite())
    if (p.quick || !quick) names.push_back(p.name);
  return names;
}

int run_validate(const ValidateOptions& opt, std::vector<ValidationRow>* out_rows) {
  std::vector<Problem> chosen;
  for (Problem& p : suite()) {
    if (opt.quick && !p.quick) continue;
    if (!opt.only.empty() && std::none_of(opt.only.begin(), opt.only.end(), [&](const std::string& o) { return p.name.rfind(o, 0) == 0; }))
      continue;
    chosen.push_back(std::move(p));
  }
  // Every scene is loaded and its combination built before any run.
  try {
    if (chosen.empty())
      throw ConfigError(fmt::format("--only: no problem starts with {} (problems: {})", fmt::join(opt.only, " or "),
                                    fmt::join(validation_problems(false), ", ")));
    for (const Problem& p : chosen) {
      make_simulator(load_scene(fs::path(data_dir()) / p.scene, scene_overrides(p, opt.overrides)));
    }
  } catch (const ConfigError& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 2;
  }

  fs::create_directories(opt.out_dir);
  const fs::path dir(opt.out_dir);
  std::vector<ValidationRow> rows;
  auto write = [&] {  // after every problem: a failure later keeps what was measured
    std::ofstream csv((dir / "validate.csv").string());
    csv << "problem,quantity,unit,reference,measured,error,tolerance,error_kind,result,status,steps,seconds,source\n";
    Json doc = {{"quick", opt.quick}, {"overrides", opt.overrides}, {"build", build_commit()}, {"problems", Json::array()}};
    for (const ValidationRow& r : rows) {
      csv << csv_row(r);
      doc["problems"].push_back({{"problem", r.problem}, {"quantity", r.quantity}, {"unit", r.unit}, {"reference", r.reference},
                                 {"measured", r.measured}, {"error", r.error}, {"tolerance", r.tolerance},
                                 {"error_kind", r.absolute ? "absolute" : "relative"}, {"pass", r.pass}, {"status", r.status},
                                 {"steps", r.steps}, {"seconds", r.seconds}, {"source", r.source}});
    }
    std::ofstream((dir / "validate.json").string()) << doc.dump(2) << "\n";
  };
  for (const Problem& p : chosen) {
    rows.push_back(run_problem(p, opt.overrides, opt.quiet));
    write();
  }

  // The table and the report.
  std::string table = "| problem | quantity | reference | measured | error | tolerance | result |\n|---|---|---|---|---|---|---|\n";
  for (const ValidationRow& r : rows)
    table += fmt::format("| {} | {} [{}] | {:.5g} | {} | {} | {} | {} |\n", r.problem, r.quantity, r.unit, r.reference,
                         r.status == "ok" ? fmt::format("{:.5g}", r.measured) : r.status, r.status == "ok" ? error_text(r) : "-",
                         tolerance_text(r), r.pass ? "pass" : "**fail**");
  fmt::print("{}", table);
  std::ofstream md((dir / "report.md").string());
  md << "# weft validate\n\n" << fmt::format("Build {}, {} suite.\n\n", build_commit(), opt.quick ? "quick" : "full") << table
     << "\n## Problems and references\n\n";
  for (const Problem& p : chosen) md << fmt::format("- **{}**: {}. Reference: {}.\n", p.name, p.description, p.source);
  if (opt.plots && plot("validate", (dir / "validate.csv").string(), dir.string()) == PlotOutcome::written)
    md << "\n![each problem's error against its tolerance](validate.png)\n";
  if (out_rows) *out_rows = rows;
  const bool failed = std::any_of(rows.begin(), rows.end(), [](const ValidationRow& r) { return r.status != "ok"; });
  const bool missed = std::any_of(rows.begin(), rows.end(), [](const ValidationRow& r) { return !r.pass; });
  const int passed = static_cast<int>(std::count_if(rows.begin(), rows.end(), [](const ValidationRow& r) { return r.pass; }));
  fmt::print(stderr, "validate: {} of {} problems pass; {}\n", passed, rows.size(), (dir / "report.md").string());
  return failed ? 3 : missed ? exit_validation_missed : 0;
}

}  // namespace weft::app
