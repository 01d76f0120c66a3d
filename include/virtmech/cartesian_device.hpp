// Cartesian haptic devices: devices whose SDK serves the handle's pose (a position and a
// rotation matrix) and takes a wrench (a force and a torque) rather than joint readings and
// joint torques. Force Dimension's omega.3, omega.6, omega.7 and sigma.7 and the Novint
// Falcon are such devices (docs/devices.md, "Cartesian devices").
//
// Coordinates: the handle's position (x, y, z) [m] in the SDK's base frame, then, on models
// that sense the wrist's rotation, three angles (a, b, c) [rad] with
//     R_sdk = Rx(a) Ry(b) Rz(c),
// the x-y-z gimbal parametrisation of the SDK's rotation matrix. The handle frame is the
// SDK's end-effector frame turned by a fixed handle rotation, so that its +z runs along the
// stylus. As a chain: three slides along x, y, z, then three revolute joints about x, y, z
// meeting at the handle origin. The Jacobian is exact for these coordinates: the linear
// rows the identity on the position, the angular rows the gimbal's axes; it is singular
// only at cos b = 0, outside every model's wrist range.
#pragma once

#include <string>
#include <vector>

#include "virtmech/device.hpp"

namespace virtmech {

/// What one Cartesian device model senses and drives, and its limits. The position range is
/// a box around the SDK's origin that holds the model's workspace; the angle ranges are its
/// wrist's. Which figures come from a source and which are simulation parameters:
/// docs/devices.md, "Cartesian devices".
struct CartesianModel {
  std::string name;             //!< "omega.3", "omega.6", "omega.7", "sigma.7" or "falcon"
  bool orientation_sensed;      //!< the wrist's rotation is read (6 coordinates; else 3)
  bool torque_actuated;         //!< the wrist is driven: the device renders a torque
  bool gripper;                 //!< the device has an actuated gripper (its force kept 0)
  double max_force;             //!< largest force at the handle [N]
  double max_torque;            //!< largest torque at the handle [N·m]; 0: none rendered
  Eigen::Vector3d position_lower, position_upper;  //!< workspace box [m]
  Eigen::Vector3d angle_lower, angle_upper;        //!< wrist range of (a, b, c) [rad]
  double stiffness;             //!< default translational Kp [N/m]
  double damping;               //!< default translational Kv [N·s/m]
};

/// Every model, in the order of cartesian_model_names().
const std::vector<CartesianModel>& cartesian_models();
/// The model called `name`; throws std::invalid_argument naming the key `model`, the value
/// and the names expected when there is none.
const CartesianModel& cartesian_model(const std::string& name);
/// The names of the models, e.g. for a message: "omega.3", "omega.6", ...
std::vector<std::string> cartesian_model_names();

/// The handle rotation of a Cartesian device by default: Rx(pi), the handle's +z (the
/// stylus) along the SDK end-effector frame's -z.
Eigen::Matrix3d default_cartesian_handle_rotation();

/// A Cartesian device: its model's coordinates, actuation and limits.
class CartesianDevice final : public SerialDevice {
 public:
  /// The device of model `model`; `handle_rotation` turns the SDK's end-effector frame into
  /// the handle frame (+z along the stylus). Throws std::invalid_argument naming `model` or
  /// `handle_rotation`.
  explicit CartesianDevice(const std::string& model,
                           const Eigen::Matrix3d& handle_rotation =
                               default_cartesian_handle_rotation());

  const CartesianModel& model() const noexcept { return model_; }
  const Eigen::Matrix3d& handle_rotation() const noexcept { return handle_rotation_; }
  bool orientation_sensed() const noexcept { return model_.orientation_sensed; }
  bool torque_actuated() const noexcept { return model_.torque_actuated; }

  /// The pose in closed form (the same values as the chain walk, to rounding).
  void forward(const double* q, Pose& T) const noexcept override;
  void forward_jacobian(const double* q, Pose& T, Jacobian& J) const noexcept override;

  /// Coordinates q (dof() entries) of the SDK's reading: position p [m] and end-effector
  /// rotation R_sdk; the angles on the branch nearest `previous` (dof() entries, each within
  /// pi of it; nullptr: nearest zero). Models without orientation ignore R_sdk.
  void coordinates(const Eigen::Vector3d& p, const Eigen::Matrix3d& R_sdk, const double* previous,
                   double* q) const noexcept;
  /// The SDK's reading at coordinates q: position p [m] and end-effector rotation R_sdk
  /// (the identity on models without orientation).
  void sdk_pose(const double* q, Eigen::Vector3d& p, Eigen::Matrix3d& R_sdk) const noexcept;
  /// Coordinate rates dq of the SDK's velocities: linear v [m/s] and angular w [rad/s] in
  /// base axes (w ignored without orientation). False at the gimbal lock (cos b = 0), dq
  /// then has the position's rates and zero angle rates.
  bool rates(const double* q, const Eigen::Vector3d& v, const Eigen::Vector3d& w,
             double* dq) const noexcept;
  /// The handle wrench whose coordinate torques are tau (J^T [f; m] = tau): force f [N] and
  /// torque m [N·m] in base axes (m = 0 without orientation). False at the gimbal lock (m
  /// then 0).
  bool wrench(const double* q, const double* tau, Eigen::Vector3d& f,
              Eigen::Vector3d& m) const noexcept;

 private:
  CartesianModel model_;
  Eigen::Matrix3d handle_rotation_;
};

}  // namespace virtmech
