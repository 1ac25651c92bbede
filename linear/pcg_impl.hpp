#pragma once
/// \file pcg_impl.hpp
/// Member definitions of `ModifiedPcg<P>` and `Ppcg<P>` (linear/pcg.hpp). Include this in
/// the one translation unit that instantiates the templates for a preconditioner P; the
/// CG loop itself is non-template (linear/pcg.cpp).
#include <fmt/format.h>

#include "framework/timers.hpp"
#include "linear/pcg.hpp"

namespace weft::linear {
namespace detail {

template <Preconditioner P>
Status PreconditionerSlot<P>::analyze_pattern(const BlockCsr& A) {
  built_ = false;
  const Status s = p_.analyze_pattern(A);
  if (s != Status::success) {
    status_ = s;
    message_ = fmt::format("preconditioner '{}': analyze_pattern failed ({})", P::name, to_string(s));
    return s;
  }
  status_ = Status::invalid_input;  // until the first factorize
  message_ = "call factorize() before solve()";
  return Status::success;
}

template <Preconditioner P>
Status PreconditionerSlot<P>::setup(const BlockCsr& M, const SolveContext& ctx, const VertexFilterView& F) {
  if (built_ && policy_ == PreconditionerSetup::once_per_pattern) return status_;
  if constexpr (FiltersOnTheFly<P>) {
    status_ = p_.setup(M, ctx, F);
  } else {
    WEFT_ASSERT(F.empty(), "preconditioner '{}' cannot read a matrix through filters", P::name);
    status_ = p_.setup(M, ctx);
  }
  ++builds_;
  built_ = status_ == Status::success;
  if (built_) {
    message_.clear();
  } else if constexpr (requires { { p_.message() } -> std::convertible_to<std::string>; }) {
    message_ = p_.message();
  } else {
    message_ = fmt::format("preconditioner '{}': setup failed ({})", P::name, to_string(status_));
  }
  return status_;
}

template <Preconditioner P>
bool PreconditionerSlot<P>::proves_indefinite() const {
  if constexpr (requires { p_.inverse_blocks(); }) return status_ == Status::numerical_issue;
  else return false;
}

template <Preconditioner P>
PrecondView PreconditionerSlot<P>::view() const {
  PrecondView v;
  v.self = &p_;
  v.apply = [](const void* self, const Eigen::VectorXd& r, Eigen::VectorXd& z) { static_cast<const P*>(self)->apply(r, z); };
  if constexpr (requires(const Eigen::VectorXd& r, Eigen::VectorXd& z) { p_.apply(r, z, z); })
    v.apply_work = [](const void* self, const Eigen::VectorXd& r, Eigen::VectorXd& z, Eigen::VectorXd& work) {
      static_cast<const P*>(self)->apply(r, z, work);
    };
  if constexpr (requires { { p_.inverse_blocks().data() } -> std::convertible_to<const double*>; })
    v.block_inverse = p_.inverse_blocks().data();
  return v;
}

inline std::string size_mismatch(const ConstraintSet& c, const BlockCsr& A) {
  return fmt::format("the constraint set has {} vertices but the matrix {} block rows", c.num_vertices(), A.block_rows());
}

/// Fills the fields every Krylov solve reports the same way.
template <class Slot>
void fill_common(const Slot& slot, const KrylovWork& w, LinearReport& rep) {
  const PreconditionerInfo info = slot.get().info();
  rep.memory_bytes += info.memory_bytes + w.bytes();
  rep.levels = info.levels;
  rep.operator_complexity = info.operator_complexity;
}

/// The report of a solve that could not start (no factorisation, failed setup).
template <class Slot>
LinearReport refuse(const Slot& slot, double setup_seconds) {
  LinearReport rep;
  rep.solves = 1;
  rep.setup_seconds = setup_seconds;
  rep.status = slot.status() == Status::success ? Status::invalid_input : slot.status();
  rep.indefinite = slot.proves_indefinite();
  rep.message = slot.message();
  return rep;
}

/// The report of a solve that cannot run: no factorize, a failed preconditioner set-up, a
/// constraint set or right-hand side of the wrong size. Returns false when the solve may run.
template <class Slot>
bool refuse_solve(const Slot& slot, const BlockCsr* A, const Eigen::VectorXd& b, const std::string& input_error,
                  double setup_seconds, LinearReport& rep) {
  if (A && slot.status() == Status::success && b.size() == A->rows()) return false;
  rep = refuse(slot, setup_seconds);
  if (!input_error.empty()) {
    rep.status = Status::invalid_input;
    rep.message = input_error;
  } else if (slot.status() == Status::success) {
    rep.status = Status::invalid_input;
    rep.message = A ? "right-hand side of the wrong size" : "call factorize() before solve()";
  }
  return true;
}

}  // namespace detail

// ---------------------------------------------------------------------------------------
// ModifiedPcg

template <Preconditioner P>
ModifiedPcg<P>::ModifiedPcg(const Params& prm) : prm_(prm), slot_(prm.preconditioner, prm.setup) {
  Params::validate(prm_).throw_if_failed();
}

template <Preconditioner P>
Status ModifiedPcg<P>::analyze_pattern(const BlockCsr& A) {
  ScopedTimer t(setup_seconds_);
  A_ = nullptr;
  work_.resize(A.rows());
  return slot_.analyze_pattern(A);
}

template <Preconditioner P>
Status ModifiedPcg<P>::factorize(const BlockCsr& A) {
  ScopedTimer t(setup_seconds_);
  A_ = &A;
  const ConstraintSet* c = constraints();
  if (c && c->num_vertices() != A.block_rows()) {
    A_ = nullptr;
    input_error_ = detail::size_mismatch(*c, A);
    return Status::invalid_input;
  }
  input_error_.clear();
  if (c) filters_.build(*c);
  else filters_.clear();
  // The preconditioner of the full, unfiltered system: it sees no constraints (methods/multigrid §7.5).
  return slot_.setup(A, SolveContext{nullptr, ctx_.positions});
}

template <Preconditioner P>
LinearReport ModifiedPcg<P>::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  const double setup_seconds = setup_seconds_;
  setup_seconds_ = 0;
  LinearReport rep;
  if (detail::refuse_solve(slot_, A_, b, input_error_, setup_seconds, rep)) return rep;
  rep.solves = 1;
  rep.setup_seconds = setup_seconds;
  const ConstraintSet* c = constraints();
  {
    ScopedTimer t(rep.solve_seconds);
    // x0 = z on the constrained directions; the free part is 0 or (warm start) S x_in.
    const Eigen::VectorXd x_in = prm_.warm_start && x.size() == b.size() ? x : Eigen::VectorXd();
    auto start = [&] {
      if (x_in.size() > 0) {
        x = x_in;
        if (c) {
          c->filter(x);
          x += c->target();
        }
      } else if (c) {
        x = c->target();
      } else {
        x.setZero(b.size());
      }
    };
    start();
    work_.resize(b.size());
    detail::pcg(*A_, b, x, slot_.view(), c ? &filters_ : nullptr, {tolerance(), prm_.max_iterations}, work_, rep);
    if (work_.preconditioner_breakdown && slot_.recover_from_breakdown(*A_, SolveContext{nullptr, ctx_.positions})) {
      const int spent = rep.iterations;
      start();
      detail::pcg(*A_, b, x, slot_.view(), c ? &filters_ : nullptr, {tolerance(), prm_.max_iterations}, work_, rep);
      rep.iterations += spent;
    }
  }
  detail::diagnose(*A_, c, b, x, x_star_, work_.q, rep);
  // A hierarchy kept from an indefinite matrix must not serve the retry (e.g. the shifted
  // Newton matrix of integrator.hessian = adaptive): the next factorize refreshes it.
  if (rep.indefinite || rep.status != Status::success) slot_.begin_step();
  rep.memory_bytes = filters_.bytes();
  detail::fill_common(slot_, work_, rep);
  return rep;
}

