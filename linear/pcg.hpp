#pragma once
/// \file pcg.hpp
/// Preconditioned conjugate gradients with per-vertex constraints (methods/multigrid §7-8), in the
/// two forms the thesis compares:
///
/// - `ModifiedPcg<P>`: Baraff-Witkin 1998 modified PCG (MPCG, methods/multigrid §7.2). x starts at z
///   on the constrained directions and stays there; the residual and the search direction
///   are filtered by S = blockdiag(S_i) inside the loop. The preconditioner is built from
///   the *unfiltered* A (it knows nothing about the constraints).
///       x = z (+ S x_in with warm_start);  r = S (b - A x);  p = S B r;  delta = r^T B r
///       loop:  q = S A p;  alpha = delta / p^T q;  x += alpha p;  r -= alpha q
///              s = B r;  delta' = r^T s;  p = S (s + (delta'/delta) p)
/// - `Ppcg<P>`: prefiltered PCG (PPCG, methods/multigrid §7.3-7.4). The constrained problem becomes
///   the SPD system of A's size and pattern (linear/prefilter.hpp)
///       (S A S + Sigma (I - S)) y = S (b - A z),   x = z + S y,
///   the preconditioner is set up *from Ahat* (with the constraint set, so SA can make its
///   near-null modes admissible), and standard, unfiltered PCG runs from y0 = 0 (the thesis
///   does not state its initial guess; zero is the faithful choice, methods/multigrid §8) or, with
///   warm_start, from y0 = S (x_in - z). The final x = z + S y meets the constraints to
///   round-off.
///
/// Both stop when ||r_i||_{B} / ||r_0||_{B} < tolerance with ||r||_B = sqrt(r^T B r), B the
/// preconditioner (the thesis's M^{-1}-norm criterion, methods/multigrid §8), and guard the two CG
/// breakdowns of methods/multigrid §6.2: r^T B r <= 0 ("preconditioner not positive definite") and
/// p^T A p <= 0 ("matrix not positive definite", `indefinite` set), both
/// Status::numerical_issue, like NaN/Inf. The iteration limit gives Status::no_convergence
/// with the reached residual in the message. On failure x holds the last iterate.
///
/// Without constraints both forms are plain PCG and give identical iterates.
///
/// Concrete policies: `DiagPcg` (thesis baseline, MPCG + block Jacobi) and `DiagPpcg`
/// (PPCG + block Jacobi). The member definitions live in linear/pcg_impl.hpp, so another
/// translation unit can instantiate the templates for another preconditioner:
///     #include "linear/pcg_impl.hpp"
///     template class weft::linear::Ppcg<weft::linear::SaAmg>;
#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "framework/block_csr.hpp"
#include "framework/concepts.hpp"
#include "framework/constraints.hpp"
#include "framework/params.hpp"
#include "framework/status.hpp"
#include "linear/block_jacobi.hpp"
#include "linear/preconditioner.hpp"
#include "linear/prefilter.hpp"

namespace weft::linear {

/// When the preconditioner is (re)built.
enum class PreconditionerSetup {
  every_factorize,   ///< rebuilt for every linear solve (thesis, methods/multigrid §9)
  once_per_pattern,  ///< built at the first factorize after analyze_pattern, then frozen
                     ///< (a frozen SPD preconditioner keeps PCG valid; only its quality drops).
                     ///< Needs a preconditioner that owns its data (no reference to the matrix,
                     ///< whose values change; BlockJacobi copies)
};
inline constexpr std::array<std::string_view, 2> preconditioner_setup_names = {"every_factorize", "once_per_pattern"};

template <class PrecondParams>
struct KrylovParams;

namespace detail {
/// Why a run resumed from a checkpoint (framework/checkpoint.hpp) would not repeat the
/// uninterrupted one to the bit: a preconditioner kept across solves is rebuilt at the
/// first solve after the restore, from another matrix than the one it was built from.
template <class PrecondParams>
std::string kept_preconditioner_caveat(const KrylovParams<PrecondParams>& p);
}  // namespace detail

/// Parameters of the Krylov solvers; the preconditioner's own parameters nest under
/// "preconditioner" when they have a `visit`.
template <class PrecondParams>
struct KrylovParams {
  double tolerance = 1e-5;    ///< [-] in (0, 1): stop when ||r_i||_B / ||r_0||_B < tolerance (methods/multigrid §8)
  int max_iterations = 10000; ///< >= 1: CG iterations before Status::no_convergence
  bool warm_start = false;    ///< start from the x given to solve() (projected onto the constraints)
                              ///< instead of x = z (y0 = 0); changes what the relative criterion means
  PreconditionerSetup setup = PreconditionerSetup::every_factorize;  ///< when the preconditioner is rebuilt
  PrecondParams preconditioner{};  ///< the preconditioner's own parameters

