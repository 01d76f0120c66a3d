// The Cartesian devices (CartesianDevice: Force Dimension omega.3/6/7, sigma.7; the Novint
// Falcon) as a kind: the model by name, the handle frame's rotation in the SDK's
// end-effector frame as a rotation vector.
#include "kinds.hpp"
#include "virtmech/cartesian_device.hpp"
#include "virtmech/se3.hpp"

namespace virtmech::kinds {

void add_cartesian_device(Registry& r) {
  const Eigen::Vector3d handle = so3_log(default_cartesian_handle_rotation());
  DeviceKind k;
  k.name = "CartesianDevice";
  k.doc = "A Cartesian device (Force Dimension omega.3/6/7, sigma.7; Novint Falcon): its SDK "
          "serves the handle's pose and takes a wrench. Coordinates: position (x, y, z) [m] in "
          "the SDK's base frame, then, where the wrist's rotation is sensed, (a, b, c) [rad] "
          "with R_sdk = Rx(a) Ry(b) Rz(c) (docs/devices.md, \"Cartesian devices\").";
  k.params = {
      string_param("model", std::nullopt, cartesian_model_names(),
                   "the device model: its coordinates, actuation, workspace and limits"),
      array_param("handle_rotation", {3}, std::vector<double>{handle[0], handle[1], handle[2]},
                  "rad",
                  "the handle frame's rotation vector in the SDK's end-effector frame "
                  "(default: the stylus along its -z)")};
  k.type = typeid(CartesianDevice);
  k.make = [](const Params& p) {
    return std::make_shared<const CartesianDevice>(p.string("model"),
                                                   so3_exp(p.vector3("handle_rotation")));
  };
  k.describe = [](const Device& dev) {
    const auto& d = static_cast<const CartesianDevice&>(dev);
    return Params("CartesianDevice")
        .set("model", d.model().name.c_str())
        .set("handle_rotation", Eigen::Vector3d(so3_log(d.handle_rotation())));
  };
  r.add(std::move(k));
}

}  // namespace virtmech::kinds
