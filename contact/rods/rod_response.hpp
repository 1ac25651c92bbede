#pragma once
/// \file rod_response.hpp
/// The contact strategies of elastic rods (methods/rod-contact §8, §10, §11), one code path for all of
/// them as the thesis ran its baselines (§10.9): the strategies differ only in the
/// compliance D that maps contact multipliers to displacements, in whether it is refreshed
/// inside a constrained Newton loop, and in the inner contact solver.
///
///   strategy               D                                   outer loop                 inner solve
///   impulse                M^-1                                one pass                   Gauss-Seidel (GS)
///   linear_compliance      (M + h^2 H(q + d_DEL))^-1, frozen    one pass                   GS
///   adonis                 (M + h^2 H(q + d))^-1, refreshed     until no rod of the group  GS
///                          only for over-stretched rods          is stretched > tol
///   staggered_projections  refreshed for every rod of the group  as ADONIS                 alternate a contact
///                                                                                          (normal) and a friction
///                                                                                          problem, each by GS until
///                                                                                          a sweep moves less than
///                                                                                          `sp_inner` x its first
///
/// Per step (Algorithm 6 of the thesis, cleaned in methods/rod-contact §10.8): detection on the
/// unconstrained trajectory q -> q + d_DEL (rod-rod proximity or CCD, rod-obstacle CCD:
/// contact/rods/rod_detection.hpp); per contact k the stencil weights gamma, the frame
/// F_k = [n, t1, t2] and the scale s_k = (sum over free stencil vertices of gamma^2)^-1/2,
/// so that the local displacement is u_k = s_k F_k^T (sum_j gamma_j d_j - d_obstacle)
///  = G_k^T d + b_k (b_k: the held vertices' and the obstacle's scripted motion); contact
/// groups = connected components of rods linked by rod-rod contacts, each solved on its
/// own (in parallel). Inside a group, with lambda_k the multiplier of contact k (units of
/// M times a displacement, N s^2) and P_k = D G_k stored on the rows of its one or two
/// rods:
///   loop:  d_u = d (first iteration: the DEL solution) or d - D f(d) (later ones; by default
///          only for the rods re-linearised in the iteration, the others keep theirs: `predictor`)
///          x = d_u + sum_k P_k lambda_k;  GS sweeps (or staggered projections) until the
///          largest Fischer-Burmeister residual is below `contact_tol` or `gs_max` sweeps
///          `solver = newton`: then semismooth Newton on the group's Fischer-Burmeister system
///            (rod_group_solver.hpp) until the residual is below `contact_tol`, or the step fails
///          d = x;  stop unless the strategy re-linearises and some rod is over-stretched;
///            stop as well when d moved by at most `contact_tol` (converged with a rod still
///            over-stretched: `stretched_groups`) or after `newton_max` iterations (`capped_groups`)
///          re-linearise those rods (all rods: staggered projections), rebuild their P_k
///          an iterate that folds or collapses an edge fails the group; with the exact Hessian
///          (the default) such a group, or one capped at `newton_max`, starts again from d_DEL
///          with projected re-linearisations (`projected_restart`, `restarted_groups`)
/// Contact law: Signorini with Coulomb friction on the smooth cone, the constraint
/// n^T d >= 0 of the end-of-step linearisation (methods/rod-contact (4.1); `gap` adds the start gap).
#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <random>
#include <set>
#include <string_view>
#include <utility>
#include <vector>

#include "contact/coulomb.hpp"
#include "contact/detection/distance.hpp"
#include "contact/rods/anderson.hpp"
#include "contact/rods/rod_detection.hpp"
#include "contact/rods/rod_group_solver.hpp"
#include "contact/rods/thick_ccd.hpp"
#include "framework/concepts.hpp"
#include "framework/params.hpp"
#include "framework/interrupt.hpp"
#include "framework/scene.hpp"
#include "framework/status.hpp"
#include "framework/timers.hpp"

