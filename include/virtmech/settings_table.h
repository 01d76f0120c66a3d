/* virtmech's settings as tables, one row per setting (as MuJoCo's mjxmacro.h): the C++
 * structs (ControllerSettings, MechanismSetSettings), their C mirrors (vm_settings,
 * vm_set_settings), the conversion between the two, the checks of every value, the Python
 * bindings and the scenario format are all generated from these rows, so that a setting is
 * named, given its default and its range in one place. Plain C (C89 preprocessor): the C
 * API includes it.
 *
 * Columns of a row:
 *   VEC6(name, unit, doc)
 *       an optional 6-vector of values >= 0, [x y z rx ry rz]; unset, the controller derives
 *       it from the device and the mechanism (docs/theory.md).
 *   REAL(name, default, min, max, flags, unit, doc)
 *       a number in [min, max] (flags below); the default is a double constant expression.
 *   INT(name, default, min, max, unit, doc)
 *       an integer in [min, max].
 *   ENUM(name, Type, default, doc)
 *       one of the values of the enumeration Type (its own table of names below); the
 *       default is the value's integer.
 * The names of a row's min and max may be VM_INF (+infinity); only C++ expands them.
 */
#ifndef VIRTMECH_SETTINGS_TABLE_H_
#define VIRTMECH_SETTINGS_TABLE_H_

/* Flags of a REAL row's range. */
#define VM_RANGE_CLOSED 0       /* min <= value <= max, finite */
#define VM_RANGE_ABOVE_MIN 1    /* min < value: the lower bound itself is refused */
#define VM_RANGE_INF_ALLOWED 2  /* +infinity is a value too (no limit) */

/* The controller's settings (virtmech::ControllerSettings, vm_settings). */
#define VM_CONTROLLER_SETTINGS(VEC6, REAL, INT, ENUM)                                            \
  VEC6(kp, "N/m x3; N·m/rad x3",                                                                 \
       "stiffness; unset: the device's stiffness on the task axes it renders, 0 elsewhere")      \
  VEC6(kv, "N·s/m x3; N·m·s/rad x3",                                                             \
       "damping; unset: the device's damping on the task axes it renders, 0 elsewhere")          \
  VEC6(w_a, "1 x3; m² x3",                                                                      \
       "filter weights W_A; unset: [1 1 1 L^2 L^2 L^2] on the task axes the device renders")     \
  VEC6(w_e, "1 x3; m² x3",                                                                      \
       "nearest-placement weights W_e; unset: as W_A")                                           \
  VEC6(w_e_star, "1 x3; m² x3",                                                                 \
       "un-powered placement weights W_e* (eq. 25); unset: the task axes the device does not "   \
       "render")                                                                                 \
  REAL(length_scale, 0.0, 0.0, 10.0, VM_RANGE_CLOSED, "m",                                       \
       "L; it weighs rotations against translations; 0 takes the mechanism's")                   \
  ENUM(law, ControlLaw, 0,                                                                       \
       "the control law: auto (eq. 26 on an under-actuated device, else eq. 11), null_space "    \
       "(eq. 11), under_actuated (eq. 26)")                                                      \
  ENUM(error_velocity, ErrorVelocity, 0,                                                         \
       "how e_dot is formed: relative (the handle's velocity the mechanism does not follow) or " \
       "handle (eq. 10, -J_R dq)")                                                               \
  REAL(period_s, 1e-3, 0.0, 1.0, VM_RANGE_ABOVE_MIN, "s", "servo period")                        \
  REAL(ramp_time_s, 0.25, 0.0, 60.0, VM_RANGE_ABOVE_MIN, "s",                                    \
       "the force's ramp-in after the start, a fault or a watchdog trip (one period or less: "   \
       "none at the start; after a fault or a watchdog trip the ramp lasts at least 50 ms "      \
       "whatever this says)")                                                                    \
  REAL(watchdog_s, 0.0, 0.0, 60.0, VM_RANGE_CLOSED, "s",                                         \
       "the longest gap allowed between the time stamps t of step(q, dq, t); a longer gap, or "  \
       "time running backwards, restarts the ramp-in and empties the energy tank (status "       \
       "'watchdog'); 0: off")                                                                    \
  REAL(max_force, 0.0, 0.0, VM_INF, VM_RANGE_CLOSED, "N",                                        \
       "the limit on the force at the handle; 0 takes the device's")                             \
  REAL(max_torque, 0.0, 0.0, VM_INF, VM_RANGE_CLOSED, "N·m",                                     \
       "the limit on the moment at the handle; 0 takes the device's")                            \
  INT(max_iterations, 10, 1, 1000, "", "placement iterations per cycle")                         \
  INT(max_iterations_initial, 100, 1, 100000, "",                                                \
      "placement iterations on the first cycle (after a start, a reset or a fault)")             \
  REAL(secondary_weight, 1e-6, 0.0, 1.0, VM_RANGE_CLOSED, "",                                    \
       "the weight of [1 1 1 L^2 L^2 L^2] added to W_e and W_e* (dimensionless), so that "       \
       "directions their weights leave free are settled by the full pose error instead of "      \
       "drifting")                                                                               \
  REAL(range_margin_rad, (5.0 * 3.14159265358979323846 / 180.0), 0.0, 3.14159265358979323846,   \
       VM_RANGE_CLOSED, "rad",                                                                   \
       "how far q may leave a revolute joint's range before the cycle faults "                   \
       "(fault_out_of_range)")                                                                   \
  REAL(range_margin_m, 0.005, 0.0, 1.0, VM_RANGE_CLOSED, "m",                                    \
       "how far q may leave a prismatic joint's range before the cycle faults "                  \
       "(fault_out_of_range)")                                                                   \
  REAL(velocity_margin_rad_s, 5.0, 0.0, 1e4, VM_RANGE_CLOSED, "rad/s",                           \
       "how far |dq| may exceed a revolute joint's fastest plausible speed (the device's) "       \
       "before the cycle faults (fault_implausible_velocity)")                                   \
  REAL(velocity_margin_m_s, 0.5, 0.0, 1e3, VM_RANGE_CLOSED, "m/s",                               \
       "how far |dq| may exceed a prismatic joint's fastest plausible speed (the device's) "      \
       "before the cycle faults (fault_implausible_velocity)")                                   \
  ENUM(passivity, Passivity, 1,                                                                  \
       "energy_tank: eq. 26's range term only as long as the user has put in the energy it "     \
       "gives, faded in and out continuously; off: the laws as written (the paper's "            \
       "behaviour)")                                                                             \
  REAL(passivity_start_energy_j, 0.001, 0.0, VM_INF, VM_RANGE_INF_ALLOWED, "J",                  \
       "the most of what the law's springs hold at the start that the tank takes as its level "  \
       "(a tip that starts above its plane may be pulled down; inf: all of it)")                 \
  REAL(passivity_max_energy_j, 0.001, 0.0, VM_INF, VM_RANGE_INF_ALLOWED, "J",                    \
       "the most energy the tank holds beyond what the law's springs store (inf: no cap)")       \
  REAL(passivity_fade_j, 1e-6, 0.0, 1000.0, VM_RANGE_ABOVE_MIN, "J",                             \
       "the range term's factor aims at 1 while the tank is at least -passivity_budget_j and "   \
       "falls linearly to 0 as it goes on down by this much")                                    \
  REAL(passivity_budget_j, 0.0, 0.0, 1000.0, VM_RANGE_CLOSED, "J",                               \
       "the most net work the motors may do beyond what the user put in before the range term "  \
       "fades: 0 for a passive rendering; a guide the user turns into (a stylus through a "      \
       "port) needs the motors to carry the hand a little")                                      \
  REAL(passivity_fade_time_s, 0.025, 0.0, 60.0, VM_RANGE_ABOVE_MIN, "s",                         \
       "the range term's factor moves toward its aim so that its force changes by at most "      \
       "max_force period_s / passivity_fade_time_s a cycle (and its moment likewise): the "      \
       "force never steps")                                                                      \
  REAL(passivity_resolution_rad, (2.0 * 3.14159265358979323846 / 15000.0), 0.0, 0.1,             \
       VM_RANGE_CLOSED, "rad",                                                                   \
       "a revolute joint's position resolution, one encoder count: the passivity observer's "    \
       "displacement is held within half of it of the reading (default: the simulated Omni's); " \
       "0: the readings as they are")                                                            \
  REAL(passivity_resolution_m, 1e-5, 0.0, 0.01, VM_RANGE_CLOSED, "m",                            \
       "a prismatic joint's position resolution (as passivity_resolution_rad)")

