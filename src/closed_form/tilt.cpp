// The tilt of a stylus about one axis (closed_form.hpp: tilt_about_axis, turn_stylus): the
// weighted optimum reduced to one angle between the position term's minimiser and the
// handle's own, solved by a bracketed Newton solve (docs/theory.md, section 4).
#include <algorithm>
#include <cmath>
#include <limits>

#include "../closed_form.hpp"
#include "angle_solve.hpp"
#include "virtmech/se3.hpp"

namespace virtmech::detail {

bool isotropic_blocks(const Vector6& w, double& w_p, double& w_r) noexcept {
  if (!(w[0] == w[1] && w[1] == w[2] && w[3] == w[4] && w[4] == w[5])) return false;
  w_p = w[0];
  w_r = w[3];
  return w_p >= 0.0 && w_r >= 0.0 && (w_p > 0.0 || w_r > 0.0);
}

namespace {

// A sphere's position cost (rho - radius)^2 as a function of c: its derivatives P_c and
// P_cc (rho = sqrt(sa - 2 sb c): drho/dc = -sb / rho), the one-sided cost's where it acts
void sphere_cost_derivatives(const TiltCost& k, double c, double& P_c, double& P_cc) noexcept {
  const double rho = std::sqrt(std::max(k.sa - 2.0 * k.sb * c, 0.0));
  if (!(rho > 0.0)) {  // (the handle within rounding of the sphere's centre at this angle)
    P_c = P_cc = 0.0;
    return;
  }
  P_c = -2.0 * k.sb * (1.0 - k.radius / rho);
  P_cc = 2.0 * k.sb * k.sb * k.radius / (rho * rho * rho);
}

// the position cost's derivatives in phi, g'(phi) and g''(phi), from c = cos(phi), s = sin(phi)
void position_derivatives(const TiltCost& k, double c, double s, double& g1, double& g2) noexcept {
  if (k.sphere) {
    double P_c, P_cc;
    sphere_cost_derivatives(k, c, P_c, P_cc);
    if (k.one_sided && !(P_c > 0.0)) P_c = P_cc = 0.0;  // rho >= radius: lifted, no cost
    g1 = -P_c * s;
    g2 = P_cc * s * s - P_c * c;
    return;
  }
  if (k.one_sided && !(k.b * c > k.a)) {
    g1 = g2 = 0.0;
    return;
  }
  const double p2 = k.one_sided ? k.b * k.b : k.p2;
  const double p1 = k.one_sided ? -2.0 * k.a * k.b : k.p1;
  const double dc = 2.0 * p2 * c + p1;  // dg/dc
  g1 = -dc * s;
  g2 = 2.0 * p2 * s * s - dc * c;
}

// The tilt's angles below are measured from phi_r, the handle's own (the stylus's angle from
// the axis, in [0, pi]), and carry their own cosine and sine: an Angle {y, cos y, sin y} is
// phi_r + y, whose cosine and sine follow from phi_r's (`base`, {cos phi_r, sin phi_r}) by
// the angle sum. Neither angle itself is needed: the one atan2 is of their difference.
Angle absolute(const Angle& y, const Angle& base) noexcept {
  return {base.x + y.x, base.c * y.c - base.s * y.s, base.s * y.c + base.c * y.s};
}

// The angle in [0, pi] minimising the position cost, nearest phi_r among minimisers,
// measured from phi_r (base: phi_r's cosine and sine).
Angle position_minimiser(const TiltCost& k, const Angle& base) noexcept {
  constexpr Angle here{0.0, 1.0, 0.0};  // phi_r itself
  auto from_cosine_sine = [&](double c, double s) {
    // phi - phi_r in [-pi, pi] (both in [0, pi]): its cosine and sine by the angle difference
    const double cy = c * base.c + s * base.s, sy = s * base.c - c * base.s;
    return Angle{detail::atan2(sy, cy), cy, sy};
  };
  auto from_cosine = [&](double c) {
    c = std::min(1.0, std::max(-1.0, c));
    // (1 - c)(1 + c), not 1 - c^2: the sine keeps its relative accuracy near c = +-1
    return from_cosine_sine(c, std::sqrt((1.0 - c) * (1.0 + c)));
  };
  if (k.sphere) {
    if (!(k.sb > 0.0)) return here;  // the cost does not depend on the angle
    const double c0 = (k.sa - k.radius * k.radius) / (2.0 * k.sb);  // rho = radius there
    if (k.one_sided && base.c <= c0) return here;  // lifted already: zero cost
    return from_cosine(c0);
  }
  if (k.one_sided) {
    if (!(k.b * base.c > k.a)) return here;  // already at zero cost
    return k.b > 0.0 ? from_cosine(k.a / k.b) : here;
  }
  if (k.p2 > 0.0) return from_cosine(-k.p1 / (2.0 * k.p2));
  if (k.p1 < 0.0) return from_cosine_sine(1.0, 0.0);
  if (k.p1 > 0.0) return from_cosine_sine(-1.0, 0.0);
  return here;
}

// minimiser of f(phi) = w_p g(phi) + w_r (phi - phi_r)^2 between phi0 (g's minimiser) and
// phi_r, where f' runs from - to +; angles measured from phi_r (base: its cosine and sine)
Angle solve_tilt(const TiltCost& k, double w_p, double w_r, const Angle& phi0,
                 const Angle& base) noexcept {
  constexpr Angle phi_r{0.0, 1.0, 0.0};
  if (phi0.x == phi_r.x || w_p == 0.0) return phi_r;
  if (w_r == 0.0) return phi0;
  const double lo = std::min(phi0.x, phi_r.x), hi = std::max(phi0.x, phi_r.x);
  // f' has one root in the bracket, so any start inside gives the same minimiser: g is
  // p2 c^2 + p1 c (one-sided: that where b c > a, else 0) with p2 >= 0, so f'' is a concave
  // function of c = cos(phi) (0 on a one-sided cost's flat part) and, c falling with phi,
  // f'' is - then + then - along the bracket; f' falls from f'(lo) < 0 on the first part,
  // rises through one root on the second and falls to f'(hi) > 0 on the third. A sphere's
  // g'' is concave in c too: its second derivative in c is -2 radius sb^2 (4 sa^2 - sa sb c
  // + sb^2 c^2 - 15 sb^2) / rho^7, and the bracket is >= 0 for |c| <= 1 because sa >= 2 sb
  // (its least, at c = 1, is 4 sa^2 - sa sb - 14 sb^2 >= 0); a one-sided sphere's bracket
  // lies where the tip would be inside, where g is the bilateral one's.
  // Start at the minimiser of the two terms' quadratic models about their minimisers (g's
  // curvature at its minimiser, from the side where it acts): with the weights far apart, as
  // on an under-actuated device, it is so close to the root that the first step's error term
  // (bracketed_newton) ends the solve
  const Angle at0 = absolute(phi0, base);
  const double c0 = at0.c, s0 = at0.s;
  double g2_0;  // g'' at phi0, from the side where the cost acts
  if (k.sphere) {
    double P_c, P_cc;
    sphere_cost_derivatives(k, c0, P_c, P_cc);
    g2_0 = P_cc * s0 * s0 - P_c * c0;
  } else {
    const double p2 = k.one_sided ? k.b * k.b : k.p2;
    const double p1 = k.one_sided ? -2.0 * k.a * k.b : k.p1;
    g2_0 = 2.0 * p2 * s0 * s0 - (2.0 * p2 * c0 + p1) * c0;
  }
  const double c_p = w_p * std::max(0.0, g2_0);
  const double c_r = 2.0 * w_r;
  // strictly inside: at an end f' may vanish without a minimum there (the stylus exactly
  // along the axis is a saddle of the tilt)
  const double inset = 1e-12 * (hi - lo);
  const double x0 = std::min(std::max((c_p * phi0.x + c_r * phi_r.x) / (c_p + c_r), lo + inset),
                             hi - inset);
  // its cosine and sine from the nearer end's (usually within rounding of it)
  const Angle& end = std::abs(x0 - phi0.x) <= std::abs(x0 - phi_r.x) ? phi0 : phi_r;
  return bracketed_newton(
      [&](double x, double c, double s, double& f1, double& f2, double& f3) {
        double g1, g2;
        const Angle at = absolute({x, c, s}, base);
        position_derivatives(k, at.c, at.s, g1, g2);
        f1 = w_p * g1 + 2.0 * w_r * (x - phi_r.x);
        f2 = w_p * g2 + 2.0 * w_r;
        // g''' of p2 c^2 + p1 c: s (8 p2 c + p1); a one-sided cost's has a jump at its edge,
        // a sphere's is not written out
        f3 = k.sphere || k.one_sided ? std::numeric_limits<double>::quiet_NaN()
                                     : w_p * at.s * (8.0 * k.p2 * at.c + k.p1);
      },
      lo, hi, advanced(end, x0 - end.x));
}

// R_R turned about the unit axis k by the angle whose cosine and sine are c and s
// (Rodrigues' formula, column by column)
Eigen::Matrix3d rotated(const Eigen::Matrix3d& R_R, const Eigen::Vector3d& k, double c,
                        double s) noexcept {
  Eigen::Matrix3d R;
  for (int j = 0; j < 3; ++j) {
    const Eigen::Vector3d v = R_R.col(j);
    R.col(j) = c * v + s * k.cross(v) + ((1.0 - c) * k.dot(v)) * k;
  }
  return R;
}

}  // namespace

TiltSetup tilt_setup(const Eigen::Matrix3d& R_R, const Eigen::Vector3d& axis,
                     const TiltCost& cost) noexcept {
  TiltSetup t;
  const Eigen::Vector3d u_r = -R_R.col(2);
  t.k = u_r.cross(axis);
  t.kn = t.k.norm();
  t.cr = u_r.dot(axis);
  // phi0 - phi_r (see position_minimiser), from phi_r's cosine and sine alone
  const Angle phi0 = position_minimiser(cost, Angle{0.0, t.cr, t.kn});
  t.phi0_x = phi0.x;
  t.phi0_c = phi0.c;
  t.phi0_s = phi0.s;
  return t;
}

void tilt_about_axis(const TiltSetup& t, const Eigen::Matrix3d& R_R,
                     const Eigen::Vector3d& axis, const TiltCost& cost, double w_p, double w_r,
                     const LazyDirection& hint, Eigen::Matrix3d& R,
                     Eigen::Vector3d& turn) noexcept {
  const Angle base{0.0, t.cr, t.kn};  // phi_r's cosine and sine (the angle itself is not needed)
  // phi - phi_r
  const Angle phi = solve_tilt(cost, w_p, w_r, Angle{t.phi0_x, t.phi0_c, t.phi0_s}, base);
  if (phi.x == 0.0) {
    R = R_R;
    turn.setZero();
    return;
  }
  // turn u_r toward the axis by phi_r - phi, about u_r x axis
  const double c = phi.c, s = -phi.s;  // cos(phi_r - phi), sin(phi_r - phi)
  if (t.kn < 1e-12) {  // u_r along the axis: tilt toward the hint, about u_r x hint
    const Eigen::Vector3d u_r = -R_R.col(2);
    const Eigen::Vector3d v = hint();
    Eigen::Vector3d h = v - v.dot(axis) * axis;
    if (h.norm() < 1e-12) h = any_orthogonal(axis);
    const Eigen::Vector3d k_h = u_r.cross(h).normalized();
    R = rotated(R_R, k_h, c, std::abs(s));  // by |phi - phi_r|
    turn = std::abs(phi.x) * k_h;
    return;
  }
  const Eigen::Vector3d k = t.k / t.kn;
  R = rotated(R_R, k, c, s);
  turn = -phi.x * k;
}

void tilt_about_axis(const Eigen::Matrix3d& R_R, const Eigen::Vector3d& axis,
                     const TiltCost& cost, double w_p, double w_r, const LazyDirection& hint,
                     Eigen::Matrix3d& R, Eigen::Vector3d& turn) noexcept {
  tilt_about_axis(tilt_setup(R_R, axis, cost), R_R, axis, cost, w_p, w_r, hint, R, turn);
}

Eigen::Matrix3d turn_stylus(const Eigen::Matrix3d& R_R, const Eigen::Vector3d& u,
                            Eigen::Vector3d& turn) noexcept {
  const Eigen::Vector3d u_r = -R_R.col(2);
  Eigen::Vector3d k = u_r.cross(u);
  const double s = k.norm(), c = u_r.dot(u);
  if (s <= 1e-300) {
    if (c > 0.0) {
      turn.setZero();
      return R_R;
    }
    k = any_orthogonal(u_r);
  } else {
    k /= s;
  }
  turn = detail::atan2(s, c) * k;
  // the angle's cosine and sine: (c, s) / n (s and c of unit vectors, s > 1e-300 here, so
  // that the squares neither overflow nor all underflow)
  const double n = std::sqrt(s * s + c * c);
  return rotated(R_R, k, c / n, s / n);
}

}  // namespace virtmech::detail