namespace weft::contact::rods {

enum class RodStrategy { impulse, linear_compliance, adonis, staggered_projections };
inline constexpr std::array<std::string_view, 4> rod_strategy_names = {"impulse", "linear_compliance", "adonis",
                                                                       "staggered_projections"};

/// Which start gap enters the linearised constraint.
enum class GapTerm {
  none,         ///< n^T d >= 0 (methods/rod-contact (4.1), the thesis)
  penetration,  ///< n^T d >= -min(gap, 0): an overlap at the start is pushed out
  full,         ///< n^T d >= -gap: a proximity contact may close its gap
  start,        ///< n^T d >= -gap_0, gap_0 the start distance along n: a contact found by CCD at
                ///< toi may approach up to its plane instead of stopping where the step began
};
inline constexpr std::array<std::string_view, 4> gap_term_names = {"none", "penetration", "full", "start"};

/// Which rods get a new predictor d_u = d - K^-1 f(d) at a constrained Newton iteration after
/// the first (ADONIS; staggered projections re-linearise every rod, so both are the same there).
enum class PredictorUpdate {
  relinearized,  ///< only the rods re-linearised in this iteration; the others keep their last
                 ///< linear model (predictor and P_k), which their stretch already accepted
  every_rod,     ///< every rod of the group, with its stale K where it was not re-linearised
                 ///< (modified Newton, the thesis' Algorithm 6 as printed)
};
inline constexpr std::array<std::string_view, 2> predictor_update_names = {"relinearized", "every_rod"};

/// The multipliers a re-detection round starts its groups from. Every round restarts the
/// groups from d_DEL, with K linearised there (the first constrained Newton iteration).
enum class RoundStart {
  last,   ///< those the last round ended with: balanced against the stiffnesses of its last
          ///< iteration, re-linearised where rods stretched, not against the first linearisation
  first,  ///< those after the last round's first constrained Newton iteration, which solved the
          ///< same linearisation with the contacts known then
  zero,   ///< none (a cold start)
};
inline constexpr std::array<std::string_view, 3> round_start_names = {"last", "first", "zero"};

/// The solver of a group's contact problem (rod_group_solver.hpp): Gauss-Seidel up to
/// `gs_max`, then with `newton` semismooth Newton to `contact_tol` (the step fails if it cannot).
using contact::ContactSolver;

/// Parameters shared by every rod strategy (one runtime struct, methods/rod-contact §16.2).
struct RodContactParams {
  double friction = 0.2;       ///< Coulomb coefficient of rod-rod contacts (obstacles: their own `friction`)
  RodDetectionParams detection{.rod_ccd = true};  ///< proximity radius, rod-rod CCD, self contact
  double contact_tol = 1e-8;   ///< [m] largest Fischer-Burmeister residual of a converged contact solve (1e-6 cm, the thesis)
  int gs_max = 150;            ///< Gauss-Seidel sweeps per contact solve
  double stretch_tol = 0.01;   ///< ADONIS: a rod whose edges extend more than this is re-linearised
  int newton_max = 100;        ///< ADONIS, staggered projections: constrained Newton iterations per group
  bool limit_stretch = false;  ///< ADONIS, staggered projections: the strain trust region of the constrained Newton step
  HessianMode relinearization = HessianMode::exact;  ///< ADONIS, staggered projections: the Hessian of the re-linearisations
  bool projected_restart = true;  ///< relinearization = exact: a group whose iterate leaves the model's domain, or that reaches newton_max, starts again with projected re-linearisations
  PredictorUpdate predictor = PredictorUpdate::relinearized;  ///< ADONIS: which rods get a new predictor after the first iteration
  RoundStart round_start = RoundStart::first;  ///< the multipliers a re-detection round starts from
  int sp_max = 100;            ///< staggered projections: alternations per Newton iteration
  double sp_tol = 1e-6;        ///< staggered projections: relative change of the multipliers that stops them (friction only with exact projections)
  double sp_inner = 0.1;       ///< staggered projections: a projection's sweeps stop when one changes the multipliers by less than sp_inner x its first did (0: exact projections)
  int sp_anderson = 0;         ///< staggered projections: Anderson acceleration of the alternation over this many past alternations (0: plain)
  GapTerm gap = GapTerm::none;
  int redetections = 4;        ///< detections on the corrected trajectory that may add contacts (then the step fails)
  double overlap_tol = 0.01;   ///< re-detection: end overlap (fraction of r_a + r_b) that gives a contacted rod pair a contact at its new closest points (0: off)
  bool overlap_follow = true;  ///< end-overlap contacts follow their edge pair: moved to the new closest points and their end normal, not added again
  bool overlap_keep = true;    ///< overlap_follow: a follower that moves again leaves a fixed contact where it bore load
  ContactSolver solver = ContactSolver::gauss_seidel;  ///< the contact solve of a group
  int solver_max = 200;        ///< newton: Newton (and fallback) steps per contact solve after Gauss-Seidel
                               ///< (a hair-ball group of 1605 contacts took 66: about 45 damped steps
                               ///< before the fast local convergence; 50 stopped it at 1e-5 m)
  bool groups = true;          ///< solve contact groups separately (false: every contacted rod in one group)
  int order_seed = 0;          ///< 0: contacts in detection order within a group; otherwise a shuffle with this seed (ordering tests)
  template <class V>
  void visit(V& v) {
    v.field("friction", friction, {Unit::none, Range::ge(0), "Coulomb coefficient of rod-rod contacts (obstacles use their own)"});
    v.section("detection", detection);
    v.field("contact_tol", contact_tol, {Unit::length, Range::gt(0), "Fischer-Burmeister residual of a converged contact solve"});
    v.field("gs_max", gs_max, {Unit::none, Range::closed(1, 1000000), "Gauss-Seidel sweeps per contact solve"});
    v.field("stretch_tol", stretch_tol, {Unit::none, Range::gt(0), "ADONIS: re-linearise rods whose edges extend more than this"});
    v.field("newton_max", newton_max, {Unit::none, Range::closed(1, 100000), "constrained Newton iterations per contact group"});
    v.choice("relinearization", relinearization, hessian_mode_names,
              "ADONIS, staggered projections: the Hessian of K = M + h^2 H at the re-linearisations after the first (at "
              "d_DEL, a minimiser, the exact one): exact (the thesis; falls back to projected when it does not factorise) or "
              "projected (per-element PSD projection: K positive definite, as the constrained Newton step needs)");
    v.field("projected_restart", projected_restart,
            {Unit::none, Range::any(),
             "ADONIS, staggered projections with relinearization = exact: a group whose constrained Newton iterate folds or "
             "collapses an edge, or that stops at newton_max (the exact Hessian's step ran away), starts again from d_DEL with "
             "projected re-linearisations (`restarted_groups` in the stats; a capped exact result is kept when the restart fails, "
             "or is capped too and stretches its rods more); false: the step fails, or is accepted capped, there (the thesis)"});
    v.choice("predictor", predictor, predictor_update_names,
             "ADONIS: which rods get a new predictor d - K^-1 f(d) at each constrained Newton iteration after the first: "
             "relinearized (only the rods re-linearised in it; the others keep the linear model their stretch accepted) or "
             "every_rod (modified Newton with the stale K of the others: the thesis as printed, which runs away on the hair balls "
             "at 10 ms)");
    v.choice("round_start", round_start, round_start_names,
             "the multipliers each re-detection round starts its groups from (every round restarts them from d_DEL and K "
             "linearised there): last (those the last round ended with, balanced against its re-linearised stiffnesses; applied "
             "through the first, softer linearisation they can throw rods far), first (those after the last round's first "
             "constrained Newton iteration, which solved that same linearisation) or zero (cold start)");
    v.field("limit_stretch", limit_stretch,
            {Unit::none, Range::any(),
             "ADONIS, staggered projections: halve a rod's constrained Newton step until it stays in the model's domain and its "
             "largest edge strain is at most max(10 stretch_tol, twice the iterate's) (false: full steps, the thesis)"});
    v.field("sp_max", sp_max, {Unit::none, Range::closed(1, 100000), "staggered projections: alternations per Newton iteration"});
    v.field("sp_tol", sp_tol,
            {Unit::none, Range::gt(0),
             "staggered projections: relative change of the multipliers that stops them (of the friction ones alone when sp_inner = 0)"});
    v.field("sp_inner", sp_inner,
            {Unit::none, Range::closed(0, 1),
             "staggered projections: inexact projections - each projection's Gauss-Seidel stops when a sweep changes the multipliers by "
             "less than sp_inner times its first sweep did (0: every projection solved to 1e-3 contact_tol)"});
    v.field("sp_anderson", sp_anderson,
            {Unit::none, Range::closed(0, 50),
             "staggered projections: Anderson acceleration of the alternation from this many past alternations; a mix is "
             "projected onto the friction cones and kept only when it lowers the Coulomb residual (0: the plain alternation)"});
    v.field("redetections", redetections, {Unit::none, Range::closed(0, 100), "detections on the corrected trajectory that may add contacts before the step fails"});
    v.field("overlap_tol", overlap_tol,
            {Unit::none, Range::closed(0, 1),
             "re-detection: two edges of a rod pair in contact (or their neighbours) that end the corrected step overlapping by more "
             "than this fraction of r_a + r_b get a contact at their closest end points (its normal: overlap_follow) (0: off; the "
             "contacts hold only at their own material points along their own normals)"});
    v.field("overlap_follow", overlap_follow,
            {Unit::none, Range::any(),
             "re-detection with overlap_tol > 0: an edge pair keeps one following end-overlap contact (overlap_keep: plus fixed "
             "contacts at the places it left while bearing load), which each round that finds the pair overlapping again moves "
             "to the new closest end points and takes their normal at the end of the corrected step (the "
             "linearisation of the edges' distance at the current iterate; where the end points nearly meet or have passed each "
             "other, the normal of the edges' crossing, on the side where they were at the start); false: each such round adds "
             "another contact, with the start offset of its points as normal"});
    v.field("overlap_keep", overlap_keep,
            {Unit::none, Range::any(),
             "overlap_follow: from its second move in a step on, a follower about to move whose normal multiplier is positive "
             "(it bore load in the last solve) stays where it is as a fixed contact, with its multipliers, and the new place "
             "gets the pair's follower: the linearisations of the edges' distance accumulate instead of replacing each other "
             "(false: the follower always moves; where the held point acts as a pivot the pair then alternates between two "
             "places, or creeps along the edges, until the re-detections run out)"});
    v.choice("gap", gap, gap_term_names,
             "start gap in the linearised constraint: none (n^T d >= 0, the thesis), penetration (an overlap at the start is pushed "
             "out), full (n^T d >= -gap at detection: a proximity contact may close its gap), or start (n^T d >= -gap_0, the distance "
             "along n at the start of the step: a CCD contact may approach up to its plane)");
    v.choice("solver", solver, contact::contact_solver_names,
             "contact solve of a group: gauss_seidel (the thesis, capped at gs_max) or newton (Gauss-Seidel, then semismooth Newton to contact_tol; the step fails above it)");
    v.field("solver_max", solver_max, {Unit::none, Range::closed(1, 100000), "newton: Newton steps per contact solve after the Gauss-Seidel sweeps"});
    v.field("groups", groups, {Unit::none, Range::any(), "solve contact groups separately (false: one monolithic group of every contacted rod)"});
    v.field("order_seed", order_seed,
            {Unit::none, Range::ge(0), "0: contacts in detection order inside a group; otherwise shuffled with this seed (ordering-independence tests)"});
  }
  static Checker validate(const RodContactParams& p) {
    Checker c("contact");
    c.merge(RodDetectionParams::validate(p.detection));
    return c;
  }
};

/// Statistics of one group's solve.
struct GroupStats {
  int contacts = 0, outer = 0, sweeps = 0, relinearized = 0, sp_iterations = 0;
  int newton = 0, fallbacks = 0;  ///< Newton contact solver: steps, and steps taken by its fallbacks
  int damped = 0;                 ///< rod steps of the constrained Newton iteration cut by its strain trust region
  double residual = 0;
  bool unconverged = false, capped = false;
  bool stretched = false;  ///< converged (the iterate stopped moving) with a rod above stretch_tol
  bool left_domain = false;  ///< failed: an iterate folded or collapsed an edge
  bool restarted = false;    ///< solved again with projected re-linearisations after `left_domain` or `capped` (projected_restart)
  Status status = Status::success;
  std::string message;
  /// Adds the work of another attempt at the same group (iterations, sweeps, refactorisations).
  void add_work(const GroupStats& o) {
    outer += o.outer, sweeps += o.sweeps, relinearized += o.relinearized, sp_iterations += o.sp_iterations;
    newton += o.newton, fallbacks += o.fallbacks, damped += o.damped;
  }
};

/// Union-find over rods: contact groups (methods/rod-contact §10.2), deterministic order (rods and
/// contacts ascending within a group, groups by their smallest rod). `separate = false`
/// joins every contacted rod into one monolithic group (param `groups`).
std::vector<std::vector<int>> contact_groups(int num_rods, const std::vector<RodContactRows>& contacts,
                                             std::vector<std::vector<int>>& group_rods, bool separate = true);

/// The code path shared by the four strategies.
template <RodStrategy S>
class RodResponse {
 public:
  static constexpr RodStrategy strategy = S;
  static constexpr std::string_view name = rod_strategy_names[static_cast<int>(S)];
  static constexpr bool uses_stiffness = S != RodStrategy::impulse;
  static constexpr bool relinearizes = S == RodStrategy::adonis || S == RodStrategy::staggered_projections;
  using Params = RodContactParams;

