// Any serial-chain device ("Device", C++ SerialDevice) as a kind.
#include "kinds.hpp"

namespace virtmech::kinds {

void add_serial_device(Registry& r) {
  const DeviceLimits d;
  DeviceKind k;
  k.name = "Device";
  k.doc = "A serial-chain device with any actuation mask.";
  k.params = {
      tables_param("joints", joint_fields(), "the chain's joints from its base"),
      bools_param("actuated", -1, std::nullopt, "one true or false per joint"),
      optional(array_param("torque_limit", {-1}, std::nullopt, "N·m or N",
                           "one limit per joint; 0 where passive; none: no limit")),
      optional(number_param("max_force", std::nullopt, 0.0, 1000.0, "N", "force limit", true)),
      optional(number_param("max_torque", std::nullopt, 0.0, 1000.0, "N·m", "moment limit",
                            true)),
      number_param("stiffness", d.stiffness, 0.0, 1e6, "N/m", "default translational Kp"),
      number_param("damping", d.damping, 0.0, 1e4, "N·s/m", "default translational Kv"),
      point_param("handle", Eigen::Vector3d::Zero(), "the handle in the last joint's frame [m]"),
      array_param("handle_rotation", {3}, std::vector<double>{0.0, 0.0, 0.0}, "rad",
                  "its rotation vector"),
      point_param("base_position", Eigen::Vector3d::Zero(), "the chain's base [m]"),
      array_param("base_rotation", {3}, std::vector<double>{0.0, 0.0, 0.0}, "rad",
                  "its rotation vector"),
      string_param("name", std::string("SerialDevice"), {}, "the device's name"),
      optional(array_param("coupling", {-1, -1}, std::nullopt, "1",
                           "C of the joint map s = C q + c0 from the device's joints q to the "
                           "chain's s; none: the identity")),
      optional(array_param("coupling_offset", {-1}, std::nullopt, "rad or m",
                           "c0 of that map; none: zero"))};
  k.type = typeid(SerialDevice);
  k.make = [](const Params& p) {
    DeviceLimits L;
    L.actuated = p.bools("actuated");
    if (p.has("torque_limit")) {
      const Eigen::VectorXd t = p.vector("torque_limit");
      L.torque_limit.assign(t.data(), t.data() + t.size());
    }
    L.max_force = p.has("max_force") ? p.number("max_force") : kInf;
    L.max_torque = p.has("max_torque") ? p.number("max_torque") : kInf;
    L.stiffness = p.number("stiffness");
    L.damping = p.number("damping");
    const KinematicChain chain(pose_from(p.vector3("base_position"), p.vector3("base_rotation")),
                               joints_from(p.tables("joints")),
                               pose_from(p.vector3("handle"), p.vector3("handle_rotation")));
    if (!p.has("coupling") && !p.has("coupling_offset")) {  // the chain's joints and limits
      return std::make_shared<const SerialDevice>(p.string("name"), chain, L);
    }
    const int n = chain.dof();
    const JointMatrix C = p.has("coupling") ? JointMatrix(p.matrix("coupling"))
                                            : JointMatrix(JointMatrix::Identity(n, n));
    const JointVector c0 = p.has("coupling_offset") ? JointVector(p.vector("coupling_offset"))
                                                    : JointVector(JointVector::Zero(n));
    return std::make_shared<const SerialDevice>(p.string("name"), chain, L, C, c0);
  };
  k.describe = [](const Device& dev) {  // the kind's parameters: make() rebuilds it
    const auto& d = static_cast<const SerialDevice&>(dev);
    std::vector<bool> actuated;
    for (int i = 0; i < d.dof(); ++i) actuated.push_back(d.actuated(i));
    Params p("Device");
    p.set("joints", describe_joints(d.chain().joints())).set("actuated", actuated);
    // a limit is never left out where one joint has it (an infinite one then names itself)
    if (d.torque_limit().array().isFinite().any()) p.set_vector("torque_limit", d.torque_limit());
    if (std::isfinite(d.max_force())) p.set("max_force", d.max_force());  // none: no limit
    if (std::isfinite(d.max_torque())) p.set("max_torque", d.max_torque());
    p.set("stiffness", d.stiffness()).set("damping", d.damping());
    set_pose(p, "handle", "handle_rotation", d.chain().handle());
    set_pose(p, "base_position", "base_rotation", d.chain().base());
    p.set("name", d.name().c_str());
    if (d.coupling().isIdentity(0.0) && d.coupling_offset().isZero(0.0)) return p;  // none
    return p.set_matrix("coupling", d.coupling()).set_vector("coupling_offset", d.coupling_offset());
  };
  r.add(std::move(k));
}

}  // namespace virtmech::kinds
