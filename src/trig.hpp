// Sine and cosine, and atan2, for the servo cycle. glibc's are correctly rounded and cost
// more (docs/performance.md, "Hand-made routines"); these stay within 2 ulp of the
// exact values (tests/cpp/test_trig.cpp checks them against long double). Arguments beyond
// what the reductions below serve go to the library's. The coefficients and constants are
// scripts/trig_fits.py's (mpmath, 50 digits; tests/python/test_trig_fits.py regenerates and
// compares them). A core built on <cmath> (VIRTMECH_STD_MATH) uses the library's instead.
// Internal to the core.
#pragma once

#if defined(__FAST_MATH__)
#error "src/trig.hpp needs IEEE arithmetic (its reductions round by adding and subtracting a constant): build the core without -ffast-math"
#endif

#include <algorithm>
#include <cmath>

#include "std_math.hpp"

namespace virtmech::detail {

/// sin x and cos x. For |x| <= 1e3: x = k pi/2 + r with |r| <= pi/4, then r + r^3 S(r^2) and
/// 1 - r^2/2 + r^4 C(r^2), S and C Chebyshev fits of degree 5 on that interval (their
/// errors, times r^2 and r^4, below 2e-17); beyond, std::sin and std::cos.
inline void sincos_by_fit(double x, double& s, double& c) noexcept {
  if (!(std::abs(x) <= 1e3) || x == 0.0) {  // (NaN, infinities and signed zeros: there)
    s = std::sin(x);
    c = std::cos(x);
    return;
  }
  // k = x 2/pi rounded to nearest by adding and subtracting 1.5 2^52 (std::nearbyint is a
  // library call on baseline x86-64)
  constexpr double kShift = 6755399441055744.0;
  const double k = (x * 0.63661977236758134 + kShift) - kShift;
  // r = x - k pi/2 with pi/2 in three parts, the first two of 33 bits, so that k times each
  // is exact (|k| < 2^10 here) and x - k P1 is too (Cody and Waite)
  const double r = ((x - k * 1.5707963267341256) - k * 6.077100506303966e-11) -
                   k * 2.0222662487959506e-21;
  const double z = r * r, z2 = z * z, z4 = z2 * z2;
  const double S = (-0.16666666666666666 + 0.008333333333330948 * z) +
                   (-0.00019841269836758574 + 2.755731610255244e-06 * z) * z2 +
                   (-2.5051131845003624e-08 + 1.5918129294866608e-10 * z) * z4;
  const double C = (0.041666666666666664 - 0.0013888888888887398 * z) +
                   (2.480158729876569e-05 - 2.7557317271729793e-07 * z) * z2 +
                   (2.08761462684032e-09 - 1.1382632425521717e-11 * z) * z4;
  const double sr = r + r * z * S;
  // 1 - z/2 with the rounding of the subtraction carried into the small terms
  const double hz = 0.5 * z, w = 1.0 - hz;
  const double cr = w + (((1.0 - w) - hz) + z2 * C);
  // the quadrant: sin x = sr, cr, -sr, -cr and cos x = cr, -sr, -cr, sr for k mod 4 = 0..3
  const long long q = static_cast<long long>(k);
  const bool odd = q & 1;
  const double a = odd ? cr : sr, b = odd ? sr : cr;
  s = (q & 2) ? -a : a;
  c = ((q + 1) & 2) ? -b : b;
}

/// (atan(u) / u - 1) / z, z = u^2, for |u| <= 1/2 (z <= 1/4): atan(u) = u + u z P(z), P a
/// Chebyshev fit of (atan(u) - u) / u^3 on that interval, degree 12 (its error, times z,
/// below 1e-18), evaluated by Estrin's scheme.
inline double atan_series(double z) noexcept {
  const double z2 = z * z, z4 = z2 * z2, z8 = z4 * z4;
  const double p01 = -0.3333333333333333 + 0.19999999999999488 * z;
  const double p23 = -0.14285714285599188 + 0.11111111100917376 * z;
  const double p45 = -0.09090908620322523 + 0.07692294712540285 * z;
  const double p67 = -0.06666435677235948 + 0.05879578429582425 * z;
  const double p89 = -0.05240099507994713 + 0.04628024868570153 * z;
  const double p1011 = -0.03806653672057366 + 0.025006503566489507 * z;
  return (p01 + p23 * z2) + (p45 + p67 * z2) * z4 +
         ((p89 + p1011 * z2) - 0.009215792047089858 * z4) * z8;
}

/// The largest z = u^2 atan_series serves.
constexpr double kAtanSeriesMaxZ = 0.25;

/// atan2(y, x) in [-pi, pi]: std::atan2's value to 2 ulp, and its signs of zero.
inline double atan2_by_fit(double y, double x) noexcept {
  const double ax = std::abs(x), ay = std::abs(y);
  const double hi = std::max(ax, ay), lo = std::min(ax, ay);
  if (!(ax < 1e300 && ay < 1e300 && hi > 1e-300)) return std::atan2(y, x);  // (NaN: here)
  // atan(lo / hi) in [0, pi/4]: from lo = hi / 2 on as pi/4 + atan(u), u = (lo - hi) /
  // (lo + hi) (the same division; lo - hi exact there, by Sterbenz's lemma), so that
  // |u| <= 1/2 everywhere
  const bool upper = lo >= 0.5 * hi;
  const double u = (upper ? lo - hi : lo) / (upper ? lo + hi : hi);
  // atan(u) = u + u z P(z), z = u^2
  const double z = u * u, P = atan_series(z);
  // atan2 = k pi/4 + s atan(u): k pi/4 as a double and its remainder, added last
  constexpr double kHi[5] = {0.0, 0.7853981633974483, 1.5707963267948966, 2.356194490192345,
                             3.141592653589793};
  constexpr double kLo[5] = {0.0, 3.061616997868383e-17, 6.123233995736766e-17,
                             9.184850993605148e-17, 1.2246467991473532e-16};
  int k = upper ? 1 : 0;
  double s = 1.0;
  if (ay > ax) {  // atan(hi / lo) = pi/2 - atan(lo / hi)
    k = 2 - k;
    s = -s;
  }
  if (x < 0.0) {  // pi - atan(|y| / |x|)
    k = 4 - k;
    s = -s;
  }
  const double r = kHi[k] + (s * u + (s * u * z * P + kLo[k]));
  return std::copysign(r, y);
}

/// The cycle's sine and cosine: sincos_by_fit, or the library's in a core built on <cmath>.
inline void sincos(double x, double& s, double& c) noexcept {
  if constexpr (kStdMath) {
    s = std::sin(x);
    c = std::cos(x);
  } else {
    sincos_by_fit(x, s, c);
  }
}

/// The cycle's atan2: atan2_by_fit, or the library's in a core built on <cmath>.
inline double atan2(double y, double x) noexcept {
  if constexpr (kStdMath) {
    return std::atan2(y, x);
  } else {
    return atan2_by_fit(y, x);
  }
}

}  // namespace virtmech::detail
