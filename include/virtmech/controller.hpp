// The virtual-mechanism controller: one servo cycle turns device joint state into joint
// torques (paper eqs. 11 and 26 in their six-degree-of-freedom form, plus safety).
//
// Model / workspace split (as Pinocchio's Model / Data): ControllerModel is the immutable,
// validated configuration (every default resolved); ControllerData holds every buffer and
// all state the cycle updates (both placements, the ramp counter), allocated once. The
// cycle is a straight line of named stages over the two (src/controller.cpp):
//   check_input -> device_kinematics -> place (nearest, un-powered) -> wrench (eq. 26)
//   -> passivity (energy tank, src/passivity.cpp) -> keep_renderable -> safety -> outputs
//
// Threads: one Controller (and one MechanismSet) belongs to one thread at a time; its
// step(), place(), render() and the rest mutate its ControllerData and are not for
// concurrent calls. Devices, mechanisms and shapes are immutable once built: any number of
// controllers on any threads may share one (through the shared_ptr they hold), as may
// several threads read one ControllerModel. docs/theory.md, "Threads".
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>

#include "virtmech/device.hpp"
#include "virtmech/filters.hpp"
#include "virtmech/mechanism.hpp"
#include "virtmech/output_table.h"
#include "virtmech/passivity.hpp"
#include "virtmech/settings.hpp"
#include "virtmech/track.hpp"

