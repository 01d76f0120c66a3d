#include "closed_form.hpp"

#include <algorithm>
#include <cmath>

#include "virtmech/se3.hpp"

namespace virtmech::detail {

bool isotropic_blocks(const Vector6& w, double& w_p, double& w_r) noexcept {
  if (!(w[0] == w[1] && w[1] == w[2] && w[3] == w[4] && w[4] == w[5])) return false;
  w_p = w[0];
  w_r = w[3];
  return w_p >= 0.0 && w_r >= 0.0 && (w_p > 0.0 || w_r > 0.0);
}

namespace {

// the position cost's derivatives in phi: g'(phi), g''(phi)
void position_derivatives(const TiltCost& k, double phi, double& g1, double& g2) noexcept {
  const double c = std::cos(phi), s = std::sin(phi);
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

// the angle in [0, pi] minimising the position cost, nearest phi_r among minimisers
double position_minimiser(const TiltCost& k, double phi_r) noexcept {
  if (k.one_sided) {
    if (!(k.b * std::cos(phi_r) > k.a)) return phi_r;  // already at zero cost
    return k.b > 0.0 ? std::acos(std::min(1.0, std::max(-1.0, k.a / k.b))) : phi_r;
  }
  if (k.p2 > 0.0) return std::acos(std::min(1.0, std::max(-1.0, -k.p1 / (2.0 * k.p2))));
  if (k.p1 < 0.0) return 0.0;
  if (k.p1 > 0.0) return M_PI;
  return phi_r;
}

// the root of f' in [lo, hi] where f' runs from - (at lo) to + (at hi), from x: Newton
// steps kept inside the shrinking bracket, bisection where Newton would leave it.
// derivatives(x, f1, f2) gives f'(x) and f''(x).
template <typename Derivatives>
double bracketed_newton(const Derivatives& derivatives, double lo, double hi, double x) noexcept {
  // start inside: at an end f' may vanish without a minimum there (the stylus exactly along
  // the axis is a saddle of the tilt)
  const double inset = 1e-3 * (hi - lo);
  x = std::min(std::max(x, lo + inset), hi - inset);
  for (int it = 0; it < 100; ++it) {
    double f1, f2;
    derivatives(x, f1, f2);
    if (f1 < 0.0) lo = x;
    else if (f1 > 0.0) hi = x;
    else return x;
    double next = f2 > 0.0 ? x - f1 / f2 : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);  // also NaN
    if (std::abs(next - x) <= 1e-16 * (1.0 + std::abs(x)) || hi - lo <= 4e-16 * (1.0 + std::abs(hi))) {
      return next;
    }
    x = next;
  }
  return x;
}

// minimiser of f(phi) = w_p g(phi) + w_r (phi - phi_r)^2 between phi0 (g's minimiser) and
// phi_r, where f' runs from - to +
double solve_tilt(const TiltCost& k, double w_p, double w_r, double phi0, double phi_r) noexcept {
  if (phi0 == phi_r || w_p == 0.0) return phi_r;
  if (w_r == 0.0) return phi0;
  const double lo = std::min(phi0, phi_r), hi = std::max(phi0, phi_r);
  // start at the minimiser of the two terms' quadratic models about their minimisers
  // (g's curvature at its minimiser, from the side where it acts)
  const double p2 = k.one_sided ? k.b * k.b : k.p2;
  const double p1 = k.one_sided ? -2.0 * k.a * k.b : k.p1;
  const double c0 = std::cos(phi0), s0 = std::sin(phi0);
  const double c_p = w_p * std::max(0.0, 2.0 * p2 * s0 * s0 - (2.0 * p2 * c0 + p1) * c0);
  const double c_r = 2.0 * w_r;
  const double x0 = (c_p * phi0 + c_r * phi_r) / (c_p + c_r);
  return bracketed_newton(
      [&](double x, double& f1, double& f2) {
        double g1, g2;
        position_derivatives(k, x, g1, g2);
        f1 = w_p * g1 + 2.0 * w_r * (x - phi_r);
        f2 = w_p * g2 + 2.0 * w_r;
      },
      lo, hi, x0);
}

}  // namespace

void tilt_about_axis(const Eigen::Matrix3d& R_R, const Eigen::Vector3d& axis,
                     const TiltCost& cost, double w_p, double w_r, const Eigen::Vector3d& hint,
                     Eigen::Matrix3d& R) noexcept {
  const Eigen::Vector3d u_r = -R_R.col(2);
  const double phi_r = std::atan2(u_r.cross(axis).norm(), u_r.dot(axis));
  const double phi = solve_tilt(cost, w_p, w_r, position_minimiser(cost, phi_r), phi_r);
  if (phi == phi_r) {
    R = R_R;
    return;
  }
  // turn u_r toward the axis by phi_r - phi, about u_r x axis
  Eigen::Vector3d k = u_r.cross(axis);
  double kn = k.norm();
  if (kn < 1e-12) {  // u_r along the axis: tilt toward the hint, about u_r x hint
    Eigen::Vector3d h = hint - hint.dot(axis) * axis;
    if (h.norm() < 1e-12) h = any_orthogonal(axis);
    k = u_r.cross(h).normalized();
    R = Eigen::AngleAxisd(std::abs(phi - phi_r), k).toRotationMatrix() * R_R;
    return;
  }
  k /= kn;
  R = Eigen::AngleAxisd(phi_r - phi, k).toRotationMatrix() * R_R;
}

double arc_minimiser(double a, double theta_p, double b, double theta_o, double c,
                     double w_r) noexcept {
  // f(x) = -a cos(x - theta_p) + w_r acos(y)^2, y = c + b cos(x - theta_o); both terms grow
  // with the distance to their own minimiser, so f's minimum lies on the short arc between
  // theta_p and theta_o (any other point is farther from both than some point on it)
  const double span = std::remainder(theta_o - theta_p, 2.0 * M_PI);  // in [-pi, pi]
  if (!(a > 0.0) || span == 0.0) return theta_o;
  if (!(w_r > 0.0) || !(b > 0.0)) return theta_p;
  // on u in [0, |span|] from theta_p toward theta_o: f' runs from - to +
  const double dir = span > 0.0 ? 1.0 : -1.0;
  const double u = bracketed_newton(
      [&](double t, double& f1, double& f2) {
        const double x = theta_p + dir * t;
        const double sp = std::sin(x - theta_p), cp = std::cos(x - theta_p);
        const double so = std::sin(x - theta_o), co = std::cos(x - theta_o);
        const double y = std::min(1.0, std::max(-1.0, c + b * co));
        const double s1 = std::sqrt(std::max(0.0, 1.0 - y * y));  // sin of the angle
        const double ang = std::atan2(s1, y);
        // d acos(y)^2 / dy = -2 ang / s1 (-> -2 as ang -> 0), written h = ang / s1
        const double h = ang > 1e-8 ? ang / s1 : 1.0 + ang * ang / 6.0;
        const double dh = ang > 1e-4 ? (ang * y - s1) / (s1 * s1 * s1) : -1.0 / 3.0;
        const double y1 = -b * so, y2 = -b * co;
        const double dfx = a * sp - 2.0 * w_r * h * y1;
        const double ddfx = a * cp - 2.0 * w_r * (dh * y1 * y1 + h * y2);
        f1 = dir * dfx;  // d/dt = dir d/dx
        f2 = ddfx;
      },
      // start at the minimiser of the two terms' quadratic models: a u^2 / 2 and
      // w_r b (|span| - u)^2 (acos(c + b cos x)^2 ~ b x^2 near its minimum)
      0.0, std::abs(span), std::abs(span) * 2.0 * w_r * b / (a + 2.0 * w_r * b));
  return theta_p + dir * u;
}

Eigen::Vector3d euler_xyz_nearest(const Eigen::Matrix3d& M, const Eigen::Vector3d& start) noexcept {
  // M = Rx(a) Ry(b) Rz(c): M(1,2) = -sin a cos b, M(2,2) = cos a cos b give a (at the
  // gimbal lock, |cos b| < 1e-12, a is free: the start's, within 1e-12 of M); then
  // Rx(-a) M = Ry(b) Rz(c) gives b and c exactly, also close to the lock
  const double a = std::hypot(M(1, 2), M(2, 2)) > 1e-12 ? std::atan2(-M(1, 2), M(2, 2))
                                                        : start[0];
  const double ca = std::cos(a), sa = std::sin(a);
  // rows 0 and 1 of N = Rx(-a) M, and N(2, 2)
  const double n02 = M(0, 2), n10 = ca * M(1, 0) + sa * M(2, 0), n11 = ca * M(1, 1) + sa * M(2, 1);
  const double n22 = -sa * M(1, 2) + ca * M(2, 2);
  Eigen::Vector3d e1, e2;
  e1 << a, std::atan2(n02, n22), std::atan2(n10, n11);
  e2 << e1[0] + M_PI, M_PI - e1[1], e1[2] + M_PI;  // the other branch (cos b < 0)
  auto wrap_near = [](double x, double ref) {
    return x + 2.0 * M_PI * std::round((ref - x) / (2.0 * M_PI));
  };
  for (int i = 0; i < 3; ++i) {
    e1[i] = wrap_near(e1[i], start[i]);
    e2[i] = wrap_near(e2[i], start[i]);
  }
  return (e1 - start).squaredNorm() <= (e2 - start).squaredNorm() ? e1 : e2;
}

}  // namespace virtmech::detail
