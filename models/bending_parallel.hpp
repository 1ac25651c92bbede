#pragma once
/// \file bending_parallel.hpp
/// The element loops of the bending paths. A loop runs on the OpenMP team only when it is
/// long enough and more than one thread is available: entering a parallel region costs a
/// thread wake-up, and with a single thread libgomp allocates a team descriptor per region,
/// which would put heap allocations into single-threaded evaluations (and their timings).
#ifdef _OPENMP
#include <omp.h>
#endif

namespace weft::models::bending::detail {

/// Loops shorter than this run serially.
inline constexpr int parallel_min = 256;

/// f(i) for i in [0, n); each i must write only its own outputs.
template <class F>
void for_each_element(int n, F&& f) {
#ifdef _OPENMP
  if (n >= parallel_min && omp_get_max_threads() > 1 && !omp_in_parallel()) {
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; ++i) f(i);
    return;
  }
#endif
  for (int i = 0; i < n; ++i) f(i);
}

}  // namespace weft::models::bending::detail