  template <class V>
  void visit(V& v) {
    v.field("tolerance", tolerance,
            {Unit::none, Range::open(0, 1), "stop when ||r_i||_B / ||r_0||_B < tolerance, B the preconditioner"});
    v.field("max_iterations", max_iterations,
            {Unit::none, Range::closed(1, 1e8), "CG iterations before the solve reports no_convergence"});
    v.field("warm_start", warm_start,
            {Unit::none, Range::any(), "start from the given x (projected onto the constraints) instead of x = z"});
    v.choice("setup", setup, preconditioner_setup_names,
             "every_factorize: rebuild the preconditioner for each solve (thesis); once_per_pattern: freeze it "
             "until the next analyze_pattern");
    if constexpr (requires(PrecondParams& q, V& w) { q.visit(w); }) v.section("preconditioner", preconditioner);
  }
  static Checker validate(const KrylovParams& p) {
    Checker c("linear");
    c.require(p.tolerance > 0 && p.tolerance < 1, "tolerance", p.tolerance, "in (0, 1)")
        .require(p.max_iterations >= 1, "max_iterations", p.max_iterations, ">= 1");
    if constexpr (requires { PrecondParams::validate(p.preconditioner); })
      c.merge(PrecondParams::validate(p.preconditioner));
    return c;
  }
};

namespace detail {

/// The per-vertex filters S_i of a constraint set in the form the CG loops apply.
class VertexFilters {
 public:
  /// From a constraint set (an empty set gives empty filters).
  void build(const ConstraintSet& c);
  void clear();
  bool empty() const { return S_.empty() && full_ == 0; }
  /// v <- S_i v.
  void apply(int i, Eigen::Vector3d& v) const {
    const int s = slot_[i];
    if (s == free_slot) return;
    if (s == full_slot) v.setZero();
    else v = S_[s] * v;
  }
  std::size_t bytes() const { return slot_.capacity() * sizeof(int) + S_.capacity() * sizeof(Block3); }

 private:
  static constexpr int free_slot = -1, full_slot = -2;
  std::vector<int> slot_;   // per vertex: free_slot, full_slot, or index into S_
  std::vector<Block3> S_;   // filters of partially constrained vertices
  int full_ = 0;
};

/// A preconditioner as the (non-template) CG core sees it.
struct PrecondView {
  const void* self = nullptr;
  void (*apply)(const void* self, const Eigen::VectorXd& r, Eigen::VectorXd& z) = nullptr;
  /// Non-null when B can borrow a work vector of r's size (`apply(r, z, work)`): the CG
  /// lends its A p vector, idle while B is applied, so B need not own one.
  void (*apply_work)(const void* self, const Eigen::VectorXd& r, Eigen::VectorXd& z, Eigen::VectorXd& work) = nullptr;
  /// Non-null: B is block diagonal with these 3x3 row-major blocks; the core then fuses
  /// z = B r and r^T z into the vector update.
  const double* block_inverse = nullptr;
};

/// Work vectors of the CG loop, allocated once per size.
struct KrylovWork {
  Eigen::VectorXd r, z, p, q;
  bool preconditioner_breakdown = false;  ///< the last `pcg` stopped on r^T B r <= 0 for r != 0
  void resize(Eigen::Index n);
  std::size_t bytes() const { return sizeof(double) * static_cast<std::size_t>(r.size() + z.size() + p.size() + q.size()); }
};

struct KrylovOptions {
  double tolerance = 1e-5;
  int max_iterations = 10000;
};

/// PCG (S == nullptr) or BW98 modified PCG (S given; x must already be feasible) on
/// A x = b from the x given; with filters F (PPCG on the fly), on Ahat x = b where Ahat =
/// S A S + Sigma (I - S) is applied from A and F without being stored. b may be w.r itself
/// (PPCG writes its prefiltered right-hand side there). Fills status,
/// iterations, residual_history, convergence_rate, indefinite and message of `rep`. No
/// allocation inside the iteration loop.
void pcg(const BlockCsr& A, const Eigen::VectorXd& b, Eigen::VectorXd& x, const PrecondView& B,
         const VertexFilters* S, const KrylovOptions& opt, KrylovWork& w, LinearReport& rep,
         const VertexFilterView& F = {});

/// Diagnostics after a solve of the constrained problem (c may be null): the true relative
/// residual ||S (b - A x)|| / ||S b||, the constraint violation and, with x_star, the energy
/// error ||S (x - x*)||_A / ||x*||_A. `tmp` is scratch.
void diagnose(const BlockCsr& A, const ConstraintSet* c, const Eigen::VectorXd& b, const Eigen::VectorXd& x,
              const Eigen::VectorXd* x_star, Eigen::VectorXd& tmp, LinearReport& rep);

/// The preconditioner with its setup policy and the outcome of its last setup.
template <Preconditioner P>
class PreconditionerSlot {
 public:
  PreconditionerSlot(const typename P::Params& prm, PreconditionerSetup policy) : p_(prm), policy_(policy) {}
  Status analyze_pattern(const BlockCsr& A);
  /// Builds from M unless frozen (once_per_pattern after a successful build); with a
  /// non-empty F, from the operator M read through F (P must support it: `filters_on_the_fly`).
  Status setup(const BlockCsr& M, const SolveContext& ctx, const VertexFilterView& F = {});
  const P& get() const { return p_; }
  PrecondView view() const;
  Status status() const { return status_; }
  const std::string& message() const { return message_; }
  /// A failed setup of a block-diagonal preconditioner proves the matrix not positive definite.
  bool proves_indefinite() const;
  /// A new time step begins (forwarded to P if it keeps a hierarchy per step: SaAmg).
  void begin_step() {
    if constexpr (requires { p_.begin_step(); }) p_.begin_step();
  }
  /// Number of builds since construction (tests of the setup policy).
  int builds() const { return builds_; }
  /// After a preconditioner breakdown: whether P could make itself SPD again; the solve is
  /// then repeated once. A hierarchy kept from another matrix (SaAmg under reuse = frozen or
  /// step: that matrix may have been indefinite, the exact Hessian of an earlier Newton
  /// iteration) is set up again from M, the matrix of the failed solve; otherwise SaAmg widens
  /// its smoothers' intervals to a guaranteed bound.
  bool recover_from_breakdown(const BlockCsr& M, const SolveContext& ctx, const VertexFilterView& F = {}) {
    if constexpr (requires { { p_.kept() } -> std::same_as<bool>; p_.begin_step(); }) {
      if (p_.kept() && policy_ == PreconditionerSetup::every_factorize) {
        p_.begin_step();
        return setup(M, ctx, F) == Status::success;
      }
    }
    if constexpr (requires { { p_.widen_smoothers() } -> std::same_as<bool>; }) return p_.widen_smoothers();
    else return false;
  }

