// Cylinder (include/virtmech/geometry.hpp): the angle u about its axis and the
// distance v along it.
#include <cmath>

#include "../trig.hpp"
#include "shape_support.hpp"
#include "virtmech/geometry.hpp"

namespace virtmech {

using detail::clamp_order;
using detail::dcos;
using detail::dsin;
using detail::kPi;
using detail::safe_normalized;

Cylinder::Cylinder(const Eigen::Vector3d& point, const Eigen::Vector3d& direction, double radius)
    : a_(point), r_(radius) {
  require_finite("point", Eigen::VectorXd(point));
  d_ = safe_normalized(direction, "direction");
  require_positive("radius", radius);
  e1_ = d_.unitOrthogonal();
  e2_ = d_.cross(e1_);
}

Eigen::Vector2d Cylinder::lower() const noexcept { return {-kPi, -kInf}; }
Eigen::Vector2d Cylinder::upper() const noexcept { return {kPi, kInf}; }

Eigen::Vector3d Cylinder::evaluate(double u, double v) const noexcept {
  const double s = std::sin(u), c = std::cos(u);
  return a_ + r_ * (c * e1_ + s * e2_) + v * d_;
}

void Cylinder::derivatives(double u, double v, int order, SurfaceDerivatives& d) const noexcept {
  const int nd = clamp_order(order);
  for (int k = 0; k <= nd; ++k)
    for (int l = 0; l <= nd; ++l) d(k, l).setZero();
  for (int k = 0; k <= nd; ++k) d(k, 0) = r_ * (dcos(u, k) * e1_ + dsin(u, k) * e2_);
  d(0, 0) += a_ + v * d_;
  if (nd >= 1) d(0, 1) = d_;
}

Eigen::Vector3d Cylinder::normal(double u, double) const noexcept {
  return std::cos(u) * e1_ + std::sin(u) * e2_;
}

Eigen::Vector2d Cylinder::closest_point(const Eigen::Vector3d& p,
                                        Eigen::Vector3d& point) const noexcept {
  const Eigen::Vector3d q = p - a_;
  const double v = q.dot(d_);
  const double x = q.dot(e1_), y = q.dot(e2_);
  const double u = (x == 0.0 && y == 0.0) ? 0.0 : detail::atan2(y, x);
  point = evaluate(u, v);
  return {u, v};
}

}  // namespace virtmech