namespace virtmech {

/// A bit of a status word and its name.
struct BitName {
  std::uint32_t bit;
  const char* name;
};

/// Status bits of a cycle. Bits below kFaultMask inform; a fault bit means zero torque.
namespace status {
constexpr std::uint32_t kOk = 0;
constexpr std::uint32_t kRamping = 1u << 0;         //!< force ramp-in in progress
constexpr std::uint32_t kForceClamped = 1u << 1;    //!< wrench scaled to the force limit
constexpr std::uint32_t kTorqueClamped = 1u << 2;   //!< torques scaled to the joint limits
constexpr std::uint32_t kNotConverged = 1u << 3;    //!< a placement hit its iteration cap
constexpr std::uint32_t kWatchdog = 1u << 4;        //!< cycle gap exceeded the watchdog
constexpr std::uint32_t kPassivity = 1u << 5;  //!< the energy tank held back some range term
constexpr std::uint32_t kSwitching = 1u << 6;  //!< a MechanismSet blends between two members
constexpr std::uint32_t kFaultNonFiniteInput = 1u << 8;   //!< q or dq not finite
constexpr std::uint32_t kFaultNonFiniteOutput = 1u << 9;  //!< computation produced NaN/inf
constexpr std::uint32_t kFaultBadSize = 1u << 10;         //!< q or dq of the wrong length
constexpr std::uint32_t kFaultOutOfRange = 1u << 11;      //!< q beyond the joint range + margin
/// dq beyond the device's fastest plausible speed + margin
constexpr std::uint32_t kFaultImplausibleVelocity = 1u << 12;
constexpr std::uint32_t kFaultMask = 0xFF00u;
/// Each bit's name, as Python's status_names() and the logs' readers spell it.
inline constexpr BitName kNames[] = {
    {kRamping, "ramping"},
    {kForceClamped, "force_clamped"},
    {kTorqueClamped, "torque_clamped"},
    {kNotConverged, "not_converged"},
    {kWatchdog, "watchdog"},
    {kPassivity, "passivity"},
    {kSwitching, "switching"},
    {kFaultNonFiniteInput, "fault_nonfinite_input"},
    {kFaultNonFiniteOutput, "fault_nonfinite_output"},
    {kFaultBadSize, "fault_bad_size"},
    {kFaultOutOfRange, "fault_out_of_range"},
    {kFaultImplausibleVelocity, "fault_implausible_velocity"}};
}  // namespace status

/// User settings, one member per row of VM_CONTROLLER_SETTINGS
/// (include/virtmech/settings_table.h: each row's unit, default, range and meaning); unset
/// optionals take the defaults of docs/theory.md, derived from the device and the mechanism.
struct ControllerSettings {
#define VM_SETTING_VEC6(name, unit, doc) std::optional<Vector6> name;
#define VM_SETTING_REAL(name, value, min, max, flags, unit, doc) double name = value;
#define VM_SETTING_INT(name, value, min, max, unit, doc) int name = value;
#define VM_SETTING_ENUM(name, Type, value, doc) Type name = static_cast<Type>(value);
  VM_CONTROLLER_SETTINGS(VM_SETTING_VEC6, VM_SETTING_REAL, VM_SETTING_INT, VM_SETTING_ENUM)
#undef VM_SETTING_VEC6
#undef VM_SETTING_REAL
#undef VM_SETTING_INT
#undef VM_SETTING_ENUM
};

/// Checks every setting against its row's range (std::invalid_argument naming the setting,
/// its range and the value). The Controller's constructor runs it first.
void check_settings(const ControllerSettings& settings);

/// The depth over which a joint at a limit takes hold [m]: its lock weight rises from 0 at
/// the bound to 1 at this depth (a contact's damping builds up with it instead of stepping
/// in as the tip touches).
constexpr double kLockDepthM = 1e-4;

/// The shortest force ramp-in after a fault or a watchdog trip [s], whatever ramp_time_s.
constexpr double kMinimumFaultRampS = 0.05;

/// The shortest force ramp-in at the start that a device driver accepts [s] (DriverServo):
/// a shorter ramp_time_s puts the force on a hand as a step (one period: the whole force on
/// the first tick). 20 periods at 1 kHz: the Omni's 3.3 N rises at most 165 N/s.
constexpr double kMinimumDeviceRampS = 0.02;

/// The validated configuration with every default resolved.
struct ControllerModel {
  Vector6 kp, kv, w_a, w_e, w_e_star;
  Vector6 w_e_effective;       //!< W_e + secondary_weight * U, as the solver uses it
  Vector6 w_e_star_effective;  //!< W_e* + secondary_weight * U
  /// 1 / w_e_effective (1 / w_e_star_effective) where every weight is > 0, else all 0: the
  /// placement's rate from a mechanism's constraint wrench needs the weights invertible
  Vector6 w_e_inverse, w_e_star_inverse;
  int w_a_support = 0;         //!< task axes W_A weighs (> 0)
  /// W_A is a multiple of W_e + secondary_weight * U (same zeros, ratios equal to rounding)
  /// and the error velocity is kRelative: P(W_A) at the nearest placement is the projector
  /// of its rate, factorised once (P(c W) = P(W)).
  bool w_a_shares_rate = false;
  double length_scale = 0.1;
  ControlLaw law = ControlLaw::kAuto;
  bool under_actuated_term = false;  //!< eq. 26's range-space term is evaluated
  ErrorVelocity error_velocity = ErrorVelocity::kRelative;
  double period_s = 1e-3;
  long ramp_cycles = 1;        //!< the ramp-in after the start [cycles]
  long fault_ramp_cycles = 1;  //!< the ramp-in after a fault or a watchdog trip [cycles]
  double watchdog_s = 0.0;
  double max_force = kInf, max_torque = kInf;
  TrackOptions track, track_initial;
  std::array<bool, 6> renderable{};  //!< task axes the passive joints never move
  JointVector q_min, q_max;          //!< plausible q: the device's range widened by the margin
  JointVector dq_max;                //!< plausible |dq|: the device's speeds plus the margin
  Passivity passivity = Passivity::kEnergyTank;
  double passivity_max_energy = 0.001;  //!< [J]
  double passivity_start_energy = 0.001;  //!< [J]
  double passivity_fade = 1e-6;         //!< [J]
  double passivity_budget = 0.0;        //!< [J]
  double passivity_fade_step = 0.02;    //!< largest change of the range term's factor a cycle
  JointVector passivity_play;           //!< the observer's play per joint [rad or m]
};

/// Everything one cycle reports, one member per row of VM_CYCLE_OUTPUT
/// (include/virtmech/output_table.h: each field's meaning, shape and unit). Fixed-capacity
/// members: copying never allocates.
struct CycleOutput {
#define VM_OUT_JOINTS(name, doc) JointVector name;
#define VM_OUT_VEC6(name, doc) Vector6 name = Vector6::Zero();
#define VM_OUT_POSE(name, doc) Pose name = Pose::Identity();
#define VM_OUT_LOCKS(name, of, doc) std::uint32_t name = 0;
#define VM_OUT_INT(name, doc) int name = 0;
#define VM_OUT_REAL(name, value, doc) double name = value;
#define VM_OUT_BITS(name, doc) std::uint32_t name = status::kOk;
  VM_CYCLE_OUTPUT(VM_OUT_JOINTS, VM_OUT_VEC6, VM_OUT_POSE, VM_OUT_LOCKS, VM_OUT_INT, VM_OUT_REAL,
                  VM_OUT_BITS)
#undef VM_OUT_JOINTS
#undef VM_OUT_VEC6
#undef VM_OUT_POSE
#undef VM_OUT_LOCKS
#undef VM_OUT_INT
#undef VM_OUT_REAL
#undef VM_OUT_BITS
};

/// One placement of the mechanism (eqs. 18-20) with its state: used twice per cycle, with
/// W_e (nearest) and with W_e* (un-powered, eq. 25).
struct Placement {
  JointVector theta;       //!< the placement
  JointVector theta_prev;  //!< the placement one cycle earlier (warm start)
  bool converged = false;  //!< the last placement converged
  bool extrapolate = false;  //!< ... and so did the one before it
  Pose pose = Pose::Identity();  //!< mechanism handle pose at theta
  Jacobian J;              //!< J_V at theta, every column
  /// pose_error(target, pose): X_R - X_V at theta, as the placement evaluated it (its
  /// residual's), so that the cycle need not compute it again
  Vector6 error = Vector6::Zero();
  Jacobian J_free;         //!< J_V without the columns of the active joints
  std::uint32_t active = 0;  //!< joints held at a limit that acts
  /// Each active joint's lock weight in [0, 1]: how far the cost presses it past its bound
  /// (|J_i^T W e| |J_i|_U / (J_i^T W J_i), a depth [m]) over kLockDepthM, at most 1: a limit
  /// takes hold continuously as the handle presses into it (docs/theory.md, 6)
  std::array<double, kMaxDof> lock{};
  std::uint32_t partial = 0;  //!< active joints with a lock weight below 1
  double partial_lock = 1.0;  //!< the least lock weight of those (1 where none)
  /// the mechanism's constraint wrench at theta for J_free (Mechanism::constraint_wrench):
  /// J_free^T wrench = 0, J_free of rank 5; has_wrench false where it has none
  bool has_wrench = false;
  Vector6 wrench = Vector6::Zero();
  TrackResult result;
};

/// Every buffer and all state of the cycle, allocated once (ControllerData(model, ...)).
struct ControllerData {
  Placement nearest, unpowered;
  Pose handle_pose = Pose::Identity();
  Jacobian J_R;     //!< device Jacobian at q
  Vector6 v_R;      //!< handle twist J_R dq
  /// What the null-space term's soft rank renders beyond N(W_A) with the rank's hard cut,
  /// (P - P_phi)(Kp e + Kv e_dot): the range term leaves it out (docs/theory.md, 6).
  Vector6 null_soft_excess = Vector6::Zero();
  // one projector per weighting, so that each keeps its weights' square roots
  WeightedProjector rate;         //!< sqrt(W_e) J_V at the nearest placement: its rate
  WeightedProjector rate_star;    //!< sqrt(W_e*) J_V at the un-powered placement: its rate
  WeightedProjector projector_a;  //!< P(W_A) / N(W_A) at the nearest placement
  WeightedProjector projector;    //!< P(W_A) at the un-powered placement; the renderable part
  WeightedProjector rate_partial; //!< a placement's rate with its partly locked joints free
  bool first = true;            //!< next cycle starts placements afresh
  long ramp_count = 0;
  long ramp_cycles = 1;         //!< the ramp-in in progress: its length [cycles]
  PassivityState passivity;     //!< the energy tank and its observer (src/passivity.cpp)
  double last_t = std::numeric_limits<double>::quiet_NaN();
  CycleOutput last;
  // the cycle between place() and render(): its joint values and rates, and its start
  JointVector q_cycle, dq_cycle;
  std::uint64_t cycle_start = 0;  // (the cycle clock's ticks)
};

/// The device's pose and Jacobian at one q (Device::forward_jacobian's outputs), computed
/// once for several controllers of the same device: a MechanismSet's members.
struct DeviceKinematics {
  Pose pose = Pose::Identity();
  Jacobian J;
};

/// The controller of one mechanism on one device. Not for concurrent use: one thread steps
/// it (a controller per thread); the device and mechanism it holds are immutable and may be
/// shared with controllers on other threads.
class Controller {
 public:
  /// Validates settings and allocates every buffer; throws std::invalid_argument.
  Controller(std::shared_ptr<const Device> device, std::shared_ptr<const Mechanism> mechanism,
             const ControllerSettings& settings = ControllerSettings());

