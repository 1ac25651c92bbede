#include "apps/bench_linear_systems.hpp"

#include "apps/bench_common.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <stdexcept>

#include "framework/error.hpp"
#include "framework/mesh_generators.hpp"
#include "models/hinge_bending.hpp"
#include "models/stvk_membrane.hpp"

namespace weft::app::benchlin {
namespace {


const Eigen::Vector3d gravity(0, 0, -9.81);

/// A unit-speed planar curve in the (y, z) plane made of straight pieces and circular arcs
/// (turtle graphics), evaluated by arc length; beyond its end it continues straight.
class Path {
 public:
  Path(Eigen::Vector2d start, double heading) : p0_(std::move(start)), phi0_(heading) {}
  void straight(double length) { pieces_.push_back({length, 0, 0}); }
  /// Arc of `radius` turning by `angle` (> 0), counter-clockwise for turn = +1.
  void arc(double radius, double angle, int turn) { pieces_.push_back({radius * angle, radius, turn}); }
  double length() const {
    double l = 0;
    for (const auto& p : pieces_) l += p.length;
    return l;
  }
  Eigen::Vector2d at(double s) const {
    Eigen::Vector2d p = p0_;
    double phi = phi0_;
    for (const auto& pc : pieces_) {
      const double t = std::min(s, pc.length);
      advance(pc, t, p, phi);
      s -= t;
      if (s <= 0) return p;
    }
    return p + s * Eigen::Vector2d(std::cos(phi), std::sin(phi));
  }

