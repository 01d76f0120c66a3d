// A stylus's direction for a tip held to a point, a line, a half-line or a half-plane
// (closed_form.hpp: stylus_direction): Newton's method on the sphere from several starts,
// ended early by the certificates of a global minimum (docs/theory.md, section 4).
#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "../closed_form.hpp"
#include "angle_solve.hpp"
#include "virtmech/se3.hpp"

namespace virtmech::detail {

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

// The step on the sphere's tangent plane from the gradient g2 and the Riemannian Hessian
// H2 there (`scale` the cost's): Newton's step where H2 is positive definite (its least
// eigenvalue above the floor: H2 - floor I has a positive corner and determinant;
// `newton`); else along the direction of negative curvature (a saddle such as the stylus
// exactly along a symmetry axis), as far as a radian and backtracked, plus Newton's step
// along the other eigenvector
Eigen::Vector2d tangent_step(const Eigen::Vector2d& g2, const Eigen::Matrix2d& H2, double scale,
                             bool& newton) noexcept {
  const double floor = 1e-12 * scale;
  const double h00 = H2(0, 0), h01 = 0.5 * (H2(0, 1) + H2(1, 0)), h11 = H2(1, 1);
  newton = h00 - floor > 0.0 && (h00 - floor) * (h11 - floor) - h01 * h01 > 0.0;
  Eigen::Vector2d step;
  if (newton) {
    const double det = h00 * h11 - h01 * h01;
    step << -(h11 * g2[0] - h01 * g2[1]) / det, -(h00 * g2[1] - h01 * g2[0]) / det;
    return step;
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig;
  eig.computeDirect(H2);  // closed form for 2 x 2
  const Eigen::Vector2d lam = eig.eigenvalues();
  const Eigen::Matrix2d V = eig.eigenvectors();
  const double g1 = V.col(0).dot(g2), g2v = V.col(1).dot(g2);
  step = V.col(0) * (lam[0] < -floor ? (g1 > 0.0 ? -1.0 : 1.0) : -g1 / scale) -
         V.col(1) * (g2v / (lam[1] > floor ? lam[1] : scale));
  return step;
}

// Backtracking (Armijo) on the cost from u (of cost `value`) along the tangent step
// (basis E; g2 the gradient there), the exponential map as retraction: u and value moved
// to the step accepted; t ends halved once past it. False where none is.
bool sphere_line_search(const StylusCost& f, const Eigen::Matrix<double, 3, 2>& E,
                        const Eigen::Vector2d& g2, const Eigen::Vector2d& step,
                        Eigen::Vector3d& u, double& value, double& t) noexcept {
  const double slope = std::min(g2.dot(step), 0.0);  // 0 only at a saddle
  t = 1.0;
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
  return accepted;
}

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
    bool newton;
    Eigen::Vector2d step = tangent_step(g2, H2, scale, newton);
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
    double t;
    if (!sphere_line_search(f, E, g2, step, u, value, t) || t * step.norm() <= 1e-15) break;
  }
  if (stale) value = f.value(u);
  return u;
}

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

// The best of the descents' ends so far. A tie (two distinct minima, more than 1e-3 apart,
// within 1e-10 of each other's cost, as the mirror minima of a handle square to the line)
// goes to the one nearer the start: the placement stays on its side instead of alternating
// between the two on rounding from one cycle to the next. Ends of one minimum (closer) go
// by their cost, as others.
struct BestEnd {
  Eigen::Vector3d u;
  double value = 0.0;
  void offer(const Eigen::Vector3d& end, double end_value, const Eigen::Vector3d& start) noexcept {
    const bool tie = (end - u).norm() > 1e-3 &&
                     std::abs(end_value - value) <= 1e-10 * std::abs(value);
    if (tie ? (end - start).norm() < (u - start).norm() : end_value < value) {
      value = std::min(end_value, value);
      u = end;
    }
  }
};

// Newton on the sphere for a tip held to a line (f.set.free), from u_start (the last
// placement's: its end is usually the answer, and certified_global() may show it), u_R,
// u_extra, the stylus normal to the line and the directions that put the tip on it; the
// best end
Eigen::Vector3d multistart(const StylusCost& f, const Eigen::Vector3d& u_start,
                           const Eigen::Vector3d& u_extra) noexcept {
  BestEnd best_end;
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
  Eigen::Vector3d& best = best_end.u;
  double& best_value = best_end.value;
  best = f.u_R;
  best_value = f.value(f.u_R);
  Eigen::Vector3d ends[8];
  int n_ends = 0;
  auto descend = [&](const Eigen::Vector3d& s) {
    double value;
    ends[n_ends] = sphere_newton(f, s, value);
    best_end.offer(ends[n_ends++], value, u_start);
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

}  // namespace virtmech::detail
