#pragma once
/// \file predicates.hpp
/// Exact orientation predicates on double coordinates: the sign of a 2x2 or 3x3
/// determinant, correct for every finite input (no epsilon, no tolerance).
///
/// Method (a filter and two exact stages, in the manner of Shewchuk, written afresh):
///  1. Floating-point evaluation. With u = 2^-53, every difference, product and sum
///     rounded once, the computed determinant D~ differs from the exact one by at most
///     gamma_k P, where P is the permanent (the same expansion with |.| on every term) and
///     gamma_k = k u / (1 - k u), k = 4 (2D) or 8 (3D) roundings per term. The permanent
///     is computed from the same rounded values, which only loses another factor
///     (1 - gamma_k). A product that underflows adds an absolute error below 2^-1075,
///     which later products scale by at most the |w| they multiply. The bounds used are
///       2D: 5 u P~ + 2^-1071,    3D: 9 u P~ + 2^-1069 (|w_x| + |w_y| + |w_z| + 1),
///     with w = d - a; if |D~| exceeds it, the sign of D~ is the exact sign. An overflow
///     makes P~ infinite or NaN, which fails the test. When P~ == 0 and every term of the
///     expansion has a zero factor (rounded differences are zero exactly when the exact
///     ones are), the determinant is exactly 0: coordinate-aligned planes and lines cost
///     nothing.
///  2. Floating-point expansions, when every coordinate difference is exact (checked with
///     Knuth's two-sum error term, as for nearby points) and lies in [2^-180, 2^180]:
///     the fused multiply-add's two-product turns each term of the determinant into doubles that sum to
///     it exactly (24 in 3D, 4 in 2D), and the sign of that sum is found by error-free
///     distillation (Ogita, Rump and Oishi's AccSign, with a nonoverlapping expansion as
///     the last resort). No underflow or overflow can occur in that range.
///  3. Exact integer evaluation otherwise. Every double is m 2^e with an integer
///     |m| < 2^53: scaled by the smallest exponent of the inputs, all coordinates become
///     integers, and the determinant of their differences is evaluated in
///     arbitrary-precision integers (Boost.Multiprecision cpp_int); its sign is exact.
/// Stages 2 and 3 are written from the published algorithms, not copied.
///
/// Requirements: finite inputs (checked in stage 3), IEEE double arithmetic rounding to
/// nearest without extended precision (x86-64 SSE2, AArch64), and no -ffast-math (which
/// would let the compiler reassociate the filter; a build with it fails to compile).
/// FMA contraction is harmless: in the filter a fused product-sum is at least as
/// accurate as the two roundings it replaces (the bound counts both), and stage 2 uses
/// only sums and explicit std::fma.
#include <Eigen/Core>

#include <cmath>
#include <cstdint>

#if defined(__FAST_MATH__)
#error "contact/verify/predicates.hpp: exact predicates need IEEE arithmetic; do not build with -ffast-math"
#endif

