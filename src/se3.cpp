#include "virtmech/se3.hpp"

#include "rotation_log.hpp"
#include "trig.hpp"

#include <cmath>

namespace virtmech {

Eigen::Matrix3d skew(const Eigen::Vector3d& w) noexcept {
  Eigen::Matrix3d S;
  S << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return S;
}

Eigen::Vector3d so3_log(const Eigen::Matrix3d& R) noexcept {
  const double tr1 = 1.0 + R.trace();
  if (tr1 > 1.0) {  // below 2 pi / 3
    return detail::log_from_axis_part(
        Eigen::Vector3d(R(2, 1) - R(1, 2), R(0, 2) - R(2, 0), R(1, 0) - R(0, 1)), tr1);
  }
  // near pi the quaternion route (from the diagonal) is well conditioned
  const Eigen::Quaterniond q(R);
  const double n = q.vec().norm();
  if (n < 1e-300) return Eigen::Vector3d::Zero();
  const double w = q.w();
  const double angle = 2.0 * detail::atan2(n, std::abs(w));
  const double sign = (w < 0.0) ? -1.0 : 1.0;
  return (sign * angle / n) * q.vec();
}

Eigen::Matrix3d so3_exp(const Eigen::Vector3d& w) noexcept {
  const double angle = w.norm();
  if (angle < 1e-300) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

Vector6 pose_error(const Pose& T_a, const Pose& T_b) noexcept {
  Vector6 e;
  e.head<3>() = T_a.translation() - T_b.translation();
  e.tail<3>() = so3_log(T_a.linear() * T_b.linear().transpose());
  return e;
}

Pose make_pose(const Eigen::Matrix3d& R, const Eigen::Vector3d& p) noexcept {
  Pose T = Pose::Identity();
  T.linear() = R;
  T.translation() = p;
  return T;
}

Eigen::Vector3d any_orthogonal(const Eigen::Vector3d& n) noexcept {
  // cross with the world axis least aligned with n
  Eigen::Index k = 0;
  n.cwiseAbs().minCoeff(&k);
  const Eigen::Vector3d t = n.cross(Eigen::Vector3d::Unit(k));
  return t.normalized();
}

}  // namespace virtmech