  /// One servo cycle: q, dq (device joints, dof() each) in, out filled. t_s is the cycle's
  /// time stamp [s] for the watchdog (NaN: untimed). noexcept, allocation-free. Its
  /// arithmetic runs with subnormal numbers flushed to zero (x86 FTZ/DAZ, AArch64 FZ; no
  /// quantity of the cycle means anything at 1e-308, and one converging to an exact zero
  /// would otherwise slow every operation on it a hundredfold); the caller's floating-point
  /// mode is restored before it returns. place() and render() below do the same.
  std::uint32_t step(const double* q, const double* dq, CycleOutput& out,
                     double t_s = std::numeric_limits<double>::quiet_NaN()) noexcept;
  /// As above, with sizes checked (a wrong size is the fault kFaultBadSize).
  std::uint32_t step(const Eigen::Ref<const Eigen::VectorXd>& q,
                     const Eigen::Ref<const Eigen::VectorXd>& dq, CycleOutput& out,
                     double t_s = std::numeric_limits<double>::quiet_NaN()) noexcept;

  /// step() in two halves, for a caller that needs the placements of several controllers
  /// before it renders one (a MechanismSet): place() checks the input, runs the watchdog,
  /// the device's kinematics and both placements, and writes their outputs (theta,
  /// theta_star, the poses, the errors e and e*, iterations, residuals, the joints at a
  /// limit, kNotConverged); a faulted input ends the cycle there (the return value has a
  /// fault bit; out is complete). render(out) then computes the wrench and the torque
  /// (eqs. 11 / 26, passivity, what the device cannot render, safety) as step() does, and
  /// unrendered(out) ends the cycle without them: zero wrench and torque, the ramp-in
  /// advancing as if rendered. All three noexcept and allocation-free.
  std::uint32_t place(const double* q, const double* dq, CycleOutput& out,
                      double t_s = std::numeric_limits<double>::quiet_NaN()) noexcept;
  /// place() with the device's kinematics at q given: `at_q` must be
  /// device().forward_jacobian(q) (the same device object's), so that the result is
  /// place(q, dq, out, t_s)'s, bit for bit, without computing them again.
  std::uint32_t place(const double* q, const double* dq, const DeviceKinematics& at_q,
                      CycleOutput& out,
                      double t_s = std::numeric_limits<double>::quiet_NaN()) noexcept;
  std::uint32_t render(CycleOutput& out) noexcept;
  std::uint32_t unrendered(CycleOutput& out) noexcept;

