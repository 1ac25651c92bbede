#include "contact/verify/predicates.hpp"

// GCC 12 reports a false -Wmaybe-uninitialized inside cpp_int's small-buffer storage.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <boost/multiprecision/cpp_int.hpp>
#pragma GCC diagnostic pop

#include <algorithm>
#include <climits>

#include "framework/error.hpp"

namespace weft::contact::verify {

namespace {

using boost::multiprecision::cpp_int;

thread_local std::uint64_t exact_count = 0;

/// x = m 2^e with an integer m, |m| < 2^53 (m = 0 for x = 0).
struct Dyadic {
  std::int64_t m = 0;
  int e = 0;
};

Dyadic split(double x) {
  WEFT_ASSERT(std::isfinite(x), "exact predicate on a non-finite coordinate {}", x);
  if (x == 0.0) return {};
  int e = 0;
  const double f = std::frexp(x, &e);  // x = f 2^e, 1/2 <= |f| < 1; ldexp below is exact
  return {static_cast<std::int64_t>(std::ldexp(f, 53)), e - 53};
}

/// The N doubles as integers X_i = x_i 2^-emin, emin the smallest exponent among them:
/// the common positive scale does not change the sign of any homogeneous polynomial.
template <int N>
std::array<cpp_int, N> to_integers(const std::array<double, N>& x) {
  std::array<Dyadic, N> d;
  int emin = INT_MAX;
  for (int i = 0; i < N; ++i) {
    d[i] = split(x[i]);
    if (d[i].m != 0) emin = std::min(emin, d[i].e);
  }
  std::array<cpp_int, N> out;
  for (int i = 0; i < N; ++i)
    if (d[i].m != 0) out[i] = cpp_int(d[i].m) << (d[i].e - emin);
  return out;
}

// ---- Stage 2: floating-point expansions, exact when the differences are -----------------
// Error-free transformations (Knuth's two-sum, the two-product by a fused multiply-add)
// turn the determinant of exactly computed differences into a sum of doubles
// equal to it; its sign is that of the largest component of the nonoverlapping
// expansion the sum grows into. Exact barring overflow and underflow, excluded by
// requiring every nonzero difference in [2^-180, 2^180]: then every product of up to
// three differences and every rounding error in it is a multiple of 2^-696 below 2^541.

/// a - b = d exactly? (the rounding error of the subtraction is zero)
bool exact_difference(double a, double b, double d) {
  const double bv = a - d, av = d + bv;
  return (a - av) + (bv - b) == 0.0;
}

bool in_expansion_range(double d) {
  const double m = std::abs(d);
  return m == 0.0 || (m >= 0x1p-180 && m <= 0x1p180);
}

void two_sum(double a, double b, double& s, double& e) {
  s = a + b;
  const double bv = s - a, av = s - bv;
  e = (a - av) + (b - bv);
}

/// p + e = a b exactly: the fused multiply-add rounds a b - p once, and that value is
/// representable (no underflow in the range above). Immune to FMA contraction, unlike a
/// Veltkamp split.
void two_product(double a, double b, double& p, double& e) {
  p = a * b;
  e = std::fma(a, b, -p);
}

/// Sign of the exact sum of t[0..n) (t is overwritten). Repeated error-free
/// distillation (Ogita, Rump and Oishi's AccSign): a pass of two-sums carries the sum into
/// t[n-1] and leaves the rounding errors below, the total unchanged; once |t[n-1]|
/// exceeds the sum of the others' magnitudes (with a margin for that sum's own rounding)
/// its sign is the sign of the total. A few passes suffice; past 32, a nonoverlapping
/// expansion decides (Shewchuk's Grow-Expansion, zeros dropped: the sign of its largest
/// component).
int sign_of_sum(double* t, int n) {
  for (int pass = 0; pass < 32; ++pass) {
    for (int i = 1; i < n; ++i) two_sum(t[i], t[i - 1], t[i], t[i - 1]);
    double rest = 0;
    for (int i = 0; i + 1 < n; ++i) rest += std::abs(t[i]);
    if (rest == 0.0 || std::abs(t[n - 1]) > rest * (1.0 + 4.0 * n * 0x1p-53)) return (t[n - 1] > 0) - (t[n - 1] < 0);
  }
  double e[64];
  int m = 0;
  for (int i = 0; i < n; ++i) {
    double q = t[i];
    int k = 0;
    for (int j = 0; j < m; ++j) {
      double h;
      two_sum(q, e[j], q, h);
      if (h != 0.0) e[k++] = h;
    }
    if (q != 0.0) e[k++] = q;
    m = k;
  }
  return m == 0 ? 0 : (e[m - 1] > 0 ? 1 : -1);
}

/// x y z as four doubles with the exact sum, appended at t.
void triple_product(double x, double y, double z, double*& t, double sign) {
  double p, e;
  two_product(x, y, p, e);
  two_product(sign * p, z, t[0], t[1]);
  two_product(sign * e, z, t[2], t[3]);
  t += 4;
}

}  // namespace

namespace detail {

int orient2d_exact_sign(double ax, double ay, double bx, double by, double cx, double cy) {
  ++exact_count;
  const double bax = bx - ax, bay = by - ay, cax = cx - ax, cay = cy - ay;
  if (exact_difference(bx, ax, bax) && exact_difference(by, ay, bay) && exact_difference(cx, ax, cax) &&
      exact_difference(cy, ay, cay) && in_expansion_range(bax) && in_expansion_range(bay) && in_expansion_range(cax) &&
      in_expansion_range(cay)) {
    double t[4];
    two_product(bax, cay, t[0], t[1]);
    two_product(-bay, cax, t[2], t[3]);
    return sign_of_sum(t, 4);
  }
  return orient2d_exact(ax, ay, bx, by, cx, cy);
}

int orient3d_exact_sign(const double* a, const double* b, const double* c, const double* d) {
  ++exact_count;
  double u[3], v[3], w[3];
  bool ok = true;
  for (int k = 0; k < 3; ++k) {
    u[k] = b[k] - a[k], v[k] = c[k] - a[k], w[k] = d[k] - a[k];
    ok = ok && exact_difference(b[k], a[k], u[k]) && exact_difference(c[k], a[k], v[k]) &&
         exact_difference(d[k], a[k], w[k]) && in_expansion_range(u[k]) && in_expansion_range(v[k]) &&
         in_expansion_range(w[k]);
  }
  if (ok) {
    // w . (u x v), six triple products.
    double t[24];
    double* p = t;
    triple_product(w[0], u[1], v[2], p, 1.0);
    triple_product(w[0], u[2], v[1], p, -1.0);
    triple_product(w[1], u[2], v[0], p, 1.0);
    triple_product(w[1], u[0], v[2], p, -1.0);
    triple_product(w[2], u[0], v[1], p, 1.0);
    triple_product(w[2], u[1], v[0], p, -1.0);
    return sign_of_sum(t, 24);
  }
  return orient3d_exact(Eigen::Vector3d(a[0], a[1], a[2]), Eigen::Vector3d(b[0], b[1], b[2]),
                        Eigen::Vector3d(c[0], c[1], c[2]), Eigen::Vector3d(d[0], d[1], d[2]));
}

}  // namespace detail

int orient2d_exact(double ax, double ay, double bx, double by, double cx, double cy) {
  const auto X = to_integers<6>({ax, ay, bx, by, cx, cy});
  const cpp_int ux = X[2] - X[0], uy = X[3] - X[1], vx = X[4] - X[0], vy = X[5] - X[1];
  return cpp_int(ux * vy - uy * vx).sign();
}

int orient3d_exact(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                   const Eigen::Vector3d& d) {
  const auto X = to_integers<12>({a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2], d[0], d[1], d[2]});
  const cpp_int ux = X[3] - X[0], uy = X[4] - X[1], uz = X[5] - X[2];
  const cpp_int vx = X[6] - X[0], vy = X[7] - X[1], vz = X[8] - X[2];
  const cpp_int wx = X[9] - X[0], wy = X[10] - X[1], wz = X[11] - X[2];
  const cpp_int det = wx * (uy * vz - uz * vy) + wy * (uz * vx - ux * vz) + wz * (ux * vy - uy * vx);
  return det.sign();
}

std::uint64_t exact_evaluations() { return exact_count; }

}  // namespace weft::contact::verify