 private:
  P p_;
  PreconditionerSetup policy_;
  bool built_ = false;
  int builds_ = 0;
  Status status_ = Status::invalid_input;
  std::string message_ = "call analyze_pattern() and factorize() before solve()";
};

}  // namespace detail

/// Baraff-Witkin modified PCG; the preconditioner is built from the unfiltered A.
template <Preconditioner P>
class ModifiedPcg {
 public:
  static constexpr std::string_view name = "mpcg";
  /// Nothing carried between steps changes the next one (checkpoints), except a kept
  /// preconditioner: `resume_caveat`.
  static constexpr bool stateless = true;
  using Params = KrylovParams<typename P::Params>;

  explicit ModifiedPcg(const Params& prm);
  Status analyze_pattern(const BlockCsr& A);
  /// Builds the filters from the context's constraints and sets up the preconditioner from
  /// A (given the positions but not the constraints). A must outlive the next solve.
  Status factorize(const BlockCsr& A);
  /// x: the initial guess on entry (read only with warm_start), the solution on exit.
  LinearReport solve(const Eigen::VectorXd& b, Eigen::VectorXd& x);
  /// The constraints and positions of the next factorize.
  void set_context(const SolveContext& ctx) { ctx_ = ctx; }
  /// A known solution x* for the energy error of the next solves (nullptr: none; not owned):
  /// energy_error = ||S (x - x*)||_A / ||x*||_A with the unfiltered A (methods/multigrid §8, V23).
  void set_reference(const Eigen::VectorXd* x_star) { x_star_ = x_star; }
  /// The relative tolerance of the next solves, looser than linear.tolerance (an inexact
  /// Newton's forcing term); 0 or below linear.tolerance: linear.tolerance.
  void set_tolerance(double relative) { forced_tolerance_ = relative; }
  /// A new time step begins (`HasStepHook`): a preconditioner kept per step refreshes next.
  void begin_step() { slot_.begin_step(); }
  const P& preconditioner() const { return slot_.get(); }
  int preconditioner_builds() const { return slot_.builds(); }
  std::string resume_caveat() const { return detail::kept_preconditioner_caveat(prm_); }

