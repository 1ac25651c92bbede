#pragma once
/// \file rod_backward_euler.hpp
/// `RodBackwardEuler`: the unconstrained time step of one elastic rod (methods/rod-contact §3), backward
/// Euler in displacement form solved as the minimisation of the incremental potential
///     E_inc(d) = 1/2 d^T M d - h d^T M v + h^2 (V(q + d) - f_ext^T d),
/// whose gradient is the DEL residual f(d) = M d - h M v + h^2 (grad V(q + d) - f_ext)
/// and whose Hessian is K(d) = M + h^2 H(q + d). Newton with a backtracking (Armijo) line
/// search on E_inc over the rod's free DoFs; the held DoFs (a scripted root) are set to
/// their targets first and their rows decoupled. Rods are independent systems: the rod
/// simulator runs one solve per rod, in parallel.
///
/// The exact Hessian is tried first; when it does not give a descent direction (or its
/// factorisation fails) the step is recomputed with the per-stencil PSD projection. The
/// iteration stops when the largest vertex move of the full Newton step K^-1 f is below
/// `tolerance` times the rod's mean rest edge length: the residual measured in metres
/// through K^-1, scale-free and insensitive to the conditioning of K (|f| itself is reported
/// as well). It fails after `max_iterations`, or when the line search cannot decrease E_inc.
///
/// Large steps. A hair is nearly inextensible (h^2 k_stretch / m ~ 1e7 at 30 ms),
/// so at large h the minimiser is reached by rotating edges through large angles. A Newton
/// step moves vertices along straight lines: rotating an edge of length l by phi that way
/// stretches it by l phi^2 / 2, which the stiff stretching energy punishes, so Armijo cut
/// every step and Newton crept along the curved valley of constant edge lengths (on the whip
/// at 20 rad/s: 146 iterations per step on average at h = 100 ms, and the 50-iteration cap
/// was hit from h = 30 ms; with the start-of-step guess d = h v the held root's rotation
/// over one step also stretched the first free edge by 300-400 %). The two remedies, both
/// on by default and both leaving the problem (E_inc, exact derivatives, tolerance) as it is:
///   - `arc_step`: the line search follows the curve d(s) on which every edge e_j = l t_j is
///     rotated by s omega_j (omega_j = t_j x de_j^perp / l, the transverse part of the Newton
///     direction's edge change de_j) and its length changed by s a_j (a_j = t_j . de_j; for
///     a_j < 0, l exp(s a_j / l) keeps it positive); the vertices are rebuilt from the first
///     one by summing edges, held DoFs and twists move linearly. d'(0) is the Newton
///     direction, so Armijo, the descent test and local quadratic convergence are those of
///     Newton; only the path bends with the edges (a retraction onto constant lengths, the
///     geometric counterpart of a second-order correction against the Maratos effect).
///   - `follow_the_leader`: the initial guess d = h v (held DoFs at their targets) is also
///     projected, from the root outwards, onto the start-of-step edge lengths (each free
///     vertex placed at its edge's length from its already placed predecessor, in the
///     guess's direction); Newton starts from whichever of the two has the lower E_inc.
/// On the whip without the wall (20 rad/s, 1 s simulated) the mean / largest Newton
/// iterations per step went from 10.7 / 35 to 4.1 / 7 at h = 10 ms, from 32.8 / 82 to
/// 5.2 / 8 at h = 30 ms and from 146 / 170 to 9.2 / 11 at h = 100 ms, to the same minimisers.
/// Levenberg-Marquardt damping or a trust region were not needed: they shorten the same
/// straight steps and do not bend them. A short accepted step is not taken for convergence
/// (the former test "s times the step below tolerance" could stop a stalled line search).
/// The reference twist's branch follows the iterate (`follow_twist`, default on). The model's
/// energy takes each reference twist on the 2 pi branch nearest `frames.reference_twist`;
/// left at the start of the step, that makes E_inc jump where the twist has turned by pi
/// since then.
/// At a hairpin (adjacent edges turned by nearly pi against each other) the transport between
/// the two tangents is nearly singular and the reference twist turns fast: measured on a 1 um
/// rod under ADONIS at 2 ms (the tension-free whip, step 152, 166 degrees between the held
/// edge and the next), Newton stalled against that jump at |f| = 4.5e-15 with an 82 um step:
/// E_inc rose by 6.1e-18 (the twist energy from 1.7e-17 to 1.5e-12) for every step length
/// from 1 down to 2^-40 and the line search failed from both starts. After every accepted
/// Newton step `frames.reference_twist` is set to the twist at the new iterate, so the
/// branch is continuous along the Newton path (as the per-iteration frame updates of common
/// DER codes), and the step's end transports the frames on that branch. Wherever the twist
/// stays within pi of the step's start the branches, and so every result, are unchanged; a
/// failed solve puts the start's back.
/// A full step that lowers E_inc by more than the linear prediction f.dir (negative curvature
/// along it, which the PSD-projected Hessian hides) is extended by doublings while E_inc
/// falls (`expand`, default on; measured case at the line search below).
/// The energy transports the reference directors from the frames' tangents, dividing by
/// 1 + a.b: singular for an edge that turns by pi within the step. Once an edge of the
/// iterate points more than 170 degrees away from its frame's tangent, the frames are
/// transported to the iterate and the energy transports from there on (`follow_frames`,
/// default on; measured case at `follow_frames` below). The simulator puts the step's start
/// frames back when the step fails.
///
/// A `Body` provides: `model` (energy(q, frames), add_gradient, add_hessian, admissible),
/// `q`, `v`, `mass`, `fext` (n-vectors), `fixed` (n flags), `target` (n: end-of-step values
/// of the held DoFs), `frames` (the frames at q; `follow_twist` and `follow_frames` move them to
/// the iterate, a failed solve puts them back), `d` (the displacement: initial guess in,
/// solution out), `K` (a BandMatrix scratch), `lu` (a linear solver with
/// factorize(BandMatrix) -> Status and solve(Eigen::Ref<MatrixXd>)), `mean_edge`; DoFs
/// interleaved as in models/discrete_elastic_rod.hpp (x_i = 4i..4i+2, theta_j = 4j+3).
#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cmath>
#include <string_view>

