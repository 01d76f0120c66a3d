// Plane (include/virtmech/geometry.hpp): coordinates u, v along two orthonormal
// directions in it.
#include <cmath>

#include "shape_support.hpp"
#include "virtmech/geometry.hpp"

namespace virtmech {

using detail::clamp_order;
using detail::safe_normalized;

Plane::Plane(const Eigen::Vector3d& point, const Eigen::Vector3d& normal) : o_(point) {
  require_finite("point", Eigen::VectorXd(point));
  n_ = safe_normalized(normal, "normal");
  e1_ = n_.unitOrthogonal();
  e2_ = n_.cross(e1_);
}

Eigen::Vector2d Plane::lower() const noexcept { return {-kInf, -kInf}; }
Eigen::Vector2d Plane::upper() const noexcept { return {kInf, kInf}; }

Eigen::Vector3d Plane::evaluate(double u, double v) const noexcept {
  return o_ + u * e1_ + v * e2_;
}

void Plane::derivatives(double u, double v, int order, SurfaceDerivatives& d) const noexcept {
  const int nd = clamp_order(order);
  for (int k = 0; k <= nd; ++k)
    for (int l = 0; l <= nd; ++l) d(k, l).setZero();
  d(0, 0) = evaluate(u, v);
  if (nd >= 1) {
    d(1, 0) = e1_;
    d(0, 1) = e2_;
  }
}

Eigen::Vector3d Plane::normal(double, double) const noexcept { return n_; }

Eigen::Vector2d Plane::closest_point(const Eigen::Vector3d& p,
                                     Eigen::Vector3d& point) const noexcept {
  const Eigen::Vector3d q = p - o_;
  const Eigen::Vector2d uv(q.dot(e1_), q.dot(e2_));
  point = evaluate(uv[0], uv[1]);
  return uv;
}

}  // namespace virtmech
