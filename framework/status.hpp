#pragma once
/// \file status.hpp
/// Numerical outcomes and the reports every stage returns. A `StepReport` nests the
/// Newton, linear and contact reports of one time step; ablations, plots and benchmarks
/// read these, never log lines.
#include <algorithm>
#include <array>
#include <cstddef>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "framework/timers.hpp"

namespace weft {

/// Outcome of a numerical stage. Returned, never thrown.
enum class Status {
  success,          ///< converged / completed
  no_convergence,   ///< iteration limit reached before the tolerance
  numerical_issue,  ///< NaN/Inf, breakdown, failed line search, singular matrix
  invalid_input,    ///< the stage was called with inconsistent data
  interrupted,      ///< stopped by a signal between steps
};
std::string_view to_string(Status s);

/// One linear solve (or the sum over the solves of a step, see `accumulate`).
struct LinearReport {
  Status status = Status::success;
  int solves = 0;                 ///< number of solves summarised
  int iterations = 0;             ///< Krylov iterations (0 for direct solvers)
  double relative_residual = 0;   ///< true ||b - A x|| / ||b|| of the last solve
  double setup_seconds = 0;       ///< analyze_pattern + factorize
  double solve_seconds = 0;
  int negative_pivots = -1;       ///< LDL^T only: count of negative D entries (-1: unknown)
  bool indefinite = false;        ///< the solver found the matrix not positive definite
  std::string message;
  // Iterative solvers (methods/multigrid §8). The criterion is ||r_i||_{M^-1} / ||r_0||_{M^-1} < eps.
  std::vector<double> residual_history;  ///< ||r_i||_{M^-1} / ||r_0||_{M^-1}, i = 0..N (last solve)
  double convergence_rate = 0;    ///< geometric mean rate (||r_N|| / ||r_0||)^(1/N) (mean over solves when summed)
  double energy_error = -1;       ///< ||x - x*||_A / ||x*||_A against a known solution (-1: not computed)
  double constraint_violation = 0;  ///< max |n^T x - value| over the constrained directions
  double prefilter_seconds = 0;   ///< building S A S + Sigma (I - S) and S (b - A z)
  std::size_t memory_bytes = 0;   ///< solver-owned storage (factors, hierarchy, work vectors)
  int levels = 0;                 ///< multigrid levels (0: none)
  double operator_complexity = 0; ///< sum_l nnz(A_l) / nnz(A_1) (multigrid)
  void accumulate(const LinearReport& r);
};

/// One Newton iteration of a time step.
struct NewtonIteration {
  double merit = 0;                   ///< merit function at the start of the iteration
  double residual = 0;                ///< ||f||_{M^-1} at the start of the iteration
  double directional_derivative = 0;  ///< d merit / ds at s = 0 along the direction
  double step_length = 0;             ///< accepted line-search step s
  double step_norm = 0;               ///< max-norm of the accepted displacement increment [m]
  int line_search_evaluations = 0;
  int linear_iterations = 0;
  bool projected = false;             ///< the direction used the PSD-projected Hessian
  double shift = 0;                   ///< tau of the shifted matrix K + tau M~ (0: unshifted)
  bool constraints_updated = false;   ///< contacts were added at the iterate this update reached (re-detection)
  double step_bound = 1;              ///< bounded problems: the admissible fraction of the direction (CCD), 1 otherwise
};

struct NewtonReport {
  Status status = Status::success;
  int iterations = 0;
  double initial_residual = 0;  ///< ||f(d0)||_{M^-1}
  double final_residual = 0;
  double tolerance = 0;         ///< the residual threshold that was used
  std::string stop_reason;      ///< which criterion stopped the iteration
  int round_off_steps = 0;      ///< full steps taken on the derivative test, E_inc's decrease below round-off
  std::string method;           ///< the solver: merit, globalisation, line search, Hessian choice
  std::vector<NewtonIteration> history;
  std::string message;
};

struct ContactReport {
  Status status = Status::success;
  int contacts = 0;
  double detection_seconds = 0;
  double response_seconds = 0;
  std::string message;
  // Counters of the impulse strategy (contact/impulse.hpp); 0 for the other strategies.
  int obstacle_contacts = 0;   ///< vertex-obstacle contacts (within the thickness at the end of the step, or crossed during it)
  int proximity_contacts = 0;  ///< cloth-cloth proximity pairs closer than the thickness at the end of the step
  int ccd_hits = 0;            ///< cloth-cloth CCD hits, summed over every detection of the step
  int ccd_sweeps = 0;          ///< CCD impulse sweeps that applied impulses
  int impulses = 0;            ///< impulses applied (obstacle, repulsion and CCD)
  int impact_zones = 0;        ///< impact zones (failsafe) at the end of the step
  int zone_vertices = 0;       ///< vertices moved rigidly by the impact zones
  int zone_iterations = 0;     ///< impact-zone iterations (0: the impulses sufficed)
  double max_penetration = 0;  ///< [m] largest depth of a free vertex below the contact thickness of an obstacle after the response
  // Counters of the obstacle-constraint strategy (contact/obstacle_constraints.hpp), which also
  // fills `obstacle_contacts` and `max_penetration`; 0 for the other strategies.
  int released = 0;            ///< contacts released, each once: at end_step when its normal reaction pulled, at begin_step when vertex and obstacle separate
  int sticking = 0;            ///< contacts held by static friction (3D constraints) during the step
  int projected = 0;           ///< vertices projected onto an obstacle's thickness surface after the solve
  double solve_penetration = 0;  ///< [m] largest depth below the contact thickness after the solve, before the projection
  int redetected = 0;          ///< contacts added (rods: or end-overlap contacts moved, overlap_follow) by the re-detections of the step (obstacle constraints: vertices the solve put inside; see `redetections`)
  // Counters of the implicit contact strategy (contact/implicit_contact.hpp).
  int springs = 0;             ///< cloth-cloth repulsion springs of the step (pairs within the thickness at the start or the prediction)
  int pattern_updates = 0;     ///< 1 when the springs changed the matrix pattern this step (new symbolic analysis)
  // Counters of the linear compliance strategy (contact/linear_compliance.hpp).
  int gs_sweeps = 0;           ///< Gauss-Seidel sweeps of the contact solve
  double gs_residual = 0;      ///< [m/s] largest Fischer-Burmeister residual at its end
  int gs_unconverged = 0;      ///< 1 when the contact solve stopped at its sweep limit above the tolerance
  // Counters of the rod strategies (contact/rods/): impulse, linear compliance, ADONIS, staggered projections.
  int rod_contacts = 0;        ///< rod-rod contacts (obstacle contacts of rods count in `obstacle_contacts`)
  int contact_groups = 0;      ///< connected components of rods linked by contacts
  int largest_group = 0;       ///< contacts in the largest group
  int outer_iterations = 0;    ///< constrained Newton iterations, summed over the groups
  int max_outer_iterations = 0;  ///< constrained Newton iterations of the group that needed most
  int relinearized = 0;        ///< rod Hessians re-evaluated and refactored after the first iteration, summed
  int sp_alternations = 0;     ///< staggered projections: alternations (contact problem, then friction problem), summed over the groups and iterations
  int capped_groups = 0;       ///< groups that stopped at the Newton cap above the stretch tolerance
  int stretched_groups = 0;    ///< groups whose constrained Newton converged (the iterate stopped moving) with a rod above the stretch tolerance
  int restarted_groups = 0;    ///< groups solved again with projected re-linearisations after the exact iteration left the model's domain or stopped at newton_max (contact.projected_restart)
  double max_stretch = 0;      ///< largest edge extension |e|/|e_rest| - 1 after the response
  int redetections = 0;        ///< detections on the corrected trajectory that found new contacts (then solved again); obstacle constraints: rounds in which the converged solve left vertices inside and was continued with their contacts
  int contact_newton = 0;      ///< `contact.solver = newton` (rods, linear compliance on cloth): Newton iterations of the contact solves, summed over groups and outer iterations
  int contact_fallbacks = 0;   ///< `contact.solver = newton`: steps taken by its fallbacks (damped least squares, Gauss-Seidel) instead of Newton
  int damped_steps = 0;        ///< ADONIS, staggered projections: rod steps of the constrained Newton iteration cut by its strain trust region (contact.limit_stretch)
  // Counters of the barrier strategy (contact/barrier.hpp).
  int barrier_pairs = 0;       ///< pairs (point-triangle, edge-edge, obstacle) within the thickness at the end of the step
  double min_gap = 0;          ///< [m] smallest distance of a pair within the thickness at the end of the step (0: none)
  int bounded_steps = 0;       ///< Newton directions the CCD cut short (step bound < 1), summed over the step

