// Rigid-body helpers: the pose error (docs/theory.md, section 1) and the SO(3) exponential
// and logarithm.
#pragma once

#include "virtmech/types.hpp"

namespace virtmech {

/// Skew-symmetric matrix [w]x such that [w]x v = w x v.
Eigen::Matrix3d skew(const Eigen::Vector3d& w) noexcept;

/// Rotation vector (axis * angle, angle in [0, pi]) of a rotation matrix [rad].
Eigen::Vector3d so3_log(const Eigen::Matrix3d& R) noexcept;

/// Rotation matrix of a rotation vector [rad].
Eigen::Matrix3d so3_exp(const Eigen::Vector3d& w) noexcept;

/// Pose error e = [p_a - p_b; log(R_a R_b^T)]: position difference [m] then the rotation
/// vector taking frame b's orientation to frame a's, both in world axes [rad].
Vector6 pose_error(const Pose& T_a, const Pose& T_b) noexcept;

/// Builds a pose from a rotation and a translation.
Pose make_pose(const Eigen::Matrix3d& R, const Eigen::Vector3d& p) noexcept;

/// A unit vector orthogonal to the unit vector n (deterministic choice).
Eigen::Vector3d any_orthogonal(const Eigen::Vector3d& n) noexcept;

}  // namespace virtmech
