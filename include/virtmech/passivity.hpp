// The passivity layer of the servo cycle (docs/theory.md, section 8): an energy tank whose
// level is the energy the rendering has absorbed, observed at the motors' port with the
// torque held over each cycle (zero-order hold) times a displacement that the encoders'
// quantisation and one-cycle glitches do not move, and a factor on eq. 26's range term that
// follows the level continuously (it changes by at most one fade step per cycle).
#pragma once

#include "virtmech/types.hpp"

namespace virtmech {

/// The passivity layer's state (ControllerData::passivity): the tank's level, the
/// observer's short history and the range term's factor. Fixed capacity; never allocates.
///
/// The observer books cycle k - 2's torque over its interval at cycle k, once q_k is known:
/// the displacement over that interval is taken between q~_{k-2} and q~_{k-1}, where q~ is
/// the median of three consecutive readings (a one-cycle glitch is not motion), held within
/// half a count of q~ (a play: an encoder flipping between two counts is no motion either,
/// while motion beyond it is followed count by count), each joint's move booked with the
/// torque averaged over the cycles since its last (those in which it travelled the count).
/// The displacement is the readings' alone, never the velocity estimate: the law's damping acts on that estimate, so a
/// displacement that followed it would book the damping's dissipation of the estimate's
/// spikes, not of the joint's motion.
struct PassivityState {
  double energy = 0.0;  //!< the tank's level E [J]
  /// The work the held torque does over the displacement the observer's play has not
  /// booked yet, tau . (q~ - p), where it is motor output (else 0) [J]: the factor's aim
  /// counts it as done.
  double pending = 0.0;
  /// The range term's rendered share of the wrench limits the last cycle (its force over
  /// max_force, or its moment over max_torque, at most 1).
  double rendered = 1.0;
  /// The range term's factor the last cycle applied (rendered over the range term's share).
  double factor = 1.0;
  /// The share the last cycle rendered over the range term's share within the limits.
  double scale = 1.0;
  /// The range term rendered as it is (the tank's aim 1): the rendered share follows it.
  bool following = true;
  /// Cycles observed since the tank (re)started; 0: the next cycle restarts it.
  long cycles = 0;
  /// The restart is the start: the level starts at the springs' energy, at most
  /// passivity_start_energy_j (after a fault or a watchdog trip, at 0).
  bool start_with_springs = true;
  JointVector q_before;    //!< q two cycles back (the median's first reading)
  JointVector q_last;      //!< q one cycle back
  JointVector played;      //!< the observer's displacement two cycles back
  /// per joint: the torques held since its displacement last moved, summed, and how many
  JointVector torque_sum, torque_count;
  JointVector tau_before;  //!< the torque held from two cycles back to one cycle back
  JointVector tau_last;    //!< the torque held since the last cycle
  /// The range term's spring P(W_A) Kp e* of the cycle, for what the springs hold.
  Vector6 range_spring = Vector6::Zero();
};

}  // namespace virtmech
