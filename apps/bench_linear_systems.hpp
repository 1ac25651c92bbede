#pragma once
/// \file bench_linear_systems.hpp
/// The examples of thesis Table 11.1 (methods/multigrid §10.2) and the simulation that produces their
/// linear systems: a Baraff-Witkin linearly implicit step (one linear solve per step),
///   A = M + dt^2 H(x) [+ dt^2 K_springs],   b = dt M v - dt^2 (grad V(x) - f_gravity) + dt^2 f_springs,
/// unknown the position increment d = dt v_new. H is the sum of the PSD-projected element
/// Hessians of the StVK membrane and the theta hinge bending (so A is SPD). Pinned vertices
/// are fixed (d_i = 0) and box contacts are normal constraints, both through a
/// `ConstraintSet` that every solver receives with the positions (`SolveContext`).
///
/// Examples on a 1 m x 1 m cotton-like sheet (`ShellMaterial` defaults: 0.15 kg/m^2, Y 20 MPa,
/// nu 0.3, 0.3 mm), (m+1)^2 grid vertices, gravity, dt = 2 ms:
///   - pinned: the whole boundary pinned, the sheet starts flat at rest;
///   - drooping: the two sides u = +-0.5 pinned (the thesis does not say which two; these are
///     two opposite sides), the sheet starts flat at rest;
///   - re-entrant: the L-shape of `make_l_shape` (the (+u, +v) quadrant removed, so about 3/4
///     of the vertices), the two edges meeting at the re-entrant corner pinned;
///   - dropHorizontal: the flat sheet meets the top of a box (footprint 0.8 m x 0.8 m, a
///     0.3 m x 0.3 m square hole in the middle of its top, top at z = 0) at the moment of
///     impact, falling at 1 m/s (a 5 cm drop), so the few steps of a large mesh see contact;
///   - dropVertical: the same box; the sheet, dropped from vertical, is started pre-buckled:
///     its lower half folded into an accordion of horizontal layers (about 10 cm long,
///     stacked over the solid part of the top, spacing 4/pi mesh spacings, closer than the
///     repulsion distance), its upper half still vertical, everything falling at 1 m/s.
///
/// Box contact ("simple analytic box contact", top face only): a free vertex at or just below
/// the top (within 1 cm), inside the footprint and outside the hole, not moving up and not
/// released, gets the normal constraint n = +z with value top - z (it lands on the surface).
/// After the step, vertices that crossed the top there are projected onto it and their normal
/// velocity is zeroed; a contact whose constraint force pulled (n^T (A d - b) < 0) is released
/// for the next step (Baraff-Witkin 1998).
///
/// Cloth-cloth repulsion (dropVertical): a spring between every pair of vertices closer than
/// the repulsion distance h = 1.5 mesh spacings whose rest distance exceeds 3 h (not adjacent,
/// and not across the inside of a fold), found by a spatial hash with cell size h. Energy
/// k/2 (h - d)^2 with k = Y thickness (the membrane's stretch stiffness scale, 6000 N/m); its
/// PSD-projected Hessian k n n^T enters A implicitly (new off-diagonal blocks: the pattern
/// changes whenever the spring set does, and the solvers re-run analyze_pattern). After the
/// step, separating spring pairs lose their relative normal velocity (inelastic repulsion).
#include <Eigen/Core>

#include <array>
#include <cmath>
#include <cstddef>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "framework/block_csr.hpp"
#include "framework/constraints.hpp"
#include "framework/scene.hpp"
#include "framework/state.hpp"

