// A plugin adding one kind, "RingArm": a PlanarArm of its own class (a subclass living in
// the plugin, with the plugin's own copy of the core), for the registry's tests.
#include "virtmech/registry.hpp"

namespace {

using namespace virtmech;

class RingArm final : public ChainMechanism {
 public:
  explicit RingArm(double radius)
      : ChainMechanism("RingArm", arm(radius), radius, JointVector::Zero(1)), radius_(radius) {}
  double radius() const noexcept { return radius_; }

 private:
  static KinematicChain arm(double radius) {
    Joint j;
    j.axis = Eigen::Vector3d::UnitZ();
    Pose handle = Pose::Identity();
    handle.translation() << radius, 0.0, 0.0;
    return KinematicChain(Pose::Identity(), {j}, handle);
  }
  double radius_;
};

void add_ring(Registry& r) {
  MechanismKind k;
  k.name = "RingArm";
  k.doc = "the handle on a circle of `radius` about the origin in the x-y plane";
  k.params = {number_param("radius", 0.1, 0.0, 1.0, "m", "the circle's radius", true)};
  k.type = typeid(RingArm);
  k.make = [](const Params& p) { return std::make_shared<const RingArm>(p.number("radius")); };
  k.describe = [](const Mechanism& m) {
    return Params("RingArm").set("radius", static_cast<const RingArm&>(m).radius());
  };
  k.distance = [](const Mechanism& m, const Eigen::Vector3d& p, const Eigen::Vector3d&) {
    const double radial = p.head<2>().norm() - static_cast<const RingArm&>(m).radius();
    return Distances{std::hypot(radial, p.z()), radial, p.z(), radial};
  };
  r.add(std::move(k));
}

}  // namespace

VIRTMECH_PLUGIN(add_ring)