 private:
  struct Piece {
    double length, radius;
    int turn;  // 0: straight
  };
  static void advance(const Piece& pc, double t, Eigen::Vector2d& p, double& phi) {
    if (pc.turn == 0) {
      p += t * Eigen::Vector2d(std::cos(phi), std::sin(phi));
      return;
    }
    const double r = pc.radius, sg = pc.turn;
    const Eigen::Vector2d c = p + r * sg * Eigen::Vector2d(-std::sin(phi), std::cos(phi));
    phi += sg * t / r;
    p = c + r * sg * Eigen::Vector2d(std::sin(phi), -std::cos(phi));
  }
  Eigen::Vector2d p0_;
  double phi0_;
  std::vector<Piece> pieces_;
};

/// Pairs i < j with ||x_i - x_j|| < h and rest distance > min_rest, by a uniform grid of
/// cell size h (sorted cell keys; a vertex looks at the 27 cells around its own). Sorted.
std::vector<std::pair<int, int>> close_pairs(const Eigen::VectorXd& x, const Eigen::MatrixX3d& rest, double h,
                                             double min_rest) {
  const int n = static_cast<int>(x.size() / 3);
  if (n == 0) return {};
  Eigen::Vector3d lo = x.segment<3>(0), hi = lo;
  for (int i = 1; i < n; ++i) lo = lo.cwiseMin(x.segment<3>(3 * i)), hi = hi.cwiseMax(x.segment<3>(3 * i));
  const std::int64_t nx = static_cast<std::int64_t>((hi[0] - lo[0]) / h) + 1, ny = static_cast<std::int64_t>((hi[1] - lo[1]) / h) + 1,
                     nz = static_cast<std::int64_t>((hi[2] - lo[2]) / h) + 1;
  auto cell = [&](int i) {
    return std::array<std::int64_t, 3>{static_cast<std::int64_t>((x[3 * i] - lo[0]) / h), static_cast<std::int64_t>((x[3 * i + 1] - lo[1]) / h),
                                       static_cast<std::int64_t>((x[3 * i + 2] - lo[2]) / h)};
  };
  auto key = [&](std::int64_t ix, std::int64_t iy, std::int64_t iz) { return ix + nx * (iy + ny * iz); };
  std::vector<std::pair<std::int64_t, int>> keys(n);
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i) {
    const auto c = cell(i);
    keys[i] = {key(c[0], c[1], c[2]), i};
  }
  std::sort(keys.begin(), keys.end());
  const double h2 = h * h, r2 = min_rest * min_rest;
  std::vector<std::pair<int, int>> pairs;
#pragma omp parallel
  {
    std::vector<std::pair<int, int>> local;
#pragma omp for schedule(dynamic, 1024)
    for (int i = 0; i < n; ++i) {
      const auto c = cell(i);
      const Eigen::Vector3d xi = x.segment<3>(3 * i);
      const Eigen::Vector3d Xi = rest.row(i).transpose();
      for (std::int64_t dz = -1; dz <= 1; ++dz)
        for (std::int64_t dy = -1; dy <= 1; ++dy) {
          const std::int64_t iy = c[1] + dy, iz = c[2] + dz;
          if (iy < 0 || iy >= ny || iz < 0 || iz >= nz) continue;
          const std::int64_t k0 = key(std::max<std::int64_t>(0, c[0] - 1), iy, iz), k1 = key(std::min(nx - 1, c[0] + 1), iy, iz);
          auto it = std::lower_bound(keys.begin(), keys.end(), std::pair<std::int64_t, int>{k0, -1});
          for (; it != keys.end() && it->first <= k1; ++it) {
            const int j = it->second;
            if (j <= i) continue;
            if ((x.segment<3>(3 * j) - xi).squaredNorm() >= h2) continue;
            if ((rest.row(j).transpose() - Xi).squaredNorm() <= r2) continue;
            local.emplace_back(i, j);
          }
        }
    }
#pragma omp critical
    pairs.insert(pairs.end(), local.begin(), local.end());
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

}  // namespace

struct LinearBenchSimulation::Models {
  models::StvkMembrane<models::Isotropic> membrane;
  models::HingeBending<models::ThetaEnergy> bending;
  AssemblyPlan plan;
  ElementBuffer buf;
  // Bending projected per hinge by eigen-decomposition: the systems of bench/results/table-11-1.
  Models(const Scene& s) : membrane(s, {}), bending(s, {.projection = models::BendingProjection::eigen}) {}
};

LinearBenchSimulation::LinearBenchSimulation(const ExampleConfig& cfg) : cfg_(cfg) {
  if (cfg.m < 2 || cfg.m % 2) throw ConfigError(fmt::format("bench linear: m = {} must be even and >= 2", cfg.m));
  const MeshData gen = cfg.example == Example::reentrant
                           ? make_l_shape(Eigen::Vector2d(1, 1), {cfg.m + 1, cfg.m + 1}, cfg.tessellation, cfg.seed)
                           : make_rectangle(Eigen::Vector2d(1, 1), {cfg.m + 1, cfg.m + 1}, cfg.tessellation, cfg.seed);
  // A scene built in code: one cloth with the default (cotton-like) material and the thesis'
  // bending constant k = D / 2 (its Table 11.1 systems).
  scene_.mesh = TriangleMesh(gen.V, gen.F);
  ClothSpec cloth;
  cloth.name = "sheet";
  cloth.material.bending_calibration = BendingCalibration::thesis;
  scene_.spec.cloths.push_back(cloth);
  n_ = scene_.mesh.num_vertices();
  const int nf = scene_.mesh.num_faces();
  scene_.face_cloth.assign(nf, 0);
  scene_.cloth_vertex_offset = {0, n_};
  scene_.cloth_face_offset = {0, nf};
  scene_.dof.assign(n_, Dof::free);
  scene_.vertex_motion.assign(n_, -1);

  models_ = std::make_unique<Models>(scene_);
  models_->membrane.declare(models_->plan);
  models_->bending.declare(models_->plan);
  models_->plan.finalize(n_);
  models_->buf = models_->plan.make_buffer();
  A_ = models_->plan.pattern();

  state_.mass = scene_.lumped_masses();
  state_.dof = scene_.dof;
  state_.x.resize(3 * n_);
  state_.v = Eigen::VectorXd::Zero(3 * n_);
  mass3_.resize(3 * n_);
  for (int i = 0; i < n_; ++i) mass3_.segment<3>(3 * i).setConstant(state_.mass[i]);
  const Eigen::MatrixX3d& X = scene_.mesh.rest();
  for (int i = 0; i < n_; ++i) state_.x.segment<3>(3 * i) = X.row(i).transpose();

  const double delta = 1.0 / cfg.m;  // mesh spacing
  const ShellMaterial& mat = scene_.spec.cloths[0].material;
  h_rep_ = 1.5 * delta;
  k_rep_ = mat.youngs_modulus * mat.thickness;

  pinned_.assign(n_, 0);
  released_.assign(n_, 0);
  in_contact_.assign(n_, 0);
  constexpr double eps = 1e-9;
  for (int i = 0; i < n_; ++i) {
    const double u = X(i, 0), v = X(i, 1);
    const bool left = u < -0.5 + eps, right = u > 0.5 - eps, bottom = v < -0.5 + eps, top = v > 0.5 - eps;
    switch (cfg.example) {
      case Example::pinned: pinned_[i] = left || right || bottom || top; break;
      case Example::drooping: pinned_[i] = left || right; break;
      case Example::reentrant: pinned_[i] = (std::abs(u) < eps && v > -eps) || (std::abs(v) < eps && u > -eps); break;
      default: break;
    }
  }

  if (cfg.example == Example::drop_horizontal) {
    for (int i = 0; i < n_; ++i) {
      state_.x[3 * i + 2] = box_.top;
      state_.v[3 * i + 2] = -cfg.drop_speed;
    }
  } else if (cfg.example == Example::drop_vertical) {
    // Accordion: layers of length L (a multiple of the spacing, about 10 cm) joined by
    // semicircles of radius 2 delta / pi (arc = 2 spacings, layer spacing 4 delta / pi <
    // h_rep), stacked from the top of the box over its solid part; the lower half of the
    // sheet (v from -0.5) is folded, the rest rises vertically.
    const double r = 2 * delta / std::numbers::pi;
    const double L = std::max(2.0, std::round(0.1 / delta)) * delta;
    const int layers = std::max(2, static_cast<int>(std::floor(0.5 / (L + 2 * delta))));
    Path path(Eigen::Vector2d(0.2, box_.top), 0.0);
    for (int k = 0; k < layers; ++k) {
      path.straight(L);
      const int turn = k % 2 == 0 ? +1 : -1;
      if (k + 1 < layers) path.arc(r, std::numbers::pi, turn);
      else path.arc(r, 0.5 * std::numbers::pi, turn);
    }
    for (int i = 0; i < n_; ++i) {
      const Eigen::Vector2d yz = path.at(X(i, 1) + 0.5);
      state_.x.segment<3>(3 * i) = Eigen::Vector3d(X(i, 0), yz[0], yz[1]);
      state_.v[3 * i + 2] = -cfg.drop_speed;
    }
  }
  for (int i = 0; i < n_; ++i)
    if (pinned_[i]) state_.v.segment<3>(3 * i).setZero();
  constraints_.reset(n_);
  b_.resize(3 * n_);
  g_.resize(3 * n_);
}

LinearBenchSimulation::~LinearBenchSimulation() = default;

int LinearBenchSimulation::num_faces() const { return scene_.mesh.num_faces(); }

std::size_t LinearBenchSimulation::matrix_bytes() const {
  return static_cast<std::size_t>(A_.num_blocks()) * (72 + 4) + static_cast<std::size_t>(A_.block_rows() + 1) * 8;
}

void LinearBenchSimulation::rebuild_union_pattern() {
  const BlockCsr& P = models_->plan.structure();
  std::vector<std::vector<int>> cols(n_);
  for (int i = 0; i < n_; ++i) cols[i].assign(P.col().begin() + P.row_ptr()[i], P.col().begin() + P.row_ptr()[i + 1]);
  for (const auto& [i, j] : springs_) cols[i].push_back(j), cols[j].push_back(i);
  for (auto& c : cols) {
    std::sort(c.begin(), c.end());
    c.erase(std::unique(c.begin(), c.end()), c.end());
  }
  A_ = BlockCsr(cols);
  cols = {};
  h_to_a_.resize(P.num_blocks());
  for (int i = 0; i < n_; ++i)
    for (int k = P.row_ptr()[i]; k < P.row_ptr()[i + 1]; ++k) h_to_a_[k] = A_.find(i, P.col()[k]);
  union_pattern_ = true;
}

StepCounts LinearBenchSimulation::build_system() {
  StepCounts c;
  auto t0 = Clock::now();
  const Eigen::VectorXd& x = state_.x;
  const Eigen::VectorXd& v = state_.v;
  // Constraints: pins, then box contacts.
  constraints_.reset(n_);
  std::fill(in_contact_.begin(), in_contact_.end(), 0);
  for (int i = 0; i < n_; ++i)
    if (pinned_[i]) constraints_.fix(i, Eigen::Vector3d::Zero()), ++c.pinned;
  if (cfg_.example == Example::drop_horizontal || cfg_.example == Example::drop_vertical) {
    for (int i = 0; i < n_; ++i) {
      if (pinned_[i] || released_[i]) continue;
      const double z = x[3 * i + 2];
      if (z > box_.top + 1e-9 || z < box_.top - 0.01 || v[3 * i + 2] > 0) continue;
      if (!box_.over_top(x[3 * i], x[3 * i + 1])) continue;
      constraints_.add_direction(i, Eigen::Vector3d::UnitZ(), box_.top - z);
      in_contact_[i] = 1;
      ++c.box_contacts;
    }
  }
  // Repulsion springs; a new spring set means a new pattern.
  if (cfg_.example == Example::drop_vertical) {
    springs_ = close_pairs(x, scene_.mesh.rest(), h_rep_, 3 * h_rep_);
    if (first_ || springs_ != prev_springs_) {
      if (!springs_.empty()) {
        rebuild_union_pattern();
        c.pattern_changed = true;
      } else if (union_pattern_) {
        A_ = models_->plan.pattern();
        union_pattern_ = false;
        c.pattern_changed = true;
      }
      prev_springs_ = springs_;
    }
  }
  c.springs = static_cast<int>(springs_.size());
  if (first_) c.pattern_changed = true;
  first_ = false;
  c.detect_seconds = seconds_since(t0);

  // Assembly: A = M + dt^2 (H + K_springs), b = dt M v + dt^2 (f_elastic + f_gravity + f_springs).
  t0 = Clock::now();
  const double dt = cfg_.dt;
  g_.setZero();
  models_->membrane.add_gradient(state_, g_);
  models_->bending.add_gradient(state_, g_);
  // Element Hessians go straight into the block matrix (direct assembly: no element storage).
  if (union_pattern_ && H_.num_blocks() != models_->plan.structure().num_blocks()) H_ = models_->plan.pattern();
  BlockCsr& target = union_pattern_ ? H_ : A_;
  models_->buf.start(target);
  models_->membrane.add_hessian(state_, models_->buf, HessianMode::projected);
  models_->bending.add_hessian(state_, models_->buf, HessianMode::projected);
  models_->buf.finish();
  if (!union_pattern_) {
    A_.scale(dt * dt);
  } else {
    A_.set_zero();
    double* a = A_.values().data();
    const double* h = H_.values().data();
    const int nb = H_.num_blocks();
#pragma omp parallel for schedule(static)
    for (int k = 0; k < nb; ++k)
      for (int q = 0; q < 9; ++q) a[9 * static_cast<std::size_t>(h_to_a_[k]) + q] = dt * dt * h[9 * static_cast<std::size_t>(k) + q];
    // Springs: E = k/2 (h - d)^2 for d < h; grad_i = -k (h - d) n; PSD Hessian k n n^T.
    for (const auto& [i, j] : springs_) {
      const Eigen::Vector3d e = x.segment<3>(3 * i) - x.segment<3>(3 * j);
      const double d = e.norm();
      if (!(d > 0)) continue;
      const Eigen::Vector3d nrm = e / d;
      const Block3 B = dt * dt * k_rep_ * nrm * nrm.transpose();
      A_.block(A_.diagonal(i)) += B;
      A_.block(A_.diagonal(j)) += B;
      A_.block(A_.find(i, j)) -= B;
      A_.block(A_.find(j, i)) -= B;
      const Eigen::Vector3d f = k_rep_ * (h_rep_ - d) * nrm;  // on i; -f on j
      g_.segment<3>(3 * i) -= f;
      g_.segment<3>(3 * j) += f;
    }
  }
  A_.add_diagonal(mass3_);
  // Pinned rows decoupled as the simulator's step system does (diagonal tr(A_ii)/3): every
  // solver sees the same matrix, and PPCG needs no prefiltered copy for the pins.
  A_.filter_rows(pinned_, -1.0);
  for (int i = 0; i < n_; ++i)
    b_.segment<3>(3 * i) = dt * state_.mass[i] * v.segment<3>(3 * i) - dt * dt * (g_.segment<3>(3 * i) - state_.mass[i] * gravity);
  c.assembly_seconds = seconds_since(t0);
  return c;
}

void LinearBenchSimulation::advance(const Eigen::VectorXd& d, StepCounts& c) {
  const double dt = cfg_.dt;
  if (!d.allFinite()) throw std::runtime_error("bench linear: the step increment is not finite");
  // Release contacts whose constraint force pulled the vertex onto the top.
  std::fill(released_.begin(), released_.end(), 0);
  if (c.box_contacts > 0) {
    Eigen::VectorXd r;
    A_.multiply(d, r);
    r -= b_;
    for (int i = 0; i < n_; ++i)
      if (in_contact_[i] && r[3 * i + 2] < 0) released_[i] = 1, ++c.released;
  }
  const Eigen::VectorXd x_prev = state_.x;
  state_.x += d;
  state_.v = d / dt;
  state_.t += dt;
  if (cfg_.example == Example::drop_horizontal || cfg_.example == Example::drop_vertical) {
    for (int i = 0; i < n_; ++i) {
      double& z = state_.x[3 * i + 2];
      if (z >= box_.top || x_prev[3 * i + 2] < box_.top - 1e-9) continue;
      if (!box_.over_top(state_.x[3 * i], state_.x[3 * i + 1])) continue;
      z = box_.top;
      state_.v[3 * i + 2] = 0;
      ++c.projected;
    }
  }
  // Inelastic repulsion: spring pairs do not separate faster than they touched.
  for (const auto& [i, j] : springs_) {
    const Eigen::Vector3d e = state_.x.segment<3>(3 * i) - state_.x.segment<3>(3 * j);
    const double dist = e.norm();
    if (!(dist > 0)) continue;
    const Eigen::Vector3d nrm = e / dist;
    const double vrel = nrm.dot(state_.v.segment<3>(3 * i) - state_.v.segment<3>(3 * j));
    if (vrel <= 0) continue;
    const double mi = state_.mass[i], mj = state_.mass[j];
    state_.v.segment<3>(3 * i) -= vrel * mj / (mi + mj) * nrm;
    state_.v.segment<3>(3 * j) += vrel * mi / (mi + mj) * nrm;
  }
  if (!state_.x.allFinite()) throw std::runtime_error("bench linear: positions are not finite");
}

}  // namespace weft::app::benchlin
