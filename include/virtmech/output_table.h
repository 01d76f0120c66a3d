/* What one controller cycle reports, one row per field (as settings_table.h): the C++
 * struct (virtmech::CycleOutput), its C mirror (vm_diagnostics), the copy between the two
 * and the Python properties are generated from these rows, so that a field is named, typed
 * and described in one place. Plain C (C89 preprocessor): the C API includes it.
 *
 * Columns of a row (doc: what Python's help() shows; shapes in parentheses):
 *   JOINTS(name, doc)        joint values, one per joint (C: double[VM_MAX_DOF], zero beyond)
 *   VEC6(name, doc)          a 6-vector [x y z rx ry rz]
 *   POSE(name, doc)          a rigid transform (C: row-major 4x4)
 *   LOCKS(name, of, doc)     joints held at a limit that acts, bit i for joint i of `of`
 *   INT(name, doc)           an integer, 0 at first
 *   REAL(name, value, doc)   a number, `value` at first
 *   BITS(name, doc)          a word of status bits (virtmech::status, VM_STATUS_*)
 */
#ifndef VIRTMECH_OUTPUT_TABLE_H_
#define VIRTMECH_OUTPUT_TABLE_H_

#define VM_CYCLE_OUTPUT(JOINTS, VEC6, POSE, LOCKS, INT, REAL, BITS)                            \
  JOINTS(torque, "Joint torques (n,) [N·m or N]; exactly 0 on passive joints.")                  \
  VEC6(wrench, "Wrench applied at the handle (6,) [N; N·m], after safety.")                      \
  VEC6(wrench_null, "Null-space part N(W_A)(Kp e + Kv e_dot) (6,), before safety.")              \
  VEC6(wrench_range, "Range-space part P(W_A)(Kp e* + Kv e*_dot) (6,), before safety.")          \
  VEC6(wrench_unrendered, "Part of the commanded wrench the device cannot apply (6,).")          \
  JOINTS(theta, "Nearest placement (m,) (W_e).")                                                 \
  JOINTS(theta_star, "Un-powered placement (m,) (W_e*).")                                        \
  VEC6(error, "e = X_V - X_R (6,) [m; rad].")                                                    \
  VEC6(error_dot, "The rate of e (6,) [m/s; rad/s] (error_velocity: 'relative' or 'handle').")   \
  VEC6(error_star, "e* = X_V* - X_R at the un-powered placement theta_star (6,) [m; rad] "       \
                   "(eq. 25).")                                                                  \
  VEC6(error_star_dot, "The rate of e* (6,) [m/s; rad/s].")                                      \
  POSE(handle_pose, "The device's handle pose X_R (4, 4) [m]: origin at the grip point, +z "     \
                    "along the stylus toward the tip.")                                          \
  POSE(mechanism_pose, "The mechanism's handle pose X_V at theta (4, 4) [m].")                   \
  POSE(mechanism_pose_star, "The mechanism's handle pose X_V* at theta_star (4, 4) [m].")        \
  REAL(residual, 0.0,                                                                            \
       "The nearest placement's weighted error sqrt(e^T W_e e) [m] (rotations weighted by the "  \
       "length scale squared): 0 when the handle is on the mechanism.")                          \
  REAL(residual_star, 0.0,                                                                       \
       "The un-powered placement's, sqrt(e*^T W_e* e*) [m]; 0 without eq. 26's range term.")     \
  INT(iterations, "Gauss-Newton iterations of this cycle's nearest placement (0: its closed "    \
                  "form).")                                                                      \
  INT(iterations_star, "Gauss-Newton iterations of this cycle's un-powered placement.")          \
  LOCKS(active, theta,                                                                           \
        "Joints of the nearest placement held at a limit that acts (m,) of bool: locked for "    \
        "the filters (a one-sided limit renders contact).")                                      \
  LOCKS(active_star, theta_star,                                                                 \
        "Joints of the un-powered placement held at a limit that acts (m,).")                    \
  REAL(ramp, 0.0, "Ramp-in factor applied, in [0, 1].")                                          \
  REAL(limit_scale, 1.0, "Factor applied by the force and torque limits, in (0, 1].")            \
  REAL(energy, 0.0,                                                                              \
       "The energy tank's level [J]: the energy the rendering has absorbed (at the start the "   \
       "springs' energy up to passivity_start_energy_j, after a fault or a watchdog trip 0), "   \
       "less the motors' work since as the observer books it (two cycles late), at most "       \
       "stored_energy + passivity_max_energy_j; below 0 a deficit, which fades the range term "  \
       "out (docs/theory.md, 8). 0 with passivity off.")                                         \
  REAL(stored_energy, 0.0,                                                                       \
       "What the law's springs hold [J]: Kp e at the nearest placement and, with eq. 26, the "   \
       "range term's P(W_A) Kp e* times the factor the tank applied to it the cycle before, "    \
       "each saturating at the wrench limits (the energy tank subtracts it).")                   \
  VEC6(wrench_passivity,                                                                         \
       "The part of the range term the energy tank held back (6,), before safety: (scale l - "   \
       "1) wrench_range, l = min(1, max_force / |force|, max_torque / |moment|) of "             \
       "wrench_range.")                                                                          \
  REAL(passivity_scale, 1.0,                                                                     \
       "The range term's factor the energy tank applied, in [0, 1]; it changes by at most "      \
       "passivity_fade_step a cycle.")                                                           \
  BITS(status, "Status bits (virtmech.status).")                                                 \
  REAL(computation_time_us, 0.0,                                                                 \
       "This cycle's own computation time [µs] (the processor's time-stamp counter where it is " \
       "invariant, else steady_clock).")

#endif /* VIRTMECH_OUTPUT_TABLE_H_ */
