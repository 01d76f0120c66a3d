// The servo cycle's own clock, for CycleOutput::computation_time_us: the processor's
// time-stamp counter where it is invariant (x86-64 with CPUID's invariant-TSC bit; the
// Linux "constant_tsc nonstop_tsc" flags), else std::chrono::steady_clock. One read of the
// counter costs a few nanoseconds where a steady_clock read costs about 20 (a vDSO call);
// a cycle takes two, and with steady_clock the Omni + PlanarArm cycle takes 9 % longer,
// Omni + Probe's 5 % (docs/performance.md, "Hand-made routines"). A core built on <cmath> and steady_clock
// alone (VIRTMECH_STD_MATH) uses steady_clock everywhere.
#pragma once

#include <chrono>
#include <cstdint>

#include "std_math.hpp"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <cpuid.h>
#include <x86intrin.h>
#define VIRTMECH_CYCLE_CLOCK_TSC 1
#endif

namespace virtmech::detail {

class CycleClock {
 public:
  /// The clock's ticks now (the time-stamp counter, or steady_clock's nanoseconds).
  static std::uint64_t now() noexcept {
#ifdef VIRTMECH_CYCLE_CLOCK_TSC
    if (!kStdMath && scale().tsc) return __rdtsc();
#endif
    return static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                          std::chrono::steady_clock::now().time_since_epoch())
                                          .count());
  }
  /// Microseconds from `start` to `end` (two now()); 0 if the clock went back (a thread
  /// moved between processors whose counters differ).
  static double microseconds(std::uint64_t start, std::uint64_t end) noexcept {
    return end > start ? static_cast<double>(end - start) * scale().us_per_tick : 0.0;
  }
  /// Calibrates the clock, once per process (about 3 ms against steady_clock on the first
  /// call): call it outside the servo cycle (the Controller's constructor does).
  static void calibrate() noexcept { (void)scale(); }

 private:
  struct Scale {
    bool tsc = false;
    double us_per_tick = 1e-3;
  };
  static const Scale& scale() noexcept {
    static const Scale s = measure();
    return s;
  }
  static Scale measure() noexcept {
    Scale s;
#ifdef VIRTMECH_CYCLE_CLOCK_TSC
    if (kStdMath) return s;
    unsigned a = 0, b = 0, c = 0, d = 0;
    if (__get_cpuid(0x80000000u, &a, &b, &c, &d) == 0 || a < 0x80000007u) return s;
    __cpuid(0x80000007u, a, b, c, d);
    if (!(d & (1u << 8))) return s;  // the counter's rate may follow the processor's clock
    // each counter read between two steady_clock reads, over 1 ms; of three tries the one
    // whose brackets are narrowest (a try the scheduler interrupted has a wide one)
    using Steady = std::chrono::steady_clock;
    auto bracketed = [](std::uint64_t& c, double& width_us) {
      const Steady::time_point a = Steady::now();
      c = __rdtsc();
      const Steady::time_point b = Steady::now();
      width_us = std::chrono::duration<double, std::micro>(b - a).count();
      return a + (b - a) / 2;
    };
    double best_width = 0.0;
    for (int attempt = 0; attempt < 3; ++attempt) {
      std::uint64_t c0 = 0, c1 = 0;
      double w0 = 0.0, w1 = 0.0;
      const Steady::time_point t0 = bracketed(c0, w0);
      while (Steady::now() - t0 < std::chrono::milliseconds(1)) {
      }
      const Steady::time_point t1 = bracketed(c1, w1);
      const double us = std::chrono::duration<double, std::micro>(t1 - t0).count();
      if (c1 <= c0 || !(us > 0.0)) continue;
      if (s.tsc && w0 + w1 >= best_width) continue;
      s.tsc = true;
      best_width = w0 + w1;
      s.us_per_tick = us / static_cast<double>(c1 - c0);
    }
#endif
    return s;
  }
};

}  // namespace virtmech::detail
