// Obstacle contact as equality constraints inside the implicit solve (BW98; methods/integration-and-contact §10 and
// §14, methods/multigrid §7): contact/obstacle_constraints.hpp with the plumbing of
// integrators/step_system.hpp, under modified PCG (DiagPcg), prefiltered PCG (SaPpcg,
// DiagPpcg) and the direct solver.
#include <doctest/doctest.h>
#include <fmt/format.h>

#include <cmath>
#include <memory>
#include <random>

#include "contact/obstacle_constraints.hpp"
#include "framework/scene.hpp"
#include "policies/presets.hpp"
#include "tests/support/linear_fixtures.hpp"

using namespace weft;
using contact::ObstacleConstraints;
using contact::ObstaclePose;

namespace {

constexpr double kDelta = 0.002;  // contact thickness [m]
constexpr double kDt = 1.0 / 240.0;

template <class Linear>
using LieSim = Simulator<ClothTheta, integrators::LinearlyImplicit, ObstacleConstraints, Linear>;
using RootSim = Simulator<ClothTheta, integrators::BackwardEulerRoot, ObstacleConstraints, linear::Direct>;

// A 0.3 m sheet of 9 x 9 vertices in the plane z = 0 above the given obstacles.
Scene sheet_scene(const std::string& obstacles, const std::string& extra = "{}") {
  Json doc = Json::parse(R"({
    "cloths": [{"mesh": {"source": "rectangle", "size": [0.3, 0.3], "resolution": [9, 9]},
                "material": {"density": 0.1, "youngs_modulus": 2e7, "thickness": 3e-4}}],
    "time": {"dt": 0.004166666666666667, "duration": 1.0, "frame_rate": 24}
  })");
  doc["obstacles"] = Json::parse(obstacles);
  doc.merge_patch(Json::parse(extra));
  return build_scene(doc, ".", "test");
}

// The drop scenes: a plane tilted by 0.1 rad (the sheet lands edge first and sticks), a box
// the sheet overhangs by a third (it drapes over the edge), a sphere.
const char* const drop_obstacles[] = {
    R"([{"shape": "plane", "center": [0, 0, -0.03], "normal": [0.1, 0, 1], "friction": 0.5}])",
    R"([{"shape": "box", "center": [0.2, 0, -0.11], "half_extents": [0.25, 0.25, 0.1], "friction": 0.5}])",
    R"([{"shape": "sphere", "center": [0.02, 0.01, -0.11], "radius": 0.1, "friction": 0.3}])",
};
const std::string drop_names[] = {"plane", "box", "sphere"};
const int drop_min_contacts[] = {20, 20, 5};

template <class Params>
void tighten(Params& prm) {
  prm.contact.thickness = kDelta;
  if constexpr (requires { prm.linear.tolerance; }) prm.linear.tolerance = 1e-11;
}

// `projected`: PSD-projected element Hessians, so K is positive definite whatever the
// solver (the adaptive choice shifts K when the solver reports it indefinite, and an
// iterative solver need not notice what a factorisation does).
template <class Sim>
std::unique_ptr<Sim> make(const Scene& scene, bool projected = false) {
  typename Sim::Params prm{};
  tighten(prm);
  if (projected) prm.integrator.hessian = integrators::HessianChoice::projected;
  return std::make_unique<Sim>(scene, prm);
}

// Largest depth of a free vertex below the thickness surface of the obstacles at time t
// (positive: inside the contact layer).
double max_depth(const Scene& scene, const State& s) {
  double worst = -1e300;
  for (const auto& o : scene.spec.obstacles) {
    const ObstaclePose p = ObstaclePose::at(o, s.t);
    for (int i = 0; i < s.num_vertices(); ++i)
      if (s.is_free(i)) worst = std::max(worst, kDelta - p.distance(s.position(i)).phi);
  }
  return worst;
}

