// atan2 for the servo cycle: one division, a reduction to |u| <= tan(pi/8) and an odd
// polynomial of degree 23, within 2 ulp of the exact value (1.6 the largest measured;
// tests/cpp/test_arctangent.cpp checks it against long double in every quadrant and over
// 500 decades). glibc's atan2 is correctly rounded and, in the cycle, costs twice as much:
// Omni + PlanarArm calls it six times a cycle (docs/performance.md). Zeros, infinities, NaN
// and magnitudes beyond [1e-300, 1e300] go to std::atan2. Internal to the core.
#pragma once

#include <algorithm>
#include <cmath>

namespace virtmech::detail {

/// atan2(y, x) in [-pi, pi]: std::atan2's value to 2 ulp, and its signs of zero.
inline double atan2(double y, double x) noexcept {
  const double ax = std::abs(x), ay = std::abs(y);
  const double hi = std::max(ax, ay), lo = std::min(ax, ay);
  if (!(ax < 1e300 && ay < 1e300 && hi > 1e-300)) return std::atan2(y, x);  // (NaN: here)
  // atan(lo / hi) in [0, pi/4]: above tan(pi/8) as pi/4 + atan(u), u = (lo - hi) / (lo + hi)
  // (the same division), so that |u| <= tan(pi/8) everywhere
  const bool upper = lo > 0.41421356237309503 * hi;
  const double u = (upper ? lo - hi : lo) / (upper ? lo + hi : hi);
  // atan(u) = u + u z P(z), z = u^2 <= 3 - 2 sqrt(2): P a Chebyshev fit of
  // (atan(u) - u) / u^3 on that interval, degree 10 (its error, times z, below 1e-17),
  // evaluated by Estrin's scheme
  const double z = u * u, z2 = z * z, z4 = z2 * z2;
  const double p01 = -0.3333333333333333 + 0.1999999999999552 * z;
  const double p23 = -0.14285714284666542 + 0.11111111015256361 * z;
  const double p45 = -0.09090904578123903 + 0.07692183190826087 * z;
  const double p67 = -0.06664511447381948 + 0.0585814891280221 * z;
  const double p89 = -0.0508544973794026 + 0.03923165829558719 * z;
  const double P = (p01 + p23 * z2) + (p45 + p67 * z2) * z4 +
                   (p89 - 0.01917688711906226 * z2) * (z4 * z4);
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

}  // namespace virtmech::detail
