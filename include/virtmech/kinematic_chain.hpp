// A serial chain of revolute and prismatic joints: forward kinematics and the geometric
// Jacobian of its handle frame. Every mechanism and every device is built on one.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "virtmech/types.hpp"

namespace virtmech {

/// Kind of a single-axis joint.
enum class JointType : int {
  kRevolute = 0,   //!< rotation about the axis [rad]
  kPrismatic = 1,  //!< translation along the axis [m]
};

/// One joint of a serial chain.
struct Joint {
  JointType type = JointType::kRevolute;
  /// Joint axis in the joint frame (normalised at construction of the chain).
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
  /// Pose of the joint frame in the previous link's frame when the joint value is 0.
  Pose origin = Pose::Identity();
  double lower = -kInf;  //!< lower joint limit [rad or m]
  double upper = kInf;   //!< upper joint limit [rad or m]
};

/// A serial kinematic chain: base pose, up to kMaxDof joints, then a fixed handle offset.
///
/// T(q) = base * prod_i (origin_i * motion_i(q_i)) * handle. The Jacobian is geometric,
/// 6 x dof, rows [v; w]: linear velocity of the handle origin, then angular velocity,
/// both in world axes. All evaluation calls are noexcept and allocate nothing.
class KinematicChain {
 public:
  KinematicChain() = default;
  /// Validates and stores the chain; throws std::invalid_argument naming the bad field.
  KinematicChain(const Pose& base, const std::vector<Joint>& joints, const Pose& handle);

  int dof() const noexcept { return dof_; }
  /// Joint i, 0 <= i < dof() (unchecked).
  const Joint& joint(int i) const noexcept { return joints_[static_cast<size_t>(i)]; }
  std::vector<Joint> joints() const;
  /// Each joint's kind, lower and upper limit (construction-time helpers; allocate).
  std::vector<JointType> kinds() const;
  std::vector<double> lower() const;
  std::vector<double> upper() const;
  const Pose& base() const noexcept { return base_; }
  const Pose& handle() const noexcept { return handle_; }

  /// Handle pose at joint values q (q has dof() entries).
  void forward(const double* q, Pose& T) const noexcept;
  /// Handle pose and geometric Jacobian (resized to 6 x dof()) at q.
  void forward_jacobian(const double* q, Pose& T, Jacobian& J) const noexcept;

 private:
  Pose base_ = Pose::Identity();
  Pose handle_ = Pose::Identity();
  std::array<Joint, kMaxDof> joints_{};
  int dof_ = 0;
  // derived at construction for the evaluation calls: a joint axis that is +-x, +-y or +-z
  // (axis_index_ 0..2, axis_sign_ +-1; -1: any other direction), and whether the joint's
  // origin has no rotation, and no translation either
  std::array<int, kMaxDof> axis_index_{};
  std::array<double, kMaxDof> axis_sign_{};
  std::array<bool, kMaxDof> origin_translation_only_{};
  std::array<bool, kMaxDof> origin_identity_{};
};

}  // namespace virtmech
