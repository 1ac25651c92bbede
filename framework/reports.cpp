#include "framework/reports.hpp"

#include <algorithm>
#include <cmath>

namespace weft {
namespace {
// JSON has no NaN/Inf: write them as strings so every line stays valid JSON.
Json num(double x) {
  if (std::isfinite(x)) return x;
  if (std::isnan(x)) return "nan";
  return x > 0 ? "inf" : "-inf";
}
}  // namespace

std::string_view to_string(Status s) {
  switch (s) {
    case Status::success: return "success";
    case Status::no_convergence: return "no_convergence";
    case Status::numerical_issue: return "numerical_issue";
    case Status::invalid_input: return "invalid_input";
    case Status::interrupted: return "interrupted";
  }
  return "?";
}

void LinearReport::accumulate(const LinearReport& r) {
  solves += r.solves;
  iterations += r.iterations;
  relative_residual = std::max(relative_residual, r.relative_residual);
  setup_seconds += r.setup_seconds;
  solve_seconds += r.solve_seconds;
  if (r.negative_pivots >= 0) negative_pivots = std::max(negative_pivots, r.negative_pivots);
  indefinite = indefinite || r.indefinite;
  if (r.solves > 0 && r.convergence_rate > 0)
    convergence_rate = (convergence_rate * (solves - r.solves) + r.convergence_rate * r.solves) / solves;
  energy_error = std::max(energy_error, r.energy_error);
  constraint_violation = std::max(constraint_violation, r.constraint_violation);
  prefilter_seconds += r.prefilter_seconds;
  memory_bytes = std::max(memory_bytes, r.memory_bytes);
  levels = std::max(levels, r.levels);
  operator_complexity = std::max(operator_complexity, r.operator_complexity);
  if (!r.residual_history.empty()) residual_history = r.residual_history;
  if (r.status != Status::success && status == Status::success) {
    status = r.status;
    message = r.message;
  }
}

StepReport& StepReport::merge_substep(const StepReport& next) {
  newton.iterations += next.newton.iterations;
  newton.final_residual = next.newton.final_residual;
  newton.tolerance = next.newton.tolerance;
  newton.stop_reason = next.newton.stop_reason;
  newton.round_off_steps += next.newton.round_off_steps;
  newton.history.insert(newton.history.end(), next.newton.history.begin(), next.newton.history.end());
  if (next.newton.status != Status::success) {
    newton.status = next.newton.status;
    newton.message = next.newton.message;
  }
  linear.accumulate(next.linear);
  contact.merge_end(next.contact);
  times += next.times;
  substeps += next.substeps;
  subdivisions = std::max(subdivisions, next.subdivisions);
  discarded_newton_iterations += next.discarded_newton_iterations;
  if (retry_reason.empty()) retry_reason = next.retry_reason;
  time = next.time;
  if (!next.ok()) {
    status = next.status;
    failed_stage = next.failed_stage;
    message = next.message;
  }
  return *this;
}

Json to_json(const LinearReport& r) {
  Json j{{"status", to_string(r.status)}, {"solves", r.solves}, {"iterations", r.iterations},
         {"max_relative_residual", num(r.relative_residual)}, {"setup_seconds", r.setup_seconds},
         {"solve_seconds", r.solve_seconds}};
  if (r.negative_pivots >= 0) j["negative_pivots"] = r.negative_pivots;
  j["indefinite"] = r.indefinite;
  if (r.convergence_rate > 0) j["convergence_rate"] = num(r.convergence_rate);
  if (r.energy_error >= 0) j["energy_error"] = num(r.energy_error);
  if (r.constraint_violation > 0) j["constraint_violation"] = num(r.constraint_violation);
  if (r.prefilter_seconds > 0) j["prefilter_seconds"] = r.prefilter_seconds;
  if (r.memory_bytes > 0) j["memory_bytes"] = r.memory_bytes;
  if (r.levels > 0) {
    j["levels"] = r.levels;
    j["operator_complexity"] = num(r.operator_complexity);
  }
  if (!r.message.empty()) j["message"] = r.message;
  return j;
}

Json to_json(const NewtonReport& r, bool with_history) {
  Json j{{"status", to_string(r.status)}, {"iterations", r.iterations}, {"initial_residual", num(r.initial_residual)},
         {"final_residual", num(r.final_residual)}, {"tolerance", num(r.tolerance)}, {"stop_reason", r.stop_reason},
         {"method", r.method}};
  if (!r.message.empty()) j["message"] = r.message;
  if (with_history) {
    Json h = Json::array();
    for (const auto& it : r.history)
      h.push_back({{"merit", num(it.merit)}, {"residual", num(it.residual)}, {"slope", num(it.directional_derivative)},
                   {"step_length", num(it.step_length)}, {"step_norm", num(it.step_norm)},
                   {"line_search_evaluations", it.line_search_evaluations}, {"linear_iterations", it.linear_iterations},
                   {"projected", it.projected}, {"shift", it.shift},
                   {"constraints_updated", it.constraints_updated}, {"step_bound", num(it.step_bound)}});
    j["history"] = h;
  }
  return j;
}

Json to_json(const ContactReport& r) {
  Json j{{"status", to_string(r.status)}, {"contacts", r.contacts}, {"detection_seconds", r.detection_seconds},
         {"response_seconds", r.response_seconds}};
  // Strategy counters: written when set, so a scene without that strategy stays terse.
  const auto put = [&j](const char* key, auto v) {
    if (v != 0) j[key] = v;
  };
  put("obstacle_contacts", r.obstacle_contacts);
  put("proximity_contacts", r.proximity_contacts);
  put("ccd_hits", r.ccd_hits);
  put("ccd_sweeps", r.ccd_sweeps);
  put("impulses", r.impulses);
  put("impact_zones", r.impact_zones);
  put("zone_vertices", r.zone_vertices);
  put("zone_iterations", r.zone_iterations);
  put("released", r.released);
  put("sticking", r.sticking);
  put("projected", r.projected);
  put("max_penetration", r.max_penetration);
  put("solve_penetration", r.solve_penetration);
  put("redetected", r.redetected);
  put("springs", r.springs);
  put("pattern_updates", r.pattern_updates);
  put("barrier_pairs", r.barrier_pairs);
  put("min_gap", r.min_gap);
  put("bounded_steps", r.bounded_steps);
  put("gs_sweeps", r.gs_sweeps);
  put("gs_residual", r.gs_residual);
  put("gs_unconverged", r.gs_unconverged);
  put("rod_contacts", r.rod_contacts);
  put("contact_groups", r.contact_groups);
  put("largest_group", r.largest_group);
  put("outer_iterations", r.outer_iterations);
  put("max_outer_iterations", r.max_outer_iterations);
  put("relinearized", r.relinearized);
  put("sp_alternations", r.sp_alternations);
  put("capped_groups", r.capped_groups);
  put("stretched_groups", r.stretched_groups);
  put("restarted_groups", r.restarted_groups);
  put("contact_newton", r.contact_newton);
  put("damped_steps", r.damped_steps);
  put("contact_fallbacks", r.contact_fallbacks);
  put("max_stretch", r.max_stretch);
  put("redetections", r.redetections);
  if (!r.message.empty()) j["message"] = r.message;
  return j;
}

Json to_json(const StageTimes& t) {
  Json j = Json::object();
  for (size_t i = 0; i < t.seconds.size(); ++i) j[std::string(stage_names[i])] = t.seconds[i];
  return j;
}

Json to_json(const StepReport& r) {
  Json energies{{"kinetic", num(r.energy.kinetic)}, {"potential", num(r.energy.potential)},
                {"total", num(r.energy.kinetic + r.energy.potential)}};
  for (const auto& [name, value] : r.energy.terms) energies[name] = num(value);
  Json j{{"step", r.step},       {"time", r.time},
         {"dt", r.dt},           {"status", to_string(r.status)},
         {"energy", energies},   {"newton", to_json(r.newton)},
         {"linear", to_json(r.linear)}, {"contact", to_json(r.contact)},
         {"seconds", to_json(r.times)}};
  if (r.substeps > 1 || !r.retry_reason.empty()) {
    j["substeps"] = r.substeps;
    j["subdivisions"] = r.subdivisions;
    j["discarded_newton_iterations"] = r.discarded_newton_iterations;
    j["retry_reason"] = r.retry_reason;
  }
  if (!r.failed_stage.empty()) j["failed_stage"] = r.failed_stage;
  if (!r.message.empty()) j["message"] = r.message;
  return j;
}

}  // namespace weft
