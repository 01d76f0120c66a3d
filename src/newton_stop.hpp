// When a Newton iteration may stop short of its last, rounding-level step: part of the
// placements' algorithms (it decides where they stop), not a replacement of a library
// routine (docs/performance.md, "Hand-made routines"). Internal to the core.
#pragma once

namespace virtmech::detail {

/// Newton's error falls as e' = K e^2; with K ~ step / last^2 from the last two full steps
/// (lengths `step`, and `last` > 0 before it) the next step would be about step^3 / last^2.
/// True where that is at most `tol`: the step is not worth taking.
inline bool next_newton_step_below(double step, double last, double tol) noexcept {
  return last > 0.0 && step * step * step <= tol * last * last;
}

}  // namespace virtmech::detail
