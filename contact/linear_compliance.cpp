#include "contact/linear_compliance.hpp"

#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>

#include "contact/detection/collision_detector.hpp"
#include "framework/timers.hpp"

namespace weft::contact {

using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

/// One contact of the GS solve: stencil (count vertices; -1 for fixed ones, which have no
/// column in H), weights, frame (rows: normal, tangent, tangent), free velocity, mu.
struct Row {
  std::array<int, 4> v{-1, -1, -1, -1};
  std::array<double, 4> gamma{};
  int count = 0;
  Matrix3d frame = Matrix3d::Identity();
  Vector3d free_velocity = Vector3d::Zero();
  double mu = 0;
};

/// Orthonormal frame with n as its first row.
Matrix3d frame_of(const Vector3d& n) {
  const Vector3d a = std::abs(n.x()) < 0.6 ? Vector3d::UnitX() : Vector3d::UnitY();
  const Vector3d t1 = n.cross(a).normalized();
  const Vector3d t2 = n.cross(t1);
  Matrix3d F;
  F.row(0) = n.transpose();
  F.row(1) = t1.transpose();
  F.row(2) = t2.transpose();
  return F;
}

}  // namespace

LinearCompliance::LinearCompliance(const Scene& scene, const Params& prm) : prm_(prm), obstacles_(scene.spec.obstacles) {
  Params::validate(prm_).throw_if_failed(fmt::format("{}: invalid contact configuration:", scene.path));
  failsafe_ = std::make_unique<Impulse>(scene, prm_.impulse);
  rest_.resize(3 * scene.mesh.num_vertices());
  for (int i = 0; i < scene.mesh.num_vertices(); ++i) rest_.segment<3>(3 * i) = scene.mesh.rest().row(i).transpose();
  if (prm_.impulse.self_contact && scene.mesh.num_faces() > 0) {
    detection::CollisionDetectorParams d;
    d.margin = 0.5 * prm_.impulse.thickness;
    d.self_contact = true;
    d.proximity.edge_edge_interior_only = true;  // endpoint pairs are found as vertex-triangle pairs
    detector_ = std::make_unique<detection::CollisionDetector>(scene.mesh, d);
  }
}

LinearCompliance::~LinearCompliance() = default;
LinearCompliance::LinearCompliance(LinearCompliance&&) noexcept = default;
LinearCompliance& LinearCompliance::operator=(LinearCompliance&&) noexcept = default;

ContactReport LinearCompliance::begin_step(const State& s, double dt) {
  x0_ = s.x;
  t0_ = s.t;
  started_ = true;
  has_system_ = false;
  system_ = {};
  return failsafe_->begin_step(s, dt);
}

void LinearCompliance::accept_system(const SystemSolve& s) {
  system_ = s;
  has_system_ = s.matrix != nullptr && (s.solve || prm_.own_factorization);
}

