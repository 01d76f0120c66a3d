#include "virtmech/kinematic_chain.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "virtmech/validate.hpp"

namespace virtmech {

namespace {

// pose of the joint's motion for value x, in the joint frame
inline Pose joint_motion(const Joint& j, double x) noexcept {
  Pose M = Pose::Identity();
  if (j.type == JointType::kRevolute) {
    M.linear() = Eigen::AngleAxisd(x, j.axis).toRotationMatrix();
  } else {
    M.translation() = x * j.axis;
  }
  return M;
}

}  // namespace

KinematicChain::KinematicChain(const Pose& base, const std::vector<Joint>& joints,
                               const Pose& handle)
    : base_(base), handle_(handle) {
  require_pose("base", base_);
  require_pose("handle", handle_);
  if (joints.empty() || joints.size() > static_cast<size_t>(kMaxDof)) {
    std::ostringstream os;
    os << "joints: expected 1 to " << kMaxDof << " joints, got " << joints.size();
    throw std::invalid_argument(os.str());
  }
  dof_ = static_cast<int>(joints.size());
  for (int i = 0; i < dof_; ++i) {
    Joint j = joints[static_cast<size_t>(i)];
    const std::string name = "joints[" + std::to_string(i) + "]";
    require_finite(name + ".axis", j.axis);
    const double n = j.axis.norm();
    if (!(n > 1e-9)) {
      throw std::invalid_argument(name + ".axis: expected a non-zero vector, got " +
                                  format_vector(j.axis));
    }
    j.axis /= n;
    require_pose(name + ".origin", j.origin);
    if (std::isnan(j.lower) || std::isnan(j.upper) || !(j.lower <= j.upper)) {
      std::ostringstream os;
      os << name << ": expected lower <= upper, got lower=" << j.lower
         << " upper=" << j.upper;
      throw std::invalid_argument(os.str());
    }
    joints_[static_cast<size_t>(i)] = j;
  }
}

std::vector<Joint> KinematicChain::joints() const {
  return std::vector<Joint>(joints_.begin(), joints_.begin() + dof_);
}

void KinematicChain::forward(const double* q, Pose& T) const noexcept {
  T = base_;
  for (int i = 0; i < dof_; ++i) {
    const Joint& j = joints_[static_cast<size_t>(i)];
    T = T * j.origin * joint_motion(j, q[i]);
  }
  T = T * handle_;
}

void KinematicChain::forward_jacobian(const double* q, Pose& T, Jacobian& J) const noexcept {
  J.resize(6, dof_);
  // world axis and point of every joint, then the handle origin
  Eigen::Matrix<double, 3, kMaxDof> axes;
  Eigen::Matrix<double, 3, kMaxDof> points;
  T = base_;
  for (int i = 0; i < dof_; ++i) {
    const Joint& j = joints_[static_cast<size_t>(i)];
    T = T * j.origin;
    axes.col(i) = T.linear() * j.axis;
    points.col(i) = T.translation();
    T = T * joint_motion(j, q[i]);
  }
  T = T * handle_;
  const Eigen::Vector3d p = T.translation();
  for (int i = 0; i < dof_; ++i) {
    const Eigen::Vector3d a = axes.col(i);
    if (joints_[static_cast<size_t>(i)].type == JointType::kRevolute) {
      J.col(i).head<3>() = a.cross(p - points.col(i));
      J.col(i).tail<3>() = a;
    } else {
      J.col(i).head<3>() = a;
      J.col(i).tail<3>().setZero();
    }
  }
}

}  // namespace virtmech