// ---------------------------------------------------------------------------------------
// Ppcg

template <Preconditioner P>
Ppcg<P>::Ppcg(const Params& prm) : prm_(prm), slot_(prm.preconditioner, prm.setup) {
  Params::validate(prm_).throw_if_failed();
}

template <Preconditioner P>
Status Ppcg<P>::analyze_pattern(const BlockCsr& A) {
  ScopedTimer t(setup_seconds_);
  A_ = Ahat_ = nullptr;
  work_.resize(A.rows());
  return slot_.analyze_pattern(A);  // Ahat has A's pattern
}

template <Preconditioner P>
Status Ppcg<P>::factorize(const BlockCsr& A) {
  A_ = Ahat_ = nullptr;
  const ConstraintSet* c = constraints();
  if (c && c->num_vertices() != A.block_rows()) {
    input_error_ = detail::size_mismatch(*c, A);
    return Status::invalid_input;
  }
  input_error_.clear();
  A_ = &A;
  // On the fly only while the preconditioner is rebuilt with the filters of every factorize:
  // a preconditioner frozen by once_per_pattern would keep pointers to filters rebuilt since.
  bool on_the_fly = false;
  if constexpr (FiltersOnTheFly<P>) on_the_fly = prm_.setup == PreconditionerSetup::every_factorize;
  if (on_the_fly) {
    filter_ = pre_.filter(A).view();  // timed as prefiltering; Ahat is never stored
    Ahat_ = &A;
  } else {
    filter_ = {};
    Ahat_ = &pre_.matrix(A);  // timed as prefiltering
  }
  ScopedTimer t(setup_seconds_);
  return slot_.setup(*Ahat_, pre_.context(), filter_);
}