#include <fmt/format.h>

#include <limits>

#include "framework/band_matrix.hpp"
#include "framework/concepts.hpp"
#include "framework/params.hpp"
#include "framework/status.hpp"

namespace weft::integrators {

class RodBackwardEuler {
 public:
  static constexpr std::string_view name = "rod_backward_euler";
  struct Params {
    double tolerance = 1e-9;   ///< largest Newton position step, relative to the mean rest edge length
    int max_iterations = 50;
    double armijo = 1e-4;      ///< sufficient decrease constant of the backtracking line search
    int max_halvings = 40;
    bool arc_step = true;           ///< line search along edge rotations (else along the straight Newton direction)
    bool follow_the_leader = true;  ///< also try the follow-the-leader projection of the guess, keep the lower E_inc
    bool retry_start = true;        ///< follow_the_leader: a DEL that fails from one start is solved again from the other
    bool follow_twist = true;       ///< the reference twist's 2 pi branch follows the Newton iterate (else: the step's start)
    bool expand = true;             ///< a full step along negative curvature is extended by doublings while E_inc falls
    bool follow_frames = true;      ///< the frames are re-anchored at the iterate once an edge has turned by more than 170 degrees from them
    template <class V>
    void visit(V& v) {
      v.field("tolerance", tolerance, {Unit::none, Range::open(0, 1), "Newton stops when its step moves no vertex by more than this times the mean rest edge length"});
      v.field("max_iterations", max_iterations, {Unit::none, Range::closed(1, 10000), "Newton iterations before the step fails"});
      v.field("armijo", armijo, {Unit::none, Range::open(0, 0.5), "sufficient-decrease constant of the backtracking line search"});
      v.field("max_halvings", max_halvings, {Unit::none, Range::closed(1, 200), "line-search halvings before the step fails"});
      v.field("arc_step", arc_step, {Unit::none, Range::any(), "line search along the arcs that rotate each edge by the Newton direction's transverse change (false: straight lines)"});
      v.field("follow_the_leader", follow_the_leader, {Unit::none, Range::any(), "also start from the guess projected onto the start-of-step edge lengths when its E_inc is lower"});
      v.field("retry_start", retry_start,
              {Unit::none, Range::any(),
               "follow_the_leader: a DEL whose Newton fails (line search, iteration limit) from the start of lower E_inc is solved again "
               "from the other start (the guess, or its follow-the-leader projection) before the step fails; the report adds both "
               "attempts' iterations (false: it fails there)"});
      v.field("follow_twist", follow_twist,
              {Unit::none, Range::any(),
               "the energy takes each reference twist on the 2 pi branch nearest the twist at the last accepted Newton iterate, so "
               "E_inc stays continuous where a twist turns by more than pi within the step (a hairpin); false: nearest the step's "
               "start, where E_inc jumps by 2 pi of twist"});
      v.field("expand", expand,
              {Unit::none, Range::any(),
               "when the full Newton step lowers E_inc by more than the linear prediction f.dir (negative curvature along it, which "
               "the PSD-projected Hessian hides), the step is doubled while E_inc keeps falling (false: the full step is taken)"});
      v.field("follow_frames", follow_frames,
              {Unit::none, Range::any(),
               "once an edge of the Newton iterate (or of the initial guess) points more than 170 degrees away from its frame's "
               "tangent, the reference frames are transported to the iterate and the energy transports from there on, which stays "
               "well conditioned where an edge turns by nearly pi within the step (false: always from the step's start, whose "
               "transport is singular there)"});
    }
  };

