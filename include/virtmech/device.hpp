// Haptic devices: joint-space kinematics of the real robot the user holds, which joints
// have motors, and the limits the safety layer enforces.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "virtmech/kinematic_chain.hpp"

namespace virtmech {

/// Everything a device model declares besides its kinematics.
struct DeviceLimits {
  std::vector<bool> actuated;        //!< one flag per joint: true if a motor drives it
  std::vector<double> torque_limit;  //!< per joint [N·m or N]; passive joints: ignored
  std::vector<double> lower;         //!< joint limits in device coordinates [rad or m]
  std::vector<double> upper;
  double max_force = kInf;           //!< largest force the handle may receive [N]
  double max_torque = kInf;          //!< largest moment the handle may receive [N·m]
  /// Fastest plausible joint speed, per joint [rad/s or m/s] (inf: unchecked); empty: the
  /// defaults kMaxSpeedRevolute and kMaxSpeedPrismatic by joint kind. A controller faults on
  /// a dq beyond it plus its margin.
  std::vector<double> max_velocity;
  double stiffness = 500.0;          //!< default translational Kp [N/m]
  double damping = 1.0;              //!< default translational Kv [N·s/m]
};

/// Default fastest plausible speed of a revolute joint [rad/s]: a hand's fastest strokes
/// turn a desktop device's joints at up to about 10 rad/s, a falling stylus swings its
/// gimbal at up to about 12 rad/s (measured on the simulated Omni).
constexpr double kMaxSpeedRevolute = 25.0;
/// Default fastest plausible speed of a prismatic joint [m/s] (a hand's fastest strokes).
constexpr double kMaxSpeedPrismatic = 2.5;

/// A haptic device (interface): joint count and kinds, which joints have motors, the
/// limits the safety layer enforces, and the handle pose with its geometric Jacobian with
/// respect to the device's own joint coordinates. A new device (a parallel one, a
/// driver with its own conventions) is one subclass overriding forward_jacobian. A device is
/// immutable once built (every query is const and writes nothing): controllers on any
/// number of threads may share one.
class Device {
 public:
  virtual ~Device() = default;

  const std::string& name() const noexcept { return name_; }
  int dof() const noexcept { return dof_; }
  /// Kind of joint i (0 <= i < dof()): revolute [rad] or prismatic [m].
  JointType joint_type(int i) const noexcept { return kinds_[static_cast<size_t>(i)]; }
  bool actuated(int i) const noexcept { return actuated_[static_cast<size_t>(i)]; }
  int num_actuated() const noexcept { return num_actuated_; }
  bool fully_actuated() const noexcept { return num_actuated_ == dof(); }
  const JointVector& torque_limit() const noexcept { return torque_limit_; }
  /// Joint range in the device's coordinates [rad or m]; -inf / +inf where unlimited.
  const JointVector& lower() const noexcept { return lower_; }
  const JointVector& upper() const noexcept { return upper_; }
  const JointVector& home() const noexcept { return home_; }
  /// Fastest plausible joint speeds [rad/s or m/s] (DeviceLimits::max_velocity).
  const JointVector& max_velocity() const noexcept { return max_velocity_; }
  double max_force() const noexcept { return max_force_; }
  double max_torque() const noexcept { return max_torque_; }
  double stiffness() const noexcept { return stiffness_; }
  double damping() const noexcept { return damping_; }

  /// Handle pose at device joint values q (dof() entries). The default evaluates
  /// forward_jacobian; override it when the pose alone is cheaper.
  virtual void forward(const double* q, Pose& T) const noexcept;
  /// Handle pose and geometric Jacobian (6 x dof(), rows [v; w], world axes) with respect
  /// to the device's joints q.
  virtual void forward_jacobian(const double* q, Pose& T, Jacobian& J) const noexcept = 0;

 protected:
  /// Validates and stores the description; throws std::invalid_argument naming the bad
  /// field. Empty `limits.lower` / `upper` mean unlimited joints.
  Device(std::string name, const std::vector<JointType>& kinds, const DeviceLimits& limits);
  void set_home(const JointVector& home);

 private:
  std::string name_;
  int dof_ = 0;
  std::array<JointType, kMaxDof> kinds_{};
  std::array<bool, kMaxDof> actuated_{};
  int num_actuated_ = 0;
  JointVector torque_limit_, lower_, upper_, home_, max_velocity_;
  double max_force_ = kInf, max_torque_ = kInf, stiffness_ = 500.0, damping_ = 1.0;
};

/// A device that is a serial kinematic chain in "serial" coordinates s = C q + c0 of the
/// device's own joint coordinates q (C lets a parallelogram or a driver's sign / offset
/// convention be expressed exactly).
class SerialDevice : public Device {
 public:
  /// A device whose joint coordinates are the chain's own (C = I, c0 = 0); joint limits
  /// default to the chain's.
  SerialDevice(std::string name, const KinematicChain& chain, const DeviceLimits& limits);
  /// A device with a linear joint map s = C q + c0 to the chain's coordinates.
  SerialDevice(std::string name, const KinematicChain& chain, const DeviceLimits& limits,
               const JointMatrix& coupling, const JointVector& coupling_offset);

