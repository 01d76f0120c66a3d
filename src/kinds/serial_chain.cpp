// SerialChain as a kind: any serial chain of revolute and prismatic joints. It has no
// distance measure of its own (the log takes the placement's error), no named constrained
// directions and the generic drawing.
#include "kinds.hpp"

namespace virtmech::kinds {

void add_serial_chain(Registry& r) {
  MechanismKind k;
  k.name = "SerialChain";
  k.doc = "Any serial chain of revolute / prismatic joints as a mechanism.";
  k.params = {tables_param("joints", joint_fields(), "the chain's joints from its base"),
              point_param("handle", Eigen::Vector3d::Zero(),
                          "the handle's position in the last joint's frame [m]"),
              array_param("handle_rotation", {3}, std::vector<double>{0.0, 0.0, 0.0}, "rad",
                          "the handle's rotation vector in the last joint's frame"),
              point_param("base_position", Eigen::Vector3d::Zero(), "the chain's base [m]"),
              array_param("base_rotation", {3}, std::vector<double>{0.0, 0.0, 0.0}, "rad",
                          "the base's rotation vector"),
              number_param("length_scale", 0.1, 0.0, 10.0, "m",
                           "weighs rotations against translations", true)};
  k.type = typeid(SerialChain);
  k.make = [](const Params& p) {
    return std::make_shared<const SerialChain>(
        joints_from(p.tables("joints")), pose_from(p.vector3("handle"), p.vector3("handle_rotation")),
        pose_from(p.vector3("base_position"), p.vector3("base_rotation")), p.number("length_scale"));
  };
  k.describe = [](const Mechanism& m) {  // the kind's parameters: make() rebuilds it
    const auto& a = static_cast<const SerialChain&>(m);
    Params p("SerialChain");
    p.set("joints", describe_joints(a.chain().joints()));
    set_pose(p, "handle", "handle_rotation", a.chain().handle());
    set_pose(p, "base_position", "base_rotation", a.chain().base());
    return p.set("length_scale", a.length_scale());
  };
  r.add(std::move(k));
}

}  // namespace virtmech::kinds