  RodResponse(const Scene&, const Params& p) : prm_(p) {}
  const Params& params() const { return prm_; }
  /// The contacts of the last step, after the response (for tests and diagnostics).
  const std::vector<RodContactRows>& last_contacts() const { return contacts_; }
  const std::vector<GroupStats>& last_groups() const { return stats_; }

  template <class System>
  ContactReport resolve(System& sys) {
    ContactReport rep;
    const int R = sys.num_rods();
    std::vector<Eigen::VectorXd> del(R);
    for (int r = 0; r < R; ++r) del[r] = sys.body(r).d;
    contacts_.clear();
    stats_.clear();
    // Detection on q -> q + d_DEL, then again on q -> q + d after each response: the
    // constraints are linearised, and a later Newton iteration (or the response of other
    // contacts through D) may carry a point that had no contact into an obstacle or a rod.
    // New contacts join the set and every group is solved again from d_DEL, its multipliers
    // warm from the last round (`round_start`: by default those of its first iteration, which
    // solved the same linearisation at d_DEL).
    for (int round = 0; round <= prm_.redetections; ++round) {
      if (stop_requested()) {
        rep.status = Status::interrupted;
        rep.message = fmt::format("the contact response was interrupted by a stop request before detection round {}", round);
        break;
      }
      RodCurves curves;
      curves.first.assign(1, 0);
      for (int r = 0; r < R; ++r) {
        const auto& b = sys.body(r);
        for (int i = 0; i < b.num_vertices(); ++i) {
          curves.x0.push_back(b.q.template segment<3>(4 * i));
          curves.x1.push_back(b.q.template segment<3>(4 * i) + b.d.template segment<3>(4 * i));
        }
        curves.first.push_back(static_cast<int>(curves.x0.size()));
        curves.radius.push_back(b.radius);
      }
      std::vector<RodContact> found;
      {
        ScopedTimer t(rep.detection_seconds);
        found = detect_rod_contacts(curves, sys.obstacles(), sys.time(), sys.time() + sys.dt(), prm_.detection);
      }
      ScopedTimer t(rep.response_seconds);
      size_t added = 0;
      for (const RodContact& c : found) {
        // Known, or a near-duplicate of a known one (the other edge at the same crossing:
        // rod_detection.hpp) that the merge of this round kept instead.
        if (std::any_of(contacts_.begin(), contacts_.end(), [&](const RodContactRows& k) {
              return same_pair(k.geometry, c) || near_duplicates(curves, k.geometry, c, prm_.detection);
            }))
          continue;
        RodContactRows k;
        if (build_rows(sys, c, k)) contacts_.push_back(std::move(k)), ++added;
      }
      if (round > 0 && prm_.overlap_tol > 0) {
        for (const Overlap& o : end_overlaps(curves)) {
          RodContactRows k;
          if (!build_rows(sys, o.contact, k, true)) continue;
          ++added;
          k.follows = prm_.overlap_follow;
          if (o.follower < 0) {
            contacts_.push_back(std::move(k));
          } else if (RodContactRows& old = contacts_[o.follower]; prm_.overlap_keep && old.moves > 0 && old.lambda[0] > 0) {
            // A second move, and the place it leaves bore load: it keeps a (fixed) contact
            // there, with its multipliers, and the new place gets the follower (cold).
            // Replacing one linearisation of the distance by the next lets the held point
            // pivot: the pair then alternates between two places or creeps along the edges
            // round after round. (A first move is free: most pairs settle after it, and
            // every kept place is one more near-duplicate row for Gauss-Seidel.)
            old.follows = false;
            k.moves = old.moves + 1;
            contacts_.push_back(std::move(k));
          } else {  // the pair's contact moves; its multipliers stay as the warm start
            k.lambda = old.lambda;
            k.lambda_first = old.lambda_first;
            k.moves = old.moves + 1;
            old = std::move(k);
          }
        }
      }
      if (added == 0) break;
      if (round > 0) {
        ++rep.redetections;
        rep.redetected += static_cast<int>(added);
        if (round == prm_.redetections) {  // still new (or moved) contacts after the last solve
          rep.status = Status::no_convergence;
          rep.message = fmt::format("{} new or moved contacts after {} re-detections: the response keeps creating contacts", added, round);
          break;
        }
      }
      for (int r = 0; r < R; ++r) sys.body(r).d = del[r];
      if (round > 0 && prm_.round_start != RoundStart::last)
        for (auto& k : contacts_) k.lambda = prm_.round_start == RoundStart::first ? k.lambda_first : Eigen::Vector3d::Zero();
      std::vector<std::vector<int>> group_rods;
      const std::vector<std::vector<int>> groups = contact_groups(R, contacts_, group_rods, prm_.groups);
      stats_.assign(groups.size(), {});
#pragma omp parallel for schedule(dynamic, 1) if (groups.size() > 1)
      for (int g = 0; g < static_cast<int>(groups.size()); ++g) stats_[g] = solve_group_safe(sys, groups[g], group_rods[g]);
      rep.contact_groups = static_cast<int>(groups.size());
      rep.largest_group = 0;
      rep.max_outer_iterations = 0;
      rep.gs_residual = 0;
      rep.gs_unconverged = 0;
      rep.capped_groups = 0;
      rep.stretched_groups = 0;
      rep.restarted_groups = 0;
      for (const GroupStats& st : stats_) {
        rep.restarted_groups += st.restarted;
        rep.largest_group = std::max(rep.largest_group, st.contacts);
        rep.outer_iterations += st.outer;
        rep.max_outer_iterations = std::max(rep.max_outer_iterations, st.outer);
        rep.gs_sweeps += st.sweeps;
        rep.gs_residual = std::max(rep.gs_residual, st.residual);
        rep.gs_unconverged += st.unconverged;
        rep.relinearized += st.relinearized;
        rep.sp_alternations += st.sp_iterations;
        rep.capped_groups += st.capped;
        rep.stretched_groups += st.stretched;
        rep.contact_newton += st.newton;
        rep.contact_fallbacks += st.fallbacks;
        rep.damped_steps += st.damped;
        if (st.status != Status::success && rep.status == Status::success) {
          rep.status = st.status;
          rep.message = st.message;
        }
      }
      if (rep.status != Status::success) break;
    }
    rep.contacts = static_cast<int>(contacts_.size());
    for (const auto& k : contacts_) (k.geometry.kind == RodContact::Kind::rod_rod ? rep.rod_contacts : rep.obstacle_contacts)++;
    return rep;
  }