double mean_velocity(const State& s, int axis) {
  double v = 0;
  int n = 0;
  for (int i = 0; i < s.num_vertices(); ++i)
    if (s.is_free(i)) v += s.velocity(i)[axis], ++n;
  return v / n;
}

struct Run {
  std::vector<Eigen::VectorXd> x;  // positions after each step
  double max_depth = -1e300, max_violation = 0, peak_kinetic = 0, final_kinetic = 0;
  int max_contacts = 0, last_contacts = 0, released = 0, linear_iterations = 0;
};

// Runs `steps` steps, checking each report and the depth below the thickness surface.
template <class Sim>
Run run(const Scene& scene, int steps, bool projected = false) {
  auto sim = make<Sim>(scene, projected);
  Run r;
  for (int k = 0; k < steps; ++k) {
    const StepReport rep = sim->step();
    REQUIRE_MESSAGE(rep.ok(), "step ", k + 1, ": ", rep.failed_stage, ": ", rep.message);
    r.x.push_back(sim->state().x);
    r.max_depth = std::max(r.max_depth, max_depth(scene, sim->state()));
    r.max_violation = std::max(r.max_violation, rep.linear.constraint_violation);
    r.max_contacts = std::max(r.max_contacts, rep.contact.contacts);
    r.last_contacts = rep.contact.contacts;
    r.released += rep.contact.released;
    r.linear_iterations += rep.linear.iterations;
    r.peak_kinetic = std::max(r.peak_kinetic, rep.energy.kinetic);
    r.final_kinetic = rep.energy.kinetic;
  }
  return r;
}

// The steps of `Simulator::step` with the policies exposed, for the integrators the
// simulator does not compose with a constraint strategy yet (IncrementalPotential) and to
// read the strategy's own end-of-step report.
template <class Integ, class Linear>
struct Stepper {
  Scene scene;
  ClothTheta energy;
  Integ integrator;
  ObstacleConstraints contact;
  Linear linear;
  State state;
  AssemblyPlan plan;
  ElementBuffer buffer;
  BlockCsr matrix;
  std::vector<unsigned char> fixed;
  Eigen::VectorXd target;
  bool analyzed = false;
  ContactReport response;

  Stepper(Scene s, const typename Integ::Params& ip, const typename Linear::Params& lp,
          const ObstacleConstraints::Params& cp = {.thickness = kDelta})
      : scene(std::move(s)), energy(scene, {}), integrator(ip), contact(scene, cp), linear(lp) {
    state = scene.initial_state();
    energy.declare(plan);
    contact.declare(plan);
    plan.finalize(state.num_vertices());
    buffer = plan.make_buffer();
    matrix = plan.pattern();
    for (int i = 0; i < state.num_vertices(); ++i) fixed.push_back(state.is_free(i) ? 0 : 1);
  }
  StepReport step() {
    const double dt = scene.spec.time.dt;
    scene.constrained_positions(state.t + dt, state, target);
    if constexpr (HasBeginStep<ClothTheta>) energy.begin_step(state, state.t + dt);
    ContactReport begin = contact.begin_step(state, dt);
    StepProblem problem{state, dt, target, scene.spec.damping.mass, plan, buffer, matrix, fixed, analyzed};
    StepReport r = integrator.step(energy, contact, linear, problem);
    r.contact = begin;
    if (!r.ok()) return r;
    response = contact.end_step(state, dt);
    state.t += dt;
    return r;
  }
};

}  // namespace

