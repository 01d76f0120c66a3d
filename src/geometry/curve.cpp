// Curve's own methods (include/virtmech/geometry.hpp): the tangent and the curvature from
// the derivatives.
#include <cmath>

#include "virtmech/geometry.hpp"

namespace virtmech {

Eigen::Vector3d Curve::tangent(double u) const noexcept {
  CurveDerivatives d;
  derivatives(u, 1, d);
  const double n = d.col(1).norm();
  return n > 0.0 ? Eigen::Vector3d(d.col(1) / n) : Eigen::Vector3d::Zero();
}

double Curve::curvature(double u) const noexcept {
  CurveDerivatives d;
  derivatives(u, 2, d);
  const double n = d.col(1).norm();
  if (!(n > 0.0)) return 0.0;
  return d.col(1).cross(d.col(2)).norm() / (n * n * n);
}

}  // namespace virtmech
