#pragma once
/// \file barrier.hpp
/// `Barrier`: codimensional incremental-potential contact (Li et al. 2020, "Incremental
/// Potential Contact", IPC; Li et al. 2021, "Codimensional Incremental Potential Contact",
/// C-IPC). Contact is a potential of the implicit solve, infinite where two primitives
/// touch, so that every iterate of the Newton iteration is intersection-free:
///
///   V_c(x) = sum_k kappa m_k(x) b(d_k(x)^2) + sum_k mu_k lambda_k f0(|u_k(x)|)
///
/// over the pairs within the contact thickness d_hat (barrier_potential.hpp: the barrier b,
/// the parallel-edge mollifier m, the smoothed friction f0).
///
/// **Pairs.** Cloth against itself: vertex-triangle and edge-edge pairs with no shared
/// vertex, except pairs of one cloth whose closest material points are within d_hat in its
/// rest state (neighbours on a mesh finer than d_hat). Cloth against obstacles posed at the end of
/// the step: triangle meshes (OBJ files) and boxes (their 12 triangles): cloth vertex
/// against obstacle triangle, obstacle vertex against cloth triangle, cloth edge against
/// obstacle edge; spheres: the sphere against every cloth triangle (gap = distance of the
/// centre to the triangle minus the radius); planes: against every cloth vertex.
///
/// **Admissible iterates** (IPC §4.4, "CCD-filtered line search"). The integrator asks
/// `step_bound(x, dx)` for every Newton direction (framework/concepts.hpp, HasStepBound):
/// the strategy gathers every pair that comes within d_hat anywhere on the segment x ->
/// x + dx (the collision detector's CCD with eta = 2 d_hat, which misses no pair within
/// d_hat; contact/detection/ccd.hpp), so that V_c is exact on that segment, and returns
/// the largest fraction of dx along which no pair's distance falls below a fifth of its
/// current value (or of d_hat, if smaller): the pair's CCD with eta = 0.2 min(d, d_hat)
/// guarantees it stays farther than half that. The line search then stays inside.
///
/// **Stiffness.** kappa = s m / (dt^2 d_hat^2) with s = `stiffness` and m the mean mass of a
/// free cloth vertex: the barrier's curvature at a fraction of d_hat is then of the order of
/// the mass term of the Newton matrix (the role of IPC's adaptive kappa, §4.3).
///
/// **Friction** (IPC §5): lagged from the start of the step. Every pair within d_hat at the
/// start positions keeps its normal force lambda there, its closest-point weights and a
/// tangent basis; the relative tangential displacement over the step, obstacles' own
/// motion included, enters f0 with eps = `friction_velocity` dt. mu is `cloth_friction`
/// for cloth pairs and the obstacle's `friction` otherwise.
///
/// **Hessian.** Per pair, exact (the twelve-coordinate dual numbers of
/// barrier_potential.cpp) or projected to positive semidefinite (HessianMode::projected).
/// Obstacle pairs land in three static groups of the assembly plan (cloth vertices,
/// edges, triangles); cloth pairs in a group of 4-vertex elements that follows the pairs
/// found on the predicted motion in `begin_step` (HasDynamicPattern); a cloth pair met
/// later in the step joins the group before the next Newton matrix (HasPatternRefresh: the
/// plan is finalised again and the linear solver's symbolic analysis redone). Without it,
/// such a pair could only give its diagonal blocks, and a block-diagonal barrier penalises
/// the pair's common motion by its full stiffness: Newton then crawls (measured on the
/// twisted sheet at 11 x 5: 100 iterations of 2e-4 m at step 794).
///
/// **Scripted obstacles** are posed at the end of the step throughout the solve, and the
/// step must start intersection-free against that pose: an obstacle that moves into the
/// cloth by more than the cloth's gap in one step fails the step with a message naming it
/// (a smaller dt, or `time.max_subdivisions`, then helps).
///
/// Pairs of one cloth excluded at rest (closer than d_hat in its rest shape) are neither in
/// the potential nor in the step bound: on a mesh finer than d_hat, or a rest shape with
/// panels closer than d_hat, the guarantee holds for the other pairs only. Choose d_hat below
/// the edge length and the rest shape's own gaps.
///
/// Reports: `contacts` (pairs within d_hat at the start), `barrier_pairs` and `min_gap` at
/// the end, `bounded_steps` (segments the CCD cut short: Newton directions and the initial
/// guess's free part), `pattern_updates` (pattern refreshes within the step).
#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <memory>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "contact/barrier_potential.hpp"
#include "framework/concepts.hpp"
#include "framework/params.hpp"
#include "framework/scene.hpp"

namespace weft::contact {

namespace detection {
class CollisionDetector;
}

class Barrier {
 public:
  static constexpr std::string_view name = "barrier";
  static constexpr bool provides_potential = true;
  static constexpr bool stateless = true;  ///< checkpoints: pairs, friction and poses are made afresh at each begin_step