 private:
  /// An end overlap to hold: a new contact, or the new place of the pair's follower.
  struct Overlap {
    RodContact contact;
    int follower = -1;  ///< index into contacts_ of the pair's contact that moves there; -1: add
  };
  /// Edges of rod pairs in contact that end the corrected step q -> q + d (curves.x1)
  /// overlapping by more than overlap_tol (r_a + r_b): a contact holds n^T (u_a - u_b) >= -gap
  /// at its own material points along its own normal, and a rotation or a slide of nearly
  /// parallel curls brings other points through. Checked: each contact's edge pair and the
  /// adjacent edges on both rods. The contact sits at the closest end points; skipped when a
  /// known contact of these edges already sits there with that normal (merge_fraction,
  /// merge_angle). Skipping wherever a known contact is within r_a + r_b of both points
  /// instead let 16 pairs through on the 250-rod ball: the crossings happen at known
  /// contacts whose normal has turned.
  ///
  /// overlap_follow = false: a new contact each time, with the normal of its material points
  /// at the start of the step (apart there, so no approach along it keeps them apart; the
  /// constraint lets them close that start gap, n^T d >= -gap, see build_rows). Where two
  /// edges fold against each other at a shallow angle the overlap then reappears next to the
  /// new contact, just outside the merge distance, round after round, until the step fails
  /// (docs/rods.md, "the re-detection walk").
  /// overlap_follow = true: a pair has at most one such contact that follows it (overlap_keep
  /// leaves fixed ones where it bore load, see resolve), which moves to the closest
  /// end points with the normal n1 between them at the end: n1^T (p_a - p_b) >= r_a + r_b is
  /// the linearisation of the edges' distance at the current iterate (its gradient at
  /// interior closest points), so the rounds are sequential linearisations of the distance
  /// constraint. Where the end points nearly meet (no direction) or have passed each other
  /// (n1 against their start offset: the constraint would keep them crossed) the normal is
  /// that of the edges' crossing: their cross product at the end, on the side where the
  /// edges were at the start. Not the start offset of the end points: where an edge slides
  /// past a vertex (the whip_edge test) it lies nearly along that edge, and the crossing then
  /// moves by about r_a + r_b along it each round.
  std::vector<Overlap> end_overlaps(const RodCurves& c) const {
    std::vector<Overlap> out;
    std::set<std::array<int, 4>> seen;
    const double cos_merge = std::cos(prm_.detection.merge_angle * std::numbers::pi / 180);
    const size_t known = contacts_.size();
    for (size_t q = 0; q < known; ++q) {
      const RodContact& g = contacts_[q].geometry;
      if (g.kind != RodContact::Kind::rod_rod) continue;
      for (int da = -1; da <= 1; ++da)
        for (int db = -1; db <= 1; ++db) {
          int ra = g.rod_a, ea = g.edge_a + da, rb = g.rod_b, eb = g.edge_b + db;
          if (ea < 0 || eb < 0 || ea >= c.num_edges(ra) || eb >= c.num_edges(rb)) continue;
          if (std::pair(ra, ea) > std::pair(rb, eb)) std::swap(ra, rb), std::swap(ea, eb);
          if (ra == rb && (!prm_.detection.self_contact || eb - ea < prm_.detection.self_skip)) continue;
          if (!seen.insert({ra, ea, rb, eb}).second) continue;
          const int ia = c.first[ra] + ea, ib = c.first[rb] + eb;
          const double reach = c.radius[ra] + c.radius[rb];
          const auto end = detection::segment_segment_distance(c.x1[ia], c.x1[ia + 1], c.x1[ib], c.x1[ib + 1]);
          if (!(end.distance_squared < std::pow(reach * (1 - prm_.overlap_tol), 2))) continue;
          RodContact k;
          k.rod_a = ra, k.edge_a = ea, k.s_a = end.s, k.rod_b = rb, k.edge_b = eb, k.s_b = end.t;
          auto at = [&](const std::vector<Eigen::Vector3d>& x, int i, double s) -> Eigen::Vector3d { return (1 - s) * x[i] + s * x[i + 1]; };
          const Eigen::Vector3d start_offset = at(c.x0, ia, end.s) - at(c.x0, ib, end.t);
          const Eigen::Vector3d end_offset = at(c.x1, ia, end.s) - at(c.x1, ib, end.t);
          const double start = start_offset.norm(), gone = std::sqrt(end.distance_squared);
          if (prm_.overlap_follow && gone > 1e-3 * reach && end_offset.dot(start_offset) > 0) {
            k.normal = end_offset / gone;
          } else if (prm_.overlap_follow) {
            // The edges (nearly) cross at the end: the normal of their crossing (the cross
            // product of the edges at the end), on the side where the edges were at the start.
            const auto begin = detection::segment_segment_distance(c.x0[ia], c.x0[ia + 1], c.x0[ib], c.x0[ib + 1]);
            const Eigen::Vector3d side = at(c.x0, ia, begin.s) - at(c.x0, ib, begin.t);
            k.normal = segment_contact_normal({c.x1[ia], c.x1[ia + 1], c.x1[ib], c.x1[ib + 1]}, end.s, end.t, 0, {side, start_offset});
          } else {
            if (!(start > 1e-3 * reach)) continue;  // these points already met at the start: no normal to keep
            k.normal = start_offset / start;
          }
          k.gap = k.normal.dot(start_offset) - reach;
          const double la = (c.x0[ia + 1] - c.x0[ia]).norm(), lb = (c.x0[ib + 1] - c.x0[ib]).norm();
          auto sits_there = [&](const RodContact& h) {
            return std::abs(h.s_a - k.s_a) * la < prm_.detection.merge_fraction * reach &&
                   std::abs(h.s_b - k.s_b) * lb < prm_.detection.merge_fraction * reach && h.normal.dot(k.normal) > cos_merge;
          };
          int follower = -1;
          bool held = false;
          for (size_t j = 0; j < contacts_.size(); ++j) {
            const RodContact& h = contacts_[j].geometry;
            if (!same_pair(h, k)) continue;
            held = held || sits_there(h);
            if (contacts_[j].follows) follower = static_cast<int>(j);
          }
          if (!held) out.push_back({k, follower});
        }
    }
    return out;
  }

