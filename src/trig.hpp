// atan2 for the servo cycle, and the arctangent series it shares with the rotation's
// logarithm (src/rotation_log.hpp). glibc's atan2 is correctly rounded and costs about twice
// as much (docs/performance.md, "Hand-made routines"); this one stays within 2 ulp of the
// exact value (tests/cpp/test_trig.cpp checks it against long double). Arguments beyond what
// its reduction serves go to the library's. The coefficients and constants are
// scripts/trig_fits.py's (mpmath, 50 digits; tests/python/test_trig_fits.py regenerates and
// compares them). A core built on <cmath> (VIRTMECH_STD_MATH) uses the library's instead.
// Sines and cosines are the library's everywhere. Internal to the core.
#pragma once

#if defined(__FAST_MATH__)
#error "src/trig.hpp needs IEEE arithmetic (atan2 sends NaN and infinities to the library's by comparisons and adds the remainder of k pi/4 last, which -ffast-math may drop or reorder): build the core without -ffast-math"
#endif

#include <algorithm>
#include <cmath>

#include "std_math.hpp"

namespace virtmech::detail {

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

/// The cycle's atan2: atan2_by_fit, or the library's in a core built on <cmath>.
inline double atan2(double y, double x) noexcept {
  if constexpr (kStdMath) {
    return std::atan2(y, x);
  } else {
    return atan2_by_fit(y, x);
  }
}

}  // namespace virtmech::detail