  struct Params {
    double thickness = 1e-3;          ///< d_hat [m], > 0: the barrier acts on pairs closer than this
    double stiffness = 1.0;           ///< s > 0: kappa = s m / (dt^2 d_hat^2)
    double cloth_friction = 0.0;      ///< Coulomb coefficient of cloth-cloth contacts (cloth-obstacle: each obstacle's `friction`)
    double friction_velocity = 1e-3;  ///< eps_v [m/s] > 0: relative tangential speeds below it are treated as sticking
    bool self_contact = true;         ///< cloth-cloth contact
    template <class V>
    void visit(V& v) {
      v.field("thickness", thickness,
              {Unit::length, Range::gt(0), "contact thickness d_hat: the barrier acts on pairs closer than this"});
      v.field("stiffness", stiffness,
              {Unit::none, Range::gt(0), "barrier stiffness kappa = stiffness * (mean vertex mass) / (dt^2 thickness^2)"});
      v.field("cloth_friction", cloth_friction,
              {Unit::none, Range::ge(0), "Coulomb coefficient of cloth-cloth contacts (cloth-obstacle: obstacles.N.friction)"});
      v.field("friction_velocity", friction_velocity,
              {Unit::velocity, Range::gt(0), "smoothed friction: relative tangential speeds below this are treated as sticking"});
      v.field("self_contact", self_contact, {Unit::none, Range::any(), "cloth-cloth contact (off: obstacles only)"});
    }
    static Checker validate(const Params& p) {
      Checker c("contact");
      c.require(p.thickness > 0, "thickness", p.thickness, "> 0")
          .require(p.stiffness > 0, "stiffness", p.stiffness, "> 0")
          .require(p.cloth_friction >= 0, "cloth_friction", p.cloth_friction, ">= 0")
          .require(p.friction_velocity > 0, "friction_velocity", p.friction_velocity, "> 0");
      return c;
    }
  };

  /// One pair of the current list. Stencil entries with v[j] < 0 are obstacle positions
  /// (constant during the step), stored in `fixed`.
  struct Pair {
    barrier::PairKind kind = barrier::PairKind::point_triangle;
    std::array<int, 4> v{-1, -1, -1, -1};  ///< cloth vertex ids, -1 for an obstacle position
    barrier::Stencil fixed = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
                              Eigen::Vector3d::Zero()};  ///< obstacle positions (end-of-step pose)
    int obstacle = -1;                     ///< index into the scene's obstacles (-1: cloth-cloth)
    double eps_x = 0;                      ///< edge-edge mollifier threshold
    std::uint64_t key = 0;                 ///< (kind, primitive ids): identifies the pair across lists
    bool obstacle_first = false;           ///< side A (vertex or edge) is the obstacle's
    int element = -1;                      ///< the cloth triangle of a pair with three cloth vertices
  };

  /// \throws ConfigError for invalid parameters or obstacles it cannot handle.
  Barrier(const Scene& scene, const Params& prm);
  ~Barrier();
  Barrier(Barrier&&) noexcept;
  Barrier& operator=(Barrier&&) noexcept;

  void declare(AssemblyPlan& plan);
  ContactReport begin_step(const State& s, double dt);
  bool update_pattern(AssemblyPlan& plan);
  bool refresh_pattern(AssemblyPlan& plan);
  double energy(const State& s) const;
  void add_gradient(const State& s, Eigen::VectorXd& g) const;
  void add_hessian(const State& s, ElementBuffer& buf, HessianMode mode) const;
  double step_bound(const State& at, const Eigen::VectorXd& dx);
  ContactReport end_step(State& s, double dt);

  const Params& params() const { return prm_; }
  double kappa() const { return kappa_; }
  const std::vector<Pair>& pairs() const { return pairs_; }
  /// The pair's constants (thickness, stiffness, mollifier, radius, normal).
  barrier::PairConstants constants(const Pair& p) const;
  /// The pair's stencil at cloth positions x.
  barrier::Stencil stencil(const Pair& p, const Eigen::VectorXd& x) const;

 private:
  struct Obstacle;
  struct Contribution {
    int pair = -1;
    std::array<std::int8_t, 4> local{-1, -1, -1, -1};  // element-stencil position of each pair entry (-1: none)
  };
  // The pairs within d_hat anywhere on the segment x0 -> x1 (obstacles at their end pose).
  void collect(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1, std::vector<Pair>& out);
  // The largest fraction of the segment every pair of `pairs_` admits.
  double bound(const Eigen::VectorXd& x0, const Eigen::VectorXd& x1) const;
  // Element contributions of `pairs_` for the Hessian assembly.
  void index_contributions();
  bool excluded_at_rest(const Pair& p) const;

  Params prm_;
  std::vector<ObstacleSpec> specs_;
  std::vector<Obstacle> obstacles_;
  std::unique_ptr<detection::CollisionDetector> detector_;
  Eigen::MatrixX3i faces_;
  std::vector<std::array<int, 2>> edges_;
  Eigen::VectorXd rest_;
  std::vector<int> cloth_of_;         // per vertex: its cloth (rest-state exclusion within one cloth only)
  std::vector<double> edge_rest_sq_;  // |e_rest|^2 per cloth edge
  int num_vertices_ = 0;
  double kappa_ = 0;
  Eigen::VectorXd x0_;  // start of the step (friction displacements)
  std::vector<Pair> pairs_;
  std::vector<Pair> friction_pairs_;
  std::vector<barrier::FrictionPair> friction_;
  int bounded_steps_ = 0;
  int pattern_refreshes_ = 0;
  bool pattern_stale_ = false;  // pairs_ has cloth pairs the self group lacks
  // Assembly: groups and the element of each contribution.
  int vertex_group_ = -1, edge_group_ = -1, triangle_group_ = -1, self_group_ = -1;
  std::vector<int> self_ids_, declared_self_;          // pattern of the self group
  std::unordered_map<std::uint64_t, int> self_element_;  // pair key -> element of the self group
  std::unordered_map<std::uint64_t, int> edge_of_;       // (i, j) -> cloth edge id
  std::array<std::vector<int>, 4> first_;               // per group kind: CSR offsets over elements
  std::array<std::vector<Contribution>, 4> items_;
  mutable std::vector<barrier::Mat12> hess_;             // per pair, filled by add_hessian
};

static_assert(ContactStrategy<Barrier>);
static_assert(HasDynamicPattern<Barrier>);
static_assert(HasStepBound<Barrier>);
static_assert(HasPatternRefresh<Barrier>);

}  // namespace weft::contact