  /// The same contact (the same features) found again by a later detection.
  static bool same_pair(const RodContact& a, const RodContact& b) {
    return a.kind == b.kind && a.rod_a == b.rod_a && a.edge_a == b.edge_a && a.rod_b == b.rod_b && a.edge_b == b.edge_b &&
           a.obstacle == b.obstacle && a.obstacle_edge == b.obstacle_edge && (!a.vertex_contact() || a.s_a == b.s_a);
  }
  /// G_k, b_k and mu_k of a detected contact; false when every stencil vertex is held.
  /// `full_gap`: n^T d >= -gap whatever `gap` says (the contacts of end_overlaps, whose
  /// points are apart at the start: with n^T d >= 0 they could not approach at all, and on
  /// the 250-rod ball ADONIS then failed at step 14, an iterate folding an edge; with the gap
  /// the run held).
  template <class System>
  bool build_rows(System& sys, const RodContact& c, RodContactRows& k, bool full_gap = false) const {
    k.geometry = c;
    const Eigen::Vector3d n = c.normal.normalized();
    const Eigen::Vector3d a = std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
    const Eigen::Vector3d t1 = (a - a.dot(n) * n).normalized(), t2 = n.cross(t1);
    Eigen::Matrix3d F;
    F << n, t1, t2;
    // Stencil: (rod, local vertex, gamma).
    std::vector<std::tuple<int, int, double>> st = {{c.rod_a, c.edge_a, 1 - c.s_a}, {c.rod_a, c.edge_a + 1, c.s_a}};
    if (c.kind == RodContact::Kind::rod_rod) {
      st.emplace_back(c.rod_b, c.edge_b, -(1 - c.s_b));
      st.emplace_back(c.rod_b, c.edge_b + 1, -c.s_b);
      k.mu = prm_.friction;
    } else {
      k.mu = sys.obstacles()[c.obstacle].friction;
    }
    double free2 = 0;
    for (const auto& [r, i, g] : st)
      if (!sys.body(r).fixed[4 * i]) free2 += g * g;
    if (!(free2 > 1e-24)) return false;
    const double s = 1 / std::sqrt(free2);
    k.rods = {c.rod_a, c.kind == RodContact::Kind::rod_rod && c.rod_b != c.rod_a ? c.rod_b : -1};
    for (int side = 0; side < 2; ++side)
      if (k.rods[side] >= 0) k.G[side] = Eigen::MatrixXd::Zero(sys.body(k.rods[side]).q.size(), 3), k.blocks[side] = 0;
    // scripted: the held vertices' prescribed part of the relative displacement; relative: all
    // of it on the trajectory this round detected on (d), for the start gap.
    Eigen::Vector3d scripted = Eigen::Vector3d::Zero(), relative = Eigen::Vector3d::Zero();
    for (const auto& [r, i, g] : st) {
      const auto& b = sys.body(r);
      const Eigen::Vector3d moved = g * b.d.template segment<3>(4 * i);
      relative += moved;
      if (b.fixed[4 * i]) {
        scripted += moved;
        continue;
      }
      const int side = r == k.rods[0] ? 0 : 1;
      k.G[side].template middleRows<3>(4 * i) += s * g * F;
      auto& list = k.stencil[side];
      int& used = k.blocks[side];
      if (std::find(list.begin(), list.begin() + used, i) == list.begin() + used) list[used++] = i;
    }
    if (c.kind == RodContact::Kind::rod_obstacle) scripted -= c.obstacle_displacement, relative -= c.obstacle_displacement;
    k.b = s * F.transpose() * scripted;
    if (full_gap || prm_.gap == GapTerm::full || (prm_.gap == GapTerm::penetration && c.gap < 0)) {
      k.b[0] += s * c.gap;
    } else if (prm_.gap == GapTerm::start) {
      // The gap at toi less the normal approach over [0, toi] of the detected trajectory: the
      // distance along n at the start of the step.
      k.b[0] += s * (c.gap - c.toi * n.dot(relative));
    }
    return true;
  }