  explicit RodBackwardEuler(const Params& p) : prm_(p) {}
  const Params& params() const { return prm_; }

  /// f(d) = M d - h M v + h^2 (grad V(q + d) - f_ext), held rows zeroed.
  template <class Body>
  static void residual(const Body& b, const Eigen::VectorXd& d, double h, Eigen::VectorXd& f) {
    Eigen::VectorXd g = Eigen::VectorXd::Zero(d.size());
    b.model.add_gradient(b.q + d, b.frames, g);
    f = b.mass.cwiseProduct(d - h * b.v) + h * h * (g - b.fext);
    for (Eigen::Index i = 0; i < f.size(); ++i)
      if (b.fixed[i]) f[i] = 0;
  }

  /// E_inc(d) (constants dropped); +inf outside the model's domain.
  template <class Body>
  static double potential(const Body& b, const Eigen::VectorXd& d, double h) {
    const Eigen::VectorXd q = b.q + d;
    if (!b.model.admissible(q, b.frames)) return std::numeric_limits<double>::infinity();
    const double e = 0.5 * d.dot(b.mass.cwiseProduct(d)) - h * d.dot(b.mass.cwiseProduct(b.v)) +
                     h * h * (b.model.energy(q, b.frames) - b.fext.dot(d));
    return std::isfinite(e) ? e : std::numeric_limits<double>::infinity();
  }

  /// K = M + h^2 H(q + d) with the held rows and columns decoupled (diagonal M), factorised
  /// into b.lu.
  template <class Body>
  static Status relinearize(Body& b, double h, HessianMode mode) {
    const int n = static_cast<int>(b.q.size());
    if (b.K.rows() != n) b.K = BandMatrix(n, 10);
    b.K.setZero();
    b.model.add_hessian(b.q + b.d, b.frames, b.K, mode);
    const int k = b.K.bandwidth();
    for (int i = 0; i < n; ++i)
      for (int j = std::max(0, i - k); j <= std::min(n - 1, i + k); ++j) b.K(i, j) *= h * h;
    for (int i = 0; i < n; ++i) b.K(i, i) += b.mass[i];
    for (int i = 0; i < n; ++i) {
      if (!b.fixed[i]) continue;
      for (int j = std::max(0, i - k); j <= std::min(n - 1, i + k); ++j) b.K(i, j) = b.K(j, i) = 0;
      b.K(i, i) = b.mass[i] > 0 ? b.mass[i] : 1.0;
    }
    return b.lu.factorize(b.K);
  }

