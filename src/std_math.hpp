// Whether the core is built on <cmath> and std::chrono::steady_clock alone (the CMake
// option VIRTMECH_STD_MATH, off by default): its own routines that measurably shorten the
// servo cycle (docs/performance.md, "Hand-made routines") then forward to the library's.
// The one place the option is read. Internal to the core.
#pragma once

namespace virtmech::detail {

#if defined(VIRTMECH_STD_MATH) && VIRTMECH_STD_MATH
inline constexpr bool kStdMath = true;
#else
inline constexpr bool kStdMath = false;
#endif

}  // namespace virtmech::detail