  /// P_k = D G_k and W_kk for the compliance of the strategy.
  template <class System>
  void build_compliance(System& sys, RodContactRows& k) const {
    k.W.setZero();
    for (int side = 0; side < 2; ++side) {
      const int r = k.rods[side];
      if (r < 0) continue;
      k.P[side] = k.G[side];
      if constexpr (S == RodStrategy::impulse) {
        const auto& b = sys.body(r);
        for (Eigen::Index i = 0; i < k.P[side].rows(); ++i) k.P[side].row(i) *= b.fixed[i] ? 0.0 : 1.0 / b.mass[i];
      } else {
        sys.solve(r, k.P[side]);
      }
      k.W += k.G[side].transpose() * k.P[side];
    }
    k.W = 0.5 * (k.W + k.W.transpose()).eval();
    k.scale = coulomb_scale(k.W);
  }

  // An optional safeguard of the constrained Newton iteration (ADONIS, staggered
  // projections; `limit_stretch`, off by default): a strain trust region. A rod's step
  // d_r -> xs_r is halved until the iterate stays in the model's domain and its largest edge
  // strain is at most max(10 stretch_tol, 2 x that of d_r); the iteration goes on from there.
  // Far from runaways the full step is taken, so the fixed point is the thesis'. Aimed at the
  // runaway of the iterate of an exact, indefinite K_r (an edge stretched by 1e54 at the
  // fourth iteration on the 1000-rod hair ball at dt = 10 ms); it does not cure it: the
  // iteration then keeps being cut (docs/rods.md). Returns the rods whose step was cut.
  template <class System>
  int limit_outer_step(System& sys, const std::vector<int>& rods, GroupDisplacements& xs) const {
    int cut = 0;
    Eigen::VectorXd trial;
    for (size_t i = 0; i < rods.size(); ++i) {
      const int r = rods[i];
      const Eigen::VectorXd& d = sys.body(r).d;
      const double cap = std::max(10 * prm_.stretch_tol, 2 * sys.stretch(r, d));
      const auto& body = sys.body(r);
      const auto fits = [&](const Eigen::VectorXd& x) { return body.model.admissible(body.q + x, body.frames) && sys.stretch(r, x) <= cap; };
      if (fits(xs[i])) continue;
      const Eigen::VectorXd delta = xs[i] - d;
      double alpha = 0.5;
      for (int halving = 1; halving <= 30; ++halving, alpha *= 0.5) {
        trial = d + alpha * delta;
        if (fits(trial)) break;
      }
      xs[i] = fits(trial) ? trial : d;
      ++cut;
    }
    return cut;
  }

  /// Anderson step of the staggered alternation: `before` holds the multipliers the
  /// alternation started from, the contacts hold its result G and xs is consistent with
  /// them. The mix is projected onto each contact's cone (lambda_n >= 0, |lambda_t| <=
  /// mu lambda_n) and kept, with xs moved along, only when it lowers the group's Coulomb
  /// residual `plain`; else the history is reset. Returns the residual of what is kept.
  double accelerate(Anderson& anderson, const std::vector<int>& ids, const std::vector<Eigen::Vector3d>& before,
                    GroupDisplacements& xs, Eigen::VectorXd& x_k, Eigen::VectorXd& g_k, Eigen::VectorXd& mixed, double plain) {
    const auto n = static_cast<Eigen::Index>(ids.size());
    x_k.resize(3 * n);
    g_k.resize(3 * n);
    for (Eigen::Index i = 0; i < n; ++i) {
      x_k.segment<3>(3 * i) = before[i];
      g_k.segment<3>(3 * i) = contacts_[ids[i]].lambda;
    }
    if (!anderson.mix(x_k, g_k, mixed)) return plain;
    for (Eigen::Index i = 0; i < n; ++i) {
      RodContactRows& k = contacts_[ids[i]];
      Eigen::Vector3d l = mixed.segment<3>(3 * i);
      l[0] = std::max(l[0], 0.0);
      const double t = l.tail<2>().norm(), radius = k.mu * l[0];
      if (t > radius) l.tail<2>() *= t > 0 ? radius / t : 0.0;
      add_response(k, l - k.lambda, xs);
      k.lambda = l;
    }
    const double residual = contact_error(contacts_, ids, xs);
    if (residual < plain) return residual;
    for (Eigen::Index i = 0; i < n; ++i) {  // back to the plain iterate
      RodContactRows& k = contacts_[ids[i]];
      const Eigen::Vector3d g = g_k.segment<3>(3 * i);
      add_response(k, g - k.lambda, xs);
      k.lambda = g;
    }
    anderson.reset();
    return plain;
  }

