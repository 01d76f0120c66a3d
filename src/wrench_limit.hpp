// The wrench limits' comparison, shared by the safety and passivity stages.
#pragma once

#include <cmath>

namespace virtmech::detail {

/// |f| > limit for |f|^2 = norm2, without the square root where limit^2 is finite.
inline bool exceeds(double norm2, double limit) noexcept {
  return limit < 1e150 ? norm2 > limit * limit : std::sqrt(norm2) > limit;
}

}  // namespace virtmech::detail
