#include "linear/pcg.hpp"

#include <algorithm>
#include <cmath>

#include "linear/bsr.hpp"
#include "linear/pcg_impl.hpp"

namespace weft::linear {
namespace detail {

void VertexFilters::build(const ConstraintSet& c) {
  const int n = c.num_vertices();
  slot_.assign(n, free_slot);
  S_.clear();
  full_ = 0;
  for (int i = 0; i < n; ++i) {
    if (c.count(i) == 0) continue;
    if (c.count(i) == 3) {
      slot_[i] = full_slot;  // S_i = 0 exactly, not I - N N^T up to round-off
      ++full_;
    } else {
      slot_[i] = static_cast<int>(S_.size());
      S_.push_back(c.filter(i));
    }
  }
}

void VertexFilters::clear() {
  slot_.clear();
  S_.clear();
  full_ = 0;
}

void KrylovWork::resize(Eigen::Index n) {
  // resize() keeps the storage when the size is unchanged: no allocation per solve.
  r.resize(n);
  z.resize(n);
  p.resize(n);
  q.resize(n);
}

namespace {

// Every loop runs over block rows (3 scalars), statically scheduled: the reductions are
// deterministic for a fixed thread count, and the loops fuse what plain Eigen would do in
// separate passes over memory (the solver is bandwidth-bound, methods/multigrid §9). Small systems
// run serially: five parallel regions per iteration cost more than they save there, and
// far more when the cores are shared.
constexpr int parallel_rows = 4096;

double dot(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  const int n = static_cast<int>(a.size() / 3);
  double s = 0;
#pragma omp parallel for schedule(static) reduction(+ : s) if (n >= parallel_rows)
  for (int i = 0; i < n; ++i) s += a.segment<3>(3 * i).dot(b.segment<3>(3 * i));
  return s;
}

// r = S (b - A x); A read through its view (prefiltered on the fly when the view has filters).
// b may alias r (each row reads its own b_i only); x must not.
void residual(const BsrView<3, 3>& A, const Eigen::VectorXd& b, const Eigen::VectorXd& x, const VertexFilters* S,
              Eigen::VectorXd& r) {
  const int n = A.rows;
#pragma omp parallel for schedule(static) if (n >= parallel_rows)
  for (int i = 0; i < n; ++i) {
    // Sum A x first, as BlockCsr::multiply does: b = A x then gives r = 0 exactly.
    const Eigen::Vector3d acc = row_product(A, i, x.data());
    Eigen::Vector3d ri = b.segment<3>(3 * i) - acc;
    if (S) S->apply(i, ri);
    r.segment<3>(3 * i) = ri;
  }
}

// q = S A p; returns p^T q (= p^T A p for p in range(S)).
double multiply_dot(const BsrView<3, 3>& A, const Eigen::VectorXd& p, const VertexFilters* S, Eigen::VectorXd& q) {
  const int n = A.rows;
  double pq = 0;
#pragma omp parallel for schedule(static) reduction(+ : pq) if (n >= parallel_rows)
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3d acc = row_product(A, i, p.data());
    if (S) S->apply(i, acc);
    q.segment<3>(3 * i) = acc;
    pq += p.segment<3>(3 * i).dot(acc);
  }
  return pq;
}

// x += alpha p, r -= alpha q and, for a block-diagonal B, z = B r; returns r^T z (NaN when
// B is not block diagonal: the caller applies it).
double update(double alpha, const Eigen::VectorXd& p, const Eigen::VectorXd& q, Eigen::VectorXd& x, Eigen::VectorXd& r,
              const double* Binv, Eigen::VectorXd& z) {
  const int n = static_cast<int>(x.size() / 3);
  if (!Binv) {
#pragma omp parallel for schedule(static) if (n >= parallel_rows)
    for (int i = 0; i < n; ++i) {
      x.segment<3>(3 * i) += alpha * p.segment<3>(3 * i);
      r.segment<3>(3 * i) -= alpha * q.segment<3>(3 * i);
    }
    return std::nan("");
  }
  double rz = 0;
#pragma omp parallel for schedule(static) reduction(+ : rz) if (n >= parallel_rows)
  for (int i = 0; i < n; ++i) {
    x.segment<3>(3 * i) += alpha * p.segment<3>(3 * i);
    const Eigen::Vector3d ri = r.segment<3>(3 * i) - alpha * q.segment<3>(3 * i);
    const Eigen::Vector3d zi = Eigen::Map<const Block3>(Binv + 9 * static_cast<std::size_t>(i)) * ri;
    r.segment<3>(3 * i) = ri;
    z.segment<3>(3 * i) = zi;
    rz += ri.dot(zi);
  }
  return rz;
}

// z = B r; returns r^T z. `idle` is a vector B may use as work (its contents are lost).
double precondition(const PrecondView& B, const Eigen::VectorXd& r, Eigen::VectorXd& z, Eigen::VectorXd& idle) {
  if (!B.block_inverse) {
    if (B.apply_work)
      B.apply_work(B.self, r, z, idle);
    else
      B.apply(B.self, r, z);
    return dot(r, z);
  }
  const int n = static_cast<int>(r.size() / 3);
  double rz = 0;
#pragma omp parallel for schedule(static) reduction(+ : rz) if (n >= parallel_rows)
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d zi = Eigen::Map<const Block3>(B.block_inverse + 9 * static_cast<std::size_t>(i)) * r.segment<3>(3 * i);
    z.segment<3>(3 * i) = zi;
    rz += r.segment<3>(3 * i).dot(zi);
  }
  return rz;
}

// p = S (z + beta p), or p = S z for the first direction (p holds garbage then).
void direction(const Eigen::VectorXd& z, double beta, bool first, const VertexFilters* S, Eigen::VectorXd& p) {
  const int n = static_cast<int>(z.size() / 3);
#pragma omp parallel for schedule(static) if (n >= parallel_rows)
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3d v = z.segment<3>(3 * i);
    if (!first) v += beta * p.segment<3>(3 * i);
    if (S) S->apply(i, v);
    p.segment<3>(3 * i) = v;
  }
}

}  // namespace

