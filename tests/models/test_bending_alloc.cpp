// The bending evaluations allocate nothing on the heap once the model and its buffers
// exist ("no heap allocation inside element kernels"). malloc and friends are
// interposed for the whole test_models executable; they only count while `counting` is set.
#include <doctest/doctest.h>

#include <atomic>
#include <cstdlib>
#include <cstring>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "models/bending_autodiff.hpp"
#include "models/hinge_bending.hpp"
#include "tests/support/model_fixtures.hpp"

extern "C" {
void* __libc_malloc(size_t);
void* __libc_calloc(size_t, size_t);
void* __libc_realloc(void*, size_t);
void* __libc_memalign(size_t, size_t);
}

namespace {
std::atomic<bool> counting{false};
std::atomic<long> allocations{0};
void count() {
  if (counting.load(std::memory_order_relaxed)) allocations.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

extern "C" {
void* malloc(size_t n) {
  count();
  return __libc_malloc(n);
}
void* calloc(size_t n, size_t m) {
  count();
  return __libc_calloc(n, m);
}
void* realloc(void* p, size_t n) {
  count();
  return __libc_realloc(p, n);
}
int posix_memalign(void** p, size_t alignment, size_t n) {
  count();
  *p = __libc_memalign(alignment, n);
  return *p ? 0 : ENOMEM;
}
void* aligned_alloc(size_t alignment, size_t n) {
  count();
  return __libc_memalign(alignment, n);
}
void* memalign(size_t alignment, size_t n) {
  count();
  return __libc_memalign(alignment, n);
}
}

namespace {

using namespace weft;
using namespace weft::models;

/// Allocations made by f() (after a warm-up call, which may create the OpenMP team).
template <class F>
long allocations_in(F&& f) {
  f();
  allocations = 0;
  counting = true;
  f();
  counting = false;
  return allocations.load();
}

}  // namespace

TEST_SUITE("models") {
  TEST_CASE_TEMPLATE("bending alloc: forces and Hessians of all three paths allocate nothing on the heap", Angle, ThetaEnergy,
                     TanEnergy) {
    // The counter works.
    CHECK(allocations_in([] { std::free(std::malloc(64)); }) == 1);
    // 20x20 grid: above the size where the loops go parallel.
    const support::MeshData m = support::grid(20, 20, 1.0, 1.0);
    Eigen::VectorXd x = support::stack(m.V);
    for (Eigen::Index i = 0; i < x.size() / 3; ++i) x[3 * i + 2] = 0.1 * std::sin(5 * x[3 * i]) * std::cos(3 * x[3 * i + 1]);
    auto p = support::make_patch<HingeBending<Angle>>(m, x);
    AssemblyPlan plan;
    p.model.declare(plan);
    plan.finalize(p.state.num_vertices());
    BlockCsr H = plan.pattern();
    Eigen::VectorXd g = Eigen::VectorXd::Zero(x.size());
    for (auto [threads, mode] : {std::pair{1, AssemblyMode::direct}, std::pair{2, AssemblyMode::direct},
                                 std::pair{1, AssemblyMode::stored}, std::pair{2, AssemblyMode::stored}}) {
      CAPTURE(threads);
      CAPTURE(mode == AssemblyMode::direct);
      ElementBuffer buf = plan.make_buffer(mode);
      buf.start(H);
#ifdef _OPENMP
      const int saved = omp_get_max_threads();
      omp_set_num_threads(threads);
#endif
      for (BendingAssembly path : {BendingAssembly::refactored, BendingAssembly::per_hinge}) {
        CAPTURE(enum_name(path, bending_assembly_names));
        CHECK(allocations_in([&] { p.model.evaluate(p.state, &g, &buf, HessianMode::exact, path); }) == 0);
        CHECK(allocations_in([&] { p.model.evaluate(p.state, &g, nullptr, HessianMode::exact, path); }) == 0);
        CHECK(allocations_in([&] { p.model.evaluate(p.state, nullptr, &buf, HessianMode::exact, path); }) == 0);
      }
      CHECK(allocations_in([&] { p.model.add_hessian(p.state, buf, HessianMode::projected); }) == 0);
      CHECK(allocations_in([&] { bending::autodiff_evaluate(p.model, p.state, &g, &buf); }) == 0);
      CHECK(allocations_in([&] { bending::autodiff_evaluate(p.model, p.state, nullptr, &buf); }) == 0);
      // The stored mode's gather runs serially below 256 blocks (as here) and allocates nothing.
      CHECK(allocations_in([&] {
              buf.finish();
              buf.start(H);  // allocations_in may call this more than once
            }) == 0);
#ifdef _OPENMP
      omp_set_num_threads(saved);
#endif
    }
  }
}
