// The minimiser of one revolute joint's weighted cost on the short arc between its
// position and rotation terms' minimisers (closed_form.hpp: arc_minimiser), by a bracketed
// Newton solve.
#include <algorithm>
#include <cmath>

#include "../closed_form.hpp"
#include "angle_solve.hpp"

namespace virtmech::detail {

namespace {

// the direction of q, atan2(q.y, q.x), with its cosine and sine
double direction(const Eigen::Vector2d& q, double& cos_x, double& sin_x) noexcept {
  const double x = detail::atan2(q.y(), q.x());
  const double n = q.norm();
  if (n > 0.0 && std::isfinite(n)) {
    cos_x = q.x() / n;
    sin_x = q.y() / n;
  } else {  // (+-0, +-0): atan2's signed zeros decide
    sin_x = std::sin(x);
    cos_x = std::cos(x);
  }
  return x;
}

}  // namespace

ArcSetup arc_setup(const Eigen::Vector2d& p, const Eigen::Vector2d& o) noexcept {
  ArcSetup a;
  a.o = o;
  a.theta_p = direction(p, a.cp, a.sp);
  const double cross = p.x() * o.y() - p.y() * o.x(), dot = p.dot(o);
  a.span = detail::atan2(cross, dot);  // theta_o - theta_p in [-pi, pi]
  a.dir = a.span > 0.0 ? 1.0 : -1.0;
  a.width = std::abs(a.span);
  // |(cross, dot)|: the plain square root where the squares neither overflow nor underflow
  // (std::hypot, which guards against both, is a library call)
  const double n2 = cross * cross + dot * dot;
  const double n = n2 > 1e-300 && n2 < 1e300 ? std::sqrt(n2) : std::hypot(cross, dot);
  a.cs = dot / n;
  a.ss = std::abs(cross) / n;
  return a;
}

double arc_minimiser(const ArcSetup& g, double a, double b, double c, double w_r,
                     double& cos_x, double& sin_x) noexcept {
  // f(x) = -a cos(x - theta_p) + w_r acos(y)^2, y = c + b cos(x - theta_o); both terms grow
  // with the distance to their own minimiser, so f's minimum lies on the short arc between
  // theta_p and theta_o (any other point is farther from both than some point on it)
  if (!(a > 0.0) || g.span == 0.0) return direction(g.o, cos_x, sin_x);
  if (!(w_r > 0.0) || !(b > 0.0)) {
    cos_x = g.cp;
    sin_x = g.sp;
    return g.theta_p;
  }
  // on t in [0, |span|] from theta_p toward theta_o: f' runs from - to +. With x - theta_p =
  // dir t and x - theta_o = dir (t - |span|), one sine and cosine of t per step give both terms
  const double dir = g.dir, width = g.width, cs = g.cs, ss = g.ss;
  // Start at the minimiser of the two terms' quadratic models: a t^2 / 2 and
  // w_r b (|span| - t)^2 (acos(c + b cos x)^2 ~ b x^2 near its minimum). Strictly inside,
  // since at an end f' may vanish without a minimum there. Within a quarter turn both terms
  // are convex (-a cos t, and acos(y)^2 for the distance to theta_o below pi/2), so f' has
  // one root and the model's start, within rounding of it where one weight dominates, needs
  // no margin; beyond, f' may have several and the margin keeps the start away from the ends
  const double inset = (width <= 0.5 * M_PI ? 1e-12 : 1e-3) * width;
  const double t0 = std::min(std::max(width * 2.0 * w_r * b / (a + 2.0 * w_r * b), inset),
                             width - inset);
  // its cosine and sine from the nearer end's: t = 0, or t = width (cosine and sine cs, ss)
  const Angle end = t0 <= width - t0 ? Angle{0.0, 1.0, 0.0} : Angle{width, cs, ss};
  const Angle t = bracketed_newton(
      [&](double, double ct, double st, double& f1, double& f2, double& f3) {
        const double so = dir * (st * cs - ct * ss), co = ct * cs + st * ss;
        const double y = std::min(1.0, std::max(-1.0, c + b * co));
        const double s1 = std::sqrt(std::max(0.0, 1.0 - y * y));  // sin of the angle
        double ang, h, dh, d2h;
        acos_squared_terms(y, s1, ang, h, dh, &d2h);
        const double y1 = -b * so, y2 = -b * co;
        f1 = a * st - dir * 2.0 * w_r * h * y1;  // d/dt = dir d/dx
        f2 = a * ct - 2.0 * w_r * (dh * y1 * y1 + h * y2);
        // f''' = -a sin t - 2 w_r dy (d2h dy^2 + 3 dh y'' - h), dy = dir y1 (y''' = -dy)
        f3 = -a * st - 2.0 * w_r * dir * y1 * (d2h * y1 * y1 + 3.0 * dh * y2 - h);
      },
      0.0, width, advanced(end, t0 - end.x));
  cos_x = g.cp * t.c - dir * g.sp * t.s;  // x = theta_p + dir t
  sin_x = g.sp * t.c + dir * g.cp * t.s;
  return g.theta_p + dir * t.x;
}

double arc_minimiser(double a, const Eigen::Vector2d& p, double b, const Eigen::Vector2d& o,
                     double c, double w_r, double& cos_x, double& sin_x) noexcept {
  return arc_minimiser(arc_setup(p, o), a, b, c, w_r, cos_x, sin_x);
}

}  // namespace virtmech::detail