  /// solve_group with the scene's re-linearisation; with `projected_restart`, a group whose
  /// exact iteration leaves the model's domain or stops at newton_max is solved again from
  /// d_DEL and its start multipliers with projected re-linearisations (the first
  /// linearisation, at d_DEL, is the same); a capped exact result is kept if that attempt
  /// fails, or is capped too and stretches its rods more. Groups that converge with the exact
  /// Hessian are unchanged.
  template <class System>
  GroupStats solve_group_safe(System& sys, const std::vector<int>& ids, const std::vector<int>& rods) {
    const bool may_restart = relinearizes && prm_.projected_restart && prm_.relinearization == HessianMode::exact;
    if (!may_restart) return solve_group(sys, ids, rods, prm_.relinearization);
    // The group's iterate: its rods' displacements and its contacts' multipliers.
    using Snapshot = std::pair<std::vector<Eigen::VectorXd>, std::vector<Eigen::Vector3d>>;
    const auto save = [&] {
      Snapshot s;
      for (int r : rods) s.first.push_back(sys.body(r).d);
      for (int id : ids) s.second.push_back(contacts_[id].lambda);
      return s;
    };
    const auto restore = [&](const Snapshot& s) {
      for (size_t i = 0; i < rods.size(); ++i) sys.body(rods[i]).d = s.first[i];
      for (size_t i = 0; i < ids.size(); ++i) contacts_[ids[i]].lambda = s.second[i];
    };
    const Snapshot start = save();
    GroupStats st = solve_group(sys, ids, rods, HessianMode::exact);
    if ((!st.left_domain && !st.capped) || st.status == Status::interrupted) return st;
    // A capped exact iteration is kept if the projected one fails or is capped too.
    const Snapshot exact_end = save();
    restore(start);
    GroupStats again = solve_group(sys, ids, rods, HessianMode::projected);
    if (st.capped && (again.status != Status::success || again.capped)) {
      // Both capped: the result that stretches its rods less is kept. Measured on a 1 um rod
      // of the 5 s edge whip under ADONIS at 30 ms (step 163): the exact result, kept, left an
      // edge stretched 5.4e70 and was reported as a step that succeeded.
      const auto largest_stretch = [&] {
        double most = 0;
        for (int r : rods) most = std::max(most, sys.stretch(r, sys.body(r).d));
        return most;
      };
      if (again.status == Status::success) {
        const double projected = largest_stretch();
        const Snapshot projected_end = save();
        restore(exact_end);
        if (projected < largest_stretch()) {
          restore(projected_end);
          again.restarted = true;
          again.add_work(st);
          return again;
        }
      } else {
        restore(exact_end);
      }
      st.add_work(again);
      return st;
    }
    again.restarted = true;
    again.add_work(st);  // the work of both attempts
    if (again.status != Status::success)
      again.message += fmt::format(" (after a restart with projected re-linearisations; the exact iteration: {})", st.message);
    return again;
  }

  /// A stop request (framework/interrupt.hpp): the group's iteration ends there.
  static bool interrupted(GroupStats& st) {
    if (!stop_requested()) return false;
    st.status = Status::interrupted;
    st.message = fmt::format("the contact solve of a group of {} contacts was interrupted by a stop request at iteration {}", st.contacts, st.outer);
    return true;
  }