TEST_SUITE("contact") {
  TEST_CASE("obstacle constraints: the constraints of an iterate hold to round-off in every linear solver") {
    // Vertices pushed into a plane and a sphere: the constraints of the iterate ask for
    // non-zero normal increments; each solver must return a solution meeting them.
    const Scene scene = sheet_scene(R"([{"shape": "plane", "center": [0, 0, -0.001], "normal": [0.2, 0, 1]},
                                        {"shape": "sphere", "center": [0.1, 0.1, -0.03], "radius": 0.04, "friction": 0.4}])");
    ObstacleConstraints c(scene, {.thickness = kDelta});
    State s = scene.initial_state();
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-0.004, 0.004);
    for (int i = 0; i < s.x.size(); ++i) s.x[i] += u(rng);
    c.begin_step(s, kDt);
    ConstraintSet set;
    c.constraints(s, set);
    REQUIRE(set.constrained_vertices() > 10);
    int sticking = 0;
    for (const auto& k : c.contacts()) sticking += k.mode == ObstacleConstraints::Mode::stick;
    CHECK(sticking > 0);  // the sphere has friction and the sheet is at rest: 3D constraints
    REQUIRE(set.target().cwiseAbs().maxCoeff() > 1e-3);  // non-trivial values

    // The increment z of the set moves each vertex onto the thickness surface.
    State moved = s;
    moved.x += set.target();
    for (const auto& k : c.contacts()) {
      const ObstaclePose p = ObstaclePose::at(scene.spec.obstacles[k.obstacle], kDt);
      CHECK(p.distance(moved.position(k.vertex)).phi == doctest::Approx(kDelta).epsilon(1e-9));
    }

    const BlockCsr A = support::block_laplacian(9, 1.0);
    REQUIRE(A.block_rows() == s.num_vertices());
    Eigen::VectorXd b(s.x.size());
    for (int i = 0; i < b.size(); ++i) b[i] = u(rng);
    auto solve = [&](auto& solver) {
      solver.set_context(SolveContext{&set, &s.x});
      REQUIRE(solver.analyze_pattern(A) == Status::success);
      REQUIRE(solver.factorize(A) == Status::success);
      Eigen::VectorXd x;
      const LinearReport rep = solver.solve(b, x);
      REQUIRE(rep.status == Status::success);
      CHECK(rep.constraint_violation <= 1e-15);
      // n^T x_i = value along every constrained direction, checked against the set itself.
      for (int i = 0; i < s.num_vertices(); ++i)
        for (int m = 0; m < set.count(i); ++m) {
          const Eigen::Vector3d n = set.directions(i).col(m);
          CHECK(std::abs(n.dot(x.segment<3>(3 * i) - set.target().segment<3>(3 * i))) <= 1e-15);
        }
      // The free part solves the filtered system: S (b - A x) = 0.
      Eigen::VectorXd r(b.size());
      A.multiply(x, r);
      r = b - r;
      set.filter(r);
      CHECK(r.norm() <= 1e-8 * b.norm());
      return x;
    };
    linear::DiagPcg mpcg({.tolerance = 1e-12});
    linear::DiagPpcg dppcg({.tolerance = 1e-12});
    linear::SaPpcg sappcg({.tolerance = 1e-12});
    linear::Direct direct({});
    const Eigen::VectorXd x1 = solve(mpcg), x2 = solve(dppcg), x3 = solve(sappcg), x4 = solve(direct);
    CHECK((x1 - x4).norm() <= 1e-9 * x4.norm());
    CHECK((x2 - x4).norm() <= 1e-9 * x4.norm());
    CHECK((x3 - x4).norm() <= 1e-9 * x4.norm());
  }

  TEST_CASE("obstacle constraints: a sheet dropped on a plane a box and a sphere stays out with the three solvers") {
    for (int k = 0; k < 3; ++k) {
      CAPTURE(drop_names[k]);
      const Scene scene = sheet_scene(drop_obstacles[k], R"({"damping": {"mass": 2.0}})");
      const int steps = 40;  // contact from step 10, then 30 steps on the obstacle
      const Run direct = run<LieSim<linear::Direct>>(scene, steps, true);
      const Run mpcg = run<LieSim<linear::DiagPcg>>(scene, steps, true);
      const Run ppcg = run<LieSim<linear::SaPpcg>>(scene, steps, true);
      for (const Run* r : {&direct, &mpcg, &ppcg}) {
        CHECK(r->max_contacts >= drop_min_contacts[k]);
        CHECK(r->max_depth <= 1e-9);       // never deeper than the projection tolerance below delta
        CHECK(r->max_violation <= 1e-12);  // constraints met by every solve [m]
      }
      CHECK(mpcg.linear_iterations > 0);
      CHECK(ppcg.linear_iterations > 0);
      const double moved = (direct.x.back() - direct.x.front()).cwiseAbs().maxCoeff();
      REQUIRE(moved > 1e-3);
      double diff_m = 0, diff_p = 0;
      for (int j = 0; j < steps; ++j) {
        diff_m = std::max(diff_m, (mpcg.x[j] - direct.x[j]).cwiseAbs().maxCoeff());
        diff_p = std::max(diff_p, (ppcg.x[j] - direct.x[j]).cwiseAbs().maxCoeff());
      }
      MESSAGE(drop_names[k] << ": max difference to Direct over " << steps << " steps: MPCG " << diff_m << " m, SA+PPCG "
                            << diff_p << " m (motion " << moved << " m); up to " << direct.max_contacts << " contacts");
      CHECK(diff_m <= 1e-8);
      CHECK(diff_p <= 1e-8);
    }
  }

  TEST_CASE("obstacle constraints: Newton iterations with line searches keep the iterates feasible") {
    // Root finding (residual merit, backtracking) through the simulator, and minimisation
    // of E_inc (Armijo backtracking) stepped by hand: the simulator does not compose a
    // minimising integrator with a constraint strategy yet. Both solve the same
    // constrained backward Euler problem to the Newton tolerance.
    integrators::IncrementalPotential::Params ip;
    ip.relative_tolerance = 1e-9;
    for (int k = 0; k < 2; ++k) {
      CAPTURE(drop_names[k]);
      const Scene scene = sheet_scene(drop_obstacles[k], R"({"damping": {"mass": 2.0}})");
      const Run root = run<RootSim>(scene, 40);
      CHECK(root.max_depth <= 1e-9);
      CHECK(root.max_violation <= 1e-12);
      CHECK(root.max_contacts >= drop_min_contacts[k]);
      Stepper<integrators::IncrementalPotential, linear::Direct> st(scene, ip, {});
      double diff = 0;
      for (int j = 0; j < 40; ++j) {
        const StepReport r = st.step();
        REQUIRE_MESSAGE(r.ok(), "step ", j + 1, ": ", r.message);
        diff = std::max(diff, (st.state.x - root.x[j]).cwiseAbs().maxCoeff());
      }
      MESSAGE(drop_names[k] << ": root finding and minimisation differ by " << diff << " m over 40 steps");
      CHECK(diff <= 1e-6);
    }
    // The sphere (curved: the constraints are relinearised at each iterate) with MPCG.
    const Scene scene = sheet_scene(drop_obstacles[2], R"({"damping": {"mass": 2.0}})");
    Stepper<integrators::IncrementalPotential, linear::DiagPcg> st(scene, {}, {.tolerance = 1e-11});
    int newton = 0, contacts = 0;
    double depth = -1, off_surface = 0;
    for (int k = 0; k < 40; ++k) {
      const StepReport r = st.step();
      REQUIRE_MESSAGE(r.ok(), "step ", k + 1, ": ", r.message);
      newton += r.newton.iterations;
      contacts = std::max(contacts, r.contact.contacts);
      depth = std::max(depth, max_depth(scene, st.state));
      CHECK(r.linear.constraint_violation <= 1e-12);
      for (const auto& it : r.newton.history) CHECK(it.step_length > 0);
      // The accepted iterate lies on the constraints: every contact at delta.
      const ObstaclePose p = ObstaclePose::at(scene.spec.obstacles[0], st.state.t);
      for (const auto& c : st.contact.contacts())
        off_surface = std::max(off_surface, std::abs(p.distance(st.state.position(c.vertex)).phi - kDelta));
    }
    MESSAGE("incremental potential on the sphere: " << newton << " Newton iterations in 40 steps, up to " << contacts
                                                    << " contacts, contacts off the surface by " << off_surface << " m");
    CHECK(contacts >= 5);
    CHECK(depth <= 1e-9);
    CHECK(off_surface <= 1e-8);
  }

  TEST_CASE("obstacle constraints: vertices the solve carries into an obstacle are re-detected and solved again") {
    // The sheet falls from rest with its contact layer 0.5 mm above a plane: the start and
    // the prediction x0 + dt v0 = x0 are out of reach, so the step starts without contacts,
    // but the free solution falls g dt^2 = 1.06 mm, 0.56 mm into the layer. Without
    // re-detection the end-of-step projection moves every vertex back; with it the solve is
    // continued with their contacts and ends on the layer with the reaction of the
    // equations of motion.
    const double dt = 1.0 / 96, gap = 5e-4, g = 9.81;
    const Scene scene = sheet_scene(
        fmt::format(R"([{{"shape": "plane", "center": [0, 0, {}], "normal": [0, 0, 1]}}])", -(kDelta + gap)),
        R"({"time": {"dt": 0.010416666666666667}})");
    // Re-detection off; at the converged solution only (the default); also at every iterate.
    Eigen::VectorXd x_converged, x_iterates;
    for (const auto& [rounds, iterates] : {std::pair{0, true}, std::pair{4, false}, std::pair{4, true}}) {
      CAPTURE(rounds);
      CAPTURE(iterates);
      Stepper<integrators::IncrementalPotential, linear::Direct> st(
          scene, {}, {}, {.thickness = kDelta, .max_redetections = rounds, .redetect_iterates = iterates});
      const StepReport r = st.step();
      REQUIRE_MESSAGE(r.ok(), r.message);
      CHECK(r.contact.contacts == 0);  // none at the start of the step
      CHECK(max_depth(scene, st.state) <= 1e-9);
      if (rounds == 0) {
        CHECK(st.response.redetections == 0);
        CHECK(st.response.projected == 81);
        CHECK(st.response.solve_penetration == doctest::Approx(g * dt * dt - gap).epsilon(1e-6));
        CHECK(st.contact.contacts().empty());
      } else {
        CHECK(st.response.redetections == 1);
        CHECK(st.response.redetected == 81);
        CHECK(st.response.projected == 0);
        CHECK(st.response.solve_penetration <= 1e-9);
        REQUIRE(st.contact.contacts().size() == 81);
        // M (v1 - v0) / dt = -M g + R with v1 = -gap / dt: the constraints carry the weight
        // and stop the fall.
        double reaction = 0;
        for (const auto& c : st.contact.contacts()) reaction += c.normal_force;
        const double mass = st.state.mass.sum();
        CHECK(reaction == doctest::Approx(mass * (g - gap / (dt * dt))).epsilon(1e-6));
        REQUIRE(!r.newton.history.empty());
        if (iterates) {
          // Caught at the first iterate, which crossed: that update added the contacts.
          CHECK(r.newton.history.front().constraints_updated);
          x_iterates = st.state.x;
        } else {
          CHECK(r.newton.iterations >= 2);  // the first solve and its continuation
          for (const auto& it : r.newton.history) CHECK(!it.constraints_updated);
          x_converged = st.state.x;
        }
      }
    }
    // The same contacts, the same constrained problem: the same step.
    CHECK((x_iterates - x_converged).cwiseAbs().maxCoeff() < 1e-9);
    // The rounds are bounded and the parameters checked.
    CHECK_THROWS_WITH_AS(ObstacleConstraints(scene, {.max_redetections = -1}), doctest::Contains("max_redetections = -1 violates"),
                         ConfigError);
    CHECK_THROWS_WITH_AS(ObstacleConstraints(scene, {.redetection_depth = -1e-3}), doctest::Contains("redetection_depth"),
                         ConfigError);
  }

  TEST_CASE("obstacle constraints: two boxes sharing a face hold a sheet as the one box they make") {
    // A sheet slides (frictionless, gravity tilted along +x) across the seam of two boxes
    // that share their face x = 0, a column of its vertices starting on the seam. Their union
    // is one flat top: the run must match the run on the single box of the same extent. Near
    // the seam a vertex is within the thickness of both boxes, and the rounded edge of the
    // box it leaves, tangent to the other's thickness surface, would pin it onto the seam.
    const std::string two = R"([{"shape": "box", "center": [-0.25, 0, -0.102], "half_extents": [0.25, 0.5, 0.1]},
                                 {"shape": "box", "center": [0.25, 0, -0.102], "half_extents": [0.25, 0.5, 0.1]}])";
    const std::string one = R"([{"shape": "box", "center": [0, 0, -0.102], "half_extents": [0.5, 0.5, 0.1]}])";
    const std::string tilted = R"({"gravity": [2.0, 0, -9.81]})";
    Stepper<integrators::IncrementalPotential, linear::Direct> a(sheet_scene(two, tilted), {}, {});
    Stepper<integrators::IncrementalPotential, linear::Direct> b(sheet_scene(one, tilted), {}, {});
    double diff = 0;
    int double_contacts = 0;
    for (int k = 0; k < 40; ++k) {
      CAPTURE(k);
      const StepReport ra = a.step(), rb = b.step();
      REQUIRE_MESSAGE(ra.ok(), ra.message);
      REQUIRE_MESSAGE(rb.ok(), rb.message);
      diff = std::max(diff, (a.state.x - b.state.x).cwiseAbs().maxCoeff());
      double_contacts = std::max(double_contacts, ra.contact.contacts - rb.contact.contacts);
      CHECK(max_depth(a.scene, a.state) <= 1e-9);
    }
    const double slid = a.state.x(Eigen::seqN(0, a.state.num_vertices(), 3)).mean() - a.scene.start.col(0).mean();
    MESSAGE("two boxes vs one: " << diff << " m apart after 40 steps; slid " << slid << " m; up to " << double_contacts
                                 << " more contacts on two boxes");
    CHECK(double_contacts >= 9);           // the guard: the seam column was in contact with both boxes
    CHECK(slid == doctest::Approx(0.5 * 2.0 * a.state.t * a.state.t).epsilon(0.05));  // it slid freely
    CHECK(diff <= 1e-8);
  }

  TEST_CASE("obstacle constraints: a resting sheet is released when gravity reverses") {
    // The sheet rests at delta above a plane with gravity pointing up: the constraints
    // pull, are released at the first step, and the sheet flies off at g.
    const Scene scene = sheet_scene(R"([{"shape": "plane", "center": [0, 0, -0.002], "normal": [0, 0, 1]}])",
                                    R"({"gravity": [0, 0, 9.81]})");
    Stepper<integrators::LinearlyImplicit, linear::Direct> st(scene, {}, {});
    StepReport r = st.step();
    REQUIRE(r.ok());
    CHECK(r.contact.contacts == 81);
    CHECK(st.response.released == 81);
    int released = r.contact.released + st.response.released;  // this harness keeps begin_step's and end_step's reports apart
    r = st.step();
    REQUIRE(r.ok());
    CHECK(r.contact.released == 0);  // the 81 dropped at the start of the second step were counted by the first
    CHECK(r.contact.contacts == 0);
    released += r.contact.released + st.response.released;
    for (int k = 2; k < 24; ++k) {
      r = st.step();
      REQUIRE(r.ok());
      CHECK(r.contact.contacts == 0);
      released += r.contact.released + st.response.released;
    }
    CHECK(released == 81);  // each contact counted once
    // Held during the first step only, then free: v = g (t - dt).
    CHECK(mean_velocity(st.state, 2) == doctest::Approx(9.81 * (st.state.t - kDt)).epsilon(1e-6));
  }

  TEST_CASE("obstacle constraints: a plane dropping away faster than gravity leaves the sheet without adhesion") {
    const Scene scene = sheet_scene(R"([{"shape": "plane", "center": [0, 0, -0.002], "normal": [0, 0, 1],
                                         "motion": {"velocity": [0, 0, -2], "start": 0.1}}])");
    for (int solver = 0; solver < 2; ++solver) {
      CAPTURE(solver);
      std::unique_ptr<LieSim<linear::DiagPcg>> mpcg;
      std::unique_ptr<LieSim<linear::SaPpcg>> ppcg;
      if (solver == 0) mpcg = make<LieSim<linear::DiagPcg>>(scene);
      else ppcg = make<LieSim<linear::SaPpcg>>(scene);
      auto step = [&] { return solver == 0 ? mpcg->step() : ppcg->step(); };
      auto state = [&]() -> const State& { return solver == 0 ? mpcg->state() : ppcg->state(); };
      int released = 0, resting = 0;
      double t_free = -1;
      for (int k = 0; k < 96; ++k) {  // 0.4 s: the plane moves from t = 0.1 s
        const StepReport r = step();
        REQUIRE_MESSAGE(r.ok(), r.message);
        released += r.contact.released;
        CHECK(max_depth(scene, state()) <= 1e-9);
        if (state().t <= 0.1 + 1e-9) {
          resting += r.contact.contacts == 81;
          CHECK(std::abs(mean_velocity(state(), 2)) <= 1e-6);  // at rest on the plane
        } else if (r.contact.contacts == 0 && t_free < 0) {
          t_free = state().t - kDt;  // free from the start of this step
        }
      }
      CHECK(resting >= 20);
      CHECK(released == 81);
      REQUIRE(t_free > 0);
      CHECK(t_free <= 0.1 + 2 * kDt + 1e-9);  // released by the step after the plane starts
      // Free fall since then: no constraint held it back.
      CHECK(mean_velocity(state(), 2) == doctest::Approx(-9.81 * (state().t - t_free)).epsilon(1e-6));
    }
  }

  TEST_CASE("obstacle constraints: friction on an inclined plane sticks below and slides above the Coulomb angle") {
    // methods/integration-and-contact E7 with a sheet: the plane is z = 0 and gravity is tilted by alpha about y.
    const double mu = 0.5, g = 9.81, alpha_c = std::atan(mu);
    for (double factor : {0.95, 1.05, 1.5}) {
      const double alpha = factor * alpha_c;
      CAPTURE(factor);
      const Scene scene = sheet_scene(
          fmt::format(R"([{{"shape": "plane", "center": [0, 0, -0.002], "normal": [0, 0, 1], "friction": {}}}])", mu),
          fmt::format(R"({{"gravity": [{}, 0, {}]}})", g * std::sin(alpha), -g * std::cos(alpha)));
      const Run r = run<LieSim<linear::DiagPcg>>(scene, 120);  // 0.5 s
      const double expected = g * (std::sin(alpha) - mu * std::cos(alpha));
      CHECK(r.max_depth <= 1e-9);
      CHECK(r.last_contacts == 81);
      CHECK(r.released == 0);
      // Mean tangential velocity along x at steps 20 and 120.
      auto vx = [&](int step) {
        const Eigen::VectorXd dx = r.x[step - 1] - r.x[step - 2];
        double v = 0;
        for (int i = 0; i < 81; ++i) v += dx[3 * i] / kDt;
        return v / 81;
      };
      const double moved = (r.x.back() - scene.initial_state().x).cwiseAbs().maxCoeff();
      if (factor < 1) {
        MESSAGE("alpha = " << factor << " alpha_c: moved " << moved << " m in 0.5 s");
        CHECK(moved <= 1e-9);  // stuck
      } else {
        const double a = (vx(120) - vx(20)) / (100 * kDt);
        MESSAGE("alpha = " << factor << " alpha_c: slide acceleration " << a << " m/s^2, expected " << expected);
        CHECK(moved > 1e-3);
        CHECK(a == doctest::Approx(expected).epsilon(0.05));
      }
    }
  }

  TEST_CASE("obstacle constraints: a sphere moving up into a hanging sheet pushes it without penetration") {
    const Scene scene = sheet_scene(
        R"([{"shape": "sphere", "center": [0, 0, -0.15], "radius": 0.06, "motion": {"velocity": [0, 0, 0.5]}}])",
        R"({"cloths": [{"mesh": {"source": "rectangle", "size": [0.3, 0.3], "resolution": [9, 9]},
                        "material": {"density": 0.1, "youngs_modulus": 2e7, "thickness": 3e-4},
                        "pins": [{"box_min": [-0.16, -0.16, -0.01], "box_max": [-0.14, -0.14, 0.01]},
                                 {"box_min": [0.14, -0.16, -0.01], "box_max": [0.16, -0.14, 0.01]},
                                 {"box_min": [-0.16, 0.14, -0.01], "box_max": [-0.14, 0.16, 0.01]},
                                 {"box_min": [0.14, 0.14, -0.01], "box_max": [0.16, 0.16, 0.01]}]}],
            "damping": {"mass": 1.0}})");
    REQUIRE(scene.initial_state().num_vertices() == 81);
    const int center = 40;  // the middle vertex
    for (int solver = 0; solver < 2; ++solver) {
      CAPTURE(solver);
      const Run r = solver == 0 ? run<LieSim<linear::DiagPcg>>(scene, 96) : run<LieSim<linear::SaPpcg>>(scene, 96);  // 0.4 s
      const double z_end = r.x.back()[3 * center + 2];
      // The sphere's top is at -0.09 + 0.5 t: at 0.4 s, 0.11 m; the sheet lies on it.
      MESSAGE("centre vertex at " << z_end << " m after 0.4 s; up to " << r.max_contacts << " contacts");
      CHECK(r.max_depth <= 1e-9);
      CHECK(r.max_contacts >= 3);
      CHECK(z_end == doctest::Approx(0.11 + kDelta).epsilon(0.02));
    }
  }

  TEST_CASE("obstacle constraints: invalid parameters are configuration errors") {
    const Scene scene = sheet_scene(R"([{"shape": "plane", "center": [0, 0, -0.01]}])");
    CHECK_THROWS_WITH_AS(ObstacleConstraints(scene, {.thickness = -1.0}), doctest::Contains("thickness = -1 violates"), ConfigError);
  }
}

TEST_SUITE("slow") {
  TEST_CASE("obstacle constraints: a sheet dropped on a plane a box and a sphere comes to rest on it with the three solvers") {
    for (int k = 0; k < 3; ++k) {
      CAPTURE(drop_names[k]);
      const Scene scene = sheet_scene(drop_obstacles[k], R"({"damping": {"mass": 2.0}})");
      const Run runs[] = {run<LieSim<linear::Direct>>(scene, 360), run<LieSim<linear::DiagPcg>>(scene, 360),
                          run<LieSim<linear::SaPpcg>>(scene, 360)};  // 1.5 s
      for (const Run& r : runs) {
        MESSAGE(drop_names[k] << ": kinetic energy peak " << r.peak_kinetic << " J, after 1.5 s " << r.final_kinetic << " J; "
                              << r.last_contacts << " contacts");
        CHECK(r.max_depth <= 1e-9);
        CHECK(r.max_violation <= 1e-12);
        CHECK(r.last_contacts >= drop_min_contacts[k]);
        CHECK(r.final_kinetic <= 1e-3 * r.peak_kinetic);
      }
    }
  }
}
