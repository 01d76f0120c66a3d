// The servo cycle's own clock, for CycleOutput::computation_time_us: the processor's
// time-stamp counter where it is invariant (x86-64 with CPUID's invariant-TSC bit; the
// Linux "constant_tsc nonstop_tsc" flags), else std::chrono::steady_clock. One read of the
// counter costs a few nanoseconds where a steady_clock read costs about 20 (a vDSO call);
// a cycle takes two (docs/performance.md).
#pragma once

#include <chrono>
#include <cstdint>

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
    if (scale().tsc) return __rdtsc();
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
  /// Calibrates the clock, once per process (about a millisecond against steady_clock on
  /// the first call): call it outside the servo cycle (the Controller's constructor does).
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
    unsigned a = 0, b = 0, c = 0, d = 0;
    if (__get_cpuid(0x80000000u, &a, &b, &c, &d) == 0 || a < 0x80000007u) return s;
    __cpuid(0x80000007u, a, b, c, d);
    if (!(d & (1u << 8))) return s;  // the counter's rate may follow the processor's clock
    using Steady = std::chrono::steady_clock;
    const Steady::time_point t0 = Steady::now();
    const std::uint64_t c0 = __rdtsc();
    Steady::time_point t1 = t0;
    while (t1 - t0 < std::chrono::milliseconds(1)) t1 = Steady::now();
    const std::uint64_t c1 = __rdtsc();
    const double us = std::chrono::duration<double, std::micro>(t1 - t0).count();
    if (c1 <= c0 || !(us > 0.0)) return s;
    s.tsc = true;
    s.us_per_tick = us / static_cast<double>(c1 - c0);
#endif
    return s;
  }
};

}  // namespace virtmech::detail
