// The paper's Fig. 8 robot (Planar3R) as a kind.
#include "kinds.hpp"

namespace virtmech::kinds {

void add_planar3r(Registry& r) {
  DeviceKind k;
  k.name = "Planar3R";
  k.doc = "The paper's Fig. 8 robot: three revolute joints about the base z axis; the distal "
          "joint un-powered; the handle origin on it, the stylus along angle q0 + q1 + q2.";
  k.params = {number_param("link1", Planar3RDefaults::kLink, 0.01, 2.0, "m", "first link"),
              number_param("link2", Planar3RDefaults::kLink, 0.01, 2.0, "m", "second link"),
              number_param("torque_limit", Planar3RDefaults::kTorqueLimit, 0.0, 1000.0, "N·m",
                           "the actuated joints' torque limit", true),
              number_param("max_force", Planar3RDefaults::kMaxForce, 0.0, 1000.0, "N",
                           "force limit", true),
              point_param("base_position", Eigen::Vector3d::Zero(), "the base [m]"),
              array_param("base_rotation", {3}, std::vector<double>{0.0, 0.0, 0.0}, "rad",
                          "the base's rotation vector")};
  k.type = typeid(Planar3R);
  k.make = [](const Params& p) {
    const Pose base = pose_from(p.vector3("base_position"), p.vector3("base_rotation"));
    return std::make_shared<const Planar3R>(p.number("link1"), p.number("link2"), base,
                                            p.number("torque_limit"), p.number("max_force"));
  };
  k.describe = [](const Device& dev) {
    const auto& d = static_cast<const Planar3R&>(dev);
    Params p("Planar3R");
    p.set("link1", d.link1())
        .set("link2", d.link2())
        .set("torque_limit", d.torque_limit()[0])
        .set("max_force", d.max_force());
    return set_pose(p, "base_position", "base_rotation", d.chain().base());
  };
  r.add(std::move(k));
}

}  // namespace virtmech::kinds