  template <class System>
  GroupStats solve_group(System& sys, const std::vector<int>& ids, const std::vector<int>& rods, HessianMode relinearization) {
    GroupStats st;
    st.contacts = static_cast<int>(ids.size());
    // The group's rods are ascending: a contact's rods are found by bisection.
    auto slot_of = [&](int r) { return static_cast<int>(std::lower_bound(rods.begin(), rods.end(), r) - rods.begin()); };
    for (int id : ids) {
      RodContactRows& k = contacts_[id];
      for (int side = 0; side < 2; ++side) k.slot[side] = k.rods[side] >= 0 ? slot_of(k.rods[side]) : -1;
    }
    // The order of the sweeps: detection order, or a shuffle (`order_seed`, ordering tests).
    std::vector<int> order = ids;
    if (prm_.order_seed != 0) std::shuffle(order.begin(), order.end(), std::mt19937_64(prm_.order_seed + 7919ull * ids.front()));
    GroupDisplacements xs(rods.size()), du(rods.size());
    // The first linearisation: K at q + d_DEL for every rod of the group.
    if constexpr (uses_stiffness)
      for (int r : rods)
        if (sys.relinearize(r) != Status::success) {
          st.status = Status::numerical_issue;
          st.message = fmt::format("rod {}: M + h^2 H cannot be factorised", r);
          return st;
        }
    std::vector<int> rebuild = ids;
    std::vector<unsigned char> fresh(rods.size(), 0);  // re-linearised in this iteration, by slot
    for (int outer = 1;; ++outer) {
      st.outer = outer;
      if (interrupted(st)) return st;
      for (int id : rebuild) build_compliance(sys, contacts_[id]);
      // Predictor: the DEL solution first, then d - K^-1 f(d) with each rod's (possibly stale) K.
      // With `predictor = relinearized` a rod whose K was not refreshed keeps its last
      // predictor: its response stays the linear one its stretch accepted. A new predictor with
      // the stale K (modified Newton, `every_rod`) is a full step along K's softest modes
      // (bending and twist of a hair are 1e5-1e9 times softer than its stretching) driven by
      // the nonlinear stretching residual of the rotated edges: on the 250-rod hair ball at
      // 10 ms it moved a coordinate of a rod that was within 1 % by 65-128 (m or rad) at the
      // second iteration, and the group ran away (edges stretched by 1e54 two iterations later).
      for (size_t i = 0; i < rods.size(); ++i) {
        const int r = rods[i];
        if (outer > 1 && prm_.predictor == PredictorUpdate::relinearized && !fresh[i]) {
          xs[i] = du[i];
          continue;
        }
        xs[i] = sys.body(r).d;
        if (outer > 1) {
          Eigen::VectorXd f;
          sys.residual(r, xs[i], f);
          Eigen::MatrixXd F = f;
          sys.solve(r, F);
          xs[i] -= F.col(0);
        }
        du[i] = xs[i];
      }
      for (int id : ids) add_response(contacts_[id], contacts_[id].lambda, xs);
      if constexpr (S == RodStrategy::staggered_projections) {
        // Alternate the contact problem (normal multipliers, friction fixed) and the
        // friction problem (tangential multipliers, normal fixed), each solved by GS, until
        // the multipliers stop changing (relative change below sp_tol) or the Coulomb
        // residual of the group is below contact_tol (the fixed point's own test). With
        // sp_inner > 0 the projections are inexact: each one's sweeps stop once a sweep
        // changes the multipliers by less than sp_inner times its first sweep did, so the
        // error left in a projection shrinks with the progress of the alternation; an exact
        // projection far from the fixed point is wasted work (on the 250-rod ball at 10 ms,
        // 9x less time for the same steps: docs/rods.md). Inexact projections can leave the
        // friction multipliers still while the normal ones are unsolved (mu = 0), so there
        // both must stop changing.
        std::vector<Eigen::Vector3d> before(ids.size());
        Anderson anderson(prm_.sp_anderson);
        Eigen::VectorXd x_k, g_k, mixed;
        for (int sp = 0; sp < prm_.sp_max; ++sp) {
          if (interrupted(st)) return st;
          ++st.sp_iterations;
          for (size_t i = 0; i < ids.size(); ++i) before[i] = contacts_[ids[i]].lambda;
          for (SweepMode mode : {SweepMode::normal, SweepMode::friction}) {
            double first = 0;
            for (int s = 0; s < prm_.gs_max; ++s) {
              ++st.sweeps;
              const auto [d, m] = gauss_seidel_sweep(contacts_, order, xs, mode);
              if (s == 0) first = d;
              if (d <= std::max(1e-3 * prm_.contact_tol, prm_.sp_inner * first) + 1e-12 * m) break;
            }
          }
          double alpha_norm = 0, alpha_change = 0, beta_norm = 0, beta_change = 0;
          for (size_t i = 0; i < ids.size(); ++i) {
            const Eigen::Vector3d& l = contacts_[ids[i]].lambda;
            alpha_change = std::max(alpha_change, std::abs(l[0] - before[i][0]));
            alpha_norm = std::max(alpha_norm, std::abs(l[0]));
            beta_change = std::max(beta_change, (l.tail<2>() - before[i].tail<2>()).norm());
            beta_norm = std::max(beta_norm, l.tail<2>().norm());
          }
          const bool still = beta_change <= prm_.sp_tol * std::max(beta_norm, 1e-300) &&
                             (prm_.sp_inner == 0 || alpha_change <= prm_.sp_tol * std::max(alpha_norm, 1e-300));
          st.residual = contact_error(contacts_, ids, xs);
          if (still || st.residual <= prm_.contact_tol) break;
          if (anderson.depth() > 0) st.residual = accelerate(anderson, ids, before, xs, x_k, g_k, mixed, st.residual);
        }
      } else {
        int sweeps = 0;
        double err = contact_error(contacts_, ids, xs);
        while (err > prm_.contact_tol && sweeps < prm_.gs_max) {
          if (sweeps % 16 == 0 && interrupted(st)) return st;
          gauss_seidel_sweep(contacts_, order, xs, SweepMode::coulomb);
          ++sweeps;
          err = contact_error(contacts_, ids, xs);
        }
        st.sweeps += sweeps;
        st.residual = err;
      }
      // The convergent solver: Newton on the full Coulomb problem of the group from where
      // Gauss-Seidel (or the staggered projections, whose fixed point is the same problem) stopped.
      if (prm_.solver == ContactSolver::newton && st.residual > prm_.contact_tol) {
        const NewtonContactResult nr = solve_contacts_newton(
            contacts_, order, xs, {.tolerance = prm_.contact_tol, .max_iterations = prm_.solver_max, .fallback_sweeps = 10, .dense_limit = 1500});
        st.newton += nr.iterations;
        st.fallbacks += nr.fallbacks;
        st.sweeps += nr.sweeps;
        st.residual = nr.residual;
        if (interrupted(st)) return st;  // the Newton contact solver stopped early for it
      }
      st.unconverged = st.residual > prm_.contact_tol;
      if (outer == 1)
        for (int id : ids) contacts_[id].lambda_first = contacts_[id].lambda;
      if (prm_.solver == ContactSolver::newton && st.unconverged) {
        for (size_t i = 0; i < rods.size(); ++i) sys.body(rods[i]).d = xs[i];
        st.status = Status::no_convergence;
        st.message = fmt::format(
            "group of {} contacts on {} rods (first rod {}): the Newton contact solver stopped at a Fischer-Burmeister residual of {:.3g} m "
            "> contact_tol = {:.3g} m after {} Newton steps in this group ({} fallbacks), constrained Newton iteration {}; raise contact.solver_max or "
            "contact.contact_tol, or reduce dt",
            ids.size(), rods.size(), rods.front(), st.residual, prm_.contact_tol, st.newton, st.fallbacks, outer);
        return st;
      }
      // A cut step leaves the contact laws unsatisfied at the iterate: the iteration goes on.
      int cut = 0;
      if constexpr (relinearizes)
        if (prm_.limit_stretch) cut = limit_outer_step(sys, rods, xs);
      st.damped += cut;
      double change = 0;  // largest move of a vertex coordinate in this iteration
      for (size_t i = 0; i < rods.size(); ++i) {
        auto& d = sys.body(rods[i]).d;
        change = std::max(change, (xs[i] - d).cwiseAbs().maxCoeff());
        d = xs[i];
      }
      if constexpr (!relinearizes) break;
      else {
        std::vector<int> over;
        for (int r : rods)
          if (sys.stretch(r, sys.body(r).d) > prm_.stretch_tol) over.push_back(r);
        if (over.empty() && cut == 0) break;
        // The iterate stopped moving: the constrained Newton iteration has converged, and the
        // step's solution itself stretches a rod beyond the tolerance (e.g. a scripted root
        // pulling a rod whose tip the wall holds). Re-linearising again changes nothing; the
        // step is reported (`stretched_groups`), as a capped one is.
        if (change <= prm_.contact_tol && cut == 0) {
          st.stretched = true;
          break;
        }
        if constexpr (S == RodStrategy::staggered_projections) over = rods;  // global re-linearisation of the group
        if (outer >= prm_.newton_max) {
          st.capped = true;
          break;
        }
        std::fill(fresh.begin(), fresh.end(), 0);
        // The next iteration evaluates every rod of the group at its iterate, which may fold or
        // collapse an edge: the model (its gradient, Hessian and transport) is undefined there,
        // so the step fails with a status instead of asserting inside the parallel region.
        for (int r : rods) {
          const auto& body = sys.body(r);
          if (!body.model.admissible(body.q + body.d, body.frames)) {
            st.status = Status::numerical_issue;
            st.left_domain = true;
            st.message = fmt::format("rod {}: the constrained Newton iterate {} folds or collapses an edge (stretch {:.3g}); reduce dt",
                                     r, outer, sys.stretch(r, body.d));
            return st;
          }
        }
        for (int r : over) {
          if (sys.relinearize(r, relinearization) != Status::success) {
            st.status = Status::numerical_issue;
            st.message = fmt::format("rod {}: M + h^2 H cannot be factorised at Newton iteration {}", r, outer);
            return st;
          }
          fresh[slot_of(r)] = 1;
          ++st.relinearized;
        }
        rebuild.clear();
        for (int id : ids) {
          const RodContactRows& k = contacts_[id];
          if (fresh[k.slot[0]] || (k.slot[1] >= 0 && fresh[k.slot[1]])) rebuild.push_back(id);
        }
      }
    }
    return st;
  }

  Params prm_;
  std::vector<RodContactRows> contacts_;
  std::vector<GroupStats> stats_;
};

using RodImpulse = RodResponse<RodStrategy::impulse>;
using RodLinearCompliance = RodResponse<RodStrategy::linear_compliance>;
using Adonis = RodResponse<RodStrategy::adonis>;
using StaggeredProjections = RodResponse<RodStrategy::staggered_projections>;

/// Rods without contact: the DEL solution is the step.
class NoRodContact {
 public:
  static constexpr std::string_view name = "none";
  static constexpr bool inert = true;  // the simulator skips the contact stage
  struct Params {
    template <class V>
    void visit(V&) {}
  };
  NoRodContact(const Scene&, const Params&) {}
  template <class System>
  ContactReport resolve(System&) {
    return {};
  }
};

}  // namespace weft::contact::rods