  /// Solves the rod's DEL; b.d holds the initial guess on entry (held entries are reset to
  /// target - q) and the solution on exit. On failure b.d is the last iterate.
  template <class Body>
  NewtonReport solve(Body& b, double h) const {
    NewtonReport rep;
    rep.method = prm_.arc_step ? "rod DEL: Newton on E_inc, exact Hessian (PSD-projected fallback), Armijo backtracking along edge arcs"
                               : "rod DEL: Newton on E_inc, exact Hessian (PSD-projected fallback), Armijo backtracking";
    const Eigen::Index n = b.q.size();
    for (Eigen::Index i = 0; i < n; ++i)
      if (b.fixed[i]) b.d[i] = b.target[i] - b.q[i];
    rep.tolerance = prm_.tolerance * b.mean_edge;
    const Eigen::VectorXd guess = b.d;
    const auto start_frames = b.frames;  // the frames (and twist branches) at the step's start, put back when a solve fails
    Eigen::VectorXd leader;
    double E = potential(b, b.d, h);
    bool from_leader = false;
    if (prm_.follow_the_leader) {
      leader.resize(n);
      follow_the_leader(b, guess, leader);
      const double El = potential(b, leader, h);
      if (El < E) b.d = leader, E = El, from_leader = true;  // a non-finite E (a folded guess) loses to any finite one
    }
    if (!std::isfinite(E)) {
      rep.status = Status::numerical_issue;
      rep.message = "the initial guess is outside the rod model's domain (zero-length or reversed edge)";
      return rep;
    }
    if (follow_frames(b)) E = potential(b, b.d, h);
    newton(b, h, E, rep);
    if (rep.status == Status::success) return rep;
    b.frames = start_frames;
    if (!prm_.follow_the_leader || !prm_.retry_start) return rep;
    // The other start. Measured on a 2 um rod under ADONIS at 5 ms (the tension-free whip,
    // step 61): from the follow-the-leader projection Newton ends in "line search failed ...
    // after 40 halvings" at |f| = 4.7e-14 with a 0.37 mm step; from h v the step converges.
    // (That failure was the twist branch's jump: with follow_twist the first start converges
    // as well; the retry stays for failures of other causes.)
    const Eigen::VectorXd& other = from_leader ? guess : leader;
    double Eo = potential(b, other, h);
    if (!std::isfinite(Eo)) return rep;
    const Eigen::VectorXd failed = b.d;
    b.d = other;
    if (follow_frames(b)) Eo = potential(b, b.d, h);
    NewtonReport second = rep;
    second.status = Status::success;
    second.message.clear();
    second.iterations = 0;
    newton(b, h, Eo, second);
    if (second.status != Status::success) {
      b.frames = start_frames;
      b.d = failed;  // the first failure, as before, with both attempts' work
      rep.iterations += second.iterations;
      rep.message += fmt::format("; from the {} as well: {}", from_leader ? "guess h v" : "follow-the-leader projection", second.message);
      return rep;
    }
    second.iterations += rep.iterations;
    second.initial_residual = rep.initial_residual;  // round_off_steps: `second` started from the first attempt's count
    second.stop_reason += fmt::format(" (from the {}, after the {} failed: {})", from_leader ? "guess h v" : "follow-the-leader projection",
                                      from_leader ? "follow-the-leader projection" : "guess h v", rep.message);
    return second;
  }