/* A mechanism set's settings (virtmech::MechanismSetSettings, vm_set_settings). */
#define VM_SET_SETTINGS(REAL)                                                                    \
  REAL(snap_distance, 0.005, 0.0, 1.0, VM_RANGE_ABOVE_MIN, "m",                                  \
       "a member engages within this distance")                                                  \
  REAL(release_distance, 0.010, 0.0, 1.0, VM_RANGE_ABOVE_MIN, "m",                               \
       "... and lets go beyond this one (at least snap_distance: the hysteresis)")               \
  REAL(force_rate, 100.0, 0.0, 1e6, VM_RANGE_ABOVE_MIN, "N/s",                                   \
       "largest change of the force while switching")                                            \
  REAL(moment_rate, 1.0, 0.0, 1e6, VM_RANGE_ABOVE_MIN, "N·m/s",                                  \
       "largest change of the moment while switching")                                           \
  REAL(period_s, 1e-3, 0.0, 1.0, VM_RANGE_ABOVE_MIN, "s", "servo period, for the rates")

/* The names of the enumerations' values: X(cpp_name, C_NAME, value, "name", doc). The
 * string is what users write (Python keywords, scenario files); C_NAME gives the C
 * constant (VM_LAW_AUTO, ...). */
#define VM_CONTROL_LAWS(X)                                                                       \
  X(kAuto, AUTO, 0, "auto", "eq. 26 when the device has un-powered joints, else eq. 11")        \
  X(kNullSpace, NULL_SPACE, 1, "null_space", "eq. 11: f = N(W_A)(Kp e + Kv e_dot)")             \
  X(kUnderActuated, UNDER_ACTUATED, 2, "under_actuated",                                         \
    "eq. 26: adds P(W_A)(Kp e* + Kv e*_dot)")
#define VM_ERROR_VELOCITIES(X)                                                                   \
  X(kRelative, RELATIVE, 0, "relative",                                                          \
    "e_dot = J_V theta_dot - J_R dq, theta_dot the placement's first-order rate: the part of "   \
    "the handle's velocity the mechanism does not follow")                                       \
  X(kHandle, HANDLE, 1, "handle", "e_dot = -J_R dq (eq. 10: desired velocity zero)")
#define VM_PASSIVITIES(X)                                                                        \
  X(kEnergyTank, ENERGY_TANK, 1, "energy_tank",                                                  \
    "an energy tank filled by a passivity observer at the motors' port (Hannaford & Ryu "        \
    "2002) that does not book the encoders' quantisation nor one-cycle glitches: eq. 26's "      \
    "range term is rendered only as long as the user has put in the energy it gives (plus "      \
    "passivity_budget_j), and fades out and back in continuously")                               \
  X(kOff, OFF, 0, "off", "the laws as written: the motors may do net work (the paper's Fig. 11)")

#endif /* VIRTMECH_SETTINGS_TABLE_H_ */
