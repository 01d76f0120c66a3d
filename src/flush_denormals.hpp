// Subnormal numbers flushed to zero for the servo cycle's arithmetic, the caller's
// floating-point mode restored afterwards.
#pragma once

#if defined(__SSE2__) || defined(_M_X64) || (defined(_M_IX86_FP) && _M_IX86_FP >= 2)
#include <xmmintrin.h>
#define VIRTMECH_FLUSH_DENORMALS_SSE 1
#elif defined(__aarch64__)
#define VIRTMECH_FLUSH_DENORMALS_AARCH64 1
#endif

namespace virtmech::detail {

/// While alive: results below the smallest normal double (2.2e-308) are flushed to zero and
/// such inputs read as zero (x86: MXCSR's FTZ and DAZ bits; AArch64: FPCR.FZ). A quantity
/// that converges to an exact zero (a placement's coordinate on a symmetry plane, shrinking
/// by a factor each cycle) otherwise ends in the subnormal range, where every operation on
/// it takes a microcode assist of about a hundred cycles: on a two-guide set that made a
/// third of the cycle's time. No value of the cycle is meaningful at 1e-308 (its quantities
/// are metres, radians, newtons), so the results are those of the exact arithmetic as
/// closely as before. The caller's mode (those bits) is restored on destruction; the sticky
/// exception flags raised inside are left for the caller to see.
class FlushDenormals {
 public:
#if defined(VIRTMECH_FLUSH_DENORMALS_SSE)
  FlushDenormals() noexcept : saved_(_mm_getcsr()) { _mm_setcsr(saved_ | kFtzDaz); }
  // the caller's two bits back; the exception flags the cycle raised stay raised
  ~FlushDenormals() { _mm_setcsr((_mm_getcsr() & ~kFtzDaz) | (saved_ & kFtzDaz)); }

 private:
  // flush-to-zero (bit 15), denormals-are-zero (bit 6)
  static constexpr unsigned kFtzDaz = 0x8040u;
  unsigned saved_;
#elif defined(VIRTMECH_FLUSH_DENORMALS_AARCH64)
  FlushDenormals() noexcept {
    __asm__ __volatile__("mrs %0, fpcr" : "=r"(saved_));
    const unsigned long fz = saved_ | (1ul << 24);
    __asm__ __volatile__("msr fpcr, %0" : : "r"(fz));
  }
  ~FlushDenormals() { __asm__ __volatile__("msr fpcr, %0" : : "r"(saved_)); }

 private:
  unsigned long saved_;
#else
  FlushDenormals() noexcept = default;  // other targets: the arithmetic as the caller set it
#endif

 public:
  FlushDenormals(const FlushDenormals&) = delete;
  FlushDenormals& operator=(const FlushDenormals&) = delete;
};

}  // namespace virtmech::detail
