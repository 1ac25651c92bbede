#include "contact/verify/hash_grid.hpp"

#include <algorithm>
#include <cmath>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "framework/error.hpp"

namespace weft::contact::verify {

namespace {

using Cell = std::array<int, 3>;

constexpr std::int64_t max_cells_per_box = 64;
// Cells are packed into 64-bit keys, 21 bits per axis; coordinates beyond 2^21 - 1 cells
// from the origin are clamped (still monotone, so still conservative: only slower).
constexpr int key_bits = 21;
constexpr double cell_clamp = (1 << key_bits) - 1;

std::uint64_t pack(std::uint64_t x, std::uint64_t y, std::uint64_t z) {
  return x << (2 * key_bits) | y << key_bits | z;
}

int thread_id() {
#ifdef _OPENMP
  return omp_get_thread_num();
#else
  return 0;
#endif
}

}  // namespace

HashGrid::HashGrid(std::span<const Box> boxes, double cell_size, int split, int threads)
    : boxes_(boxes),
      split_(split) {
  const int n = static_cast<int>(boxes.size());
  start_.assign(2, 0);
  num_buckets_ = 1;
  is_big_.assign(n, 0);
  if (n < 2) return;
  Eigen::Vector3d origin = boxes[0].lo;
  double extent = 0;
  for (const Box& b : boxes) {
    WEFT_ASSERT(b.lo.allFinite() && b.hi.allFinite(), "intersection check: non-finite coordinates");
    origin = origin.cwiseMin(b.lo);
    extent += (b.hi - b.lo).maxCoeff();
  }
  // Default: cells of twice the mean box size (fewer entries per box outweigh more boxes
  // per cell on cloth meshes).
  double h = cell_size > 0 ? cell_size : 2.0 * extent / n;
  if (!(h > 0) || !std::isfinite(1.0 / h)) h = 1.0;  // all boxes are points
  const double inv_h = 1.0 / h;
  // floor((x - o) / h), clamped: monotone in x, which is all the guarantee needs.
  auto cell_of = [&](const Eigen::Vector3d& x) {
    Cell c;
    for (int k = 0; k < 3; ++k)
      c[k] = static_cast<int>(std::clamp(std::floor((x[k] - origin[k]) * inv_h), 0.0, cell_clamp));
    return c;
  };

  std::vector<Cell> lo(n), hi(n);
  std::vector<int> first(n + 1);
  first[0] = 0;
  Cell cells{1, 1, 1};  // the grid's bounding block
  for (int i = 0; i < n; ++i) {
    lo[i] = cell_of(boxes[i].lo);
    hi[i] = cell_of(boxes[i].hi);
    std::int64_t count = 1;
    for (int k = 0; k < 3; ++k) count *= hi[i][k] - lo[i][k] + 1;
    if (count > max_cells_per_box) {
      big_.push_back(i);
      is_big_[i] = 1;
      count = 0;
    } else {
      for (int k = 0; k < 3; ++k) cells[k] = std::max(cells[k], hi[i][k] + 1);
    }
    WEFT_ASSERT(first[i] + count < (std::int64_t{1} << 31), "intersection check: too many grid entries");
    first[i + 1] = first[i] + static_cast<int>(count);
  }
  const int num_entries = first[n];

  // Buckets: the cells of the bounding block when it is small (no collisions, and buckets
  // in spatial order, which keeps the boxes they reference close in memory on spatially
  // ordered meshes); else a multiplicative hash of the packed cell.
  const double dense_cells = double(cells[0]) * cells[1] * cells[2];
  const bool dense = dense_cells <= 4.0 * num_entries + 1024;
  int bits = 4;
  while ((1 << bits) < num_entries) ++bits;
  num_buckets_ = dense ? static_cast<int>(dense_cells) : 1 << bits;
  const std::uint64_t ny = cells[1], nz = cells[2];
  auto bucket_of = [&](std::uint64_t x, std::uint64_t y, std::uint64_t z, std::uint64_t key) {
    return dense ? static_cast<std::uint32_t>((x * ny + y) * nz + z)
                 : static_cast<std::uint32_t>((key * 0x9E3779B97F4A7C15ull) >> (64 - bits));
  };

  auto key = std::unique_ptr<std::uint64_t[]>(new std::uint64_t[num_entries]);
  auto bucket = std::unique_ptr<std::uint32_t[]>(new std::uint32_t[num_entries]);
  auto mask = std::unique_ptr<std::uint8_t[]>(new std::uint8_t[num_entries]);
#pragma omp parallel for schedule(static) num_threads(threads)
  for (int i = 0; i < n; ++i) {
    int e = first[i];
    if (first[i + 1] == e) continue;
    for (int x = lo[i][0]; x <= hi[i][0]; ++x)
      for (int y = lo[i][1]; y <= hi[i][1]; ++y)
        for (int z = lo[i][2]; z <= hi[i][2]; ++z, ++e) {
          key[e] = pack(x, y, z);
          bucket[e] = bucket_of(x, y, z, key[e]);
          mask[e] = static_cast<std::uint8_t>((x == lo[i][0]) | (y == lo[i][1]) << 1 | (z == lo[i][2]) << 2);
        }
  }
  // Counting sort by bucket; stable, so each bucket lists its boxes in increasing order.
  start_.assign(num_buckets_ + 1, 0);
  for (int e = 0; e < num_entries; ++e) ++start_[bucket[e] + 1];
  for (int b = 0; b < num_buckets_; ++b) start_[b + 1] += start_[b];
  key_.reset(new std::uint64_t[num_entries]);
  box_.reset(new int[num_entries]);
  mask_.reset(new std::uint8_t[num_entries]);
  std::vector<int> fill(start_.begin(), start_.end() - 1);
  for (int i = 0; i < n; ++i)
    for (int e = first[i]; e < first[i + 1]; ++e) {
      const int to = fill[bucket[e]]++;
      key_[to] = key[e];
      box_[to] = i;
      mask_[to] = mask[e];
    }
}

std::vector<std::array<int, 2>> overlapping_pairs(std::span<const Box> boxes, const BroadPhaseParams& prm) {
  int threads = 1;
#ifdef _OPENMP
  threads = prm.threads > 0 ? prm.threads : omp_get_max_threads();
#endif
  const int n = static_cast<int>(boxes.size());
  std::vector<std::vector<std::array<int, 2>>> parts(threads);
  auto collect = [&](std::vector<std::array<int, 2>>& out) { return [&out](int i, int j) { out.push_back({i, j}); }; };
  if (prm.method == BroadPhase::brute_force) {
#pragma omp parallel for schedule(static) num_threads(threads)
    for (int i = 0; i < n; ++i)
      for (int j = i + 1; j < n; ++j)
        if (boxes[i].overlaps(boxes[j])) parts[thread_id()].push_back({i, j});
  } else {
    const HashGrid grid(boxes, prm.cell_size, -1, threads);
    const int nb = grid.num_buckets(), nbig = grid.num_big();
#pragma omp parallel num_threads(threads)
    {
      auto emit = collect(parts[thread_id()]);
#pragma omp for schedule(static)
      for (int b = 0; b < nb; ++b) grid.for_each_pair_in_bucket(b, emit);
#pragma omp for schedule(static)
      for (int t = 0; t < nbig; ++t) grid.for_each_pair_of_big(t, emit);
    }
  }
  std::vector<std::array<int, 2>> out;
  for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace weft::contact::verify
