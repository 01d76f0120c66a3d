// The PHANTOM Omni as a kind: its parameters (PhantomOmniParams), and the same device with
// other joints actuated (a fully actuated variant to compare renderings with): its chain,
// joint map and limits, motors where asked.
#include "kinds.hpp"

namespace virtmech::kinds {

namespace {

std::vector<double> triple(const std::array<double, 3>& a) { return {a[0], a[1], a[2]}; }

const std::vector<bool> kOmniActuation = {true, true, true, false, false, false};

std::shared_ptr<const Device> make_omni(const Params& p) {
  PhantomOmniParams o;
  o.l1 = p.number("l1");
  o.l2 = p.number("l2");
  o.max_force = p.number("max_force");
  for (int i = 0; i < 3; ++i) {
    o.motor_torque_limit[static_cast<size_t>(i)] = p.vector("motor_torque_limit")[i];
    o.gimbal_offset[static_cast<size_t>(i)] = p.vector("gimbal_offset")[i];
    o.gimbal_sign[static_cast<size_t>(i)] = p.vector("gimbal_sign")[i];
  }
  o.stiffness = p.number("stiffness");
  o.damping = p.number("damping");
  auto omni = std::make_shared<const PhantomOmni>(o);
  const std::vector<bool>& actuated = p.bools("actuated");
  if (actuated == kOmniActuation) return omni;
  DeviceLimits L;
  L.actuated = actuated;
  for (size_t i = 0; i < 6; ++i) {
    const double limit = i < 3 ? o.motor_torque_limit[i] : p.number("gimbal_torque_limit");
    L.torque_limit.push_back(actuated[i] ? limit : 0.0);
  }
  L.max_force = o.max_force;
  L.stiffness = omni->stiffness();
  L.damping = omni->damping();
  const KinematicChain& chain = omni->chain();
  // the Omni's physical model and frame conventions: its name
  return std::make_shared<const SerialDevice>(
      "PhantomOmni", KinematicChain(chain.base(), chain.joints(), chain.handle()), L,
      omni->coupling(), omni->coupling_offset());
}

}  // namespace

void add_phantom_omni(Registry& r) {
  const PhantomOmniParams d;
  DeviceKind k;
  k.name = "PhantomOmni";
  k.doc = "PHANTOM Omni / Geomagic Touch: waist, shoulder, absolute elbow "
          "(HD_CURRENT_JOINT_ANGLES) actuated; gimbal yaw, pitch, roll passive, meeting at the "
          "handle origin. OpenHaptics axes in metres (docs/devices.md: the gimbal zero and "
          "offsets).";
  k.params = {
      number_param("l1", d.l1, 0.01, 1.0, "m", "upper arm"),
      number_param("l2", d.l2, 0.01, 1.0, "m", "forearm"),
      number_param("max_force", d.max_force, 0.0, 100.0, "N", "peak force at the handle", true),
      array_param("motor_torque_limit", {3}, triple(d.motor_torque_limit), "N·m",
                  "the three motors' torque limits"),
      array_param("gimbal_offset", {3}, triple(d.gimbal_offset), "rad",
                  "driver gimbal angles g map to virtmech's as sign (g - offset)"),
      array_param("gimbal_sign", {3}, triple(d.gimbal_sign), "", "+1 or -1 per gimbal joint"),
      number_param("stiffness", d.stiffness, 0.0, 1e6, "N/m", "default translational Kp"),
      number_param("damping", d.damping, 0.0, 1e4, "N·s/m", "default translational Kv"),
      bools_param("actuated", 6, kOmniActuation,
                  "6 true or false: which joints have a motor (a fully actuated variant: all "
                  "true)"),
      number_param("gimbal_torque_limit", 0.1, 0.0, 10.0, "N·m",
                   "torque limit of a gimbal joint made actuated", true)};
  k.type = typeid(PhantomOmni);
  k.make = make_omni;
  k.describe = [](const Device& dev) {
    const PhantomOmniParams& o = static_cast<const PhantomOmni&>(dev).params();
    return Params("PhantomOmni")
        .set("l1", o.l1)
        .set("l2", o.l2)
        .set("max_force", o.max_force)
        .set("motor_torque_limit", Array{{3}, triple(o.motor_torque_limit)})
        .set("gimbal_offset", Array{{3}, triple(o.gimbal_offset)})
        .set("gimbal_sign", Array{{3}, triple(o.gimbal_sign)})
        .set("stiffness", o.stiffness)
        .set("damping", o.damping);
  };
  r.add(std::move(k));
}

}  // namespace virtmech::kinds
