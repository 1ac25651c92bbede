#include "contact/verify/intersection_check.hpp"

#include <algorithm>
#include <bit>
#include <chrono>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "contact/verify/predicates.hpp"
#include "contact/verify/triangle_intersection.hpp"
#include "framework/error.hpp"

namespace weft::contact::verify {

namespace {

using Eigen::Vector3d;
using Face = std::array<int, 3>;
using Pair = std::array<int, 2>;

int thread_count(int requested) {
#ifdef _OPENMP
  return requested > 0 ? requested : omp_get_max_threads();
#else
  (void)requested;
  return 1;
#endif
}

std::vector<Face> face_list(const Eigen::MatrixX3i& faces, std::size_t num_vertices) {
  std::vector<Face> out(faces.rows());
  for (Eigen::Index f = 0; f < faces.rows(); ++f) {
    out[f] = {faces(f, 0), faces(f, 1), faces(f, 2)};
    for (int k = 0; k < 3; ++k)
      WEFT_ASSERT(out[f][k] >= 0 && static_cast<std::size_t>(out[f][k]) < num_vertices,
                  "intersection check: face {} has vertex id {} out of [0, {})", f, out[f][k], num_vertices);
    WEFT_ASSERT(out[f][0] != out[f][1] && out[f][1] != out[f][2] && out[f][2] != out[f][0],
                "intersection check: face {} repeats a vertex id", f);
  }
  return out;
}

std::vector<Box> boxes_of(std::span<const Vector3d> x, const std::vector<Face>& faces) {
  std::vector<Box> boxes(faces.size());
  for (std::size_t f = 0; f < faces.size(); ++f) boxes[f] = Box::of(x[faces[f][0]], x[faces[f][1]], x[faces[f][2]]);
  return boxes;
}

/// hit(i, j) on every wanted pair (i < j; with split >= 0 only i < split <= j) whose
/// boxes overlap, in parallel; the pairs it accepts, sorted, make the report.
template <class Hit>
IntersectionReport find_pairs(std::span<const Box> boxes, int split, const IntersectionCheckParams& prm, Hit&& hit) {
  const int threads = thread_count(prm.broad_phase.threads);
  const int n = static_cast<int>(boxes.size());
  std::vector<std::vector<Pair>> parts(threads);
  std::int64_t candidates = 0, exact = 0;
  auto parallel = [&](auto&& body) {
#pragma omp parallel num_threads(threads) reduction(+ : candidates, exact)
    {
      int t = 0;
#ifdef _OPENMP
      t = omp_get_thread_num();
#endif
      const std::uint64_t exact_before = exact_evaluations();
      std::int64_t mine = 0;
      auto visit = [&](int i, int j) {
        ++mine;
        if (hit(i, j)) parts[t].push_back({i, j});
      };
      body(visit);
      candidates += mine;
      exact += static_cast<std::int64_t>(exact_evaluations() - exact_before);
    }
  };
  if (prm.broad_phase.method == BroadPhase::brute_force) {
    parallel([&](auto& visit) {
#pragma omp for schedule(dynamic, 16)
      for (int i = 0; i < n; ++i)
        for (int j = i + 1; j < n; ++j)
          if ((split < 0 || (i < split && j >= split)) && boxes[i].overlaps(boxes[j])) visit(i, j);
    });
  } else {
    const HashGrid grid(boxes, prm.broad_phase.cell_size, split, threads);
    const int nb = grid.num_buckets(), nbig = grid.num_big();
    parallel([&](auto& visit) {
#pragma omp for schedule(dynamic, 256)
      for (int b = 0; b < nb; ++b) grid.for_each_pair_in_bucket(b, visit);
#pragma omp for schedule(dynamic, 1)
      for (int t = 0; t < nbig; ++t) grid.for_each_pair_of_big(t, visit);
    });
  }
  std::vector<Pair> all;
  for (const auto& p : parts) all.insert(all.end(), p.begin(), p.end());
  std::sort(all.begin(), all.end());
  if (split >= 0)
    for (Pair& p : all) p[1] -= split;
  IntersectionReport r;
  r.num_pairs = static_cast<std::int64_t>(all.size());
  all.resize(std::min<std::size_t>(all.size(), static_cast<std::size_t>(std::max(prm.max_pairs, 0))));
  r.pairs = std::move(all);
  r.candidates = candidates;
  r.exact_evaluations = exact;
  return r;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Bit 3a + b is set iff f[a] == g[b]; `count` receives the number of set bits (vertex ids
/// within a face are distinct, so it is the number of shared vertices).
unsigned shared_mask(const Face& f, const Face& g, int& count) {
  unsigned m = 0;
  int n = 0;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) {
      const bool eq = f[a] == g[b];
      m |= static_cast<unsigned>(eq) << (3 * a + b);
      n += eq;
    }
  count = n;
  return m;
}

constexpr int next3[3] = {1, 2, 0}, prev3[3] = {2, 0, 1};

/// faces_intersect with the planes of f and g precomputed: most pairs are decided by the
/// plane sides alone (the first steps of the exact tests), which the full tests then reuse.
bool faces_intersect_cached(std::span<const Vector3d> x, const Face& f, const Face& g, const Orient3dPlane& pf,
                            const Orient3dPlane& pg) {
  const Vector3d &f0 = x[f[0]], &f1 = x[f[1]], &f2 = x[f[2]];
  const Vector3d &g0 = x[g[0]], &g1 = x[g[1]], &g2 = x[g[2]];
  auto strictly_one_side = [](const int* s) {
    return (s[0] > 0 && s[1] > 0 && s[2] > 0) || (s[0] < 0 && s[1] < 0 && s[2] < 0);
  };
  int count = 0;
  const unsigned m = shared_mask(f, g, count);
  switch (count) {
    case 0: {
      // A triangle strictly on one side of the other's plane misses it.
      const int s[3] = {pf.side(f0, f1, f2, g0), pf.side(f0, f1, f2, g1), pf.side(f0, f1, f2, g2)};
      if (strictly_one_side(s)) return false;
      const int t[3] = {pg.side(g0, g1, g2, f0), pg.side(g0, g1, g2, f1), pg.side(g0, g1, g2, f2)};
      if (strictly_one_side(t)) return false;
      return detail::triangles_intersect(f0, f1, f2, g0, g1, g2, s, t);
    }
    case 1: {
      // The far edge of one strictly on one side of the other's plane: that triangle meets
      // the other's plane in v alone. (v, a, b) and (v, c, d) are rotations of f and g,
      // which leave orient3d unchanged.
      const int bit = std::countr_zero(m), ia = bit / 3, ib = bit % 3;
      const Vector3d &v = x[f[ia]], &a = x[f[next3[ia]]], &b = x[f[prev3[ia]]];
      const Vector3d &c = x[g[next3[ib]]], &d = x[g[prev3[ib]]];
      const int sc = pf.side(f0, f1, f2, c), sd = pf.side(f0, f1, f2, d);
      if (sc * sd > 0) return false;
      const int sa = pg.side(g0, g1, g2, a), sb = pg.side(g0, g1, g2, b);
      if (sa * sb > 0) return false;
      return detail::triangles_intersect_sharing_vertex(v, a, b, c, d, sc, sd, sa, sb);
    }
    case 2: {
      // A hinge at a nonzero angle meets only along the shared edge: g's unshared corner
      // off f's plane. (u, w, a) is a rotation of f.
      const unsigned in_f = (m & 7u ? 1u : 0u) | (m & 070u ? 2u : 0u) | (m & 0700u ? 4u : 0u);
      const unsigned in_g = (m | m >> 3 | m >> 6) & 7u;
      const int ia = std::countr_zero(~in_f & 7u), ib = std::countr_zero(~in_g & 7u);
      const int s = pf.side(f0, f1, f2, x[g[ib]]);
      if (s != 0) return false;
      return detail::triangles_intersect_sharing_edge(x[f[next3[ia]]], x[f[prev3[ia]]], x[f[ia]], x[g[ib]], s);
    }
    default:
      return true;  // a duplicated face
  }
}

}  // namespace

std::vector<Vector3d> points_from_stacked(const Eigen::Ref<const Eigen::VectorXd>& x) {
  WEFT_ASSERT(x.size() % 3 == 0, "points_from_stacked: a stacked position vector has 3 entries per vertex, got {}",
              x.size());
  std::vector<Vector3d> p(x.size() / 3);
  for (std::size_t i = 0; i < p.size(); ++i) p[i] = x.segment<3>(3 * i);
  return p;
}

std::vector<Vector3d> points_from_rows(const Eigen::Ref<const Eigen::MatrixX3d>& V) {
  std::vector<Vector3d> p(V.rows());
  for (std::size_t i = 0; i < p.size(); ++i) p[i] = V.row(i).transpose();
  return p;
}

bool faces_intersect(std::span<const Vector3d> x, const Face& f, const Face& g) {
  int count = 0;
  const unsigned m = shared_mask(f, g, count);
  switch (count) {
    case 0:
      return triangles_intersect(x[f[0]], x[f[1]], x[f[2]], x[g[0]], x[g[1]], x[g[2]]);
    case 1: {
      const int bit = std::countr_zero(m), a = bit / 3, b = bit % 3;
      return triangles_intersect_sharing_vertex(x[f[a]], x[f[next3[a]]], x[f[prev3[a]]], x[g[next3[b]]],
                                                x[g[prev3[b]]]);
    }
    case 2: {
      // The unshared corners of f and g; the shared edge as f lists it.
      const unsigned in_f = (m & 7u ? 1u : 0u) | (m & 070u ? 2u : 0u) | (m & 0700u ? 4u : 0u);
      const unsigned in_g = (m | m >> 3 | m >> 6) & 7u;
      const int a = std::countr_zero(~in_f & 7u), b = std::countr_zero(~in_g & 7u);
      return triangles_intersect_sharing_edge(x[f[next3[a]]], x[f[prev3[a]]], x[f[a]], x[g[b]]);
    }
    default:
      return true;  // a duplicated face
  }
}

IntersectionReport check_self_intersections(std::span<const Vector3d> x, const Eigen::MatrixX3i& faces,
                                            const IntersectionCheckParams& prm) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<Face> F = face_list(faces, x.size());
  const std::vector<Box> boxes = boxes_of(x, F);
  std::vector<Orient3dPlane> planes(F.size());
  for (std::size_t f = 0; f < F.size(); ++f) planes[f] = Orient3dPlane(x[F[f][0]], x[F[f][1]], x[F[f][2]]);
  IntersectionReport r = find_pairs(
      boxes, -1, prm, [&](int i, int j) { return faces_intersect_cached(x, F[i], F[j], planes[i], planes[j]); });
  r.seconds = seconds_since(t0);
  return r;
}

IntersectionReport check_self_intersections(const Eigen::Ref<const Eigen::VectorXd>& x, const Eigen::MatrixX3i& faces,
                                            const IntersectionCheckParams& prm) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<Vector3d> p = points_from_stacked(x);
  IntersectionReport r = check_self_intersections(std::span<const Vector3d>(p), faces, prm);
  r.seconds = seconds_since(t0);
  return r;
}

IntersectionReport check_intersections(std::span<const Vector3d> xa, const Eigen::MatrixX3i& faces_a,
                                       std::span<const Vector3d> xb, const Eigen::MatrixX3i& faces_b,
                                       const IntersectionCheckParams& prm) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<Face> Fa = face_list(faces_a, xa.size()), Fb = face_list(faces_b, xb.size());
  std::vector<Box> boxes = boxes_of(xa, Fa);
  const std::vector<Box> bb = boxes_of(xb, Fb);
  boxes.insert(boxes.end(), bb.begin(), bb.end());
  const int na = static_cast<int>(Fa.size());
  IntersectionReport r = find_pairs(boxes, na, prm, [&](int i, int j) {
    const Face& f = Fa[i];
    const Face& g = Fb[j - na];
    return triangles_intersect(xa[f[0]], xa[f[1]], xa[f[2]], xb[g[0]], xb[g[1]], xb[g[2]]);
  });
  r.seconds = seconds_since(t0);
  return r;
}

}  // namespace weft::contact::verify
