#include "virtmech/kinematic_chain.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "virtmech/validate.hpp"

namespace virtmech {

namespace {

// the frame (R, p) walked along the chain; products are written out for the common cases
// (origins without rotation or without any offset, axes along a coordinate axis) since they
// are the servo cycle's inner loop, and kept small enough to be inlined into it
struct Frame {
  Eigen::Matrix3d R;
  Eigen::Vector3d p;
};

// f <- f * T for a general pose (out of line: the uncommon case)
[[gnu::noinline]] void apply(Frame& f, const Pose& T) noexcept {
  f.p.noalias() += f.R * T.translation();
  f.R = f.R * T.linear();
}

// f <- f * rotation about a unit axis not along a coordinate axis (out of line: uncommon)
[[gnu::noinline]] void rotate_general(Frame& f, const Eigen::Vector3d& axis, double x) noexcept {
  f.R = f.R * Eigen::AngleAxisd(x, axis).toRotationMatrix();
}

// f <- f * origin
inline void apply_origin(Frame& f, const Pose& origin, bool identity,
                         bool translation_only) noexcept {
  if (identity) return;
  if (translation_only) {
    f.p.noalias() += f.R * origin.translation();
  } else {
    apply(f, origin);
  }
}

// f <- f * motion(x): rotation about, or translation along, the joint axis
[[gnu::always_inline]] inline void apply_motion(Frame& f, const Joint& j, int axis_index, double axis_sign,
                         double x) noexcept {
  if (axis_index < 0) {
    if (j.type == JointType::kPrismatic) {
      f.p.noalias() += f.R * (x * j.axis);
    } else {
      rotate_general(f, j.axis, x);
    }
    return;
  }
  const double a = axis_sign * x;
  if (j.type == JointType::kPrismatic) {
    f.p += a * f.R.col(axis_index);
    return;
  }
  // rotation about a coordinate axis k mixes the two other columns of R
  const double c = std::cos(a), s = std::sin(a);
  const int u = axis_index == 2 ? 0 : axis_index + 1, v = axis_index == 0 ? 2 : axis_index - 1;
  const Eigen::Vector3d ru = f.R.col(u), rv = f.R.col(v);
  f.R.col(u) = c * ru + s * rv;
  f.R.col(v) = c * rv - s * ru;
}

inline Frame start(const Pose& base) noexcept { return Frame{base.linear(), base.translation()}; }

inline void finish(const Frame& f, const Pose& handle, Pose& T) noexcept {
  T.translation().noalias() = f.p + f.R * handle.translation();
  T.linear().noalias() = f.R * handle.linear();
  T.makeAffine();
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
    const size_t k = static_cast<size_t>(i);
    axis_index_[k] = -1;
    axis_sign_[k] = 1.0;
    for (int a = 0; a < 3; ++a) {
      if (std::abs(j.axis[a]) == 1.0) {
        axis_index_[k] = a;
        axis_sign_[k] = j.axis[a];
      }
    }
    origin_translation_only_[k] = j.origin.linear().isIdentity(0.0);
    origin_identity_[k] = origin_translation_only_[k] && j.origin.translation().isZero(0.0);
  }
}

std::vector<Joint> KinematicChain::joints() const {
  return std::vector<Joint>(joints_.begin(), joints_.begin() + dof_);
}

std::vector<JointType> KinematicChain::kinds() const {
  std::vector<JointType> k;
  for (int i = 0; i < dof_; ++i) k.push_back(joints_[static_cast<size_t>(i)].type);
  return k;
}

std::vector<double> KinematicChain::lower() const {
  std::vector<double> v;
  for (int i = 0; i < dof_; ++i) v.push_back(joints_[static_cast<size_t>(i)].lower);
  return v;
}

std::vector<double> KinematicChain::upper() const {
  std::vector<double> v;
  for (int i = 0; i < dof_; ++i) v.push_back(joints_[static_cast<size_t>(i)].upper);
  return v;
}

void KinematicChain::forward(const double* q, Pose& T) const noexcept {
  Frame f = start(base_);
  for (int i = 0; i < dof_; ++i) {
    const size_t k = static_cast<size_t>(i);
    apply_origin(f, joints_[k].origin, origin_identity_[k], origin_translation_only_[k]);
    apply_motion(f, joints_[k], axis_index_[k], axis_sign_[k], q[i]);
  }
  finish(f, handle_, T);
}

void KinematicChain::forward_jacobian(const double* q, Pose& T, Jacobian& J) const noexcept {
  J.resize(6, dof_);
  // world axis and point of every joint, then the handle origin
  Eigen::Matrix<double, 3, kMaxDof> axes;
  Eigen::Matrix<double, 3, kMaxDof> points;
  Frame f = start(base_);
  for (int i = 0; i < dof_; ++i) {
    const size_t k = static_cast<size_t>(i);
    const Joint& j = joints_[k];
    apply_origin(f, j.origin, origin_identity_[k], origin_translation_only_[k]);
    if (axis_index_[k] >= 0) {
      axes.col(i) = axis_sign_[k] * f.R.col(axis_index_[k]);
    } else {
      axes.col(i).noalias() = f.R * j.axis;
    }
    points.col(i) = f.p;
    apply_motion(f, j, axis_index_[k], axis_sign_[k], q[i]);
  }
  finish(f, handle_, T);
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
