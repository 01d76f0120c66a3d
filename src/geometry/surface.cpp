// Surface's own methods (include/virtmech/geometry.hpp): the normal, the closest point from
// a start, and the curvatures from the derivatives.
#include <cmath>

#include "closest_point_search.hpp"
#include "shape_support.hpp"
#include "virtmech/geometry.hpp"

namespace virtmech {

Eigen::Vector3d Surface::normal(double u, double v) const noexcept {
  SurfaceDerivatives d;
  const Eigen::Vector2d lo = lower(), hi = upper();
  u = detail::clamp(u, lo[0], hi[0]);
  v = detail::clamp(v, lo[1], hi[1]);
  derivatives(u, v, 1, d);
  Eigen::Vector3d n = d(1, 0).cross(d(0, 1));
  const double scale = d(1, 0).norm() * d(0, 1).norm();
  if (!(n.norm() > 1e-12 * scale) && std::isfinite(hi[0] - lo[0]) &&
      std::isfinite(hi[1] - lo[1])) {
    // degenerate (a collapsed edge): a little toward the patch's centre
    const Eigen::Vector2d c = 0.5 * (lo + hi);
    const double h = 1e-7;
    derivatives(u + h * (c[0] - u), v + h * (c[1] - v), 1, d);
    n = d(1, 0).cross(d(0, 1));
  }
  const double len = n.norm();
  return len > 0.0 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::UnitZ();
}

Eigen::Vector2d Surface::closest_point_from(const Eigen::Vector3d& p, const Eigen::Vector2d& start,
                                           const Eigen::Vector2d& lo, const Eigen::Vector2d& hi,
                                           Eigen::Vector3d& point) const noexcept {
  Eigen::Vector2d x = start.cwiseMax(lo).cwiseMin(hi);
  detail::refine<2>(x, lo, hi, detail::DistanceToSurface{*this, p});
  SurfaceDerivatives d;
  derivatives(x[0], x[1], 0, d);
  point = d(0, 0);
  return x;
}

SurfaceCurvature Surface::curvature(double u, double v) const noexcept {
  SurfaceDerivatives d;
  derivatives(u, v, 2, d);
  const Eigen::Vector3d n = normal(u, v);
  const double E = d(1, 0).dot(d(1, 0)), F = d(1, 0).dot(d(0, 1)), G = d(0, 1).dot(d(0, 1));
  const double L = d(2, 0).dot(n), M = d(1, 1).dot(n), N = d(0, 2).dot(n);
  const double det = E * G - F * F;
  SurfaceCurvature c;
  if (det > 0.0) {
    c.mean = (E * N - 2.0 * F * M + G * L) / (2.0 * det);
    c.gaussian = (L * N - M * M) / det;
  }
  return c;
}

}  // namespace virtmech
