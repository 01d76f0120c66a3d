// Placement of the virtual mechanism (paper section IV, eqs. 18-20): weighted, damped
// Gauss-Newton on the mechanism's joints, warm-started, bounded in iterations, respecting
// joint limits.
#pragma once

#include <cstdint>

#include "virtmech/mechanism.hpp"

namespace virtmech {

/// Settings of the placement solver.
struct TrackOptions {
  int max_iterations = 20;        //!< Gauss-Newton iterations at most
  double step_tolerance = 1e-12;  //!< stop when max |delta theta| falls below this [rad or m]
  /// stop when |J^T W e|_inf falls below this (with unequal rotation weights, J's rotation
  /// rows taken through the error's own derivative: see track())
  double gradient_tolerance = 1e-14;
  double max_step = 0.5;          //!< largest change of a revolute joint per iteration [rad]
  /// Largest change of a prismatic joint per iteration, as a fraction of the mechanism's
  /// length scale.
  double max_step_prismatic = 0.5;
  double damping = 1e-12;         //!< Levenberg damping relative to trace(J^T W J) / n
  /// Use the mechanism's closed-form placement where it has one (Mechanism::place).
  bool closed_form = true;
};

/// What one placement found.
struct TrackResult {
  int iterations = 0;      //!< Gauss-Newton iterations performed
  double residual = 0.0;   //!< sqrt(e^T W e) at the returned theta
  bool converged = false;  //!< a tolerance was met before max_iterations
  /// Joints held at a limit that acts (bit i: joint i): theta_i sits on its bound and the
  /// weighted cost would fall if it could move past it (the bound's KKT multiplier is > 0).
  std::uint32_t active = 0;
  /// Of those, the joints held at their upper limit (the others at their lower one).
  std::uint32_t active_upper = 0;
};

/// Finds theta minimising the weighted pose error e = pose_error(target, Phi_V(theta)),
/// e^T diag(W) e, starting from theta0, i.e. the fixed point of eq. 18, at which
/// J_V^T W e = 0 (eq. 23). Steps are the damped Gauss-Newton step of eq. 18, limited in
/// size, backtracked if they raise the cost, and projected onto the joint limits. Where the
/// three rotation weights differ, J_V's rotation rows are taken through the derivative of
/// the error's logarithm (J_r^-1 of the error's rotation: -de/dtheta exactly), so that the
/// fixed point is the cost's minimum; with equal ones the two coincide (docs/theory.md).
/// theta0 and theta must have mechanism.dof() entries. noexcept, allocation-free.
TrackResult track(const Mechanism& mechanism, const Pose& target, const JointVector& theta0,
                  const Vector6& weights, const TrackOptions& options,
                  JointVector& theta) noexcept;

}  // namespace virtmech
