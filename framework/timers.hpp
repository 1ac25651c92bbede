#pragma once
/// \file timers.hpp
/// Stage timers. A fixed, closed list of stages keeps the per-step statistics comparable
/// across every combination of policies.
#include <array>
#include <chrono>
#include <string_view>

namespace weft {

enum class Stage : int {
  energy,         ///< energy and gradient evaluations (including line-search trials)
  hessian,        ///< element Hessians and their assembly into the BlockCsr
  linear_setup,   ///< analyze_pattern + factorize / preconditioner setup
  linear_solve,   ///< solves
  line_search,    ///< line-search bookkeeping (its energy evaluations count under `energy`)
  contact,        ///< detection and response
  output,         ///< writing frames and statistics
  count_
};
inline constexpr std::array<std::string_view, static_cast<int>(Stage::count_)> stage_names = {
    "energy", "hessian", "linear_setup", "linear_solve", "line_search", "contact", "output"};

/// Accumulated wall time per stage [s].
struct StageTimes {
  std::array<double, static_cast<int>(Stage::count_)> seconds{};
  double& operator[](Stage s) { return seconds[static_cast<int>(s)]; }
  double operator[](Stage s) const { return seconds[static_cast<int>(s)]; }
  StageTimes& operator+=(const StageTimes& o) {
    for (size_t i = 0; i < seconds.size(); ++i) seconds[i] += o.seconds[i];
    return *this;
  }
  double total() const {
    double t = 0;
    for (double s : seconds) t += s;
    return t;
  }
};

/// Adds the lifetime of the scope to one stage, or to a plain accumulator.
///
/// Stage timers are exclusive: a stage timer opened inside another one on the same thread
/// (the energy evaluations of a line search, say) is charged to its own stage only and is
/// taken out of the enclosing stage, so the stages of a step are disjoint and their sum never
/// exceeds the step's wall time. Plain accumulators (`ScopedTimer(double&)`, the detection
/// and response seconds of a contact report) measure their scope inclusively and take no part
/// in the nesting.
class ScopedTimer {
 public:
  ScopedTimer(StageTimes& times, Stage stage)
      : target_(&times[stage]), start_(std::chrono::steady_clock::now()), parent_(current()), nested_(true) {
    current() = this;
  }
  explicit ScopedTimer(double& target) : target_(&target), start_(std::chrono::steady_clock::now()) {}
  ~ScopedTimer() {
    const double t = elapsed();
    if (!nested_) {
      *target_ += t;
      return;
    }
    *target_ += t - children_;
    if (parent_) parent_->children_ += t;
    current() = parent_;
  }
  ScopedTimer(const ScopedTimer&) = delete;
  ScopedTimer& operator=(const ScopedTimer&) = delete;
  /// Inclusive time since the scope opened [s].
  double elapsed() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  static ScopedTimer*& current() {
    thread_local ScopedTimer* open = nullptr;
    return open;
  }
  double* target_;
  std::chrono::steady_clock::time_point start_;
  ScopedTimer* parent_ = nullptr;
  double children_ = 0;
  bool nested_ = false;
};

}  // namespace weft
