// The placement with what its last evaluation already holds: the mechanism's pose, its
// Jacobian and the pose error at the returned theta, so the controller need not compute
// them again. Internal.
#pragma once

#include "virtmech/track.hpp"

namespace virtmech::detail {

/// track() that also returns the handle pose and the Jacobian of the mechanism at theta,
/// and the error pose_error(target, pose).
TrackResult track(const Mechanism& mechanism, const Pose& target, const JointVector& theta0,
                  const Vector6& weights, const TrackOptions& options, JointVector& theta,
                  Pose& pose, Jacobian& J, Vector6& error) noexcept;

/// What track() reports for a closed-form placement (Mechanism::place or place_pair): theta
/// with J and error there, converged, its residual and the joints held at a limit.
TrackResult closed_form_result(const Mechanism& mechanism, const Vector6& weights,
                               const JointVector& theta, const Jacobian& J,
                               const Vector6& error) noexcept;

}  // namespace virtmech::detail