 private:
  const ConstraintSet* constraints() const {
    return ctx_.constraints && !ctx_.constraints->empty() ? ctx_.constraints : nullptr;
  }
  Params prm_;
  detail::PreconditionerSlot<P> slot_;
  detail::VertexFilters filters_;
  detail::KrylovWork work_;
  SolveContext ctx_;
  const BlockCsr* A_ = nullptr;
  const Eigen::VectorXd* x_star_ = nullptr;
  double setup_seconds_ = 0;
  double forced_tolerance_ = 0;
  std::string input_error_;
  double tolerance() const { return std::max(prm_.tolerance, forced_tolerance_); }
};

/// Whether P can be set up from A read through per-vertex filters (Ahat on the fly):
/// `setup(A, ctx, VertexFilterView)`.
template <class P>
concept FiltersOnTheFly = requires(P& p, const BlockCsr& A, const SolveContext& ctx, const VertexFilterView& F) {
  { p.setup(A, ctx, F) } -> std::same_as<Status>;
};

/// Prefiltered PCG; the preconditioner is built from Ahat = S A S + Sigma (I - S). When P
/// supports it (`FiltersOnTheFly`: BlockJacobi, SaAmg), Ahat is not stored: CG and the
/// preconditioner read A through the per-vertex filters; otherwise a copy of A's size is
/// prefiltered (none when A is already prefiltered).
template <Preconditioner P>
class Ppcg {
 public:
  static constexpr std::string_view name = "ppcg";
  /// Nothing carried between steps changes the next one (checkpoints), except a kept
  /// preconditioner: `resume_caveat`.
  static constexpr bool stateless = true;
  using Params = KrylovParams<typename P::Params>;

  explicit Ppcg(const Params& prm);
  Status analyze_pattern(const BlockCsr& A);
  /// Prefilters A with the context's constraints and sets up the preconditioner from Ahat
  /// (given the context). A must outlive the next solve.
  Status factorize(const BlockCsr& A);
  /// x: the initial guess on entry (read only with warm_start), the solution on exit.
  LinearReport solve(const Eigen::VectorXd& b, Eigen::VectorXd& x);
  /// The constraints and positions of the next factorize.
  void set_context(const SolveContext& ctx) { pre_.set_context(ctx); }
  /// A known solution x* for the energy error of the next solves (nullptr: none; not owned):
  /// energy_error = ||S (x - x*)||_A / ||x*||_A with the unfiltered A (methods/multigrid §8, V23).
  void set_reference(const Eigen::VectorXd* x_star) { x_star_ = x_star; }
  /// The relative tolerance of the next solves, looser than linear.tolerance (an inexact
  /// Newton's forcing term); 0 or below linear.tolerance: linear.tolerance.
  void set_tolerance(double relative) { forced_tolerance_ = relative; }
  /// A new time step begins (`HasStepHook`): a preconditioner kept per step refreshes next.
  void begin_step() { slot_.begin_step(); }
  const P& preconditioner() const { return slot_.get(); }
  int preconditioner_builds() const { return slot_.builds(); }
  std::string resume_caveat() const { return detail::kept_preconditioner_caveat(prm_); }

 private:
  const ConstraintSet* constraints() const { return pre_.active() ? pre_.context().constraints : nullptr; }
  Params prm_;
  detail::PreconditionerSlot<P> slot_;
  PrefilteredSystem pre_;
  detail::KrylovWork work_;
  const BlockCsr* A_ = nullptr;     // unfiltered
  const BlockCsr* Ahat_ = nullptr;  // A itself without constraints
  const Eigen::VectorXd* x_star_ = nullptr;
  VertexFilterView filter_;         // non-empty: Ahat applied on the fly from A_
  double setup_seconds_ = 0;
  double forced_tolerance_ = 0;
  std::string input_error_;
  double tolerance() const { return std::max(prm_.tolerance, forced_tolerance_); }
};

extern template class ModifiedPcg<BlockJacobi>;
extern template class Ppcg<BlockJacobi>;

template <class PrecondParams>
std::string detail::kept_preconditioner_caveat(const KrylovParams<PrecondParams>& p) {
  if (p.setup == PreconditionerSetup::once_per_pattern)
    return "linear.setup = once_per_pattern: the frozen preconditioner is rebuilt at the first solve after a restore";
  if constexpr (requires { p.preconditioner.reuse; })
    if (static_cast<int>(p.preconditioner.reuse) != 0)
      return "linear.preconditioner.reuse is not none: the kept hierarchy is rebuilt at the first solve after a restore";
  return "";
}

/// The thesis's baseline: MPCG with the 3x3 block-Jacobi preconditioner of A (without
/// constraints: plain block-Jacobi PCG).
class DiagPcg : public ModifiedPcg<BlockJacobi> {
 public:
  static constexpr std::string_view name = "diag_pcg";
  using ModifiedPcg<BlockJacobi>::ModifiedPcg;
};

/// PPCG with the 3x3 block-Jacobi preconditioner of Ahat ("Diag-PCG with prefiltering").
class DiagPpcg : public Ppcg<BlockJacobi> {
 public:
  static constexpr std::string_view name = "diag_ppcg";
  using Ppcg<BlockJacobi>::Ppcg;
};

static_assert(LinearSolver<DiagPcg> && HasSolveContext<DiagPcg>);
static_assert(LinearSolver<DiagPpcg> && HasSolveContext<DiagPpcg>);

}  // namespace weft::linear