template <Preconditioner P>
LinearReport Ppcg<P>::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  const double setup_seconds = setup_seconds_;
  setup_seconds_ = 0;
  LinearReport rep;
  if (detail::refuse_solve(slot_, A_, b, input_error_, setup_seconds, rep)) {
    rep.prefilter_seconds = pre_.take_seconds();
    return rep;
  }
  rep.solves = 1;
  rep.setup_seconds = setup_seconds;
  const ConstraintSet* c = constraints();
  // chat = S (b - A z) goes straight into the residual vector, where the CG starts from it
  // (r = chat - Ahat y0 in place): no vector of its own.
  work_.resize(b.size());
  const Eigen::VectorXd& chat = pre_.active() ? pre_.rhs(b, work_.r) : b;
  {
    ScopedTimer t(rep.solve_seconds);
    // y0 = 0 (thesis fidelity) or, warm, S (x_in - z). y is iterated in x's storage.
    const Eigen::VectorXd x_in = prm_.warm_start && x.size() == b.size() ? x : Eigen::VectorXd();
    auto start = [&] {
      if (x_in.size() > 0) {
        x = x_in;
        if (c) {
          x -= c->target();
          c->filter(x);
        }
      } else {
        x.setZero(b.size());
      }
    };
    start();
    detail::pcg(*Ahat_, chat, x, slot_.view(), nullptr, {tolerance(), prm_.max_iterations}, work_, rep, filter_);
    if (work_.preconditioner_breakdown && slot_.recover_from_breakdown(*Ahat_, pre_.context(), filter_)) {
      const int spent = rep.iterations;
      start();
      const Eigen::VectorXd& chat_again = pre_.active() ? pre_.rhs(b, work_.r) : b;  // the solve overwrote it
      detail::pcg(*Ahat_, chat_again, x, slot_.view(), nullptr, {tolerance(), prm_.max_iterations}, work_, rep, filter_);
      rep.iterations += spent;
    }
    pre_.finish(x);  // x = z + S y: constraints to round-off
  }
  rep.prefilter_seconds = pre_.take_seconds();
  detail::diagnose(*A_, c, b, x, x_star_, work_.q, rep);
  if (rep.indefinite || rep.status != Status::success) slot_.begin_step();  // as in ModifiedPcg::solve
  rep.memory_bytes = c ? pre_.bytes() : 0;
  detail::fill_common(slot_, work_, rep);
  return rep;
}

}  // namespace weft::linear
