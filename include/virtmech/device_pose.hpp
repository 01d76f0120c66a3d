// The device's joint values for a handle pose (inverse kinematics): Levenberg-Marquardt on
// the device's own kinematics, within its joint limits, from seeds in order of preference.
// Setup code (a simulation's start pose, a test's): it allocates, it is not for the cycle.
#pragma once

#include <vector>

#include "virtmech/device.hpp"

namespace virtmech {

/// What reach() found: the joint values and the pose error left there.
struct DevicePose {
  JointVector q;                  //!< device joint values, within the device's limits
  Vector6 error = Vector6::Zero();  //!< pose_error(target, device.forward(q)) [m; rad]
  int seed = -1;                  //!< the seed it started from
};

/// The device's joint values within its limits whose handle pose is nearest `target` in
/// the weighted pose error e^T diag(1, 1, 1, L², L², L²) e (L = length_scale > 0):
/// Levenberg-Marquardt (damped Gauss-Newton, its damping adapted to each step's success,
/// steps projected onto the limits) from each of `seeds` in turn (each clamped into the
/// limits, at most max_iterations iterations), the first that reaches the target (weighted
/// error below 1e-12) kept, else the nearest. A redundant device ends on the solution the
/// path from its seed leads to. Throws std::invalid_argument naming the argument for an
/// empty seed list, a seed of the wrong size or a length_scale <= 0.
DevicePose reach(const Device& device, const Pose& target, const std::vector<JointVector>& seeds,
                 double length_scale, int max_iterations = 200);

}  // namespace virtmech
