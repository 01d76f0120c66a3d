// Fixed-capacity Eigen types shared by every part of the core.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <limits>

namespace virtmech {

/// Largest number of joints a device or a mechanism may have.
constexpr int kMaxDof = 8;

/// Positive infinity, the default for joints without limits.
constexpr double kInf = std::numeric_limits<double>::infinity();

/// A rigid transform (4x4 homogeneous, rotation + translation) [m].
using Pose = Eigen::Isometry3d;

/// A 6-vector: a twist [v; w], a wrench [f; m], a pose error or diagonal weights.
using Vector6 = Eigen::Matrix<double, 6, 1>;
using Matrix6 = Eigen::Matrix<double, 6, 6>;

/// Joint-space vector with at most kMaxDof entries; resizing never allocates.
using JointVector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxDof, 1>;

/// Geometric Jacobian, 6 x dof, rows [v; w] in world axes; resizing never allocates.
using Jacobian = Eigen::Matrix<double, 6, Eigen::Dynamic, Eigen::ColMajor, 6, kMaxDof>;

/// Square joint-space matrix with at most kMaxDof rows; resizing never allocates.
using JointMatrix =
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor, kMaxDof, kMaxDof>;

}  // namespace virtmech