namespace weft::app::benchlin {

enum class Example { pinned, drooping, reentrant, drop_horizontal, drop_vertical };
inline constexpr std::array<std::string_view, 5> example_names = {"pinned", "drooping", "re-entrant", "dropHorizontal",
                                                                  "dropVertical"};
/// Frames the thesis averaged over (methods/multigrid §10.1).
inline constexpr std::array<int, 5> thesis_frames = {10, 10, 10, 15, 25};

/// The box of the drop examples: top face at z = top, square footprint and square hole.
struct Box {
  double top = 0.0;          ///< [m]
  double half = 0.4;         ///< [m] half the footprint side
  double hole_half = 0.15;   ///< [m] half the side of the hole in the top
  /// (x, y) over the solid part of the top.
  bool over_top(double x, double y) const {
    const double ax = std::abs(x), ay = std::abs(y);
    return ax <= half && ay <= half && !(ax < hole_half && ay < hole_half);
  }
};

struct ExampleConfig {
  Example example = Example::pinned;
  Tessellation tessellation = Tessellation::regular;
  int m = 30;            ///< grid intervals per side: (m+1)^2 vertices (m even)
  double dt = 2e-3;      ///< [s]
  int seed = 1;          ///< irregular tessellation
  double drop_speed = 1.0;  ///< [m/s] initial downward speed of the drop examples
};

/// Counters of one step.
struct StepCounts {
  int pinned = 0;           ///< fixed vertices
  int box_contacts = 0;     ///< vertices with a box normal constraint
  int springs = 0;          ///< repulsion springs in A
  bool pattern_changed = false;  ///< A's pattern differs from the previous step's
  double detect_seconds = 0;     ///< contact and spring detection
  double assembly_seconds = 0;   ///< gradient, element Hessians, gather, springs, mass
  int projected = 0;        ///< vertices projected onto the box top after the step
  int released = 0;         ///< contacts released for the next step (pulling constraint force)
};

/// A running example: builds the system of the current step, then advances with the solution.
class LinearBenchSimulation {
 public:
  explicit LinearBenchSimulation(const ExampleConfig& cfg);
  ~LinearBenchSimulation();
  LinearBenchSimulation(const LinearBenchSimulation&) = delete;
  LinearBenchSimulation& operator=(const LinearBenchSimulation&) = delete;

  int num_vertices() const { return n_; }
  int num_faces() const;
  const ExampleConfig& config() const { return cfg_; }
  /// Detection (contacts, springs), then A, b and the constraints of the coming step.
  StepCounts build_system();
  const BlockCsr& A() const { return A_; }
  const Eigen::VectorXd& b() const { return b_; }
  const ConstraintSet& constraints() const { return constraints_; }
  const Eigen::VectorXd& positions() const { return state_.x; }
  SolveContext context() const { return {&constraints_, &state_.x}; }
  /// x += d, v = d / dt, then the post-step box projection and inelastic repulsion; fills
  /// `projected` and `released` of `counts`. Throws std::runtime_error on non-finite positions.
  void advance(const Eigen::VectorXd& d, StepCounts& counts);
  /// Repulsion distance and spring stiffness (dropVertical).
  double repulsion_distance() const { return h_rep_; }
  double spring_stiffness() const { return k_rep_; }
  const Box& box() const { return box_; }
  /// Bytes of the system matrix A (values and indices).
  std::size_t matrix_bytes() const;

 private:
  struct Models;
  void detect_springs();
  void rebuild_union_pattern();

  ExampleConfig cfg_;
  Scene scene_;
  std::unique_ptr<Models> models_;
  State state_;
  int n_ = 0;
  Box box_;
  double h_rep_ = 0, k_rep_ = 0;
  std::vector<unsigned char> pinned_, released_, in_contact_;
  ConstraintSet constraints_;
  BlockCsr H_;                 // element Hessians gathered (plan pattern)
  BlockCsr A_;                 // the system matrix (plan pattern, or the union with the springs)
  bool union_pattern_ = false; // A_ has the springs' union pattern
  std::vector<int> h_to_a_;    // block index of H_ in A_ (union pattern)
  std::vector<std::pair<int, int>> springs_, prev_springs_;
  Eigen::VectorXd b_, g_, mass3_;
  bool first_ = true;
};

}  // namespace weft::app::benchlin
