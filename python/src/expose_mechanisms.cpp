// Joints and mechanisms (include/virtmech/mechanism.hpp); each kind's constructor and
// parameters are its registry entry's (src/kinds/).
#include "expose.hpp"

namespace vmpy {

using namespace nb::literals;

/// dof, forward, forward_many, jacobian and the joint limits of a Mechanism or a Device.
template <class T>
void def_kinematics(nb::class_<T>& cls) {
  cls.def_prop_ro("dof", &T::dof, "Number of joints.")
      .def("forward", [](const T& self, nb::handle x) {
            Pose P;
            self.forward(joints_arg("x", x, self.dof()).data(), P);
            return Eigen::Matrix4d(P.matrix());
          }, "x"_a, "Handle pose (4, 4) at joint values x (dof,).")
      .def("forward_many", [](const T& self, nb::handle X) {
            const Array x = array_arg("X", X, {-1, self.dof()}, "m");
            const Eigen::Index rows = x.shape[0];
            Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor> poses(4 * rows, 4);
            Pose P;
            for (Eigen::Index r = 0; r < rows; ++r) {
              self.forward(x.data.data() + r * self.dof(), P);
              poses.middleRows<4>(4 * r) = P.matrix();
            }
            return nb::cast(poses).attr("reshape")(rows, 4, 4);
          }, "X"_a, "Handle poses (m, 4, 4) at the m rows of joint values X (m, dof).")
      .def("jacobian", [](const T& self, nb::handle x) {
            Pose P;
            Jacobian J;
            self.forward_jacobian(joints_arg("x", x, self.dof()).data(), P, J);
            return Eigen::MatrixXd(J);
          }, "x"_a,
          "Geometric Jacobian (6, dof) at x: rows [v; w], handle-origin linear velocity then "
          "angular velocity, world axes.")
      .def_prop_ro("lower", [](const T& self) { return Eigen::VectorXd(self.lower()); },
                   "Lower joint limits (dof,) [rad or m].")
      .def_prop_ro("upper", [](const T& self) { return Eigen::VectorXd(self.upper()); },
                   "Upper joint limits (dof,) [rad or m].")
      .def_prop_ro("home", [](const T& self) { return Eigen::VectorXd(self.home()); },
                   "Default joint values (dof,).")
      .def_prop_ro("joint_types", [](const T& self) {
            std::vector<std::string> out;
            for (int i = 0; i < self.dof(); ++i) out.push_back(name_of(self.joint_type(i)));
            return out;
          }, "'revolute' or 'prismatic' per joint.");
}

template void def_kinematics<Device>(nb::class_<Device>&);

namespace {

template <class T, class Base>
void def_mechanism(nb::module_& m, const char* name) {
  nb::class_<T, Base> cls(m, name, registry().mechanism(name)->doc.c_str());
  def_kind<T>(cls, registry().mechanism(name)->params, name, [name](Params p) {
    p.set("type", name);
    return make_mechanism(p, "");
  });
}

}  // namespace

void expose_mechanisms(nb::module_& m) {
  nb::class_<Joint>(m, "Joint", "One revolute or prismatic joint of a serial chain.")
      .def("__init__", [](Joint* self, const std::string& type, nb::handle axis, nb::handle origin,
                          double lower, double upper) {
            Joint j;
            j.type = enum_from_name<JointType>("type", type);
            j.axis = vector_arg("axis", axis, 3);
            if (!origin.is_none() && nb::len(origin) == 3) {
              j.origin = Pose::Identity();
              j.origin.translation() = vector_arg("origin", origin, 3);
            } else {
              j.origin = pose_arg("origin", origin);
            }
            j.lower = lower;
            j.upper = upper;
            new (self) Joint(j);
          }, "type"_a = "revolute", "axis"_a = nb::make_tuple(0.0, 0.0, 1.0), "origin"_a = nb::none(),
          "lower"_a = -kInf, "upper"_a = kInf,
          "A joint: type 'revolute' or 'prismatic'; axis (3,) in the joint frame; origin: pose "
          "(4, 4) or position (3,) of the joint frame in the previous frame at zero; limits "
          "[rad or m].")
      .def_prop_ro("type", [](const Joint& j) { return name_of(j.type); })
      .def_ro("axis", &Joint::axis)
      .def_prop_ro("origin", [](const Joint& j) { return Eigen::Matrix4d(j.origin.matrix()); })
      .def_ro("lower", &Joint::lower)
      .def_ro("upper", &Joint::upper)
      .def("__repr__", [](const Joint& j) {
        return "Joint(type='" + std::string(name_of(j.type)) + "', axis=" + format_vector(j.axis) +
               ", origin=" + format_vector(j.origin.translation()) + ")";
      });

  nb::class_<Mechanism> mech(m, "Mechanism", "A virtual mechanism (base class).");
  def_kinematics(mech);
  mech.def_prop_ro("type", &Mechanism::type_name)
      .def_prop_ro("length_scale", &Mechanism::length_scale,
                   "Characteristic length [m] weighting rotations against translations.")
      .def_prop_ro("contact_joint", &Mechanism::contact_joint,
                   "The lift-off joint of a unilateral mechanism (held at its lower limit 0 "
                   "while in contact), or -1.")
      .def("to_dict", [](const Mechanism& self) { return to_python(describe(self)); },
           "The mechanism's parameters ('type' first) as a JSON-ready dict (its kind's).");
  nb::class_<ChainMechanism, Mechanism>(m, "ChainMechanism",
                                        "A mechanism that is a serial chain (base class).")
      .def_prop_ro("joints", [](const ChainMechanism& self) { return self.chain().joints(); });

  def_mechanism<PlanarArm, ChainMechanism>(m, "PlanarArm");
  def_mechanism<Probe, ChainMechanism>(m, "Probe");
  def_mechanism<PointPivot, ChainMechanism>(m, "PointPivot");
  def_mechanism<LineGuide, ChainMechanism>(m, "LineGuide");
  def_mechanism<SurfaceProbe, Mechanism>(m, "SurfaceProbe");
  def_mechanism<CurveGuide, Mechanism>(m, "CurveGuide");
  def_mechanism<HandlePath, Mechanism>(m, "HandlePath");

  nb::class_<SerialChain, ChainMechanism>(
      m, "SerialChain", "Any serial chain of revolute / prismatic joints as a mechanism.")
      .def("__init__", [](SerialChain* self, std::vector<Joint> joints, nb::handle handle,
                          nb::handle base, double length_scale) {
            new (self) SerialChain(rebuildable(SerialChain(
                joints, pose_arg("handle", handle), pose_arg("base", base), length_scale)));
          }, "joints"_a, "handle"_a = nb::none(), "base"_a = nb::none(), "length_scale"_a = 0.1,
          "joints: sequence of Joint; handle, base: (4, 4) poses; length_scale [m].");
}

}  // namespace vmpy
