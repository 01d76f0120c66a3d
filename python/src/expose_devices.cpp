// Devices (include/virtmech/device.hpp). The Omni's and the Cartesian devices' constructors
// and parameters are their kinds' (src/kinds/phantom_omni.cpp, cartesian_device.cpp); a
// serial-chain device and the Planar3R take a chain and poses as C++ does, and refuse what
// their kinds refuse (rebuildable()).
#include "expose.hpp"

namespace vmpy {

using namespace nb::literals;

template <class T>
void def_kinematics(nb::class_<T>& cls);  // expose_mechanisms.cpp

namespace {

void expose_device_base(nb::module_& m) {
  nb::class_<Device> dev(m, "DeviceBase", "A haptic device (interface): kinematics, actuation and limits.");
  def_kinematics(dev);
  dev.def_prop_ro("name", &Device::name)
      .def_prop_ro("actuated", [](const Device& d) {
            std::vector<bool> a;
            for (int i = 0; i < d.dof(); ++i) a.push_back(d.actuated(i));
            return nb::module_::import_("numpy").attr("array")(a);
          }, "Actuation mask (dof,) of bool.")
      .def_prop_ro("torque_limit", [](const Device& d) { return Eigen::VectorXd(d.torque_limit()); },
                   "Joint torque limits (dof,) [N·m or N]; 0 for passive joints.")
      .def_prop_ro("max_force", &Device::max_force, "[N]")
      .def_prop_ro("max_torque", &Device::max_torque, "[N·m]")
      .def_prop_ro("max_velocity", [](const Device& d) { return Eigen::VectorXd(d.max_velocity()); },
                   "Fastest plausible joint speeds (dof,) [rad/s or m/s]: a faster dq is a "
                   "fault (beyond the controller's velocity margin).")
      .def_prop_ro("stiffness", &Device::stiffness, "Default translational Kp [N/m].")
      .def_prop_ro("damping", &Device::damping, "Default translational Kv [N·s/m].")
      .def("to_dict", [](const Device& self) { return to_python(describe(self)); },
           "The device's description ('type' first) as a JSON-ready dict (its kind's).");
}

void expose_serial_device(nb::module_& m) {
  nb::class_<SerialDevice, Device>(
      m, "Device",
      "A serial-chain device (C++ SerialDevice) with any actuation mask; every device shares "
      "DeviceBase.")
      .def("__init__", [](SerialDevice* self, std::vector<Joint> joints, std::vector<bool> actuated,
                          nb::handle handle, nb::handle base, nb::handle torque_limit,
                          double max_force, double max_torque, double stiffness, double damping,
                          const std::string& name, nb::handle coupling, nb::handle coupling_offset) {
            const long n = static_cast<long>(joints.size());
            DeviceLimits L;
            L.actuated = actuated;
            if (!torque_limit.is_none()) {
              const Eigen::VectorXd t = vector_arg("torque_limit", torque_limit, n);
              L.torque_limit.assign(t.data(), t.data() + n);
            }
            L.max_force = max_force;
            L.max_torque = max_torque;
            L.stiffness = stiffness;
            L.damping = damping;
            const KinematicChain chain(pose_arg("base", base), joints, pose_arg("handle", handle));
            if (coupling.is_none() && coupling_offset.is_none()) {
              new (self) SerialDevice(rebuildable(SerialDevice(name, chain, L)));
              return;
            }
            const JointMatrix C = coupling.is_none() ? JointMatrix(JointMatrix::Identity(n, n))
                                                     : JointMatrix(matrix_arg("coupling", coupling, n, n));
            const JointVector c0 = coupling_offset.is_none()
                                       ? JointVector(JointVector::Zero(n))
                                       : JointVector(vector_arg("coupling_offset", coupling_offset, n));
            new (self) SerialDevice(rebuildable(SerialDevice(name, chain, L, C, c0)));
          }, "joints"_a, "actuated"_a, "handle"_a = nb::none(), "base"_a = nb::none(),
          "torque_limit"_a = nb::none(), "max_force"_a = kInf, "max_torque"_a = kInf,
          "stiffness"_a = DeviceLimits().stiffness, "damping"_a = DeviceLimits().damping,
          "name"_a = "SerialDevice", "coupling"_a = nb::none(), "coupling_offset"_a = nb::none(),
          "A serial-chain device with any actuation mask. joints: sequence of Joint; actuated: one "
          "bool per joint; torque_limit (dof,) [N·m or N]; max_force [N]; max_torque [N·m]; "
          "stiffness [N/m] and damping [N·s/m]: the default translational gains; coupling C (dof, "
          "dof) and coupling_offset c0 (dof,): the device's joints q map to the chain's as s = C q "
          "+ c0 (default: the chain's own).")
      .def_prop_ro("joints", [](const SerialDevice& d) { return d.chain().joints(); },
                   "The joints of the underlying chain (in chain coordinates).")
      .def_prop_ro("base", [](const SerialDevice& d) { return Eigen::Matrix4d(d.chain().base().matrix()); },
                   "The chain's base pose (4, 4): the first joint's frame is base @ joints[0].origin.")
      .def_prop_ro("handle", [](const SerialDevice& d) { return Eigen::Matrix4d(d.chain().handle().matrix()); },
                   "The handle frame (4, 4) in the last joint's frame.")
      .def_prop_ro("coupling", [](const SerialDevice& d) { return Eigen::MatrixXd(d.coupling()); },
                   "C (dof, dof) of the joint map s = C q + c0 from device to chain coordinates.")
      .def_prop_ro("coupling_offset", [](const SerialDevice& d) { return Eigen::VectorXd(d.coupling_offset()); },
                   "c0 (dof,) of the joint map s = C q + c0.");
}

void expose_omni_and_planar3r(nb::module_& m) {
  const DeviceKind& omni_kind = *registry().device("PhantomOmni");
  nb::class_<PhantomOmni, SerialDevice> omni(m, "PhantomOmni", omni_kind.doc.c_str());
  def_kind<PhantomOmni>(omni, omni_kind.params, "PhantomOmni", [](Params p) {
    p.set("type", "PhantomOmni");
    return make_device(p, "");
  });

  nb::class_<Planar3R, SerialDevice>(m, "Planar3R", registry().device("Planar3R")->doc.c_str())
      .def("__init__", [](Planar3R* self, double link1, double link2, nb::handle base,
                          double torque_limit, double max_force) {
            new (self) Planar3R(rebuildable(
                Planar3R(link1, link2, pose_arg("base", base), torque_limit, max_force)));
          }, "link1"_a = Planar3RDefaults::kLink, "link2"_a = Planar3RDefaults::kLink,
          "base"_a = nb::none(), "torque_limit"_a = Planar3RDefaults::kTorqueLimit,
          "max_force"_a = Planar3RDefaults::kMaxForce,
          "link1, link2 [m]; base (4, 4); torque_limit [N·m]; max_force [N].")
      .def_prop_ro("link1", &Planar3R::link1)
      .def_prop_ro("link2", &Planar3R::link2);
}

void expose_cartesian_device(nb::module_& m) {
  const DeviceKind& cartesian_kind = *registry().device("CartesianDevice");
  nb::class_<CartesianDevice, SerialDevice> cartesian(m, "CartesianDevice",
                                                       cartesian_kind.doc.c_str());
  def_kind<CartesianDevice>(cartesian, cartesian_kind.params, "CartesianDevice", [](Params p) {
    p.set("type", "CartesianDevice");
    return make_device(p, "");
  });
  cartesian
      .def_prop_ro("orientation_sensed", &CartesianDevice::orientation_sensed,
                   "True where the wrist's rotation is read (6 coordinates; else 3).")
      .def_prop_ro("torque_actuated", &CartesianDevice::torque_actuated,
                   "True where the wrist is driven (the device renders a torque).")
      .def_prop_ro("gripper", [](const CartesianDevice& d) { return d.model().gripper; },
                   "True where the device has an actuated gripper.")
      .def("coordinates", [](const CartesianDevice& d, nb::handle p, nb::handle R,
                             nb::handle previous) {
            Eigen::VectorXd q(d.dof());
            Eigen::VectorXd prev;
            if (!previous.is_none()) prev = vector_arg("previous", previous, d.dof());
            d.coordinates(vector_arg("p", p, 3), matrix_arg("R", R, 3, 3),
                          previous.is_none() ? nullptr : prev.data(), q.data());
            return q;
          }, "p"_a, "R"_a, "previous"_a = nb::none(),
          "Coordinates (dof,) of the SDK's position p (3,) [m] and rotation R (3, 3); the angles "
          "on the branch nearest `previous` (dof,).")
      .def("sdk_pose", [](const CartesianDevice& d, nb::handle q) {
            const Eigen::VectorXd x = vector_arg("q", q, d.dof());
            Eigen::Vector3d p;
            Eigen::Matrix3d R;
            d.sdk_pose(x.data(), p, R);
            return nb::make_tuple(p, R);
          }, "q"_a, "(p (3,) [m], R (3, 3)): the SDK's reading at coordinates q.")
      .def("rates", [](const CartesianDevice& d, nb::handle q, nb::handle v, nb::handle w) {
            const Eigen::VectorXd x = vector_arg("q", q, d.dof());
            Eigen::VectorXd dq(d.dof());
            if (!d.rates(x.data(), vector_arg("v", v, 3), vector_arg("w", w, 3), dq.data())) {
              throw std::invalid_argument("q: at the gimbal lock (cos b = 0): no angle rates");
            }
            return dq;
          }, "q"_a, "v"_a, "w"_a,
          "Coordinate rates (dof,) of the SDK's linear v [m/s] and angular w [rad/s] velocity.")
      .def("wrench", [](const CartesianDevice& d, nb::handle q, nb::handle tau) {
            const Eigen::VectorXd x = vector_arg("q", q, d.dof());
            const Eigen::VectorXd t = vector_arg("tau", tau, d.dof());
            Eigen::Vector3d f, mo;
            if (!d.wrench(x.data(), t.data(), f, mo)) {
              throw std::invalid_argument("q: at the gimbal lock (cos b = 0): no torque");
            }
            Eigen::VectorXd out(6);
            out << f, mo;
            return out;
          }, "q"_a, "tau"_a,
          "The handle wrench (6,) [N; N·m] whose coordinate torques are tau: J^T w = tau.");
  cartesian.attr("MODELS") = nb::module_::import_("builtins").attr("tuple")(
      nb::cast(cartesian_model_names()));
}

}  // namespace

void expose_devices(nb::module_& m) {
  expose_device_base(m);
  expose_serial_device(m);
  expose_omni_and_planar3r(m);
  expose_cartesian_device(m);
}

}  // namespace vmpy