 private:
  /// Newton on E_inc from b.d (E_inc = E there), into `rep`: on success b.d is the solution,
  /// on failure rep.status and rep.message say why and b.d is the last iterate.
  template <class Body>
  void newton(Body& b, double h, double E, NewtonReport& rep) const {
    const Eigen::Index n = b.q.size();
    const double step_tol = rep.tolerance;
    Eigen::VectorXd f(n), dir(n), trial(n);
    for (int it = 0; it < prm_.max_iterations; ++it) {
      residual(b, b.d, h, f);
      if (it == 0) rep.initial_residual = f.norm();
      rep.final_residual = f.norm();
      if (!f.allFinite()) {
        rep.status = Status::numerical_issue;
        rep.message = fmt::format("non-finite residual at Newton iteration {}", it);
        return;
      }
      if (f.squaredNorm() == 0) {
        rep.stop_reason = "zero residual";
        return;
      }
      double slope = 0;
      bool descent = false;
      for (HessianMode mode : {HessianMode::exact, HessianMode::projected}) {
        if (relinearize(b, h, mode) != Status::success) continue;
        dir = -f;
        b.lu.solve(dir);
        for (Eigen::Index i = 0; i < n; ++i)
          if (b.fixed[i]) dir[i] = 0;
        slope = f.dot(dir);
        if (dir.allFinite() && slope < 0) {
          descent = true;
          break;
        }
      }
      if (!descent) {
        rep.status = Status::numerical_issue;
        rep.message = fmt::format("no descent direction at Newton iteration {} (|f| = {:.3e})", it, f.norm());
        return;
      }
      // Converged to what E_inc can resolve although the step is long: the predicted decrease
      // -f.dir / 2 below round-off of E_inc and the residual 1e-8 of its start. A nearly
      // singular Hessian (a flat mode) makes a long Newton step out of a residual at
      // round-off; no line search can verify it, and iterating only exhausts max_iterations
      // (measured: |f| = 1.9e-17 N after 50 iterations on a whip against a near wall).
      if (-0.5 * slope <= 1e-14 * std::abs(E) && f.norm() <= 1e-8 * rep.initial_residual) {
        rep.iterations = it;
        rep.stop_reason = "Newton decrement below round-off of E_inc";
        return;
      }
      if (largest_move(dir) <= step_tol) {  // converged: the full (tiny) Newton step, below what E_inc can resolve
        b.d += dir;
        follow_twist(b);
        rep.iterations = it + 1;
        residual(b, b.d, h, f);
        rep.final_residual = f.norm();
        rep.stop_reason = "Newton step below tolerance";
        return;
      }
      // A Newton step within 1000x the tolerance (1e-6 of an edge by default) whose decrease
      // E_inc cannot verify has converged at what E_inc resolves: the full step was accepted
      // only because E_inc did not change beyond round-off, or a shorter one by Armijo on
      // E_inc's noise, or none at all. Measured on the 240-vertex whip against a near wall at
      // |f| = 1.7e-19 to 3.1e-19 N with Newton steps of 1.1e-12 to 2.1e-12 m (tolerance
      // 8.4e-13 m): Armijo accepted 2^-22 of the step, which left every coordinate unchanged,
      // 190 times until max_iterations (0.1 ms); the halvings ran out (0.1 ms, later); 200
      // iterations moved the iterate without converging (ADONIS, 50 us).
      const bool at_resolution = largest_move(dir) <= 1e3 * step_tol;
      auto stop_at_resolution = [&](int iterations) {
        rep.iterations = iterations;
        rep.stop_reason = "Newton step at the resolution of E_inc";
      };
      double s = 1;
      double Et = 0;
      bool round_off = false;
      for (int halvings = 0;; ++halvings) {
        if (prm_.arc_step) advance(b, b.d, dir, s, trial);
        else trial = b.d + s * dir;
        Et = potential(b, trial, h);
        if (Et <= E + prm_.armijo * s * slope) break;
        // Below round-off of E_inc the decrease cannot be resolved: accept the full step if
        // E_inc is unchanged to round-off (the next, smaller Newton step decides convergence,
        // unless this one is already at E_inc's resolution).
        if (s == 1 && std::isfinite(Et) && std::abs(Et - E) <= 1e-12 * (std::abs(E) + 1e-300)) {
          ++rep.round_off_steps;
          round_off = true;
          break;
        }
        if (halvings >= prm_.max_halvings) {
          if (at_resolution) return stop_at_resolution(it);
          rep.status = Status::numerical_issue;
          rep.message = fmt::format("line search failed at Newton iteration {} after {} halvings (|f| = {:.3e}, Newton step {:.3e} m)",
                                    it, halvings, f.norm(), largest_move(dir));
          return;
        }
        s *= 0.5;
      }
      // E_inc fell by more than the linear prediction f.dir: it is concave along the step (a
      // convex function lies above its tangent), which the quadratic model, with the PSD
      // projection where the exact Hessian gives no descent, does not see. Measured on a 60 um
      // rod under ADONIS at 30 ms (the tension-free whip over 5 s, step 143): from iteration 7
      // every full projected step lowered E_inc by 1.0006 f.dir and moved it 3.4e-7 m along the
      // same valley, with |f| flat at 5e-13, until max_iterations. The step is doubled while
      // E_inc keeps falling; where E_inc is convex along the step this never applies, so
      // Newton's local convergence is untouched.
      if (prm_.expand && s == 1 && !round_off && Et - E < slope) {
        Eigen::VectorXd longer(n);
        for (double t = 2; t <= 0x1p30; t *= 2) {
          if (prm_.arc_step) advance(b, b.d, dir, t, longer);
          else longer = b.d + t * dir;
          const double El = potential(b, longer, h);
          if (!(El < Et)) break;
          Et = El;
          trial.swap(longer);
        }
      }
      if (at_resolution && (round_off || s < 1)) {
        if (trial == b.d) return stop_at_resolution(it);
        b.d = trial;
        follow_twist(b);
        return stop_at_resolution(it + 1);
      }
      if (trial == b.d) {  // Armijo accepted a step that changes nothing, on a step that is not tiny
        rep.status = Status::numerical_issue;
        rep.iterations = it;
        rep.message = fmt::format("the line search cannot move the iterate at Newton iteration {} (|f| = {:.3e}, Newton step {:.3e} m)",
                                  it, f.norm(), largest_move(dir));
        return;
      }
      // A short accepted step is progress, not convergence: only the full Newton step decides.
      b.d = trial;
      const bool moved = follow_frames(b);  // its transport moves the twist branches as well
      if (!moved) follow_twist(b);
      E = prm_.follow_twist || moved ? potential(b, b.d, h) : Et;  // Et, unless the iterate's twist or frames moved the energy's anchor
      rep.iterations = it + 1;
    }
    residual(b, b.d, h, f);
    rep.final_residual = f.norm();
    rep.status = Status::no_convergence;
    rep.message = fmt::format("rod DEL did not converge in {} Newton iterations (|f| = {:.3e}; raise integrator.max_iterations)",
                              prm_.max_iterations, rep.final_residual);
    return;
  }

