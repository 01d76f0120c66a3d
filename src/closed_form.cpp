#include "closed_form.hpp"
#include "newton_stop.hpp"
#include "trig.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

#include "virtmech/se3.hpp"

namespace virtmech::detail {

bool isotropic_blocks(const Vector6& w, double& w_p, double& w_r) noexcept {
  if (!(w[0] == w[1] && w[1] == w[2] && w[3] == w[4] && w[4] == w[5])) return false;
  w_p = w[0];
  w_r = w[3];
  return w_p >= 0.0 && w_r >= 0.0 && (w_p > 0.0 || w_r > 0.0);
}

namespace {

// an angle with its cosine and sine
struct Angle {
  double x, c, s;
};

// an orthonormal basis of the sphere's tangent plane at the unit vector u (its columns)
Eigen::Matrix<double, 3, 2> tangent_basis(const Eigen::Vector3d& u) noexcept {
  Eigen::Matrix<double, 3, 2> E;
  E.col(0) = any_orthogonal(u);
  E.col(1) = u.cross(E.col(0));
  return E;
}

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

// The angle x with its cosine and sine.
[[gnu::noinline]] Angle at_angle(double x) noexcept {
  Angle a{x, 1.0, 0.0};
  detail::sincos(x, a.s, a.c);
  return a;
}

// The angle a.x + d with its cosine and sine from a's: for |d| < 1e-3 by the angle sum with
// the Taylor polynomials of cos d and sin d (their next terms, d^6 / 720 and d^7 / 5040,
// are below 1e-20: exact to rounding), which saves a sincos; else directly.
Angle advanced(const Angle& a, double d) noexcept {
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
// error); each step carries the cosine and sine on (advanced(): a sincos only for steps of
// 1e-3 or more, and after a bisection); the root is returned with its cosine and sine,
// which the callers need next.
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
void acos_squared_terms(double y, double s1, double& ang, double& h, double& dh,
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

Eigen::Vector3d TipSet::residual(const Eigen::Vector3d& q, bool& lifted) const noexcept {
  Eigen::Vector3d r = q - point;
  r -= free.dot(r) * free;
  const double lambda = one_sided.dot(r);
  lifted = lambda > 0.0;
  if (lifted) r -= lambda * one_sided;
  return r;
}

namespace {

// f(u) = w_p dist(p_R - L u, set)^2 + w_r acos(u . u_R)^2 on the unit sphere
struct StylusCost {
  const TipSet& set;
  Eigen::Vector3d p_R, u_R;
  double L, w_p, w_r;

  double value(const Eigen::Vector3d& u) const noexcept {
    bool lifted;
    const double s = u.cross(u_R).norm(), c = u.dot(u_R);
    const double ang = s == 0.0 && c > 0.0 ? 0.0 : detail::atan2(s, c);  // (atan2's own 0)
    return w_p * set.residual(p_R - L * u, lifted).squaredNorm() + w_r * ang * ang;
  }

  // the ambient gradient g and Hessian H of f at u (as a function on R^3), and f(u) (as
  // value() gives it)
  void derivatives(const Eigen::Vector3d& u, Eigen::Vector3d& g, Eigen::Matrix3d& H,
                   double& f) const noexcept {
    bool lifted;
    const Eigen::Vector3d r = set.residual(p_R - L * u, lifted);
    // dist^2 is piecewise quadratic: its Hessian is 2 (I - f f^T - [lifted] o o^T)
    Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - set.free * set.free.transpose();
    if (lifted) P -= set.one_sided * set.one_sided.transpose();
    double ang, h, dh;
    acos_squared_terms(u.dot(u_R), u.cross(u_R).norm(), ang, h, dh);
    g = -2.0 * w_p * L * r - 2.0 * w_r * h * u_R;
    H = 2.0 * w_p * L * L * P - 2.0 * w_r * dh * u_R * u_R.transpose();
    f = w_p * r.squaredNorm() + w_r * ang * ang;
  }
};

// Newton's method on the sphere from u (gradient steps where the Hessian is not positive
// definite, an Armijo backtracking line search, the exponential map as retraction)
Eigen::Vector3d sphere_newton(const StylusCost& f, Eigen::Vector3d u, double& value) noexcept {
  bool stale = true;  // value is f(u)'s unless u moved since the last derivatives
  double last = 0.0;  // the last quadratic-phase Newton step, 0 if the last was not one
  const double scale = f.w_p * f.L * f.L + f.w_r;
  for (int it = 0; it < 60; ++it) {
    Eigen::Vector3d g;
    Eigen::Matrix3d H;
    f.derivatives(u, g, H, value);
    stale = false;
    const Eigen::Matrix<double, 3, 2> E = tangent_basis(u);
    const Eigen::Vector2d g2 = E.transpose() * g;
    if (!(g2.norm() > 1e-15 * scale)) break;  // also NaN
    // the Riemannian Hessian: the tangent block of H less (u . g) I
    Eigen::Matrix2d H2 = E.transpose() * H * E;
    H2.diagonal().array() -= u.dot(g);
    // Newton's step where H2 is positive definite (its least eigenvalue above the floor:
    // H2 - floor I has a positive corner and determinant); else along the direction of
    // negative curvature (a saddle such as the stylus exactly along a symmetry axis), as far
    // as a radian and backtracked, plus Newton's step along the other eigenvector
    const double floor = 1e-12 * scale;
    const double h00 = H2(0, 0), h01 = 0.5 * (H2(0, 1) + H2(1, 0)), h11 = H2(1, 1);
    const bool newton = h00 - floor > 0.0 && (h00 - floor) * (h11 - floor) - h01 * h01 > 0.0;
    Eigen::Vector2d step;
    if (newton) {
      const double det = h00 * h11 - h01 * h01;
      step << -(h11 * g2[0] - h01 * g2[1]) / det, -(h00 * g2[1] - h01 * g2[0]) / det;
    } else {
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig;
      eig.computeDirect(H2);  // closed form for 2 x 2
      const Eigen::Vector2d lam = eig.eigenvalues();
      const Eigen::Matrix2d V = eig.eigenvectors();
      const double g1 = V.col(0).dot(g2), g2v = V.col(1).dot(g2);
      step = V.col(0) * (lam[0] < -floor ? (g1 > 0.0 ? -1.0 : 1.0) : -g1 / scale) -
             V.col(1) * (g2v / (lam[1] > floor ? lam[1] : scale));
    }
    const double n = step.norm();
    if (n > 1.0) step /= n;  // at most a radian at a time
    if (newton && n < 1e-3) {
      // close to the minimum Newton converges quadratically; a line search would stall
      // where the decrease falls below the cost's rounding (about sqrt(eps) from it). The
      // step's cosine and sine by their Taylor polynomials (next terms n^6 / 720 and
      // n^6 / 5040 relative, below 1e-20), and the cost only once it is needed
      const double n2 = n * n;
      const double cn = 1.0 - n2 * (0.5 - n2 * (1.0 / 24.0));
      const double sn_n = 1.0 - n2 * (1.0 / 6.0 - n2 * (1.0 / 120.0));  // sin(n) / n
      u = (cn * u + sn_n * (E * step)).normalized();
      stale = true;
      if (n <= 1e-15) break;
      // the next step at rounding level is not taken
      if (next_newton_step_below(n, last, 1e-15)) break;
      last = n;
      continue;
    }
    last = 0.0;
    const double slope = std::min(g2.dot(step), 0.0);  // 0 only at a saddle
    double t = 1.0;
    bool accepted = false;
    for (int k = 0; k < 50 && !accepted; ++k, t *= 0.5) {
      const double a = t * step.norm();
      const Eigen::Vector3d v = E * (t * step);
      const Eigen::Vector3d next = (std::cos(a) * u + std::sin(a) / a * v).normalized();
      const double fn = f.value(next);
      if (fn <= value + 1e-4 * t * slope && (slope < 0.0 || fn < value)) {
        u = next;
        value = fn;
        accepted = true;
      }
    }
    if (!accepted || t * step.norm() <= 1e-15) break;  // t was halved once past the step taken
  }
  if (stale) value = f.value(u);
  return u;
}

}  // namespace

namespace {

// Whether u, a descent's end of cost `value` on a tip held to a line, is f's global minimum,
// by a certificate: every minimiser has w_r angle(u, u_R)^2 <= value (the position term is
// >= 0), so lies in the cap of radius t = sqrt(value / w_r) about u_R, as u does; where t <
// pi/2 (the cap is geodesically convex) and f's Riemannian Hessian is positive definite on
// the whole cap, f has one local minimum there, which the descent found. The Hessian is at
// least the rotation term's least eigenvalue, w_r 2 t cot t at the cap's edge (2 and
// 2 theta cot theta at theta from u_R), less 2 w_p L max |r|: the position term's ambient
// Hessian 2 w_p L^2 (I - e e^T) is positive semi-definite and its gradient -2 w_p L r enters
// as -(u . gradient) (r: the tip's offset from the line, 1-Lipschitz in the tip, so |r(u)| <=
// |r(u_R)| + L |u - u_R|). With the weights of an un-powered placement on an under-actuated
// device (w_r >> w_p) it holds nearly always; a descent then replaces the multistart.
bool certified_global(const StylusCost& f, double value) noexcept {
  if (!(f.w_r > 0.0) || !(value >= 0.0)) return false;
  const double t = std::sqrt(value / f.w_r);
  if (!(t < 1.5)) return false;
  const double rotation = t > 1e-8 ? 2.0 * t / std::tan(t) : 2.0;
  bool lifted;
  const double r0 = f.set.residual(f.p_R - f.L * f.u_R, lifted).norm();
  const double position = 2.0 * f.w_p * f.L * (r0 + 2.0 * f.L * std::sin(0.5 * t));
  return f.w_r * rotation > 1.01 * position;  // (a margin for the rounding of both)
}

// Newton on the sphere from each of `count` starts: the end of lowest cost, or `fallback`
// where none is below its cost
Eigen::Vector3d lowest_descent(const StylusCost& f, const Eigen::Vector3d* starts, int count,
                               const Eigen::Vector3d& fallback) noexcept {
  Eigen::Vector3d best = fallback;
  double best_value = f.value(fallback);
  for (int i = 0; i < count; ++i) {
    double value;
    const Eigen::Vector3d u = sphere_newton(f, starts[i], value);
    if (value < best_value) {
      best_value = value;
      best = u;
    }
  }
  return best;
}

// The two caps of a tip held to a line within the stylus's reach. With x = (I - e e^T) u and
// w = p_R's offset from the line, the position term is w_p |w - L x|^2; every minimiser has
// it at most `value` (the lowest cost found), so its x lies in the disk |x - x0| <= eps, x0 =
// w / L, eps = sqrt(value / w_p) / L. Where that disk is inside the unit disk (|x0| + eps <
// 1), it lifts to two caps of the sphere, u = x + s z(x) e, z = sqrt(1 - |x|^2), s = +-1, each
// a graph over the disk: in that chart (x the coordinates) the position term is exactly
// quadratic, its Hessian 2 w_p L^2 I, and the rotation term phi(c) = acos(c)^2 of c = u . u_R
// = x . a + s z b (u_R = a + b e) has the Hessian phi'' grad c grad c^T + phi' Hess c: the
// first positive semi-definite (phi is convex), the second phi' (-s b)(I / z + x x^T / z^3)
// with phi' = -2 theta / sin(theta), positive semi-definite where s b >= 0 and otherwise at
// least -2 (theta / sin theta) |b| / z_min^3 (z >= z_min = sqrt(1 - (|x0| + eps)^2)). With
// theta / sin(theta) <= pi / sin(psi), psi = min(2 asin(delta / 2), pi / 2) and delta = |x0 +
// a| - eps the least chord from -u_R (the projection is 1-Lipschitz), f is strictly convex
// on a cap whose bound holds: the cap (a convex disk in the chart) holds at most one local
// minimum. Where both caps are convex the global minimum is the lower of their minima.
//
// Where the line is beyond the reach (|x0| > 1, so x0 . w_hat >= |x0| - eps on the disk),
// every minimiser lies within the chord rho = sqrt(2 (1 - |x0| + eps)) of w_hat = w / |w|
// (|u - w_hat|^2 = 2 (1 - x . w_hat)): one cap. There the position term's Riemannian Hessian
// is at least 2 w_p L (u . r) (its ambient Hessian is positive semi-definite; its gradient
// -2 w_p L r, r = w - L x, enters as -(u . gradient)) and u . r = u . w - L |x|^2 >= |w| (1 -
// rho^2 / 2) - L; the rotation term's is at least w_r min(2, 2 theta cot theta) at the cap's
// farthest angle theta from u_R. Where their sum is positive on a geodesically convex cap,
// it holds one local minimum.

// the one cap about w_hat of a line beyond the stylus's reach (above)
LineCaps beyond_reach_cap(const StylusCost& f, const Eigen::Vector3d& w, LineCaps caps) noexcept {
  const double r0 = caps.x0.norm();
  if (!(r0 > 1.0)) return caps;
  caps.rho = std::sqrt(2.0 * std::max(0.0, 1.0 - r0 + caps.eps));
  caps.chord = caps.rho;
  caps.centre[0] = w / w.norm();
  // the cap's geodesic radius 2 asin(rho / 2) below pi / 4: rho below 2 sin(pi / 8)
  if (!(caps.rho < 0.7653668647301796)) return caps;
  const double position =
      2.0 * f.w_p * f.L * f.L * (r0 * (1.0 - 0.5 * caps.rho * caps.rho) - 1.0);
  double rotation = 0.0;  // its least eigenvalue is >= 0 where the cap is within pi / 2 of u_R:
  // cos angle(centre, u_R) >= sin(radius) = rho sqrt(1 - rho^2 / 4)
  if (!(caps.centre[0].dot(f.u_R) >= caps.rho * std::sqrt(1.0 - 0.25 * caps.rho * caps.rho))) {
    const double theta = detail::atan2(caps.centre[0].cross(f.u_R).norm(),
                                    caps.centre[0].dot(f.u_R)) +
                         2.0 * std::asin(0.5 * caps.rho);
    if (!(theta < M_PI - 1e-3)) return caps;
    rotation = f.w_r * std::min(2.0, 2.0 * theta / std::tan(theta));
  }
  if (!(position + rotation > 0.01 * std::abs(position))) return caps;  // (a margin)
  caps.count = 1;
  return caps;
}

LineCaps line_caps(const StylusCost& f, const Eigen::Vector3d& w, double value) noexcept {
  LineCaps caps;
  if (!(f.w_p > 0.0) || !(value >= 0.0)) return caps;
  const Eigen::Vector3d& e = f.set.free;
  caps.x0 = w / f.L;
  caps.eps = std::sqrt(value / f.w_p) / f.L;
  const double r0 = caps.x0.norm(), reach = r0 + caps.eps;
  if (!(reach < 1.0)) return beyond_reach_cap(f, w, caps);
  const double z_min = std::sqrt((1.0 - reach) * (1.0 + reach));
  const double z0 = std::sqrt((1.0 - r0) * (1.0 + r0));
  // u - centre = (x - x0) + s (z(x) - z0) e, z Lipschitz with constant (|x0| + eps) / z_min
  // on the disk: |u - centre| <= eps sqrt(1 + (|x0| + eps)^2 / z_min^2) = eps / z_min
  caps.chord = caps.eps / z_min;
  const double b = f.u_R.dot(e);
  const double position = 2.0 * f.w_p * f.L * f.L;
  for (int i = 0; i < 2; ++i) {
    const double s = i == 0 ? 1.0 : -1.0;
    caps.centre[i] = caps.x0 + s * z0 * e;
    if (s * b >= 0.0) continue;  // the rotation term convex in the chart
    const double delta = (caps.x0 + f.u_R - b * e).norm() - caps.eps;
    if (!(delta > 0.0)) return caps;  // -u_R may lie on the cap
    // sin(psi) = sin(2 asin(delta / 2)) = delta sqrt(1 - delta^2 / 4) below delta = sqrt(2)
    const double sin_psi = delta < M_SQRT2 ? delta * std::sqrt(1.0 - 0.25 * delta * delta) : 1.0;
    const double rotation =
        2.0 * f.w_r * (M_PI / sin_psi) * std::abs(b) / (z_min * z_min * z_min);
    if (!(rotation < 0.99 * position)) return caps;  // (a margin for rounding)
  }
  caps.count = 2;
  return caps;
}

// Newton on the sphere for a tip held to a line (f.set.free), from u_start (the last
// placement's: its end is usually the answer, and certified_global() may show it), u_R,
// u_extra, the stylus normal to the line and the directions that put the tip on it; the
// best end
Eigen::Vector3d multistart(const StylusCost& f, const Eigen::Vector3d& u_start,
                           const Eigen::Vector3d& u_extra) noexcept {
  Eigen::Vector3d starts[6];
  int count = 0;
  auto add = [&](const Eigen::Vector3d& v) {
    const double n = v.norm();
    if (!(n > 0.0) || !std::isfinite(n)) return;
    const Eigen::Vector3d s = v / n;
    if (s.dot(f.u_R) < -1.0 + 1e-12) return;  // the rotation term's gradient is undefined there
    for (int i = 0; i < count; ++i) {
      if ((starts[i] - s).norm() < 1e-9) return;
    }
    starts[count++] = s;
  };
  add(u_start);
  add(f.u_R);
  add(u_extra);
  bool lifted;
  const Eigen::Vector3d w = f.set.residual(f.p_R, lifted);  // p_R - c0, c0 its nearest point
  add(w);
  // the sphere of radius L about the handle cut by the line: c0 + tau e, |w - tau e| = L
  const Eigen::Vector3d& e = f.set.free;
  const double we = w.dot(e), disc = we * we - w.squaredNorm() + f.L * f.L;
  if (disc >= 0.0) {
    add(w - (we - std::sqrt(disc)) * e);
    add(w - (we + std::sqrt(disc)) * e);
  }
  // the first start's end, and where a certificate shows the global minimum among the
  // ends met so far, no further starts
  Eigen::Vector3d best = f.u_R;
  double best_value = f.value(f.u_R);
  Eigen::Vector3d ends[8];
  int n_ends = 0;
  auto descend = [&](const Eigen::Vector3d& s) {
    double value;
    ends[n_ends++] = sphere_newton(f, s, value);
    if (value < best_value) {
      best_value = value;
      best = ends[n_ends - 1];
    }
    return value;
  };
  if (count == 0) return best;
  if (certified_global(f, descend(starts[0]))) return best;
  const LineCaps caps = line_caps(f, w, best_value);
  if (caps.count > 0) {
    bool found = true;
    for (int c = 0; c < caps.count && found; ++c) {
      bool in_cap = false;
      for (int i = 0; i < n_ends && !in_cap; ++i) in_cap = cap_holds(caps, c, ends[i], e);
      if (in_cap) continue;
      // no direction of the cap below the lowest cost found: f >= w_r angle(u, u_R)^2 >=
      // w_r |u - u_R|^2 (a chord is at most its angle), |u - u_R| >= |centre - u_R| - chord
      const double gap = std::max(0.0, (caps.centre[c] - f.u_R).norm() - caps.chord);
      if (f.w_r * gap * gap > best_value * (1.0 + 1e-12)) continue;
      descend(caps.centre[c]);  // the cap's one local minimum, if the descent stays on it
      found = cap_holds(caps, c, ends[n_ends - 1], e);
    }
    if (found) return best;
  }
  for (int i = 1; i < count; ++i) descend(starts[i]);
  return best;
}

}  // namespace

namespace {

// the stylus's direction u for a tip held to a plane through `point` with normal n, the
// tip in the plane (one angle: the Probe's), or to `point` itself (n = 0: one angle about
// the handle's direction from the point)
Eigen::Vector3d tilt_to_plane_or_point(const Eigen::Vector3d& point, const Eigen::Vector3d& n,
                                       const Eigen::Vector3d& p_R, double length,
                                       const Eigen::Matrix3d& R_R, const Eigen::Vector3d& hint,
                                       double w_p, double w_r) noexcept {
  TiltCost cost;
  Eigen::Vector3d axis = n;
  if (n.isZero(0.0)) {
    // |v - L u|^2 = r^2 + L^2 - 2 L r cos(angle(u, v)), v = p_R - point
    const Eigen::Vector3d v = p_R - point;
    const double r = v.norm();
    if (!(r > 1e-12 * length)) return -R_R.col(2);  // any direction: the handle's own
    axis = v / r;
    cost.p1 = -2.0 * length * r;
  } else {
    // tip height d - L cos(phi), phi the stylus's angle from n
    const double d = n.dot(p_R - point);
    cost.p2 = length * length;
    cost.p1 = -2.0 * d * length;
  }
  Eigen::Matrix3d R;
  Eigen::Vector3d turn;
  tilt_about_axis(R_R, axis, cost, w_p, w_r, LazyDirection([&] { return hint; }), R, turn);
  return -R.col(2);
}

}  // namespace

bool handle_cap_certified(const TipSet& line, const Eigen::Vector3d& p_R,
                          const Eigen::Vector3d& u_R, double length, double w_p, double w_r,
                          double value) noexcept {
  return certified_global(StylusCost{line, p_R, u_R, length, w_p, w_r}, value);
}

LineCaps line_caps(const TipSet& line, const Eigen::Vector3d& p_R, const Eigen::Vector3d& u_R,
                   double length, double w_p, double w_r, double value) noexcept {
  bool lifted;
  return line_caps(StylusCost{line, p_R, u_R, length, w_p, w_r}, line.residual(p_R, lifted),
                   value);
}

Eigen::Vector3d stylus_direction(const TipSet& set, const Eigen::Vector3d& p_R, double length,
                                 const Eigen::Matrix3d& R_R, const Eigen::Vector3d& u_start,
                                 double w_p, double w_r) noexcept {
  const Eigen::Vector3d u_R = -R_R.col(2);
  if (w_p == 0.0) return u_R;
  const bool has_free = !set.free.isZero(0.0), one_sided = !set.one_sided.isZero(0.0);
  if (!has_free && !one_sided) {  // a point: one angle
    return tilt_to_plane_or_point(set.point, Eigen::Vector3d::Zero(), p_R, length, R_R, u_start,
                                  w_p, w_r);
  }
  const StylusCost f{set, p_R, u_R, length, w_p, w_r};
  if (!one_sided) return multistart(f, u_start, u_R);  // a line
  // One-sided (a half-line or a half-plane). The relaxed problem, the one-sided direction
  // made free (a line; a plane: one angle), has a cost nowhere above this one's (a superset
  // is nearer), so where its optimum has the tip on the allowed side (the costs agree
  // there) that optimum is this problem's too. That covers most lifted tips, where a
  // half-plane's cost has a flat valley Newton would crawl along. Otherwise Newton on this
  // cost from: the relaxed optimum, the optimum with the tip held to the edge (the point;
  // the line), and for a half-line the directions that put the tip on it (the relaxed
  // line's other local minimum may lie on the allowed side; a plane's valley has one).
  const Eigen::Vector3d& o = set.one_sided;
  Eigen::Vector3d starts[4];
  int count = 0;
  TipSet edge = set;
  edge.one_sided.setZero();
  if (has_free) {
    starts[count++] = tilt_to_plane_or_point(set.point, set.free.cross(o), p_R, length, R_R,
                                             u_start, w_p, w_r);
    if (o.dot(p_R - length * starts[0] - set.point) >= 0.0) return starts[0];
    starts[count++] =
        multistart(StylusCost{edge, p_R, u_R, length, w_p, w_r}, u_start, starts[0]);
  } else {
    TipSet relaxed = set;
    relaxed.free = o;
    relaxed.one_sided.setZero();
    starts[count++] = multistart(StylusCost{relaxed, p_R, u_R, length, w_p, w_r}, u_start, u_R);
    if (o.dot(p_R - length * starts[0] - set.point) >= 0.0) return starts[0];
    starts[count++] = tilt_to_plane_or_point(set.point, Eigen::Vector3d::Zero(), p_R, length,
                                             R_R, u_start, w_p, w_r);
    const Eigen::Vector3d v = p_R - set.point;
    const double lambda0 = o.dot(v), disc = length * length - (v - lambda0 * o).squaredNorm();
    for (double sign : {-1.0, 1.0}) {
      const double tau = sign * std::sqrt(std::max(disc, 0.0));  // tip at lambda0 + tau
      if (disc >= 0.0 && lambda0 + tau >= 0.0) starts[count++] = (v - (lambda0 + tau) * o) / length;
    }
  }
  return lowest_descent(f, starts, count, starts[0]);
}

namespace {

// Newton's method for a probe's stylus whose tip is held to a shape of N parameters (a
// curve, N = 1, or a surface, N = 2): x the parameters in [lo, hi], u the tip-to-handle
// direction on S^2, minimising w_p |P(x) + L u - p_R|^2 + w_r angle(u, u_R)^2.
// `shape(x, order, P, D1, D2)`: the point, its first derivatives (columns) and, for order
// 2, its second (column i * N + j the derivative in x_i and x_j).
template <int N, typename Shape>
bool stylus_newton(const Shape& shape, const Eigen::Matrix<double, N, 1>& lo,
                   const Eigen::Matrix<double, N, 1>& hi, const Eigen::Vector3d& p_R,
                   const Eigen::Vector3d& u_R, double length, double w_p, double w_r,
                   Eigen::Matrix<double, N, 1>& x, Eigen::Vector3d& u) noexcept {
  constexpr int M = N + 2;
  using VecN = Eigen::Matrix<double, N, 1>;
  using VecM = Eigen::Matrix<double, M, 1>;
  using MatM = Eigen::Matrix<double, M, M>;
  using D1 = Eigen::Matrix<double, 3, N>;
  using D2 = Eigen::Matrix<double, 3, N * N>;
  const double L = length;
  const auto inside = [&](const VecN& y) {
    return (y.array() >= lo.array()).all() && (y.array() <= hi.array()).all();
  };
  if (!inside(x) || !(w_p > 0.0)) return false;
  u.normalize();
  double last = 0.0;  // the last full Newton step (scaled), 0 if the last was not one
  // after a full Newton step: the cost before it and the position error its linear model
  // predicted (for the second-order correction below); after a correction, the point it
  // corrected and its cost
  double f_before = std::numeric_limits<double>::infinity();
  Eigen::Vector3d r_model = Eigen::Vector3d::Zero();
  int corrections = 0;
  // the position term stiff against the turn's (the rotation weighing at most a hundredth
  // at the stylus's length): where the valley below is narrow; on a curve (N = 1) there is
  // none (see below)
  const bool stiff = N == 2 && w_r <= 1e-2 * w_p * L * L;
  bool corrected = false;
  VecN x_uncorrected = x;
  Eigen::Vector3d u_uncorrected = u;
  double f_uncorrected = 0.0;
  const auto cost = [&](const VecN& y, const Eigen::Vector3d& u_) {
    Eigen::Vector3d P;
    D1 d1;
    D2 d2;
    shape(y, 0, P, d1, d2);
    const Eigen::Vector3d r = P + L * u_ - p_R;
    const double ang = detail::atan2(u_.cross(u_R).norm(), u_.dot(u_R));
    return w_p * r.squaredNorm() + w_r * ang * ang;
  };
  for (int it = 0; it < 12; ++it) {
    Eigen::Vector3d P;
    D1 d1;
    D2 d2;
    shape(x, 2, P, d1, d2);
    const Eigen::Vector3d r = P + L * u - p_R;  // the handle's position error
    double ang, h, dh;
    acos_squared_terms(u.dot(u_R), u.cross(u_R).norm(), ang, h, dh);
    const double f_here = w_p * r.squaredNorm() + w_r * ang * ang;
    if (corrected) {  // the correction kept only where it lowered the cost
      corrected = false;
      if (f_here > f_uncorrected) {
        x = x_uncorrected;
        u = u_uncorrected;
        --it;
        continue;
      }
    }
    // A full Newton step that raised the cost, or whose position error is off its linear
    // model by more than 1e-3 of it, has left the valley of the position term, the stiff
    // one: on a surface with w_r << w_p L^2 (a nearest placement, the rotation
    // weighted 1e-6) and the handle pressed in, the tip may sit anywhere on the circle where
    // the stylus reaches the surface, a narrow, curved valley, where the quadratic model's
    // error along a long step (w_p times the surface's and the sphere's curvature)
    // outweighs the angle term's gain: the Maratos effect. The second-order correction
    // brings the position error back to what the step's linear model predicted, by the
    // least change of the parameters and the stylus: (dx, du) = -A^T (A A^T)^-1 (r -
    // r_model), A = [d1, L E]; it is kept where it lowers the cost (at most 12 of them,
    // each costing one or two evaluations more), and the convergence test then starts
    // afresh. On a curve (N = 1) A is square: the position term's minimum is a point,
    // there is no valley, and no correction is made; nor where the turn's weight is not
    // small (`stiff`), where the corrections were kept on half the tries or fewer.
    const Eigen::Matrix<double, 3, 2> E = tangent_basis(u);  // (u's, for both uses below)
    const double off_model = (r - r_model).norm();
    if (stiff && f_before < std::numeric_limits<double>::infinity() && corrections < 12 &&
        (f_here > f_before || (off_model > 1e-3 * r.norm() && off_model > 1e-12 * L))) {
      ++corrections;
      Eigen::Matrix<double, 3, M> A;
      A.template leftCols<N>() = d1;
      A.template rightCols<2>() = L * E;
      const Eigen::Matrix3d AAt = A * A.transpose();
      const Eigen::LLT<Eigen::Matrix3d> llt(AAt);
      if (llt.info() == Eigen::Success) {
        const VecM c = -A.transpose() * llt.solve(Eigen::Vector3d(r - r_model));
        const VecN x_c = x + c.template head<N>();
        if (c.allFinite() && inside(x_c)) {
          x_uncorrected = x;
          u_uncorrected = u;
          f_uncorrected = f_here;
          corrected = true;
          last = 0.0;  // the next full step is not the one before's successor
          x = x_c;
          const Eigen::Vector3d w = E * c.template tail<2>();
          u = (u + w).normalized();
          f_before = std::numeric_limits<double>::infinity();
          --it;
          continue;
        }
      }
    }
    f_before = std::numeric_limits<double>::infinity();
    // the gradient and Hessian in u as a function on R^3, then on the sphere
    const Eigen::Vector3d g_u = 2.0 * w_p * L * r - 2.0 * w_r * h * u_R;
    VecM g;
    g.template head<N>() = 2.0 * w_p * (d1.transpose() * r);
    g.template tail<2>() = E.transpose() * g_u;
    MatM H;
    for (int i = 0; i < N; ++i)
      for (int j = 0; j < N; ++j)
        H(i, j) = 2.0 * w_p * (d1.col(i).dot(d1.col(j)) + d2.col(i * N + j).dot(r));
    const Eigen::Matrix<double, 2, N> H_ux = 2.0 * w_p * L * (E.transpose() * d1);
    H.template bottomLeftCorner<2, N>() = H_ux;
    H.template topRightCorner<N, 2>() = H_ux.transpose();
    const Eigen::Vector2d Ru = E.transpose() * u_R;
    Eigen::Matrix2d H_uu = (2.0 * w_p * L * L - u.dot(g_u)) * Eigen::Matrix2d::Identity();
    H_uu -= 2.0 * w_r * dh * Ru * Ru.transpose();
    H.template bottomRightCorner<2, 2>() = H_uu;
    // Newton's step where H is positive definite; else the saddle-free step (each
    // eigendirection's Newton step with |lambda|: descending along negative curvature, as
    // where the stylus stands square to the shape and the position cost is flat to second
    // order along it), with a backtracking line search on the cost
    VecM step;
    const Eigen::LLT<MatM> llt(H);
    const bool newton = llt.info() == Eigen::Success;
    if (newton) {
      step = -llt.solve(g);
    } else {
      Eigen::SelfAdjointEigenSolver<MatM> eig;
      if constexpr (M == 3) {
        eig.computeDirect(H);
      } else {
        eig.compute(H);
      }
      const VecM lam = eig.eigenvalues().cwiseAbs();
      const double floor = 1e-9 * std::max(lam.maxCoeff(), w_p * L * L);
      const VecM gv = eig.eigenvectors().transpose() * g;
      step = -eig.eigenvectors() * gv.cwiseQuotient(lam.cwiseMax(floor));
    }
    if (!step.allFinite()) return false;
    // at most a tenth of the stylus of tip motion and 0.2 rad of turn at a time
    const double tip_move = (d1 * step.template head<N>()).norm();
    double scale = 1.0;
    if (tip_move > 0.1 * L) scale = 0.1 * L / tip_move;
    if (step.template tail<2>().norm() * scale > 0.2) scale = 0.2 / step.template tail<2>().norm();
    step *= scale;
    const auto moved_to = [&](double t, VecN& x_t, Eigen::Vector3d& u_t) {
      x_t = x + t * step.template head<N>();
      const double n = t * step.template tail<2>().norm();
      // cos n and sin(n) / n; below 1e-3 by their Taylor polynomials (next terms n^6 / 720
      // and n^6 / 5040 relative, below 1e-20), as on the sphere
      const double n2 = n * n;
      double cn = 1.0 - n2 * (0.5 - n2 * (1.0 / 24.0));
      double sn_n = 1.0 - n2 * (1.0 / 6.0 - n2 * (1.0 / 120.0));
      if (!(n < 1e-3)) {
        detail::sincos(n, sn_n, cn);
        sn_n /= n;
      }
      u_t = n > 0.0
                ? Eigen::Vector3d((cn * u + sn_n * t * (E * step.template tail<2>())).normalized())
                : u;
    };
    VecN x_new;
    Eigen::Vector3d u_new;
    if (newton && scale == 1.0) {
      moved_to(1.0, x_new, u_new);
      f_before = w_p * r.squaredNorm() + w_r * ang * ang;
      r_model = r + d1 * step.template head<N>() + L * (E * step.template tail<2>());
    } else {
      const double f0 = w_p * r.squaredNorm() + w_r * ang * ang;
      const double slope = g.dot(step);  // < 0: a descent direction
      double t = 1.0;
      bool accepted = false;
      for (int k = 0; k < 30 && !accepted; ++k, t *= 0.5) {
        moved_to(t, x_new, u_new);
        accepted = inside(x_new) && cost(x_new, u_new) <= f0 + 1e-4 * t * slope;
      }
      if (!accepted) return false;
    }
    if (!inside(x_new)) return false;  // at a stop: Gauss-Newton's active set
    const double moved = (d1 * (x_new - x)).norm(), n = (u_new - u).norm();
    x = x_new;
    u = u_new;
    // converged: a full Newton step that moved the tip and the stylus by rounding noise (the
    // next would be its square); or, after two full Newton steps, one whose successor would
    const bool full = newton && scale == 1.0;
    const double a = std::max(moved / L, n);
    if (full && a <= 1e-12) return true;
    if (full && next_newton_step_below(a, last, 1e-12)) return true;
    last = full ? a : 0.0;
  }
  return false;
}

}  // namespace

bool curve_stylus_newton(const Curve& curve, const Eigen::Vector3d& p_R,
                         const Eigen::Vector3d& u_R, double length, double w_p, double w_r,
                         double& s, Eigen::Vector3d& u) noexcept {
  using V1 = Eigen::Matrix<double, 1, 1>;
  const auto shape = [&](const V1& x, int order, Eigen::Vector3d& P,
                         Eigen::Matrix<double, 3, 1>& d1, Eigen::Matrix<double, 3, 1>& d2) {
    CurveDerivatives d;
    curve.derivatives(x[0], order, d);
    P = d.col(0);
    if (order >= 1) d1 = d.col(1);
    if (order >= 2) d2 = d.col(2);
  };
  V1 x = V1::Constant(s);
  const bool ok = stylus_newton<1>(shape, V1::Constant(curve.lower()),
                                   V1::Constant(curve.upper()), p_R, u_R, length, w_p, w_r, x, u);
  s = x[0];
  return ok;
}

bool surface_stylus_newton(const Surface& surface, const Eigen::Vector3d& p_R,
                           const Eigen::Vector3d& u_R, double length, double w_p, double w_r,
                           const Eigen::Vector2d& lo, const Eigen::Vector2d& hi,
                           Eigen::Vector2d& uv, Eigen::Vector3d& u) noexcept {
  const auto shape = [&](const Eigen::Vector2d& x, int order, Eigen::Vector3d& P,
                         Eigen::Matrix<double, 3, 2>& d1, Eigen::Matrix<double, 3, 4>& d2) {
    SurfaceDerivatives d;
    surface.derivatives(x[0], x[1], order, d);
    P = d(0, 0);
    if (order >= 1) d1 << d(1, 0), d(0, 1);
    if (order >= 2) d2 << d(2, 0), d(1, 1), d(1, 1), d(0, 2);
  };
  return stylus_newton<2>(shape, lo, hi, p_R, u_R, length, w_p, w_r, uv, u);
}

namespace {

// the direction of q, atan2(q.y, q.x), with its cosine and sine
double direction(const Eigen::Vector2d& q, double& cos_x, double& sin_x) noexcept {
  const double x = detail::atan2(q.y(), q.x());
  const double n = q.norm();
  if (n > 0.0 && std::isfinite(n)) {
    cos_x = q.x() / n;
    sin_x = q.y() / n;
  } else {  // (+-0, +-0): atan2's signed zeros decide
    detail::sincos(x, sin_x, cos_x);
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
  // dir t and x - theta_o = dir (t - |span|), one sincos of t per step gives both terms
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

Eigen::Vector3d euler_xyz_nearest(const Eigen::Matrix3d& M, const Eigen::Vector3d& start,
                                  double& cos_a, double& sin_a) noexcept {
  // M = Rx(a) Ry(b) Rz(c): M(1,2) = -sin a cos b, M(2,2) = cos a cos b give a, and its
  // cosine and sine without a round trip through the angle (at the gimbal lock, |cos b| <
  // 1e-12, a is free: the start's, within 1e-12 of M); then Rx(-a) M = Ry(b) Rz(c) gives b
  // and c exactly, also close to the lock
  const double cb = std::sqrt(M(1, 2) * M(1, 2) + M(2, 2) * M(2, 2));  // |cos b|
  const bool lock = !(cb > 1e-12);
  const double a = lock ? start[0] : detail::atan2(-M(1, 2), M(2, 2));
  double ca = M(2, 2) / cb, sa = -M(1, 2) / cb;
  if (lock) detail::sincos(a, sa, ca);
  // rows 0 and 1 of N = Rx(-a) M, and N(2, 2) (= |cos b| off the lock)
  const double n02 = M(0, 2), n10 = ca * M(1, 0) + sa * M(2, 0), n11 = ca * M(1, 1) + sa * M(2, 1);
  const double n22 = lock ? -sa * M(1, 2) + ca * M(2, 2) : cb;
  Eigen::Vector3d e1, e2;
  e1 << a, detail::atan2(n02, n22), detail::atan2(n10, n11);
  e2 << e1[0] + M_PI, M_PI - e1[1], e1[2] + M_PI;  // the other branch (cos b < 0)
  auto wrap_near = [](double x, double ref) {
    return x + 2.0 * M_PI * round_half_away((ref - x) / (2.0 * M_PI));
  };
  for (int i = 0; i < 3; ++i) {
    e1[i] = wrap_near(e1[i], start[i]);
    e2[i] = wrap_near(e2[i], start[i]);
  }
  // the other branch's a is a + pi (whole turns added by wrap_near leave cos and sin be)
  const bool first = (e1 - start).squaredNorm() <= (e2 - start).squaredNorm();
  cos_a = first ? ca : -ca;
  sin_a = first ? sa : -sa;
  return first ? e1 : e2;
}

}  // namespace virtmech::detail
