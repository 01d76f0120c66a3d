// Sphere (include/virtmech/geometry.hpp): longitude u and latitude v about its axis.
#include <cmath>

#include "../trig.hpp"
#include "shape_support.hpp"
#include "virtmech/geometry.hpp"

namespace virtmech {

using detail::clamp;
using detail::clamp_order;
using detail::dcos;
using detail::dsin;
using detail::kPi;
using detail::safe_normalized;

Sphere::Sphere(const Eigen::Vector3d& center, double radius, const Eigen::Vector3d& axis)
    : c_(center), r_(radius) {
  require_finite("center", Eigen::VectorXd(center));
  require_positive("radius", radius);
  const Eigen::Vector3d a = safe_normalized(axis, "axis");
  Eigen::Vector3d e1 = Eigen::Vector3d::UnitX() - a.x() * a;
  if (e1.norm() < 1e-6) e1 = Eigen::Vector3d::UnitY() - a.y() * a;
  e1.normalize();
  A_ << e1, a.cross(e1), a;
}

Eigen::Vector2d Sphere::lower() const noexcept { return {-kPi, -0.5 * kPi}; }
Eigen::Vector2d Sphere::upper() const noexcept { return {kPi, 0.5 * kPi}; }

Eigen::Vector3d Sphere::evaluate(double u, double v) const noexcept {
  v = clamp(v, -0.5 * kPi, 0.5 * kPi);
  const double su = std::sin(u), cu = std::cos(u), sv = std::sin(v), cv = std::cos(v);
  return c_ + r_ * (A_ * Eigen::Vector3d(cu * cv, su * cv, sv));
}

void Sphere::derivatives(double u, double v, int order, SurfaceDerivatives& d) const noexcept {
  const int nd = clamp_order(order);
  v = clamp(v, -0.5 * kPi, 0.5 * kPi);
  for (int k = 0; k <= nd; ++k) {
    for (int l = 0; l <= nd; ++l) {
      const Eigen::Vector3d e(dcos(u, k) * dcos(v, l), dsin(u, k) * dcos(v, l),
                              k == 0 ? dsin(v, l) : 0.0);
      d(k, l) = r_ * (A_ * e);
    }
  }
  d(0, 0) += c_;
}

Eigen::Vector3d Sphere::normal(double u, double v) const noexcept {
  return (evaluate(u, v) - c_) / r_;
}

Eigen::Vector2d Sphere::closest_point(const Eigen::Vector3d& p,
                                      Eigen::Vector3d& point) const noexcept {
  const Eigen::Vector3d q = A_.transpose() * (p - c_);
  const double n = q.norm();
  if (!(n > 0.0)) {
    point = evaluate(0.0, 0.0);
    return {0.0, 0.0};
  }
  point = c_ + (r_ / n) * (p - c_);
  return {detail::atan2(q[1], q[0]), detail::atan2(q[2], std::hypot(q[0], q[1]))};
}

}  // namespace virtmech