ContactReport LinearCompliance::end_step(State& out, double dt) {
  ContactReport rep;
  const auto start = std::chrono::steady_clock::now();
  report_ = {};
  const int n = out.num_vertices();
  if (!started_ || x0_.size() != out.x.size()) {
    rep.status = Status::invalid_input;
    rep.message = "linear compliance contact: end_step() without a matching begin_step()";
    return rep;
  }
  started_ = false;
  const double h = prm_.impulse.thickness;
  Eigen::VectorXd& v = out.v;
  const Eigen::VectorXd x1 = out.x;

  // 1. Contacts at the end positions.
  std::vector<Row> rows;
  std::vector<ObstaclePose> p0, p1;
  for (const ObstacleSpec& spec : obstacles_) {
    p0.push_back(ObstaclePose::at(spec, t0_));
    p1.push_back(ObstaclePose::at(spec, t0_ + dt));
  }
  for (int i = 0; i < n; ++i) {
    if (!out.is_free(i)) continue;
    const Vector3d xi = x1.segment<3>(3 * i);
    for (size_t k = 0; k < obstacles_.size(); ++k) {
      const Distance d = p1[k].distance(xi);
      if (!(d.phi < h)) continue;
      Row r;
      r.v[0] = i;
      r.gamma[0] = 1;
      r.count = 1;
      r.frame = frame_of(d.grad);
      Vector3d w = Vector3d::Zero();  // the obstacle's velocity at the contact point
      if (!obstacles_[k].motion.is_static()) {
        const Vector3d p = xi - d.phi * d.grad;
        const Vector3d y = p1[k].rotation.transpose() * (p - p1[k].center);
        w = (p - (p0[k].center + p0[k].rotation * y)) / dt;
      }
      r.free_velocity = r.frame * (v.segment<3>(3 * i) - w);
      r.free_velocity[0] = -(h - d.phi) / dt;
      r.mu = obstacles_[k].friction;
      rows.push_back(r);
    }
  }
  report_.obstacle_contacts = static_cast<int>(rows.size());
  if (detector_) {
    ScopedTimer t(rep.detection_seconds);
    detector_->update(x0_, x1);
    const auto pairs = detector_->proximity(x1, h);
    for (const auto& p : pairs) {
      Vector3d g0 = Vector3d::Zero(), g1 = Vector3d::Zero(), g_rest = Vector3d::Zero(), gv = Vector3d::Zero();
      for (int j = 0; j < 4; ++j) {
        g0 += p.geometry.gamma[j] * x0_.segment<3>(3 * p.v[j]);
        g1 += p.geometry.gamma[j] * x1.segment<3>(3 * p.v[j]);
        g_rest += p.geometry.gamma[j] * rest_.segment<3>(3 * p.v[j]);
        gv += p.geometry.gamma[j] * v.segment<3>(3 * p.v[j]);
      }
      const Vector3d& nrm = p.geometry.normal;
      if (nrm.dot(g0) <= 0) continue;  // crossed during the step: the failsafe's CCD
      if (g_rest.norm() < h) continue;  // material points this close at rest: no contact
      Row r;
      for (int j = 0; j < 4; ++j)
        if (out.is_free(p.v[j]) && p.geometry.gamma[j] != 0) {
          r.v[r.count] = p.v[j];
          r.gamma[r.count] = p.geometry.gamma[j];
          ++r.count;
        }
      if (r.count == 0) continue;  // only fixed vertices: nothing to move
      r.frame = frame_of(nrm);
      r.free_velocity = r.frame * gv;
      r.free_velocity[0] = (nrm.dot(g1) - h) / dt;
      r.mu = prm_.impulse.cloth_friction;
      rows.push_back(r);
    }
  }
  const int m = static_cast<int>(rows.size());
  report_.cloth_contacts = m - report_.obstacle_contacts;

  if (m > 0) {
    // The compliance D: A^-1 (own LDL^T or the step's solver), or M^-1 without a system.
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower> ldlt;
    bool own = false;
    report_.compliance = has_system_;
    if (has_system_ && prm_.own_factorization) {
      ldlt.compute(system_.matrix->to_sparse(/*lower_only=*/true));
      own = ldlt.info() == Eigen::Success;
      if (!own) report_.compliance = system_.solve != nullptr;
    }
    Eigen::VectorXd xs;
    auto apply_d = [&](Eigen::VectorXd& y) {  // y <- D y (fixed rows ignored)
      ++report_.solves;
      out.zero_constrained(y);
      if (own) {
        y = ldlt.solve(y).eval();
      } else if (report_.compliance) {
        xs.setZero(y.size());
        system_.solve(y, xs);
        y = xs;
      } else {
        for (int i = 0; i < n; ++i) y.segment<3>(3 * i) /= out.mass[i];
      }
      out.zero_constrained(y);
    };
    auto add_transpose = [&](const Row& r, const Vector3d& local, Eigen::VectorXd& y) {  // y += H_k^T local
      const Vector3d f = r.frame.transpose() * local;
      for (int j = 0; j < r.count; ++j) y.segment<3>(3 * r.v[j]) += r.gamma[j] * f;
    };
    auto apply_h = [&](const Row& r, const Eigen::VectorXd& y) {  // H_k y
      Vector3d g = Vector3d::Zero();
      for (int j = 0; j < r.count; ++j) g += r.gamma[j] * y.segment<3>(3 * r.v[j]);
      return Vector3d(r.frame * g);
    };

    // 2. W = H D H^T, column by column.
    Eigen::MatrixXd W(3 * m, 3 * m);
    Eigen::VectorXd col(3 * n);
    for (int k = 0; k < m; ++k)
      for (int c = 0; c < 3; ++c) {
        col.setZero();
        add_transpose(rows[k], Vector3d::Unit(c), col);
        apply_d(col);
        for (int l = 0; l < m; ++l) W.block<3, 1>(3 * l, 3 * k + c) = apply_h(rows[l], col);
      }
    W = (0.5 * (W + W.transpose())).eval();  // symmetric up to the solver's rounding
    Eigen::VectorXd uf(3 * m);
    std::vector<double> mu(m);
    for (int k = 0; k < m; ++k) {
      uf.segment<3>(3 * k) = rows[k].free_velocity;
      mu[k] = rows[k].mu;
    }

    // 3. Gauss-Seidel.
    DenseDelassus op(std::move(W), uf);
    GaussSeidelParams gs;
    gs.tolerance = prm_.tolerance;
    gs.max_sweeps = prm_.max_sweeps;
    std::vector<Vector3d> r;
    report_.gauss_seidel = gauss_seidel(op, mu, r, gs);
    report_.residual = report_.gauss_seidel.residual;
    if (!report_.gauss_seidel.converged && prm_.solver == ContactSolver::newton) {
      report_.newton = solve_contacts_newton(op, mu, r, {.tolerance = prm_.tolerance, .max_iterations = prm_.solver_max});
      report_.residual = report_.newton.residual;
    }
    report_.converged = report_.residual <= prm_.tolerance;

    // 4. v += D H^T r on the free vertices, x1 = x0 + dt v.
    Eigen::VectorXd dv = Eigen::VectorXd::Zero(3 * n);
    for (int k = 0; k < m; ++k) add_transpose(rows[k], r[k], dv);
    apply_d(dv);
    for (int i = 0; i < n; ++i)
      if (out.is_free(i)) {
        v.segment<3>(3 * i) += dv.segment<3>(3 * i);
        out.x.segment<3>(3 * i) = x0_.segment<3>(3 * i) + dt * v.segment<3>(3 * i);
      }
    report_.responses = std::move(r);
    for (int k = 0; k < report_.obstacle_contacts; ++k) {  // obstacle rows come first, in vertex-obstacle order
      const int i = rows[k].v[0];
      for (size_t o = 0; o < obstacles_.size(); ++o)
        report_.solve_penetration = std::max(report_.solve_penetration, h - p1[o].distance(out.x.segment<3>(3 * i)).phi);
    }
  }
  has_system_ = false;
  system_ = {};

  // 5. The failsafe.
  ContactReport f = failsafe_->end_step(out, dt);
  rep.merge_end(f);
  rep.contacts = m + f.ccd_hits;
  rep.obstacle_contacts = report_.obstacle_contacts;
  rep.proximity_contacts = report_.cloth_contacts;
  const GaussSeidelReport& g = report_.gauss_seidel;
  if (m > 0) {
    rep.gs_sweeps = g.sweeps + report_.newton.sweeps;
    rep.gs_residual = report_.residual;
    rep.gs_unconverged = report_.converged ? 0 : 1;
    rep.contact_newton = report_.newton.iterations;
    rep.contact_fallbacks = report_.newton.fallbacks;
  }
  if (rep.status == Status::success && m > 0 && !report_.converged)
    rep.message = fmt::format("linear compliance: the contact solve did not converge: {} contacts, {} sweeps, {} Newton steps, "
                              "FB residual {:.3g} m/s (tolerance {:.3g}); the failsafe corrected the rest",
                              m, g.sweeps, report_.newton.iterations, report_.residual, prm_.tolerance);
  rep.response_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() - rep.detection_seconds;
  return rep;
}

}  // namespace weft::contact
