// The x-y-z Euler angles of a rotation on the branch nearest a start (closed_form.hpp:
// euler_xyz_nearest), for a wrist of three revolute joints.
#include <cmath>

#include "../closed_form.hpp"
#include "../trig.hpp"

namespace virtmech::detail {

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
  if (lock) {
    sa = std::sin(a);
    ca = std::cos(a);
  }
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
