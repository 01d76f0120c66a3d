// The passivity stage of the cycle (src/passivity.cpp; docs/theory.md, section 8).
#pragma once

#include "virtmech/controller.hpp"

namespace virtmech::detail {

/// The energy a spring holds whose force at the error e is f (a linear spring: e^T f / 2),
/// its force saturating at the wrench limits: per block of three axes, beyond the limit it
/// grows with the limit times |e|. Never negative.
double saturated_spring(const Vector6& e, const Vector6& f, double force_limit,
                        double moment_limit) noexcept;

/// The tank restarts at the next cycle, its observer's history forgotten: at the start
/// (`springs`) its level then starts at what the springs hold, at most
/// passivity_start_energy_j; after a fault, a watchdog trip or a cycle whose torque was not
/// applied, at 0.
void restart_passivity(PassivityState& s, bool springs) noexcept;

/// The passivity stage, after the law's terms and before what the device cannot render:
/// books the motors' work over the interval before last (the observer), bounds the level by
/// what the springs hold plus the reserve, and moves the range term's factor toward the
/// level's aim (one fade time ahead at the range term's power) by at most one fade step; the
/// range term is rendered limited to the wrench limits and times the factor. Writes
/// out.energy, stored_energy, passivity_scale, wrench_passivity (the rendered range term
/// less out.wrench_range) and the status bit kPassivity. q: the cycle's joints (dof());
/// twist: the handle's, J_R dq.
void passivity(const ControllerModel& M, const Device& dev, PassivityState& s, const double* q,
               const Vector6& twist, CycleOutput& out) noexcept;

/// After safety: the cycle's torque, held until the next cycle, enters the observer.
void hold_torque(const ControllerModel& M, PassivityState& s, const JointVector& torque) noexcept;

}  // namespace virtmech::detail