  /// Folds the report of `end_step` into that of `begin_step` (one step's report): times and
  /// event counters (impulses, hits, releases, projections) add up, counts of contacts
  /// present take the larger, depths the end-of-step value (after the response) or the
  /// larger (during the solve); a failing `end` sets the status and message.
  ContactReport& merge_end(const ContactReport& end) {
    if (end.status != Status::success) {
      status = end.status;
      message = end.message;
    }
    contacts = std::max(contacts, end.contacts);
    obstacle_contacts = std::max(obstacle_contacts, end.obstacle_contacts);
    proximity_contacts = std::max(proximity_contacts, end.proximity_contacts);
    sticking = std::max(sticking, end.sticking);
    detection_seconds += end.detection_seconds;
    response_seconds += end.response_seconds;
    ccd_hits += end.ccd_hits;
    ccd_sweeps += end.ccd_sweeps;
    impulses += end.impulses;
    impact_zones += end.impact_zones;
    zone_vertices += end.zone_vertices;
    zone_iterations += end.zone_iterations;
    released += end.released;
    projected += end.projected;
    springs = std::max(springs, end.springs);
    pattern_updates += end.pattern_updates;
    gs_sweeps += end.gs_sweeps;
    gs_residual = std::max(gs_residual, end.gs_residual);
    gs_unconverged += end.gs_unconverged;
    rod_contacts = std::max(rod_contacts, end.rod_contacts);
    contact_groups = std::max(contact_groups, end.contact_groups);
    largest_group = std::max(largest_group, end.largest_group);
    outer_iterations += end.outer_iterations;
    max_outer_iterations = std::max(max_outer_iterations, end.max_outer_iterations);
    relinearized += end.relinearized;
    sp_alternations += end.sp_alternations;
    capped_groups += end.capped_groups;
    stretched_groups += end.stretched_groups;
    restarted_groups += end.restarted_groups;
    max_stretch = end.max_stretch;
    redetections += end.redetections;
    redetected += end.redetected;
    contact_newton += end.contact_newton;
    contact_fallbacks += end.contact_fallbacks;
    damped_steps += end.damped_steps;
    max_penetration = end.max_penetration;
    solve_penetration = std::max(solve_penetration, end.solve_penetration);
    barrier_pairs = end.barrier_pairs;
    min_gap = end.min_gap;
    bounded_steps += end.bounded_steps;
    return *this;
  }
};

/// Energies at the end of a step [J]; `terms` follows the energy model's term names.
struct EnergyReport {
  double kinetic = 0;
  double potential = 0;  ///< sum of the terms
  std::vector<std::pair<std::string, double>> terms;
};

/// Everything one time step did.
struct StepReport {
  int step = 0;        ///< 1-based step index
  double time = 0;     ///< simulated time at the end of the step [s]
  double dt = 0;       ///< [s]
  Status status = Status::success;
  std::string failed_stage;  ///< the stage that failed ("" on success)
  std::string message;       ///< why it failed
  NewtonReport newton;
  LinearReport linear;       ///< summed over the Newton iterations of the step
  ContactReport contact;
  EnergyReport energy;
  StageTimes times;          ///< includes failed attempts that were retried as substeps
  // Step subdivision (`time.max_subdivisions`, cloth): a failed attempt is retried as two half steps.
  int substeps = 1;          ///< steps of dt/2^k taken to cover dt (1: no subdivision)
  int subdivisions = 0;      ///< deepest halving used: the smallest substep was dt/2^subdivisions
  int discarded_newton_iterations = 0;  ///< Newton iterations of the failed attempts (not in `newton`)
  std::string retry_reason;  ///< why the first attempt at dt failed ("" when it did not)
  bool ok() const { return status == Status::success; }
  /// Appends the report of the next substep: iterations, solves, times and event counters add
  /// up, the residuals, contact state and status are the later substep's.
  StepReport& merge_substep(const StepReport& next);
  /// Marks the step as failed in `stage` for `why`; its time is the end of the step that
  /// failed (`step_start` + dt).
  StepReport& fail(std::string stage, Status s, std::string why, double step_start) {
    status = s;
    failed_stage = std::move(stage);
    message = std::move(why);
    time = step_start + dt;
    return *this;
  }
};

}  // namespace weft