 public:
  /// trial = d advanced by s along the Newton direction dir on the arc described in the file
  /// comment: with x = q + d and the first vertex moved by s dir, every edge e = l t becomes
  ///     e(s) = l(s) R(s omega) t,  omega = t x (de - a t) / l,  a = t . de,  de = dir_{j+1} - dir_j,
  ///     l(s) = l + s a (a >= 0), l exp(s a / l) (a < 0),
  /// R the rotation by the angle |s omega| about omega (Rodrigues), and the vertices are the
  /// running sums of the edges; held DoFs and twist angles move linearly (d + s dir). Then
  /// de(s)/ds at s = 0 is dir exactly, for every vertex.
  template <class Body>
  static void advance(const Body& b, const Eigen::VectorXd& d, const Eigen::VectorXd& dir, double s, Eigen::VectorXd& trial) {
    trial = d + s * dir;
    const int V = static_cast<int>((d.size() + 1) / 4);
    Eigen::Vector3d prev = b.q.template segment<3>(0) + trial.template segment<3>(0);
    for (int j = 0; j + 1 < V; ++j) {
      const Eigen::Vector3d e = b.q.template segment<3>(4 * j + 4) + d.template segment<3>(4 * j + 4) - b.q.template segment<3>(4 * j) -
                                d.template segment<3>(4 * j);
      const Eigen::Vector3d de = dir.template segment<3>(4 * j + 4) - dir.template segment<3>(4 * j);
      const double l = e.norm();
      Eigen::Vector3d x = prev + e + s * de;  // a degenerate edge (l = 0, outside the domain anyway): straight
      if (l > 0) {
        const Eigen::Vector3d t = e / l;
        const double a = t.dot(de);
        const Eigen::Vector3d omega = t.cross(de - a * t) / l;
        const double w = omega.norm(), phi = s * w;
        Eigen::Vector3d tr = t;
        if (phi > 0) {
          const Eigen::Vector3d k = omega / w;  // k is orthogonal to t
          tr = std::cos(phi) * t + std::sin(phi) * k.cross(t);
        }
        x = prev + (a >= 0 ? l + s * a : l * std::exp(s * a / l)) * tr;
      }
      for (int c = 0; c < 3; ++c)  // held coordinates exactly at their (linear) values; the chain goes on from there
        if (b.fixed[4 * j + 4 + c]) x[c] = b.q[4 * j + 4 + c] + trial[4 * j + 4 + c];
      trial.template segment<3>(4 * j + 4) = x - b.q.template segment<3>(4 * j + 4);
      prev = x;
    }
  }

