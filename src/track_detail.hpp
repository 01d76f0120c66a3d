// The placement with what its last evaluation already holds: the mechanism's pose, its
// Jacobian and the pose error at the returned theta, so the controller need not compute
// them again. Internal.
#pragma once

#include "virtmech/track.hpp"

namespace virtmech::detail {

/// track() with the weights *io.w from *io.start into *io.theta, that also returns the
/// handle pose *io.T and the Jacobian *io.J of the mechanism at theta, and the error
/// *io.e = pose_error(target, pose).
TrackResult track(const Mechanism& mechanism, const Pose& target, const TrackOptions& options,
                  const PlacementIO& io) noexcept;

/// What track() reports for a closed-form placement (Mechanism::place or place_pair): theta
/// with J and error there, converged, its residual and the joints held at a limit.
TrackResult closed_form_result(const Mechanism& mechanism, const Vector6& weights,
                               const JointVector& theta, const Jacobian& J,
                               const Vector6& error) noexcept;

}  // namespace virtmech::detail