namespace weft::contact::verify {

namespace detail {
int orient2d_exact_sign(double ax, double ay, double bx, double by, double cx, double cy);
int orient3d_exact_sign(const double* a, const double* b, const double* c, const double* d);
inline constexpr double unit_roundoff = 0x1p-53;
inline int sign_of(double x) { return (x > 0) - (x < 0); }
}  // namespace detail

/// Sign (-1, 0, +1) of
///   det [b - a, c - a] = (b_x - a_x)(c_y - a_y) - (b_y - a_y)(c_x - a_x):
/// +1 when a, b, c turn counter-clockwise, 0 when they are collinear. Exact.
inline int orient2d(double ax, double ay, double bx, double by, double cx, double cy) {
  const double bax = bx - ax, bay = by - ay, cax = cx - ax, cay = cy - ay;
  const double l = bax * cay, r = bay * cax;
  const double det = l - r;
  const double perm = std::abs(l) + std::abs(r);
  if (std::abs(det) > 5.0 * detail::unit_roundoff * perm + 0x1p-1071) return detail::sign_of(det);
  if (perm == 0.0 && (bax == 0.0 || cay == 0.0) && (bay == 0.0 || cax == 0.0)) return 0;
  return detail::orient2d_exact_sign(ax, ay, bx, by, cx, cy);
}

/// orient2d of the projections of a, b, c that drop coordinate k, taking the remaining
/// two in cyclic order (k+1, k+2): the exact sign of component k of (b - a) x (c - a).
inline int orient2d(int k, const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const int i = (k + 1) % 3, j = (k + 2) % 3;
  return orient2d(a[i], a[j], b[i], b[j], c[i], c[j]);
}

/// Sign (-1, 0, +1) of
///   det [b - a, c - a, d - a] = ((b - a) x (c - a)) . (d - a):
/// +1 when d lies on the side of the plane through a, b, c that the normal
/// (b - a) x (c - a) points to, 0 when the four points are coplanar. Exact. The sign is
/// alternating: swapping any two arguments flips it.
inline int orient3d(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                    const Eigen::Vector3d& d) {
  const double ux = b[0] - a[0], uy = b[1] - a[1], uz = b[2] - a[2];
  const double vx = c[0] - a[0], vy = c[1] - a[1], vz = c[2] - a[2];
  const double wx = d[0] - a[0], wy = d[1] - a[1], wz = d[2] - a[2];
  // (u x v) . w, each cross-product component a difference of two products.
  const double p1 = uy * vz, p2 = uz * vy, p3 = uz * vx, p4 = ux * vz, p5 = ux * vy, p6 = uy * vx;
  const double det = wx * (p1 - p2) + wy * (p3 - p4) + wz * (p5 - p6);
  const double awx = std::abs(wx), awy = std::abs(wy), awz = std::abs(wz);
  const double perm =
      awx * (std::abs(p1) + std::abs(p2)) + awy * (std::abs(p3) + std::abs(p4)) + awz * (std::abs(p5) + std::abs(p6));
  if (std::abs(det) > 9.0 * detail::unit_roundoff * perm + 0x1p-1069 * (awx + awy + awz + 1.0))
    return detail::sign_of(det);
  if (perm == 0.0) {  // zero, or every product underflowed: a zero factor in every term decides
    const bool zux = ux == 0, zuy = uy == 0, zuz = uz == 0, zvx = vx == 0, zvy = vy == 0, zvz = vz == 0;
    const bool zwx = wx == 0, zwy = wy == 0, zwz = wz == 0;
    if ((zwx || zuy || zvz) && (zwx || zuz || zvy) && (zwy || zuz || zvx) && (zwy || zux || zvz) &&
        (zwz || zux || zvy) && (zwz || zuy || zvx))
      return 0;
  }
  return detail::orient3d_exact_sign(a.data(), b.data(), c.data(), d.data());
}

/// orient3d(a, b, c, d) for many points d against one plane through a, b, c: the terms
/// of the filter that do not depend on d (the rounded normal and its permanent parts)
/// are computed once. The same floating-point operations in the same order as orient3d,
/// and the same exact fallback, so the same signs.
class Orient3dPlane {
 public:
  Orient3dPlane() = default;
  Orient3dPlane(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
    const double ux = b[0] - a[0], uy = b[1] - a[1], uz = b[2] - a[2];
    const double vx = c[0] - a[0], vy = c[1] - a[1], vz = c[2] - a[2];
    const double p1 = uy * vz, p2 = uz * vy, p3 = uz * vx, p4 = ux * vz, p5 = ux * vy, p6 = uy * vx;
    n_[0] = p1 - p2, n_[1] = p3 - p4, n_[2] = p5 - p6;
    m_[0] = std::abs(p1) + std::abs(p2), m_[1] = std::abs(p3) + std::abs(p4), m_[2] = std::abs(p5) + std::abs(p6);
    // Whether both products of normal component k have a zero factor (see orient3d).
    zero_[0] = (uy == 0 || vz == 0) && (uz == 0 || vy == 0);
    zero_[1] = (uz == 0 || vx == 0) && (ux == 0 || vz == 0);
    zero_[2] = (ux == 0 || vy == 0) && (uy == 0 || vx == 0);
  }
  /// orient3d(a, b, c, d), exact; a, b, c must be the points the plane was built from.
  int side(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
           const Eigen::Vector3d& d) const {
    const double wx = d[0] - a[0], wy = d[1] - a[1], wz = d[2] - a[2];
    const double det = wx * n_[0] + wy * n_[1] + wz * n_[2];
    const double awx = std::abs(wx), awy = std::abs(wy), awz = std::abs(wz);
    const double perm = awx * m_[0] + awy * m_[1] + awz * m_[2];
    if (std::abs(det) > 9.0 * detail::unit_roundoff * perm + 0x1p-1069 * (awx + awy + awz + 1.0))
      return detail::sign_of(det);
    if (perm == 0.0 && (wx == 0 || zero_[0]) && (wy == 0 || zero_[1]) && (wz == 0 || zero_[2])) return 0;
    return detail::orient3d_exact_sign(a.data(), b.data(), c.data(), d.data());
  }

 private:
  double n_[3] = {0, 0, 0}, m_[3] = {0, 0, 0};
  bool zero_[3] = {true, true, true};
};

/// The same signs, always computed by stage 3 (integers; no filter, no expansions): a
/// reference for tests and a measure of what the other stages save.
int orient2d_exact(double ax, double ay, double bx, double by, double cx, double cy);
int orient3d_exact(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                   const Eigen::Vector3d& d);

/// Number of predicate evaluations on the calling thread that fell through the filter to
/// stage 2 or 3, since the thread started (a monotone counter: take differences).
std::uint64_t exact_evaluations();

}  // namespace weft::contact::verify
