#pragma once
/// \file parallel.hpp
/// Deterministic parallel filtering for the narrow phases: the index range is cut into
/// fixed chunks (independent of the number of threads), each chunk appends to its own
/// vector, and the chunks are concatenated in index order. The output is therefore the
/// same, in the same order, as a serial loop.
#include <algorithm>
#include <vector>

namespace weft::contact::detection {

/// Calls fn(i, out) for every i in [0, n); fn appends what it finds to out.
/// \returns the concatenation of the outputs in increasing i.
template <class T, class Fn>
std::vector<T> ordered_collect(int n, const Fn& fn) {
  constexpr int chunk = 1024;
  const int m = (n + chunk - 1) / chunk;
  std::vector<std::vector<T>> parts(m);
#pragma omp parallel for schedule(dynamic, 1) if (m > 1)
  for (int c = 0; c < m; ++c) {
    const int end = std::min(n, (c + 1) * chunk);
    for (int i = c * chunk; i < end; ++i) fn(i, parts[c]);
  }
  size_t total = 0;
  for (const auto& p : parts) total += p.size();
  std::vector<T> out;
  out.reserve(total);
  for (auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}

}  // namespace weft::contact::detection
