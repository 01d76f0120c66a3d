// The rotation vector of a rotation R from its axis part d = (R21 - R12, R02 - R20, R10 - R01)
// = 2 sin(angle) axis and 1 + tr R = 2 + 2 cos(angle), below 2 pi / 3 (1 + tr > 1): so3_log's
// and PlanarArm's, which has both in closed form. Internal to the core.
#pragma once

#include <cmath>

#include "std_math.hpp"
#include "trig.hpp"
#include "virtmech/types.hpp"

namespace virtmech::detail {

/// angle * axis from d and tr1 = 1 + tr R > 1: angle = 2 atan2(|d|, tr1). d keeps the
/// relative accuracy of R's off-diagonal terms at small angles.
inline Eigen::Vector3d log_from_axis_part(const Eigen::Vector3d& d, double tr1) noexcept {
  // up to 2 atan(1/2) (53 degrees), u = |d| / tr1 = tan(angle / 2) <= 1/2, and angle d / |d|
  // = 2 (atan(u) / u) d / tr1 needs neither |d| nor a second division
  // (docs/performance.md, "Hand-made routines"; a core built on <cmath> takes the atan2
  // below throughout)
  const double dd = d.squaredNorm();
  if (!kStdMath && dd <= kAtanSeriesMaxZ * tr1 * tr1) {
    const double inv = 1.0 / tr1, z = dd * inv * inv;
    return (2.0 * inv * (1.0 + z * atan_series(z))) * d;
  }
  if (kStdMath && dd <= 1e-16 * tr1 * tr1) {
    // atan(u) / u = 1 - u^2 / 3 + ...: 1 to rounding for u^2 <= 1e-16 (and |d| may underflow)
    return (2.0 / tr1) * d;
  }
  const double n = std::sqrt(dd);
  return (2.0 * atan2(n, tr1) / n) * d;
}

}  // namespace virtmech::detail