  /// out = the guess d projected onto the start-of-step edge lengths, from the root outwards:
  /// every free vertex is placed at distance |x_{j+1} - x_j| (at q) from its already placed
  /// predecessor, in the direction the guess gives it; held vertices, vertex 0 and twist
  /// angles are kept. ("Follow the leader", e.g. Mueller et al. 2012.)
  template <class Body>
  static void follow_the_leader(const Body& b, const Eigen::VectorXd& d, Eigen::VectorXd& out) {
    out = d;
    const int V = static_cast<int>((d.size() + 1) / 4);
    Eigen::Vector3d prev = b.q.template segment<3>(0) + d.template segment<3>(0);
    for (int j = 0; j + 1 < V; ++j) {
      const Eigen::Vector3d x0 = b.q.template segment<3>(4 * j + 4);
      Eigen::Vector3d x = x0 + d.template segment<3>(4 * j + 4);
      const bool held = b.fixed[4 * j + 4] || b.fixed[4 * j + 5] || b.fixed[4 * j + 6];
      const Eigen::Vector3d u = x - prev;
      if (!held && u.norm() > 0) x = prev + (x0 - b.q.template segment<3>(4 * j)).norm() / u.norm() * u;
      out.template segment<3>(4 * j + 4) = x - x0;
      prev = x;
    }
  }

 private:
  /// Moves the branches to the iterate q + d: frames.reference_twist becomes the twist there
  /// (each on the branch nearest its old value), tangents and directors stay the start's.
  template <class Body>
  void follow_twist(Body& b) const {
    if (!prm_.follow_twist) return;
    if constexpr (requires { b.frames.reference_twist; b.model.transport(b.frames, b.q); })
      b.frames.reference_twist = b.model.transport(b.frames, b.q + b.d).reference_twist;
  }

  /// Re-anchors the frames at the iterate q + d (transported there, twist branches included)
  /// when an edge of the iterate points more than 170 degrees away from its frame's tangent;
  /// returns whether it did. The transport P_{a -> b} divides by 1 + a.b: measured on a 2 um
  /// rod under ADONIS at 100 ms (the tension-free whip over 5 s, step 33), edges 2-5 turned
  /// by 179.3 to 179.9996 degrees within the step (1 + a.b down to 2.8e-11), E_inc (5.8e-12)
  /// changed by 2.4e-21 between points 4e-15 m apart, against a predicted decrease of 4e-21
  /// for the full Newton step, and the line search failed at |f| = 8.7e-11 with a 7.2e-8 m
  /// step from both starts. Transported from an anchor that the edges have turned little
  /// from, the division is by nearly 2. At the anchor itself the energy is the same function
  /// of q; elsewhere its directors differ from the start's transport by the holonomy of the
  /// detour, a change of reference frame that the twist angles absorb (the step's end
  /// transports from the same anchor).
  /// The threshold, 170 degrees (1 + a.b below 0.015: round-off amplified 65 times and more):
  /// with 90 degrees the 5 s edge-whip sweeps lost more cells than they gained, since every
  /// re-anchoring changes the Newton path, and on these nonconvex large steps its end.
  static constexpr double follow_frames_cos = 0.98480775301220802;  // -cos(170 degrees)
  template <class Body>
  bool follow_frames(Body& b) const {
    if (!prm_.follow_frames) return false;
    if constexpr (requires { b.frames.tangent; b.model.transport(b.frames, b.q); }) {
      const int edges = static_cast<int>(b.frames.tangent.size());
      for (int j = 0; j < edges; ++j) {
        const Eigen::Vector3d e = b.q.template segment<3>(4 * j + 4) + b.d.template segment<3>(4 * j + 4) - b.q.template segment<3>(4 * j) -
                                  b.d.template segment<3>(4 * j);
        if (e.dot(b.frames.tangent[j]) < -follow_frames_cos * e.norm()) {
          b.frames = b.model.transport(b.frames, b.q + b.d);
          return true;
        }
      }
    }
    return false;
  }

  /// Largest vertex displacement [m] of a DoF vector (the x entries 4i..4i+2).
  static double largest_move(const Eigen::VectorXd& dq) {
    double m = 0;
    for (Eigen::Index i = 0; i + 2 < dq.size(); i += 4) m = std::max(m, dq.segment<3>(i).norm());
    return m;
  }
  Params prm_;
};

}  // namespace weft::integrators