void pcg(const BlockCsr& Amat, const Eigen::VectorXd& b, Eigen::VectorXd& x, const PrecondView& B,
         const VertexFilters* S, const KrylovOptions& opt, KrylovWork& w, LinearReport& rep, const VertexFilterView& F) {
  WEFT_ASSERT(b.size() == Amat.rows() && x.size() == Amat.rows(), "pcg: sizes {} {} for a matrix of {} rows", b.size(),
              x.size(), Amat.rows());
  BsrView<3, 3> A = bsr_view(Amat);
  A.filter = F;
  w.resize(Amat.rows());
  rep.iterations = 0;
  rep.indefinite = false;
  w.preconditioner_breakdown = false;
  rep.residual_history.clear();
  rep.residual_history.reserve(static_cast<std::size_t>(std::min(opt.max_iterations, 100000)) + 1);
  rep.convergence_rate = 0;
  auto stop = [&](Status s, std::string msg) {
    rep.status = s;
    rep.message = std::move(msg);
    const int N = rep.iterations;
    const double last = rep.residual_history.empty() ? 0.0 : rep.residual_history.back();
    rep.convergence_rate = N > 0 && std::isfinite(last) ? std::pow(last, 1.0 / N) : 0.0;
  };

  residual(A, b, x, S, w.r);  // b may be w.r itself: row i reads b_i before it writes r_i
  double delta = precondition(B, w.r, w.z, w.q);  // q is idle until the first A p
  if (!std::isfinite(delta)) {
    rep.residual_history.push_back(std::nan(""));
    return stop(Status::numerical_issue,
                "PCG: the initial residual is not finite (NaN or Inf in the matrix, right-hand side, initial guess or "
                "preconditioner)");
  }
  if (delta <= 0) {
    if (dot(w.r, w.r) == 0) {  // x is already the solution (e.g. a zero right-hand side)
      rep.residual_history.push_back(0.0);
      rep.status = Status::success;
      return;
    }
    rep.residual_history.push_back(1.0);
    w.preconditioner_breakdown = true;
    return stop(Status::numerical_issue,
                fmt::format("PCG breakdown at iteration 0: r^T B r = {:.3e} <= 0 for r != 0, the preconditioner is not "
                            "positive definite (methods/multigrid §6.2: check its smoother interval and symmetry)",
                            delta));
  }
  const double delta0 = delta;
  const double target = opt.tolerance * opt.tolerance * delta0;
  rep.residual_history.push_back(1.0);
  direction(w.z, 0.0, /*first=*/true, S, w.p);

  for (int it = 1; it <= opt.max_iterations; ++it) {
    const double pq = multiply_dot(A, w.p, S, w.q);
    if (!std::isfinite(pq))
      return stop(Status::numerical_issue, fmt::format("PCG: p^T A p is not finite at iteration {}", it));
    if (pq <= 0) {
      rep.indefinite = true;
      return stop(Status::numerical_issue,
                  fmt::format("PCG breakdown at iteration {}: p^T A p = {:.3e} <= 0, the matrix is not positive "
                              "definite (project the element Hessians or shift the matrix)",
                              it, pq));
    }
    const double alpha = delta / pq;
    double delta_new = update(alpha, w.p, w.q, x, w.r, B.block_inverse, w.z);
    if (!B.block_inverse) delta_new = precondition(B, w.r, w.z, w.q);  // q = A p is used up
    rep.iterations = it;
    if (!std::isfinite(delta_new)) {
      rep.residual_history.push_back(std::nan(""));
      return stop(Status::numerical_issue, fmt::format("PCG: the residual is not finite at iteration {}", it));
    }
    if (delta_new <= 0 && !(delta_new == 0 && dot(w.r, w.r) == 0)) {
      rep.residual_history.push_back(0.0);
      w.preconditioner_breakdown = true;
      return stop(Status::numerical_issue,
                  fmt::format("PCG breakdown at iteration {}: r^T B r = {:.3e} <= 0 for r != 0, the preconditioner is "
                              "not positive definite (methods/multigrid §6.2: check its smoother interval and symmetry)",
                              it, delta_new));
    }
    rep.residual_history.push_back(std::sqrt(delta_new / delta0));
    if (delta_new < target) {
      stop(Status::success, "");
      return;
    }
    const double beta = delta_new / delta;
    delta = delta_new;
    direction(w.z, beta, /*first=*/false, S, w.p);
  }
  stop(Status::no_convergence,
       fmt::format("PCG reached max_iterations = {} at relative residual ||r||_B / ||r_0||_B = {:.3e} (tolerance "
                   "{:.1e}); raise max_iterations or use a stronger preconditioner",
                   opt.max_iterations, rep.residual_history.back(), opt.tolerance));
}

