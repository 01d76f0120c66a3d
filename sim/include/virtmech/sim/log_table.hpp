// The simulation log's columns, one row per field (as MuJoCo's mjxmacro.h): the servo loop's
// layout (LogLayout, ServoLoop::write_row), the Python reader (virtmech.sim.loop.log_columns,
// UNITS; virtmech.sim.inner.LOG_FIELDS) and run.json's units are all made from it, so that
// a column is named, placed and given its unit in one place. The order of the rows is the
// order of the columns in a log.
//
// X(field, width, names, units, origin):
//   width   1, 3 or 6 entries; N: one per device joint; M: one per mechanism joint (a set's
//           widest member)
//   names   the columns: "t" (one), "px py pz" (one name each), or a prefix ("q": q0, q1, ...)
//   units   the unit of the row's first column or prefix; or "key=unit|key=unit" for a row
//           whose columns have several (twist: vx=m/s|wx=rad/s)
//   origin  LOOP: written by the servo loop; DERIVED: filled after it from the row alone
//           (virtmech.sim: distances from the mechanism, PlanarArm angles, the grip)
#pragma once

#include <string>
#include <utility>
#include <vector>

#define VM_LOG_TABLE(X)                                                                       \
  X(t, 1, "t", "s", LOOP)                                                                     \
  X(q, N, "q", "rad", LOOP)                                                                   \
  X(dq, N, "dq", "rad/s", LOOP)                                                               \
  X(qm, N, "qm", "rad (measured)", LOOP)                                                      \
  X(dqm, N, "dqm", "rad/s (estimated)", LOOP)                                                 \
  X(handle_p, 3, "px py pz", "m", LOOP)                                                       \
  X(stylus, 3, "sx sy sz", "unit stylus direction", LOOP)                                     \
  X(twist, 6, "vx vy vz wx wy wz", "vx=m/s|wx=rad/s", LOOP)                                   \
  X(wrench, 6, "fx fy fz mx my mz", "fx=N (device on handle)|mx=N·m (device on handle)", LOOP) \
  X(tau, N, "tau", "N·m (controller command)", LOOP)                                          \
  X(tau_motor, N, "tau_motor", "N·m (motor output incl. gravity compensation, saturated)",    \
    LOOP)                                                                                     \
  X(status, 1, "status", "bits (virtmech.status)", LOOP)                                      \
  X(ramp, 1, "ramp", "1", LOOP)                                                               \
  X(iterations, 1, "iterations", "", LOOP)                                                    \
  X(iterations_star, 1, "iterations_star", "", LOOP)                                          \
  X(theta, M, "theta", "rad (nearest placement, W_e)", LOOP)                                  \
  X(theta_star, M, "theta_star", "rad (un-powered placement, W_e*)", LOOP)                    \
  X(e, 6, "e", "m x3, rad x3", LOOP)                                                          \
  X(e_dot, 6, "e_dot", "m/s, rad/s", LOOP)                                                    \
  X(e_star, 6, "e_star", "m, rad", LOOP)                                                      \
  X(e_star_dot, 6, "e_star_dot", "m/s, rad/s", LOOP)                                          \
  X(f_null, 6, "f_null", "N, N·m (eq. 26 null-space part)", LOOP)                             \
  X(f_range, 6, "f_range", "N, N·m (eq. 26 range-space part)", LOOP)                          \
  X(hand_wrench, 6, "fhx fhy fhz mhx mhy mhz", "fhx=N (hand on handle)|mhx=N·m (hand on handle)", \
    LOOP)                                                                                     \
  X(anchor, 3, "ax ay az", "m (hand anchor)", LOOP)                                           \
  X(segment, 1, "segment", "intent segment index", LOOP)                                      \
  X(member, 1, "member", "mechanism rendered: 0 the [mechanism], i the set's i-th (-1: none)", \
    LOOP)                                                                                     \
  X(dist, 1, "dist",                                                                          \
    "m (distance from where the mechanism allows; sim.geometry; a set's run: the rendered "   \
    "member's, with none the nearest member's)",                                              \
    DERIVED)                                                                                  \
  X(dist_signed, 1, "dist_signed",                                                            \
    "m (signed distance from the mechanism's path or surface; sim.geometry)", DERIVED)        \
  X(dist_normal, 1, "dist_normal", "m (part along the mechanism's normal; sim.geometry)",     \
    DERIVED)                                                                                  \
  X(dist_across, 1, "dist_across", "m (the rest; sim.geometry)", DERIVED)                     \
  X(arm_pos_angle, 1, "arm_pos_angle",                                                        \
    "rad (PlanarArm: angle of the handle position about the pivot)", DERIVED)                 \
  X(arm_stylus_angle, 1, "arm_stylus_angle",                                                  \
    "rad (PlanarArm: mechanism angle the stylus points for)", DERIVED)                        \
  X(finger1, 3, "ff1x ff1y ff1z", "N (finger 1 on handle)", DERIVED)                          \
  X(finger2, 3, "ff2x ff2y ff2z", "N (finger 2 on handle)", DERIVED)                          \
  X(grip_twist, 1, "grip_twist", "N·m (moment about the stylus the grip adds)", DERIVED)

namespace virtmech::sim {

/// A width of VM_LOG_TABLE: entries, or one per device (N) or mechanism (M) joint.
constexpr int kLogWidth1 = 1, kLogWidth3 = 3, kLogWidth6 = 6, kLogWidthN = -1, kLogWidthM = -2;

/// One row of VM_LOG_TABLE.
struct LogField {
  const char* field;
  int width;  //!< kLogWidth*
  const char* names;
  const char* units;
  bool derived;
};

/// The rows, in the log's order.
const std::vector<LogField>& log_fields();
/// A row's width for a device of n joints and a mechanism of m.
int log_width(const LogField& f, int n, int m);
/// A row's column names.
std::vector<std::string> log_names(const LogField& f, int n, int m);
/// Every column's name, in order: the log of a device of n joints and a mechanism of m.
std::vector<std::string> log_column_names(int n, int m);
/// (key, unit) of a row: its first column or prefix with its unit, or each key=unit.
std::vector<std::pair<std::string, std::string>> log_units(const LogField& f);

}  // namespace virtmech::sim