  const KinematicChain& chain() const noexcept { return chain_; }
  const JointMatrix& coupling() const noexcept { return coupling_; }
  const JointVector& coupling_offset() const noexcept { return coupling_offset_; }

  void forward(const double* q, Pose& T) const noexcept override;
  void forward_jacobian(const double* q, Pose& T, Jacobian& J) const noexcept override;

 private:
  void to_serial(const double* q, JointVector& s) const noexcept;

  KinematicChain chain_;
  JointMatrix coupling_;
  JointVector coupling_offset_;
  bool coupled_ = false;
  // C's non-zero entries by column: column j's are coupling_row_ / coupling_value_
  // [coupling_start_[j], coupling_start_[j + 1])
  std::array<int, kMaxDof + 1> coupling_start_{};
  std::array<int, kMaxDof * kMaxDof> coupling_row_{};
  std::array<double, kMaxDof * kMaxDof> coupling_value_{};
};

/// Parameters of the PHANTOM Omni / Geomagic Touch model (defaults and their sources:
/// docs/devices.md).
struct PhantomOmniParams {
  double l1 = 0.13335;  //!< upper arm [m] (commonly cited 133.35 mm; check)
  double l2 = 0.13335;  //!< forearm [m]
  double max_force = 3.3;  //!< peak force at the handle [N]
  /// Motor torque limits [N·m]: peak force times link length (an estimate; check).
  std::array<double, 3> motor_torque_limit{{0.44, 0.44, 0.44}};
  /// Gimbal angles as the driver reports them map to virtmech's as
  /// g_vm = sign * (g_driver - offset). Defaults: the driver already speaks virtmech's.
  std::array<double, 3> gimbal_offset{{0.0, 0.0, 0.0}};
  std::array<double, 3> gimbal_sign{{1.0, 1.0, 1.0}};
  /// default Kp [N/m]: 1.2 N/mm, between the datasheet's stiffness along z and x (1.02,
  /// 1.26 N/mm) and at most half the smallest Kp at which any hand of the grid or a released
  /// handle limit-cycles on the simulated Omni (docs/quality.md)
  double stiffness = 1200.0;
  double damping = 1.0;      //!< default Kv [N·s/m]
};

/// The PHANTOM Omni / Geomagic Touch: 6 joints in OpenHaptics order and conventions
/// (waist t1, shoulder t2, absolute elbow t3 as HD_CURRENT_JOINT_ANGLES; gimbal yaw, pitch,
/// roll). Waist, shoulder, elbow are actuated; the gimbal is passive and its three axes
/// meet at the gimbal centre, the handle origin. World frame: OpenHaptics axes (+x right,
/// +y up, +z toward the user), in metres, origin where the gimbal centre is at t = 0.
/// Gimbal zero: stylus horizontal, pointing away from the user (-z). See docs/devices.md.
class PhantomOmni final : public SerialDevice {
 public:
  explicit PhantomOmni(const PhantomOmniParams& params = PhantomOmniParams());
  const PhantomOmniParams& params() const noexcept { return params_; }

  /// The chain's pose and Jacobian written out for this geometry (the servo cycle's first
  /// stage): the same values as the chain walk through the coupling, to rounding.
  void forward(const double* q, Pose& T) const noexcept override;
  void forward_jacobian(const double* q, Pose& T, Jacobian& J) const noexcept override;

 private:
  void kinematics(const double* q, Pose& T, Jacobian* J) const noexcept;

  PhantomOmniParams params_;
};

/// Defaults of the Planar3R model (one place: the C API and the bindings use them).
struct Planar3RDefaults {
  static constexpr double kLink = 0.2;         //!< link1 = link2 [m]
  static constexpr double kTorqueLimit = 1.0;  //!< actuated joints [N·m]
  static constexpr double kMaxForce = 5.0;     //!< [N]
};

/// The paper's Fig. 8 robot: three revolute joints about the base z axis, in the base's
/// x-y plane; links `link1`, `link2`; the handle origin on the third (distal, un-powered)
/// joint, the stylus in the plane at angle q0 + q1 + q2 from the base x axis.
class Planar3R final : public SerialDevice {
 public:
  Planar3R(double link1, double link2, const Pose& base, double torque_limit, double max_force);
  double link1() const noexcept { return link1_; }
  double link2() const noexcept { return link2_; }

 private:
  double link1_, link2_;
};

}  // namespace virtmech