  /// Restarts: placements from the mechanism's home, ramp-in from zero.
  void reset() noexcept;
  /// Restarts the energy tank and forgets its observer's history, as after a fault: for a
  /// cycle whose torque was not applied (a MechanismSet's members not rendered).
  void restart_energy() noexcept;
  /// The torque the motors really hold after the last step, when it is not the one that
  /// step returned (a MechanismSet blending two members): the energy tank books the work of
  /// this torque over its interval instead. tau: dof() entries. Does not allocate.
  void applied(const double* tau) noexcept;

  const Device& device() const noexcept { return *device_; }
  const Mechanism& mechanism() const noexcept { return *mechanism_; }
  std::shared_ptr<const Device> device_ptr() const noexcept { return device_; }
  std::shared_ptr<const Mechanism> mechanism_ptr() const noexcept { return mechanism_; }
  const ControllerModel& model() const noexcept { return model_; }
  const ControllerData& data() const noexcept { return data_; }
  const CycleOutput& last() const noexcept { return data_.last; }

 private:
  // place() and render() without setting the floating-point mode (step() sets it once)
  std::uint32_t place_cycle(const double* q, const double* dq, const DeviceKinematics* at_q,
                            CycleOutput& out, double t_s) noexcept;
  std::uint32_t render_cycle(CycleOutput& out) noexcept;
  std::uint32_t finish(CycleOutput& out) noexcept;  // the cycle's time; last()

  std::shared_ptr<const Device> device_;
  std::shared_ptr<const Mechanism> mechanism_;
  ControllerModel model_;
  ControllerData data_;
};

/// Resolves settings against a device and mechanism (what the Controller constructor does).
ControllerModel make_controller_model(const Device& device, const Mechanism& mechanism,
                                      const ControllerSettings& settings);

}  // namespace virtmech
