// What the closed-form placements' one- and two-angle solves share: an angle carried with
// its cosine and sine, the bracketed Newton solve of a minimiser in one angle, the terms of
// acos(y)^2's derivatives, and a basis of the sphere's tangent plane. Internal to the core.
#pragma once

#include <cmath>

#include "../newton_stop.hpp"
#include "../trig.hpp"
#include "virtmech/se3.hpp"
#include "virtmech/types.hpp"

namespace virtmech::detail {

// an angle with its cosine and sine
struct Angle {
  double x, c, s;
};

// an orthonormal basis of the sphere's tangent plane at the unit vector u (its columns)
inline Eigen::Matrix<double, 3, 2> tangent_basis(const Eigen::Vector3d& u) noexcept {
  Eigen::Matrix<double, 3, 2> E;
  E.col(0) = any_orthogonal(u);
  E.col(1) = u.cross(E.col(0));
  return E;
}

// The angle x with its cosine and sine.
[[gnu::noinline]] inline Angle at_angle(double x) noexcept {
  return {x, std::cos(x), std::sin(x)};
}

// The angle a.x + d with its cosine and sine from a's: for |d| < 1e-3 by the angle sum with
// the Taylor polynomials of cos d and sin d (their next terms, d^6 / 720 and d^7 / 5040,
// are below 1e-20: exact to rounding), which saves a sine and a cosine; else directly.
inline Angle advanced(const Angle& a, double d) noexcept {
  const double x = a.x + d;
  if (!(std::abs(d) < 1e-3)) return at_angle(x);
  const double h = x - a.x;  // the step x really took
  const double h2 = h * h;
  const double ch = 1.0 - h2 * (0.5 - h2 * (1.0 / 24.0));
  const double sh = h * (1.0 - h2 * (1.0 / 6.0 - h2 * (1.0 / 120.0)));
  return {x, a.c * ch - a.s * sh, a.s * ch + a.c * sh};
}

// The root of f' in [lo, hi] where f' runs from - (at lo) to + (at hi), from `start`
// inside (with its cosine and sine): Newton steps kept inside the shrinking bracket,
// bisection where Newton would leave it. derivatives(x, cos x, sin x, f1, f2, f3) gives
// f'(x), f''(x) and f'''(x) (NaN where f is not smooth enough for it to bound the step's
// error); each step carries the cosine and sine on (advanced(): a sine and cosine only for
// steps of 1e-3 or more, and after a bisection); the root is returned with its cosine and
// sine, which the callers need next.
template <typename Derivatives>
Angle bracketed_newton(const Derivatives& derivatives, double lo, double hi,
                       const Angle& start) noexcept {
  double last_step = 0.0;  // the last Newton step's length (0: none, or a bisection)
  Angle at = start;
  for (int it = 0; it < 100; ++it) {
    const double x = at.x, c = at.c, s = at.s;
    double f1, f2, f3;
    derivatives(x, c, s, f1, f2, f3);
    if (f1 < 0.0) lo = x;
    else if (f1 > 0.0) hi = x;
    else return at;
    const double rounding = 1e-16 * (1.0 + std::abs(x));
    if (f2 > 0.0) {
      const double step = f1 / f2, next = x - step;
      // Converged: a step at rounding level (checked before the bracket, which it may
      // leave by rounding: x is an end of it now), or one that leaves an error at rounding
      // level. Newton's error falls as e' = K e^2, and with K ~ |step| / last_step^2 from
      // the last two steps the step leaves about |step|^3 / last_step^2; stopping there
      // saves the step after, which would only move x by rounding noise. With f''' known the
      // step leaves |f'''| step^2 / (2 f''), Newton's own error term (f''' at a point
      // within the step of x: for steps this short, x's to a fraction of itself), which ends
      // the first step too where the start is that close (a tenth of rounding: a margin).
      const double a = std::abs(step);
      const bool leaves_rounding = std::abs(f3) * a * a <= 0.2 * rounding * f2;  // (NaN: no)
      if (a <= rounding || (next > lo && next < hi &&
                            (leaves_rounding || next_newton_step_below(a, last_step, rounding)))) {
        return advanced(at, -step);
      }
      if (next > lo && next < hi) {
        last_step = a;
        at = advanced(at, -step);
        continue;
      }
    }
    // Newton would leave the bracket (or f'' <= 0, or NaN): bisect
    last_step = 0.0;
    const double mid = 0.5 * (lo + hi);
    at = at_angle(mid);
    if (hi - lo <= 4e-16 * (1.0 + std::abs(hi))) return at;
  }
  return at;
}

// for ang = acos(y) with s1 = sin(ang) >= 0 given: h = ang / s1 and dh/dy, so that
// d acos(y)^2 / dy = -2 h (-> -2 as ang -> 0) and d^2 acos(y)^2 / dy^2 = -2 dh/dy; and, where
// d2h is given, d^2 h / dy^2 = (ang s1^2 + 3 y (ang y - s1)) / s1^5, 4/15 as ang -> 0 (its
// terms cancel there: the limit below 1e-2, within 1e-4 of it). One division: 1 / s1.
inline void acos_squared_terms(double y, double s1, double& ang, double& h, double& dh,
                        double* d2h = nullptr) noexcept {
  ang = detail::atan2(s1, y);
  const double inv = 1.0 / s1, inv3 = inv * inv * inv;  // (inf at s1 = 0: not used there)
  h = ang > 1e-8 ? ang * inv : 1.0 + ang * ang / 6.0;
  dh = ang > 1e-4 ? (ang * y - s1) * inv3 : -1.0 / 3.0;
  if (d2h) {
    *d2h = ang < 1e-2 ? 4.0 / 15.0
                      : (ang * s1 * s1 + 3.0 * y * (ang * y - s1)) * (inv3 * inv * inv);
  }
}

}  // namespace virtmech::detail