void diagnose(const BlockCsr& A, const ConstraintSet* c, const Eigen::VectorXd& b, const Eigen::VectorXd& x,
              const Eigen::VectorXd* x_star, Eigen::VectorXd& tmp, LinearReport& rep) {
  // True relative residual of the constrained problem: ||S (b - A x)|| / ||S b||.
  A.multiply(x, tmp);
  tmp = b - tmp;
  double nb;
  if (c) {
    c->filter(tmp);
    Eigen::VectorXd Sb = b;
    c->filter(Sb);
    nb = Sb.norm();
  } else {
    nb = b.norm();
  }
  const double nr = tmp.norm();
  rep.relative_residual = nb > 0 ? nr / nb : nr;
  rep.constraint_violation = c ? c->violation(x) : 0.0;
  rep.energy_error = -1;
  if (x_star && x_star->size() == x.size()) {
    Eigen::VectorXd d = x - *x_star;
    if (c) c->filter(d);
    A.multiply(d, tmp);
    const double ed = std::sqrt(std::max(0.0, d.dot(tmp)));
    A.multiply(*x_star, tmp);
    const double es = std::sqrt(std::max(0.0, x_star->dot(tmp)));
    rep.energy_error = es > 0 ? ed / es : ed;
  }
}

}  // namespace detail

template class ModifiedPcg<BlockJacobi>;
template class Ppcg<BlockJacobi>;

}  // namespace weft::linear
