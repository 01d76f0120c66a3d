// Python bindings: translation only. Inputs are converted with NumPy and their shapes
// checked here (so errors name the parameter); every rule lives in the C++ core.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <cmath>
#include <optional>
#include <sstream>
#include <string>

#include "virtmech/validate.hpp"
#include "virtmech/virtmech.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using namespace virtmech;

// python/src/bind_geometry.cpp: curves and surfaces
void bind_geometry(nb::module_& m);

namespace {

struct PlacementResult {
  JointVector theta;
  int iterations = 0;
  double residual = 0.0;
  bool converged = false;
  std::uint32_t active = 0;
};

Eigen::Matrix<bool, Eigen::Dynamic, 1> joint_mask(std::uint32_t bits, Eigen::Index n) {
  Eigen::Matrix<bool, Eigen::Dynamic, 1> a(n);
  for (Eigen::Index i = 0; i < n; ++i) a[i] = ((bits >> i) & 1u) != 0;
  return a;
}

using Array1 = nb::ndarray<const double, nb::ndim<1>, nb::c_contig, nb::device::cpu>;

std::string short_repr(nb::handle h) {
  std::string s = nb::cast<std::string>(nb::repr(h));
  if (s.size() > 80) s = s.substr(0, 77) + "...";
  return s;
}

std::string shape_of(nb::handle a) { return nb::cast<std::string>(nb::repr(a.attr("shape"))); }

// a float64, C-contiguous NumPy array of `obj`, or a TypeError naming `name`
nb::object as_array(const char* name, nb::handle obj, const char* expected) {
  // leaked on purpose: must outlive the interpreter's finalisation
  static nb::object* asarray =
      new nb::object(nb::module_::import_("numpy").attr("ascontiguousarray"));
  if (obj.is_none()) {
    throw nb::type_error((std::string(name) + ": expected " + expected + ", got None").c_str());
  }
  try {
    return (*asarray)(obj, "dtype"_a = "float64");
  } catch (nb::python_error&) {
    throw nb::type_error(
        (std::string(name) + ": expected " + expected + ", got " + short_repr(obj)).c_str());
  }
}

Eigen::VectorXd to_vector(const char* name, nb::handle obj, long n) {
  const std::string expected =
      n >= 0 ? "an array of shape (" + std::to_string(n) + ",)" : std::string("a 1-D array");
  nb::object a = as_array(name, obj, expected.c_str());
  const auto nd = nb::cast<long>(a.attr("ndim"));
  const auto size = nb::cast<long>(a.attr("size"));
  if (nd != 1 || (n >= 0 && size != n)) {
    throw nb::value_error((std::string(name) + ": expected " + expected + ", got shape " +
                           shape_of(a) + " (" + short_repr(obj) + ")").c_str());
  }
  auto arr = nb::cast<Array1>(a);
  return Eigen::Map<const Eigen::VectorXd>(arr.data(), size);
}

Eigen::Vector3d to_vec3(const char* name, nb::handle obj) { return to_vector(name, obj, 3); }
Vector6 to_vec6(const char* name, nb::handle obj) { return to_vector(name, obj, 6); }

Eigen::MatrixXd to_matrix(const char* name, nb::handle obj, long rows, long cols) {
  std::ostringstream os;
  os << "an array of shape (" << rows << ", " << (cols >= 0 ? std::to_string(cols) : "n") << ")";
  nb::object a = as_array(name, obj, os.str().c_str());
  const auto nd = nb::cast<long>(a.attr("ndim"));
  if (nd != 2) {
    throw nb::value_error((std::string(name) + ": expected " + os.str() + ", got shape " +
                           shape_of(a)).c_str());
  }
  const auto shape = nb::cast<nb::tuple>(a.attr("shape"));
  const long r = nb::cast<long>(shape[0]), c = nb::cast<long>(shape[1]);
  if (r != rows || (cols >= 0 && c != cols)) {
    throw nb::value_error((std::string(name) + ": expected " + os.str() + ", got shape " +
                           shape_of(a)).c_str());
  }
  auto arr = nb::cast<nb::ndarray<const double, nb::ndim<2>, nb::c_contig, nb::device::cpu>>(a);
  Eigen::MatrixXd M(r, c);
  for (long i = 0; i < r; ++i)
    for (long j = 0; j < c; ++j) M(i, j) = arr.data()[i * c + j];
  return M;
}

Pose to_pose(const char* name, nb::handle obj) {
  Pose T;
  T.matrix() = to_matrix(name, obj, 4, 4);
  require_pose(name, T);
  return T;
}

double to_double(const char* name, nb::handle obj) {
  try {
    return nb::cast<double>(obj);
  } catch (...) {
    throw nb::type_error((std::string(name) + ": expected a number, got " + short_repr(obj)).c_str());
  }
}

Eigen::Vector3d opt_vec3(const char* name, nb::handle obj) {
  return obj.is_none() ? Eigen::Vector3d::Zero() : to_vec3(name, obj);
}

// joint values for a chain of `n` joints: fast path for float64 arrays, else converted
// A contiguous float64 buffer of n doubles (NumPy caches its buffer description, so after
// the first call on an array this allocates nothing); writable if asked. nullptr if obj is
// not one (the caller converts or raises).
struct DoubleBuffer {
  Py_buffer view{};
  bool ok = false;
  DoubleBuffer(nb::handle obj, int n, bool writable) {
    if (!PyObject_CheckBuffer(obj.ptr())) return;
    // a NumPy array says its type through dtype.num (12: float64) without the format
    // string, which NumPy would build anew on every request
    static PyObject* const kDtype = PyUnicode_InternFromString("dtype");  // made once
    static PyObject* const kNum = PyUnicode_InternFromString("num");
    int numpy_type = -1;
    if (PyObject* dt = PyObject_GetAttr(obj.ptr(), kDtype)) {
      if (PyObject* num = PyObject_GetAttr(dt, kNum)) {
        numpy_type = static_cast<int>(PyLong_AsLong(num));
        Py_DECREF(num);
      }
      Py_DECREF(dt);
    }
    PyErr_Clear();
    const int flags = PyBUF_C_CONTIGUOUS | (numpy_type < 0 ? PyBUF_FORMAT : 0) |
                      (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj.ptr(), &view, flags) != 0) {
      PyErr_Clear();
      return;
    }
    const bool is_double = numpy_type >= 0 ? numpy_type == 12
                                           : view.format && view.format[0] == 'd' &&
                                                 view.format[1] == '\0';
    ok = is_double && view.ndim == 1 && view.shape[0] == n && view.itemsize == 8;
  }
  ~DoubleBuffer() {
    if (view.obj) PyBuffer_Release(&view);
  }
  double* data() const { return ok ? static_cast<double*>(view.buf) : nullptr; }
};

JointVector joint_values(const char* name, nb::handle obj, int n) {
  const DoubleBuffer buf(obj, n, false);
  if (buf.ok) return Eigen::Map<const JointVector>(buf.data(), n);
  return to_vector(name, obj, n);
}

std::vector<Joint> to_joints(nb::handle seq) {
  std::vector<Joint> joints;
  for (nb::handle h : seq) {
    if (!nb::isinstance<Joint>(h)) {
      throw nb::type_error(("joints: expected a sequence of virtmech.Joint, got an item " + short_repr(h)).c_str());
    }
    joints.push_back(nb::cast<Joint>(h));
  }
  return joints;
}

nb::tuple triple(const std::array<double, 3>& a) { return nb::make_tuple(a[0], a[1], a[2]); }

nb::list to_list(const Eigen::Vector3d& v) {
  nb::list l;
  for (int i = 0; i < 3; ++i) l.append(v[i]);
  return l;
}

JointType joint_type_from(const std::string& s) {
  if (s == "revolute") return JointType::kRevolute;
  if (s == "prismatic") return JointType::kPrismatic;
  throw nb::value_error(("type: expected 'revolute' or 'prismatic', got '" + s + "'").c_str());
}

ControlLaw law_from(const std::string& s) {
  if (s == "auto") return ControlLaw::kAuto;
  if (s == "null_space") return ControlLaw::kNullSpace;
  if (s == "under_actuated") return ControlLaw::kUnderActuated;
  throw nb::value_error(
      ("law: expected 'auto', 'null_space' or 'under_actuated', got '" + s + "'").c_str());
}

const char* law_name(ControlLaw l) {
  switch (l) {
    case ControlLaw::kNullSpace: return "null_space";
    case ControlLaw::kUnderActuated: return "under_actuated";
    default: return "auto";
  }
}

Passivity passivity_from(const std::string& s) {
  if (s == "energy_tank") return Passivity::kEnergyTank;
  if (s == "off") return Passivity::kOff;
  throw nb::value_error(("passivity: expected 'energy_tank' or 'off', got '" + s + "'").c_str());
}

ErrorVelocity error_velocity_from(const std::string& s) {
  if (s == "relative") return ErrorVelocity::kRelative;
  if (s == "handle") return ErrorVelocity::kHandle;
  throw nb::value_error(
      ("error_velocity: expected 'relative' or 'handle', got '" + s + "'").c_str());
}

// a chain's joints (type, axis, origin, limits), handle and base into d
void chain_to_dict(const KinematicChain& chain, nb::dict& d) {
  nb::list js;
  for (const Joint& j : chain.joints()) {
    nb::dict jd;
    jd["type"] = j.type == JointType::kRevolute ? "revolute" : "prismatic";
    jd["axis"] = to_list(j.axis);
    jd["origin"] = Eigen::Matrix4d(j.origin.matrix());
    jd["lower"] = j.lower;
    jd["upper"] = j.upper;
    js.append(jd);
  }
  d["joints"] = js;
  d["handle"] = Eigen::Matrix4d(chain.handle().matrix());
  d["base"] = Eigen::Matrix4d(chain.base().matrix());
}

nb::list status_names(std::uint32_t s) {
  static const std::pair<std::uint32_t, const char*> names[] = {
      {status::kRamping, "ramping"},
      {status::kForceClamped, "force_clamped"},
      {status::kTorqueClamped, "torque_clamped"},
      {status::kNotConverged, "not_converged"},
      {status::kWatchdog, "watchdog"},
      {status::kPassivity, "passivity"},
      {status::kSwitching, "switching"},
      {status::kFaultNonFiniteInput, "fault_nonfinite_input"},
      {status::kFaultNonFiniteOutput, "fault_nonfinite_output"},
      {status::kFaultBadSize, "fault_bad_size"},
      {status::kFaultOutOfRange, "fault_out_of_range"}};
  nb::list l;
  for (const auto& [bit, name] : names)
    if (s & bit) l.append(name);
  return l;
}

template <typename T>
nb::list joint_type_names(const T& x) {
  nb::list l;
  for (int i = 0; i < x.dof(); ++i)
    l.append(x.joint_type(i) == JointType::kRevolute ? "revolute" : "prismatic");
  return l;
}

template <typename T>
void bind_kinematics(nb::class_<T>& cls) {
  cls.def_prop_ro("dof", &T::dof, "Number of joints.")
      .def(
          "forward",
          [](const T& self, nb::handle x) {
            const JointVector v = joint_values("x", x, self.dof());
            Pose P;
            self.forward(v.data(), P);
            return Eigen::Matrix4d(P.matrix());
          },
          "x"_a, "Handle pose (4, 4) at joint values x (dof,).")
      .def(
          "forward_many",
          [](const T& self, nb::handle X) {
            const std::string expected = "an array of shape (m, " + std::to_string(self.dof()) + ")";
            nb::object a = as_array("X", X, expected.c_str());
            const auto nd = nb::cast<long>(a.attr("ndim"));
            const nb::tuple shp = nb::cast<nb::tuple>(a.attr("shape"));
            if (nd != 2 || nb::cast<long>(shp[1]) != self.dof()) {
              throw nb::value_error(
                  ("X: expected " + expected + ", got shape " + shape_of(a)).c_str());
            }
            const auto rows = static_cast<size_t>(nb::cast<long>(shp[0]));
            const auto in = nb::cast<nb::ndarray<const double, nb::ndim<2>, nb::c_contig>>(a);
            auto* out = new double[rows * 16];
            nb::capsule owner(out, [](void* p) noexcept { delete[] static_cast<double*>(p); });
            Pose P;
            for (size_t r = 0; r < rows; ++r) {
              self.forward(in.data() + r * size_t(self.dof()), P);
              Eigen::Map<Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(out + 16 * r) = P.matrix();
            }
            return nb::ndarray<nb::numpy, double, nb::ndim<3>>(out, {rows, 4, 4}, owner);
          },
          "X"_a, "Handle poses (m, 4, 4) at the m rows of joint values X (m, dof).")
      .def(
          "jacobian",
          [](const T& self, nb::handle x) {
            const JointVector v = joint_values("x", x, self.dof());
            Pose P;
            Jacobian J;
            self.forward_jacobian(v.data(), P, J);
            return Eigen::MatrixXd(J);
          },
          "x"_a,
          "Geometric Jacobian (6, dof) at x: rows [v; w], handle-origin linear velocity then "
          "angular velocity, world axes.")
      .def_prop_ro("lower", [](const T& self) { return Eigen::VectorXd(self.lower()); },
                   "Lower joint limits (dof,) [rad or m].")
      .def_prop_ro("upper", [](const T& self) { return Eigen::VectorXd(self.upper()); },
                   "Upper joint limits (dof,) [rad or m].")
      .def_prop_ro("home", [](const T& self) { return Eigen::VectorXd(self.home()); },
                   "Default joint values (dof,).");
}

nb::dict model_dict(const ControllerModel& m) {
  nb::dict d;
  d["kp"] = Eigen::VectorXd(m.kp);
  d["kv"] = Eigen::VectorXd(m.kv);
  d["w_a"] = Eigen::VectorXd(m.w_a);
  d["w_e"] = Eigen::VectorXd(m.w_e);
  d["w_e_star"] = Eigen::VectorXd(m.w_e_star);
  d["length_scale"] = m.length_scale;
  d["law"] = law_name(m.law);
  d["under_actuated_term"] = m.under_actuated_term;
  d["error_velocity"] = m.error_velocity == ErrorVelocity::kHandle ? "handle" : "relative";
  d["period_s"] = m.period_s;
  d["ramp_cycles"] = m.ramp_cycles;
  d["watchdog_s"] = m.watchdog_s;
  d["max_force"] = m.max_force;
  d["max_torque"] = m.max_torque;
  d["max_iterations"] = m.track.max_iterations;
  d["max_iterations_initial"] = m.track_initial.max_iterations;
  d["passivity"] = m.passivity == Passivity::kOff ? "off" : "energy_tank";
  d["passivity_max_energy_j"] = m.passivity_max_energy;
  d["passivity_fade_j"] = m.passivity_fade;
  d["q_min"] = Eigen::VectorXd(m.q_min);
  d["q_max"] = Eigen::VectorXd(m.q_max);
  nb::list r;
  for (bool b : m.renderable) r.append(b);
  d["renderable"] = r;
  return d;
}

}  // namespace

NB_MODULE(_core, m) {
  m.doc() = "virtmech core (C++): devices, virtual mechanisms and the controller cycle.";
  m.attr("__version__") = VIRTMECH_VERSION_STRING;
  m.attr("MAX_DOF") = kMaxDof;

  // --- status bits (re-exported by virtmech.status)
  m.attr("STATUS_OK") = status::kOk;
  m.attr("STATUS_RAMPING") = status::kRamping;
  m.attr("STATUS_FORCE_CLAMPED") = status::kForceClamped;
  m.attr("STATUS_TORQUE_CLAMPED") = status::kTorqueClamped;
  m.attr("STATUS_NOT_CONVERGED") = status::kNotConverged;
  m.attr("STATUS_WATCHDOG") = status::kWatchdog;
  m.attr("STATUS_PASSIVITY") = status::kPassivity;
  m.attr("STATUS_SWITCHING") = status::kSwitching;
  m.attr("STATUS_FAULT_NONFINITE_INPUT") = status::kFaultNonFiniteInput;
  m.attr("STATUS_FAULT_NONFINITE_OUTPUT") = status::kFaultNonFiniteOutput;
  m.attr("STATUS_FAULT_BAD_SIZE") = status::kFaultBadSize;
  m.attr("STATUS_FAULT_OUT_OF_RANGE") = status::kFaultOutOfRange;
  m.attr("STATUS_FAULT_MASK") = status::kFaultMask;
  {
    // ControllerSettings' defaults, the one place they live (the scenario format takes them)
    const ControllerSettings s;
    nb::dict d;
    d["law"] = law_name(s.law);
    d["error_velocity"] = s.error_velocity == ErrorVelocity::kHandle ? "handle" : "relative";
    d["period_s"] = s.period_s;
    d["ramp_time_s"] = s.ramp_time_s;
    d["max_iterations"] = s.max_iterations;
    d["passivity"] = s.passivity == Passivity::kOff ? "off" : "energy_tank";
    d["passivity_max_energy_j"] = s.passivity_max_energy_j;
    d["passivity_fade_j"] = s.passivity_fade_j;
    m.attr("CONTROLLER_DEFAULTS") = d;
  }
  bind_geometry(m);
  m.def("status_names", &status_names, "status"_a, "Names of the bits set in a status word.");

  // --- math
  m.def(
      "pose_error",
      [](nb::handle a, nb::handle b) {
        return Eigen::VectorXd(pose_error(to_pose("T_a", a), to_pose("T_b", b)));
      },
      "T_a"_a, "T_b"_a,
      "Pose error e = [p_a - p_b; log(R_a R_b^T)] (6,): metres, then a rotation vector in "
      "world axes [rad].");
  m.def(
      "so3_log", [](nb::handle R) { return Eigen::Vector3d(so3_log(to_matrix("R", R, 3, 3))); },
      "R"_a, "Rotation vector (3,) of a rotation matrix (3, 3).");
  m.def(
      "so3_exp", [](nb::handle w) { return Eigen::Matrix3d(so3_exp(to_vec3("w", w))); }, "w"_a,
      "Rotation matrix (3, 3) of a rotation vector (3,).");
  auto filter = [](bool range) {
    return [range](nb::handle J, nb::handle W) {
      const Eigen::MatrixXd Jm = to_matrix("J", J, 6, -1);
      if (Jm.cols() < 1 || Jm.cols() > kMaxDof) {
        throw nb::value_error(("J: expected 1 to " + std::to_string(kMaxDof) +
                               " columns, got " + std::to_string(Jm.cols())).c_str());
      }
      const Jacobian Jv = Jm;
      nb::object Wa = as_array("W", W, "a (6,) or (6, 6) array");
      Matrix6 Wm;
      if (nb::cast<long>(Wa.attr("ndim")) == 1) {
        Wm = to_vec6("W", Wa).asDiagonal();
      } else {
        Wm = to_matrix("W", Wa, 6, 6);
      }
      require_finite("W", Eigen::Map<const Eigen::VectorXd>(Wm.data(), 36));
      return Eigen::MatrixXd(range ? range_filter(Jv, Wm) : null_filter(Jv, Wm));
    };
  };
  m.def("range_filter", filter(true), "J"_a, "W"_a,
        "Range-space filter P(W) = W J (J^T W J)^+ J^T (6, 6) (eq. 5). J (6, n); W a (6,) "
        "diagonal or a (6, 6) symmetric positive semi-definite matrix.");
  m.def("null_filter", filter(false), "J"_a, "W"_a, "Null-space filter N(W) = I - P(W) (eq. 9).");

  // --- joints and chains
  nb::class_<Joint>(m, "Joint", "One revolute or prismatic joint of a serial chain.")
      .def(
          "__init__",
          [](Joint* self, const std::string& type, nb::handle axis, nb::handle origin,
             double lower, double upper) {
            Joint j;
            j.type = joint_type_from(type);
            j.axis = to_vec3("axis", axis);
            if (origin.is_none()) {
              j.origin = Pose::Identity();
            } else {
              nb::object a = as_array("origin", origin, "a (3,) position or a (4, 4) pose");
              if (nb::cast<long>(a.attr("ndim")) == 1) {
                j.origin = Pose::Identity();
                j.origin.translation() = to_vec3("origin", a);
              } else {
                j.origin = to_pose("origin", a);
              }
            }
            j.lower = lower;
            j.upper = upper;
            new (self) Joint(j);
          },
          "type"_a = "revolute", "axis"_a = nb::make_tuple(0.0, 0.0, 1.0), "origin"_a = nb::none(),
          "lower"_a = -kInf, "upper"_a = kInf,
          "A joint: type 'revolute' or 'prismatic'; axis (3,) in the joint frame; origin: pose "
          "(4, 4) or position (3,) of the joint frame in the previous frame at zero; limits "
          "[rad or m].")
      .def_prop_ro("type", [](const Joint& j) {
        return j.type == JointType::kRevolute ? "revolute" : "prismatic";
      })
      .def_prop_ro("axis", [](const Joint& j) { return j.axis; })
      .def_prop_ro("origin", [](const Joint& j) { return Eigen::Matrix4d(j.origin.matrix()); })
      .def_ro("lower", &Joint::lower)
      .def_ro("upper", &Joint::upper)
      .def("__repr__", [](const Joint& j) {
        std::ostringstream os;
        os << "Joint(type='" << (j.type == JointType::kRevolute ? "revolute" : "prismatic")
           << "', axis=" << format_vector(j.axis)
           << ", origin=" << format_vector(j.origin.translation()) << ")";
        return os.str();
      });

  // --- mechanisms
  nb::class_<Mechanism> mech(m, "Mechanism", "A virtual mechanism (base class).");
  bind_kinematics(mech);
  mech.def_prop_ro("type", &Mechanism::type_name)
      .def_prop_ro("length_scale", &Mechanism::length_scale,
                   "Characteristic length [m] weighting rotations against translations.")
      .def_prop_ro("joint_types", [](const Mechanism& self) { return joint_type_names(self); },
                   "'revolute' or 'prismatic' per joint.")
      .def_prop_ro("contact_joint", &Mechanism::contact_joint,
                   "The lift-off joint of a unilateral mechanism (held at its lower limit 0 "
                   "while in contact), or -1.");
  nb::class_<ChainMechanism, Mechanism>(m, "ChainMechanism",
                                        "A mechanism that is a serial chain (base class).")
      .def_prop_ro("joints", [](const ChainMechanism& self) { return self.chain().joints(); });

  nb::class_<PlanarArm, ChainMechanism>(
      m, "PlanarArm",
      "Paper Fig. 4 / eq. 2 in 3-D: a revolute joint at `pivot` about the unit `normal`, the "
      "handle at distance `length` in direction R(theta) zero_direction, the stylus pointing "
      "from the handle to the pivot.")
      .def(
          "__init__",
          [](PlanarArm* self, nb::handle pivot, nb::handle normal, nb::handle length,
             nb::handle zero_direction) {
            new (self) PlanarArm(to_vec3("pivot", pivot), to_vec3("normal", normal),
                                 to_double("length", length),
                                 opt_vec3("zero_direction", zero_direction));
          },
          "pivot"_a, "normal"_a, "length"_a, "zero_direction"_a = nb::none())
      .def_prop_ro("pivot", &PlanarArm::pivot)
      .def_prop_ro("normal", &PlanarArm::normal)
      .def_prop_ro("length", &PlanarArm::length)
      .def_prop_ro("zero_direction", &PlanarArm::zero_direction)
      .def("to_dict", [](const PlanarArm& a) {
        nb::dict d;
        d["type"] = "PlanarArm";
        d["pivot"] = to_list(a.pivot());
        d["normal"] = to_list(a.normal());
        d["length"] = a.length();
        d["zero_direction"] = to_list(a.zero_direction());
        return d;
      }, "The mechanism's parameters as a JSON-ready dict.");

  nb::class_<Probe, ChainMechanism>(
      m, "Probe",
      "Paper Fig. 3, PPRRR: the tip slides on the plane (plane_point, unit plane_normal); "
      "three revolute joints meet at the tip; the handle is `length` back along the stylus.")
      .def(
          "__init__",
          [](Probe* self, nb::handle p, nb::handle n, nb::handle length, nb::handle tangent,
             bool unilateral) {
            new (self) Probe(to_vec3("plane_point", p), to_vec3("plane_normal", n),
                             to_double("length", length), opt_vec3("tangent", tangent),
                             unilateral);
          },
          "plane_point"_a, "plane_normal"_a, "length"_a, "tangent"_a = nb::none(),
          "unilateral"_a = false,
          "unilateral=True: the tip may leave the plane toward +plane_normal (a lift-off joint "
          "with lower limit 0 after the two in-plane ones), so the plane pushes but never pulls.")
      .def_prop_ro("plane_point", &Probe::plane_point)
      .def_prop_ro("plane_normal", &Probe::plane_normal)
      .def_prop_ro("tangent", &Probe::tangent)
      .def_prop_ro("length", &Probe::length)
      .def_prop_ro("unilateral", &Probe::unilateral)
      .def("to_dict", [](const Probe& a) {
        nb::dict d;
        d["type"] = "Probe";
        d["plane_point"] = to_list(a.plane_point());
        d["plane_normal"] = to_list(a.plane_normal());
        d["length"] = a.length();
        d["tangent"] = to_list(a.tangent());
        d["unilateral"] = a.unilateral();
        return d;
      });

  nb::class_<PointPivot, ChainMechanism>(
      m, "PointPivot", "A probe whose tip is pinned at `point` (RRR at the tip).")
      .def(
          "__init__",
          [](PointPivot* self, nb::handle p, nb::handle n, nb::handle length, nb::handle t,
             bool unilateral, bool insertion) {
            new (self) PointPivot(to_vec3("point", p), to_vec3("normal", n),
                                  to_double("length", length), opt_vec3("tangent", t), unilateral,
                                  insertion);
          },
          "point"_a, "normal"_a = nb::make_tuple(0.0, 0.0, 1.0), "length"_a = 0.1,
          "tangent"_a = nb::none(), "unilateral"_a = false, "insertion"_a = false,
          "unilateral=True: the tip may lift off toward +normal (a joint with lower limit 0). "
          "insertion=True: a trocar: the stylus passes through the point and slides along "
          "itself (a last joint s in [-0.9 length, 0], the handle at length + s from the "
          "point).")
      .def_prop_ro("point", &PointPivot::point)
      .def_prop_ro("normal", &PointPivot::normal)
      .def_prop_ro("length", &PointPivot::length)
      .def_prop_ro("unilateral", &PointPivot::unilateral)
      .def_prop_ro("insertion", &PointPivot::insertion)
      .def("to_dict", [](const PointPivot& a) {
        nb::dict d;
        d["type"] = "PointPivot";
        d["point"] = to_list(a.point());
        d["normal"] = to_list(a.normal());
        d["length"] = a.length();
        d["tangent"] = to_list(a.tangent());
        d["unilateral"] = a.unilateral();
        d["insertion"] = a.insertion();
        return d;
      });

  nb::class_<LineGuide, ChainMechanism>(
      m, "LineGuide", "A probe whose tip slides on a line (P + RRR at the tip).")
      .def(
          "__init__",
          [](LineGuide* self, nb::handle p, nb::handle dir, nb::handle length, nb::handle n,
             bool unilateral) {
            new (self) LineGuide(to_vec3("point", p), to_vec3("direction", dir),
                                 to_double("length", length), opt_vec3("normal", n), unilateral);
          },
          "point"_a, "direction"_a, "length"_a = 0.1, "normal"_a = nb::none(),
          "unilateral"_a = false,
          "unilateral=True: the tip may lift off the line toward +normal (a joint with lower "
          "limit 0).")
      .def_prop_ro("point", &LineGuide::point)
      .def_prop_ro("direction", &LineGuide::direction)
      .def_prop_ro("normal", &LineGuide::normal)
      .def_prop_ro("length", &LineGuide::length)
      .def_prop_ro("unilateral", &LineGuide::unilateral)
      .def("to_dict", [](const LineGuide& a) {
        nb::dict d;
        d["type"] = "LineGuide";
        d["point"] = to_list(a.point());
        d["direction"] = to_list(a.direction());
        d["length"] = a.length();
        d["normal"] = to_list(a.normal());
        d["unilateral"] = a.unilateral();
        return d;
      });

  nb::class_<SurfaceProbe, Mechanism>(
      m, "SurfaceProbe",
      "Paper Fig. 3 on any surface: the probe's tip slides on `surface` (joints u, v), three "
      "revolute joints meet at the tip over the surface frame [t1, n x t1, n] (t1 = S_u / "
      "|S_u|, n the normal), the handle `length` back along the stylus, which points along -n "
      "at wrist angles 0.")
      .def(
          "__init__",
          [](SurfaceProbe* self, std::shared_ptr<const Surface> surface, nb::handle length,
             bool unilateral) {
            new (self) SurfaceProbe(std::move(surface), to_double("length", length), unilateral);
          },
          "surface"_a, "length"_a = 0.1, "unilateral"_a = false,
          "surface: a Surface (NurbsSurface, Sphere, Cylinder, Plane); length [m]; "
          "unilateral=True: the tip may leave the surface toward +n (a lift-off joint with "
          "lower limit 0 after u, v), so the surface pushes but never pulls.")
      .def_prop_ro("surface", &SurfaceProbe::surface_ptr)
      .def_prop_ro("length", &SurfaceProbe::length)
      .def_prop_ro("unilateral", &SurfaceProbe::unilateral)
      .def("to_dict", [](nb::handle self) {
        const auto& a = nb::cast<const SurfaceProbe&>(self);
        nb::dict d;
        d["type"] = "SurfaceProbe";
        d["surface"] = self.attr("surface").attr("to_dict")();
        d["length"] = a.length();
        d["unilateral"] = a.unilateral();
        return d;
      });

  nb::class_<CurveGuide, Mechanism>(
      m, "CurveGuide",
      "A probe whose tip is held on a curve, the path to trace (joint u, then RRR at the tip "
      "over the fixed base [t1, normal x t1, normal]); the handle `length` back along the "
      "stylus, which points along -normal at wrist angles 0.")
      .def(
          "__init__",
          [](CurveGuide* self, std::shared_ptr<const Curve> curve, nb::handle length,
             nb::handle normal) {
            new (self) CurveGuide(std::move(curve), to_double("length", length),
                                  normal.is_none() ? Eigen::Vector3d::UnitZ()
                                                   : to_vec3("normal", normal));
          },
          "curve"_a, "length"_a = 0.1, "normal"_a = nb::none(),
          "curve: a Curve (NurbsCurve); length [m]; normal: unit, the side the hand is on "
          "(default +z).")
      .def_prop_ro("curve", &CurveGuide::curve_ptr)
      .def_prop_ro("length", &CurveGuide::length)
      .def_prop_ro("normal", &CurveGuide::normal)
      .def("to_dict", [](nb::handle self) {
        const auto& a = nb::cast<const CurveGuide&>(self);
        nb::dict d;
        d["type"] = "CurveGuide";
        d["curve"] = self.attr("curve").attr("to_dict")();
        d["length"] = a.length();
        d["normal"] = to_list(a.normal());
        return d;
      });

  nb::class_<HandlePath, Mechanism>(
      m, "HandlePath",
      "The handle itself held on a curve, its orientation free (joint u, then RRR about the "
      "handle point; the stylus along -normal at wrist angles 0).")
      .def(
          "__init__",
          [](HandlePath* self, std::shared_ptr<const Curve> curve, nb::handle normal,
             nb::handle length_scale) {
            new (self) HandlePath(std::move(curve),
                                  normal.is_none() ? Eigen::Vector3d::UnitZ()
                                                   : to_vec3("normal", normal),
                                  to_double("length_scale", length_scale));
          },
          "curve"_a, "normal"_a = nb::none(), "length_scale"_a = 0.1,
          "curve: a Curve; normal: unit (default +z); length_scale [m] weighs rotations.")
      .def_prop_ro("curve", &HandlePath::curve_ptr)
      .def_prop_ro("normal", &HandlePath::normal)
      .def("to_dict", [](nb::handle self) {
        const auto& a = nb::cast<const HandlePath&>(self);
        nb::dict d;
        d["type"] = "HandlePath";
        d["curve"] = self.attr("curve").attr("to_dict")();
        d["normal"] = to_list(a.normal());
        d["length_scale"] = a.length_scale();
        return d;
      });

  nb::class_<SerialChain, ChainMechanism>(
      m, "SerialChain", "Any serial chain of revolute / prismatic joints as a mechanism.")
      .def(
          "__init__",
          [](SerialChain* self, nb::handle joints, nb::handle handle, nb::handle base,
             nb::handle length_scale) {
            const Pose H = handle.is_none() ? Pose::Identity() : to_pose("handle", handle);
            const Pose B = base.is_none() ? Pose::Identity() : to_pose("base", base);
            new (self) SerialChain(to_joints(joints), H, B, to_double("length_scale", length_scale));
          },
          "joints"_a, "handle"_a = nb::none(), "base"_a = nb::none(), "length_scale"_a = 0.1,
          "joints: sequence of Joint; handle, base: (4, 4) poses; length_scale [m].")
      .def("to_dict", [](const SerialChain& a) {
        nb::dict d;
        d["type"] = "SerialChain";
        chain_to_dict(a.chain(), d);
        d["length_scale"] = a.length_scale();
        return d;
      });

  // --- devices
  nb::class_<Device> dev(m, "DeviceBase",
                         "A haptic device (interface): kinematics, actuation and limits.");
  bind_kinematics(dev);
  dev
      .def_prop_ro("name", &Device::name)
      .def_prop_ro("actuated",
                   [](const Device& d) {
                     Eigen::Matrix<bool, Eigen::Dynamic, 1> a(d.dof());
                     for (int i = 0; i < d.dof(); ++i) a[i] = d.actuated(i);
                     return a;
                   },
                   "Actuation mask (dof,) of bool.")
      .def_prop_ro("torque_limit", [](const Device& d) { return Eigen::VectorXd(d.torque_limit()); },
                   "Joint torque limits (dof,) [N·m or N]; 0 for passive joints.")
      .def_prop_ro("max_force", &Device::max_force, "[N]")
      .def_prop_ro("max_torque", &Device::max_torque, "[N·m]")
      .def_prop_ro("stiffness", &Device::stiffness, "Default translational Kp [N/m].")
      .def_prop_ro("damping", &Device::damping, "Default translational Kv [N·s/m].")
      .def_prop_ro("joint_types", [](const Device& self) { return joint_type_names(self); },
                   "'revolute' or 'prismatic' per joint.");


  nb::class_<SerialDevice, Device>(
      m, "Device",
      "A serial-chain device (C++ SerialDevice) with any actuation mask; every device shares "
      "DeviceBase.")
      .def(
         "__init__",
         [](SerialDevice* self, nb::handle joints, nb::handle actuated, nb::handle handle,
            nb::handle base, nb::handle torque_limit, double max_force, double max_torque,
            double stiffness, double damping, const std::string& name, nb::handle coupling,
            nb::handle coupling_offset) {
           std::vector<Joint> js = to_joints(joints);
           DeviceLimits L;
           for (nb::handle h : actuated) L.actuated.push_back(nb::cast<bool>(h));
           if (!torque_limit.is_none()) {
             const Eigen::VectorXd t =
                 to_vector("torque_limit", torque_limit, static_cast<long>(js.size()));
             L.torque_limit.assign(t.data(), t.data() + t.size());
           }
           L.max_force = max_force;
           L.max_torque = max_torque;
           L.stiffness = stiffness;
           L.damping = damping;
           const Pose H = handle.is_none() ? Pose::Identity() : to_pose("handle", handle);
           const Pose B = base.is_none() ? Pose::Identity() : to_pose("base", base);
           const long n = static_cast<long>(js.size());
           if (coupling.is_none() && coupling_offset.is_none()) {
             new (self) SerialDevice(name, KinematicChain(B, js, H), L);
           } else {
             const JointMatrix C = coupling.is_none() ? JointMatrix(JointMatrix::Identity(n, n))
                                                      : JointMatrix(to_matrix("coupling", coupling, n, n));
             const JointVector c0 = coupling_offset.is_none()
                                        ? JointVector(JointVector::Zero(n))
                                        : JointVector(to_vector("coupling_offset", coupling_offset, n));
             new (self) SerialDevice(name, KinematicChain(B, js, H), L, C, c0);
           }
         },
         "joints"_a, "actuated"_a, "handle"_a = nb::none(), "base"_a = nb::none(),
         "torque_limit"_a = nb::none(), "max_force"_a = kInf, "max_torque"_a = kInf,
         "stiffness"_a = 500.0, "damping"_a = 1.0, "name"_a = "SerialDevice",
         "coupling"_a = nb::none(), "coupling_offset"_a = nb::none(),
         "A serial-chain device with any actuation mask. joints: sequence of Joint; actuated: "
         "one bool per joint; torque_limit (dof,) [N·m or N]; max_force [N]; max_torque [N·m]; "
         "stiffness [N/m] and damping [N·s/m]: the default translational gains; coupling C "
         "(dof, dof) and coupling_offset c0 (dof,): the device's joints q map to the chain's "
         "as s = C q + c0 (default: the chain's own).")
      .def("to_dict", [](const SerialDevice& d) {
        nb::dict out;
        out["type"] = "Device";
        out["name"] = d.name();
        chain_to_dict(d.chain(), out);
        nb::list act;
        for (int i = 0; i < d.dof(); ++i) act.append(d.actuated(i));
        out["actuated"] = act;
        out["torque_limit"] = Eigen::VectorXd(d.torque_limit());
        out["coupling"] = Eigen::MatrixXd(d.coupling());
        out["coupling_offset"] = Eigen::VectorXd(d.coupling_offset());
        out["max_force"] = d.max_force();
        out["max_torque"] = d.max_torque();
        out["stiffness"] = d.stiffness();
        out["damping"] = d.damping();
        return out;
      })
      .def_prop_ro("joints", [](const SerialDevice& self) { return self.chain().joints(); },
                   "The joints of the underlying chain (in chain coordinates).")
      .def_prop_ro(
          "base", [](const SerialDevice& d) { return Eigen::Matrix4d(d.chain().base().matrix()); },
          "The chain's base pose (4, 4): the first joint's frame is base @ joints[0].origin.")
      .def_prop_ro(
          "handle",
          [](const SerialDevice& d) { return Eigen::Matrix4d(d.chain().handle().matrix()); },
          "The handle frame (4, 4) in the last joint's frame.")
      .def_prop_ro(
          "coupling", [](const SerialDevice& d) { return Eigen::MatrixXd(d.coupling()); },
          "C (dof, dof) of the joint map s = C q + c0 from device to chain coordinates.")
      .def_prop_ro(
          "coupling_offset",
          [](const SerialDevice& d) { return Eigen::VectorXd(d.coupling_offset()); },
          "c0 (dof,) of the joint map s = C q + c0.");

  nb::class_<PhantomOmni, SerialDevice>(
      m, "PhantomOmni",
      "PHANTOM Omni / Geomagic Touch: waist, shoulder, absolute elbow (HD_CURRENT_JOINT_ANGLES) "
      "actuated; gimbal yaw, pitch, roll passive, meeting at the handle origin. OpenHaptics "
      "axes in metres. See docs/devices.md for the gimbal zero and offsets.")
      .def(
          "__init__",
          [](PhantomOmni* self, double l1, double l2, double max_force, nb::handle motor_limit,
             nb::handle gimbal_offset, nb::handle gimbal_sign, double stiffness,
             double damping) {
            PhantomOmniParams p;
            p.l1 = l1;
            p.l2 = l2;
            p.max_force = max_force;
            const Eigen::Vector3d tl = to_vec3("motor_torque_limit", motor_limit);
            const Eigen::Vector3d go = to_vec3("gimbal_offset", gimbal_offset);
            const Eigen::Vector3d gs = to_vec3("gimbal_sign", gimbal_sign);
            for (int i = 0; i < 3; ++i) {
              p.motor_torque_limit[i] = tl[i];
              p.gimbal_offset[i] = go[i];
              p.gimbal_sign[i] = gs[i];
            }
            p.stiffness = stiffness;
            p.damping = damping;
            new (self) PhantomOmni(p);
          },
          "l1"_a = PhantomOmniParams().l1, "l2"_a = PhantomOmniParams().l2,
          "max_force"_a = PhantomOmniParams().max_force,
          "motor_torque_limit"_a = triple(PhantomOmniParams().motor_torque_limit),
          "gimbal_offset"_a = triple(PhantomOmniParams().gimbal_offset),
          "gimbal_sign"_a = triple(PhantomOmniParams().gimbal_sign),
          "stiffness"_a = PhantomOmniParams().stiffness, "damping"_a = PhantomOmniParams().damping)
      .def_prop_ro("l1", [](const PhantomOmni& d) { return d.params().l1; }, "[m]")
      .def_prop_ro("l2", [](const PhantomOmni& d) { return d.params().l2; }, "[m]")
      .def("to_dict", [](const PhantomOmni& d) {
        nb::dict out;
        out["type"] = "PhantomOmni";
        out["l1"] = d.params().l1;
        out["l2"] = d.params().l2;
        out["max_force"] = d.params().max_force;
        out["motor_torque_limit"] = Eigen::Vector3d(d.params().motor_torque_limit.data());
        out["gimbal_offset"] = Eigen::Vector3d(d.params().gimbal_offset.data());
        out["gimbal_sign"] = Eigen::Vector3d(d.params().gimbal_sign.data());
        out["stiffness"] = d.params().stiffness;
        out["damping"] = d.params().damping;
        return out;
      });

  nb::class_<Planar3R, SerialDevice>(
      m, "Planar3R",
      "The paper's Fig. 8 robot: three revolute joints about the base z axis; the distal "
      "joint un-powered; the handle origin on it, the stylus along angle q0 + q1 + q2.")
      .def(
          "__init__",
          [](Planar3R* self, double link1, double link2, nb::handle base, double torque_limit,
             double max_force) {
            const Pose B = base.is_none() ? Pose::Identity() : to_pose("base", base);
            new (self) Planar3R(link1, link2, B, torque_limit, max_force);
          },
          "link1"_a = Planar3RDefaults::kLink, "link2"_a = Planar3RDefaults::kLink,
          "base"_a = nb::none(), "torque_limit"_a = Planar3RDefaults::kTorqueLimit,
          "max_force"_a = Planar3RDefaults::kMaxForce, "link1, link2 [m]; base (4, 4); torque_limit [N·m]; max_force [N].")
      .def_prop_ro("link1", &Planar3R::link1)
      .def_prop_ro("link2", &Planar3R::link2)
      .def("to_dict", [](const Planar3R& d) {
        nb::dict out;
        out["type"] = "Planar3R";
        out["link1"] = d.link1();
        out["link2"] = d.link2();
        out["torque_limit"] = d.torque_limit()[0];
        out["max_force"] = d.max_force();
        return out;
      });

  nb::class_<CartesianDevice, SerialDevice>(
      m, "CartesianDevice",
      "A Cartesian device (Force Dimension omega.3/6/7, sigma.7; Novint Falcon): its SDK serves "
      "the handle's pose and takes a wrench. Coordinates: position (x, y, z) [m] in the SDK's "
      "base frame, then, where the wrist's rotation is sensed, (a, b, c) [rad] with R_sdk = "
      "Rx(a) Ry(b) Rz(c). docs/devices.md, \"Cartesian devices\".")
      .def(
          "__init__",
          [](CartesianDevice* self, const std::string& model, nb::handle handle_rotation) {
            const Eigen::Matrix3d R = handle_rotation.is_none()
                                          ? default_cartesian_handle_rotation()
                                          : Eigen::Matrix3d(to_matrix("handle_rotation",
                                                                      handle_rotation, 3, 3));
            new (self) CartesianDevice(model, R);
          },
          "model"_a = "omega.6", "handle_rotation"_a = nb::none(),
          "model: one of CartesianDevice.MODELS; handle_rotation (3, 3): the handle frame in the "
          "SDK's end-effector frame (default Rx(pi): the stylus along its -z).")
      .def_prop_ro("model", [](const CartesianDevice& d) { return d.model().name; },
                   "The model's name, one of CartesianDevice.MODELS.")
      .def_prop_ro("orientation_sensed", &CartesianDevice::orientation_sensed,
                   "True where the wrist's rotation is read (6 coordinates; else 3).")
      .def_prop_ro("torque_actuated", &CartesianDevice::torque_actuated,
                   "True where the wrist is driven (the device renders a torque).")
      .def_prop_ro("gripper", [](const CartesianDevice& d) { return d.model().gripper; },
                   "True where the device has an actuated gripper.")
      .def_prop_ro("handle_rotation",
                   [](const CartesianDevice& d) { return Eigen::Matrix3d(d.handle_rotation()); },
                   "The handle frame's rotation (3, 3) in the SDK's end-effector frame.")
      .def(
          "coordinates",
          [](const CartesianDevice& d, nb::handle p, nb::handle R, nb::handle previous) {
            Eigen::VectorXd q(d.dof());
            Eigen::VectorXd prev;
            if (!previous.is_none()) prev = to_vector("previous", previous, d.dof());
            d.coordinates(to_vec3("p", p), to_matrix("R", R, 3, 3),
                          previous.is_none() ? nullptr : prev.data(), q.data());
            return q;
          },
          "p"_a, "R"_a, "previous"_a = nb::none(),
          "Coordinates (dof,) of the SDK's position p (3,) [m] and rotation R (3, 3); the "
          "angles on the branch nearest `previous` (dof,).")
      .def(
          "sdk_pose",
          [](const CartesianDevice& d, nb::handle q) {
            const Eigen::VectorXd x = to_vector("q", q, d.dof());
            Eigen::Vector3d p;
            Eigen::Matrix3d R;
            d.sdk_pose(x.data(), p, R);
            return nb::make_tuple(p, R);
          },
          "q"_a, "(p (3,) [m], R (3, 3)): the SDK's reading at coordinates q.")
      .def(
          "rates",
          [](const CartesianDevice& d, nb::handle q, nb::handle v, nb::handle w) {
            const Eigen::VectorXd x = to_vector("q", q, d.dof());
            Eigen::VectorXd dq(d.dof());
            if (!d.rates(x.data(), to_vec3("v", v), to_vec3("w", w), dq.data())) {
              throw std::invalid_argument("q: at the gimbal lock (cos b = 0): no angle rates");
            }
            return dq;
          },
          "q"_a, "v"_a, "w"_a,
          "Coordinate rates (dof,) of the SDK's linear v [m/s] and angular w [rad/s] velocity.")
      .def(
          "wrench",
          [](const CartesianDevice& d, nb::handle q, nb::handle tau) {
            const Eigen::VectorXd x = to_vector("q", q, d.dof());
            const Eigen::VectorXd t = to_vector("tau", tau, d.dof());
            Eigen::Vector3d f, mo;
            if (!d.wrench(x.data(), t.data(), f, mo)) {
              throw std::invalid_argument("q: at the gimbal lock (cos b = 0): no torque");
            }
            Vector6 out;
            out << f, mo;
            return Eigen::VectorXd(out);
          },
          "q"_a, "tau"_a,
          "The handle wrench (6,) [N; N·m] whose coordinate torques are tau: J^T w = tau.")
      .def("to_dict", [](const CartesianDevice& d) {
        nb::dict out;
        out["type"] = "CartesianDevice";
        out["model"] = d.model().name;
        out["handle_rotation"] = Eigen::Vector3d(so3_log(d.handle_rotation()));
        out["max_force"] = d.max_force();
        out["max_torque"] = d.max_torque();
        out["stiffness"] = d.stiffness();
        out["damping"] = d.damping();
        return out;
      });
  {
    nb::list names;
    for (const std::string& n : cartesian_model_names()) names.append(n);
    m.attr("CartesianDevice").attr("MODELS") =
        nb::module_::import_("builtins").attr("tuple")(names);
  }

  // --- placement
  nb::class_<PlacementResult>(m, "TrackResult", "Result of track().")
      .def_prop_ro("theta", [](const PlacementResult& r) { return Eigen::VectorXd(r.theta); },
                   "Mechanism joint values (dof,).")
      .def_ro("iterations", &PlacementResult::iterations)
      .def_ro("residual", &PlacementResult::residual, "sqrt(e^T W e) at theta")
      .def_ro("converged", &PlacementResult::converged)
      .def_prop_ro("active",
                   [](const PlacementResult& r) { return joint_mask(r.active, r.theta.size()); },
                   "Joints held at a limit that acts (dof,) of bool.")
      .def("__repr__", [](const PlacementResult& r) {
        std::ostringstream os;
        os << "TrackResult(theta=" << format_vector(r.theta) << ", iterations=" << r.iterations
           << ", residual=" << r.residual << ", converged=" << (r.converged ? "True" : "False")
           << ")";
        return os.str();
      });

  m.def(
      "track",
      [](const Mechanism& mech, nb::handle target, nb::handle theta0, nb::handle weights,
         int max_iterations, bool closed_form) {
        const Pose T = to_pose("target_pose", target);
        const JointVector th0 =
            theta0.is_none() ? mech.home() : joint_values("theta0", theta0, mech.dof());
        require_finite("theta0", th0);
        Vector6 W;
        if (weights.is_none()) {
          const double L = mech.length_scale();
          W << 1, 1, 1, L * L, L * L, L * L;
        } else {
          W = to_vec6("weights", weights);
          require_non_negative("weights", W);
        }
        if (max_iterations < 1) {
          throw nb::value_error(("max_iterations: expected >= 1, got " +
                                 std::to_string(max_iterations)).c_str());
        }
        TrackOptions opts;
        opts.max_iterations = max_iterations;
        opts.closed_form = closed_form;
        PlacementResult out;
        const TrackResult r = track(mech, T, th0, W, opts, out.theta);
        out.iterations = r.iterations;
        out.residual = r.residual;
        out.converged = r.converged;
        out.active = r.active;
        return out;
      },
      "mechanism"_a, "target_pose"_a, "theta0"_a = nb::none(), "weights"_a = nb::none(),
      "max_iterations"_a = 20, "closed_form"_a = true,
      "The placement of eqs. 18-20: theta minimising e^T diag(W) e with e = "
      "pose_error(target_pose, mechanism.forward(theta)), within the joint limits; theta0 "
      "(dof,) (the warm start) defaults to the mechanism's home, weights (6,) to "
      "[1 1 1 L^2 L^2 L^2]. The mechanism's closed form where it has one (Probe, PointPivot "
      "with weights isotropic in position and in rotation) unless closed_form=False, else "
      "weighted Gauss-Newton. Returns .theta, .iterations (0: closed form), .residual, "
      ".converged, .active (joints held at a limit).");

  m.def(
      "reach",
      [](const Device& device, nb::handle target, nb::handle seeds, double length_scale,
         int max_iterations) {
        std::vector<JointVector> s;
        for (nb::handle h : seeds) s.push_back(joint_values("seeds", h, device.dof()));
        const DevicePose r = reach(device, to_pose("target", target), s, length_scale,
                                   max_iterations);
        return nb::make_tuple(Eigen::VectorXd(r.q), Eigen::VectorXd(r.error), r.seed);
      },
      "device"_a, "target"_a, "seeds"_a, "length_scale"_a = 0.1, "max_iterations"_a = 200,
      "The device's joint values (dof,) within its limits whose handle pose is nearest the "
      "target (4, 4), weighted [1 1 1 L^2 L^2 L^2]: Levenberg-Marquardt on the device's "
      "kinematics from each seed (dof,) in turn, the first that reaches it kept, else the "
      "nearest. Returns (q, pose_error(target, forward(q)) (6,), the seed's index).");

  // --- controller
  nb::class_<CycleOutput>(m, "CycleOutput", "Everything one controller cycle reports.")
      .def(nb::init<>(), "An empty output, to be filled by Controller.step(..., out=...).")
      .def_prop_ro("torque", [](const CycleOutput& o) { return Eigen::VectorXd(o.torque); },
                   "Joint torques (n,) [N·m or N]; exactly 0 on passive joints.")
      .def_prop_ro("wrench", [](const CycleOutput& o) { return Eigen::VectorXd(o.wrench); },
                   "Wrench applied at the handle (6,) [N; N·m], after safety.")
      .def_prop_ro("wrench_null", [](const CycleOutput& o) { return Eigen::VectorXd(o.wrench_null); },
                   "Null-space part N(W_A)(Kp e + Kv e_dot) (6,), before safety.")
      .def_prop_ro("wrench_range", [](const CycleOutput& o) { return Eigen::VectorXd(o.wrench_range); },
                   "Range-space part P(W_A)(Kp e* + Kv e*_dot) (6,), before safety.")
      .def_prop_ro("wrench_unrendered",
                   [](const CycleOutput& o) { return Eigen::VectorXd(o.wrench_unrendered); },
                   "Part of the commanded wrench the device cannot apply (6,).")
      .def_prop_ro("theta", [](const CycleOutput& o) { return Eigen::VectorXd(o.theta); },
                   "Nearest placement (m,) (W_e).")
      .def_prop_ro("theta_star", [](const CycleOutput& o) { return Eigen::VectorXd(o.theta_star); },
                   "Un-powered placement (m,) (W_e*).")
      .def_prop_ro("error", [](const CycleOutput& o) { return Eigen::VectorXd(o.error); },
                   "e = X_V - X_R (6,) [m; rad].")
      .def_prop_ro("error_dot", [](const CycleOutput& o) { return Eigen::VectorXd(o.error_dot); },
                   "The rate of e (6,) [m/s; rad/s] (error_velocity: 'relative' or 'handle').")
      .def_prop_ro("error_star", [](const CycleOutput& o) { return Eigen::VectorXd(o.error_star); },
                   "e* = X_V* - X_R at the un-powered placement theta_star (6,) [m; rad] "
                   "(eq. 25).")
      .def_prop_ro("error_star_dot",
                   [](const CycleOutput& o) { return Eigen::VectorXd(o.error_star_dot); },
                   "The rate of e* (6,) [m/s; rad/s].")
      .def_prop_ro("handle_pose",
                   [](const CycleOutput& o) { return Eigen::Matrix4d(o.handle_pose.matrix()); },
                   "The device's handle pose X_R (4, 4) [m]: origin at the grip point, +z "
                   "along the stylus toward the tip.")
      .def_prop_ro("mechanism_pose",
                   [](const CycleOutput& o) { return Eigen::Matrix4d(o.mechanism_pose.matrix()); },
                   "The mechanism's handle pose X_V at theta (4, 4) [m].")
      .def_prop_ro("mechanism_pose_star", [](const CycleOutput& o) {
        return Eigen::Matrix4d(o.mechanism_pose_star.matrix());
      }, "The mechanism's handle pose X_V* at theta_star (4, 4) [m].")
      .def_prop_ro("active", [](const CycleOutput& o) { return joint_mask(o.active, o.theta.size()); },
                   "Joints of the nearest placement held at a limit that acts (m,) of bool: "
                   "locked for the filters (a one-sided limit renders contact).")
      .def_prop_ro("active_star",
                   [](const CycleOutput& o) { return joint_mask(o.active_star, o.theta_star.size()); },
                   "Joints of the un-powered placement held at a limit that acts (m,).")
      .def_ro("iterations", &CycleOutput::iterations,
              "Gauss-Newton iterations of this cycle's nearest placement (0: its closed form).")
      .def_ro("iterations_star", &CycleOutput::iterations_star,
              "Gauss-Newton iterations of this cycle's un-powered placement.")
      .def_ro("residual", &CycleOutput::residual,
              "The nearest placement's weighted error sqrt(e^T W_e e) [m] (rotations weighted "
              "by the length scale squared): 0 when the handle is on the mechanism.")
      .def_ro("residual_star", &CycleOutput::residual_star,
              "The un-powered placement's, sqrt(e*^T W_e* e*) [m]; 0 without eq. 26's range "
              "term.")
      .def_ro("ramp", &CycleOutput::ramp, "Ramp-in factor applied, in [0, 1].")
      .def_ro("limit_scale", &CycleOutput::limit_scale, "Factor applied by the force/torque limits.")
      .def_ro("energy", &CycleOutput::energy,
              "The energy tank's level [J]: the energy the rendering has absorbed (0 at the "
              "start, less the motors' work since), at most stored_energy + "
              "passivity_max_energy_j; below 0 a deficit, which fades the range term out "
              "(docs/theory.md, 8). 0 with passivity off.")
      .def_ro("stored_energy", &CycleOutput::stored_energy,
              "What the law's springs hold [J] (the energy tank subtracts it).")
      .def_prop_ro("wrench_passivity",
                   [](const CycleOutput& o) { return Eigen::VectorXd(o.wrench_passivity); },
                   "The part of the range term the energy tank held back (6,), before safety.")
      .def_ro("passivity_scale", &CycleOutput::passivity_scale,
              "The range term's factor the energy tank applied, in [0, 1].")
      .def_ro("status", &CycleOutput::status, "Status bits (virtmech.status).")
      .def_ro("computation_time_us", &CycleOutput::computation_time_us,
              "This cycle's own computation time [µs] (the time-stamp counter where invariant).")
      .def_prop_ro("status_names", [](const CycleOutput& o) { return status_names(o.status); },
                   "The names of the status bits set, e.g. ['ramping'] while the force ramps "
                   "in (virtmech.status).")
      .def_prop_ro("fault", [](const CycleOutput& o) { return (o.status & status::kFaultMask) != 0; },
                   "True when a fault bit is set (status & 0xFF00): the torque is zero.");

  nb::class_<Controller>(m, "Controller",
                         "The virtual-mechanism controller: one step() per servo cycle.")
      .def(
          "__init__",
          [](Controller* self, std::shared_ptr<Device> device, std::shared_ptr<Mechanism> mechanism,
             nb::handle kp, nb::handle kv, nb::handle w_a, nb::handle w_e, nb::handle w_e_star,
             double length_scale, const std::string& law, const std::string& error_velocity,
             double period_s, double ramp_time_s, double watchdog_s, double max_force,
             double max_torque, int max_iterations, int max_iterations_initial,
             double secondary_weight, double range_margin_rad, double range_margin_m,
             const std::string& passivity, double passivity_max_energy_j,
             double passivity_fade_j) {
            ControllerSettings s;
            if (!kp.is_none()) s.kp = to_vec6("kp", kp);
            if (!kv.is_none()) s.kv = to_vec6("kv", kv);
            if (!w_a.is_none()) s.w_a = to_vec6("w_a", w_a);
            if (!w_e.is_none()) s.w_e = to_vec6("w_e", w_e);
            if (!w_e_star.is_none()) s.w_e_star = to_vec6("w_e_star", w_e_star);
            s.length_scale = length_scale;
            s.law = law_from(law);
            s.error_velocity = error_velocity_from(error_velocity);
            s.period_s = period_s;
            s.ramp_time_s = ramp_time_s;
            s.watchdog_s = watchdog_s;
            s.max_force = max_force;
            s.max_torque = max_torque;
            s.max_iterations = max_iterations;
            s.max_iterations_initial = max_iterations_initial;
            s.secondary_weight = secondary_weight;
            s.range_margin_rad = range_margin_rad;
            s.range_margin_m = range_margin_m;
            s.passivity = passivity_from(passivity);
            s.passivity_max_energy_j = passivity_max_energy_j;
            s.passivity_fade_j = passivity_fade_j;
            new (self) Controller(std::move(device), std::move(mechanism), s);
          },
          "device"_a, "mechanism"_a, nb::kw_only(), "kp"_a = nb::none(), "kv"_a = nb::none(),
          "w_a"_a = nb::none(), "w_e"_a = nb::none(), "w_e_star"_a = nb::none(),
          "length_scale"_a = 0.0, "law"_a = "auto", "error_velocity"_a = "relative",
          "period_s"_a = 1e-3, "ramp_time_s"_a = ControllerSettings().ramp_time_s,
          "watchdog_s"_a = 0.0, "max_force"_a = 0.0, "max_torque"_a = 0.0,
          "max_iterations"_a = ControllerSettings().max_iterations,
          "max_iterations_initial"_a = ControllerSettings().max_iterations_initial,
          "secondary_weight"_a = ControllerSettings().secondary_weight,
          "range_margin_rad"_a = ControllerSettings().range_margin_rad,
          "range_margin_m"_a = ControllerSettings().range_margin_m,
          "passivity"_a = "energy_tank",
          "passivity_max_energy_j"_a = ControllerSettings().passivity_max_energy_j,
          "passivity_fade_j"_a = ControllerSettings().passivity_fade_j,
          "Controller(device, mechanism, **settings): validated and allocated here, once; "
          "then step() once per servo cycle.\n\n"
          "Gains and weights are 6-vectors [x y z rx ry rz]; unset ones take the defaults of "
          "docs/theory.md (derived from the device's actuation and the length scale L).\n"
          "kp: stiffness [N/m x3; N·m/rad x3]. kv: damping [N·s/m x3; N·m·s/rad x3].\n"
          "w_a, w_e, w_e_star: the filters' weights W_A and the placements' W_e, W_e* "
          "(eq. 25), rotations weighted by L^2.\n"
          "length_scale: L [m]; 0 takes the mechanism's.\n"
          "law: 'auto' (eq. 26 on an under-actuated device, else eq. 11) | 'null_space' "
          "(eq. 11) | 'under_actuated' (eq. 26).\n"
          "error_velocity: 'relative' | 'handle' (docs/theory.md, 3).\n"
          "period_s: the servo period [s]. ramp_time_s: the force's ramp-in after the start, "
          "a fault or a watchdog trip [s].\n"
          "watchdog_s: the longest gap allowed between the time stamps t of step(q, dq, t) [s]; "
          "a longer gap, or time running backwards, restarts the ramp-in and empties the "
          "energy tank (status 'watchdog'); 0: off.\n"
          "max_force [N], max_torque [N·m]: limits on the wrench at the handle; 0 takes the "
          "device's.\n"
          "max_iterations, max_iterations_initial: placement iterations per cycle, and on the "
          "first cycle.\n"
          "secondary_weight: the weight of [1 1 1 L^2 L^2 L^2] added to W_e and W_e* "
          "(dimensionless), so that directions their weights leave free are settled by the "
          "full pose error instead of drifting.\n"
          "range_margin_rad [rad], range_margin_m [m]: how far q may leave the device's joint "
          "range (revolute, prismatic joints) before the cycle faults (fault_out_of_range).\n"
          "passivity: 'energy_tank' (default: eq. 26's range term never gives more than the "
          "user put in; docs/theory.md, 8) | 'off' (the laws as written).\n"
          "passivity_max_energy_j: the most the tank holds beyond the springs' energy [J]. "
          "passivity_fade_j: the range term fades out as the tank falls from 0 to -this [J].")
      .def(
          "step",
          [](Controller& self, nb::handle q, nb::handle dq, double t, nb::handle out,
             nb::handle torque) -> nb::object {
            const int n = self.device().dof();
            const JointVector qv = joint_values("q", q, n);
            const JointVector dqv = joint_values("dq", dq, n);
            nb::object result;
            CycleOutput* o = nullptr;
            if (out.is_none()) {
              result = nb::cast(CycleOutput());
            } else if (nb::isinstance<CycleOutput>(out)) {
              result = nb::borrow(out);
            } else {
              throw nb::type_error(("out: expected a virtmech.CycleOutput to fill, got " +
                                    short_repr(out)).c_str());
            }
            o = nb::inst_ptr<CycleOutput>(result);
            std::optional<DoubleBuffer> tau;
            if (!torque.is_none()) {
              tau.emplace(torque, n, true);
              if (!tau->ok) {
                throw nb::type_error(("torque: expected a writable, contiguous float64 array "
                                      "of shape (" + std::to_string(n) + ",), got " +
                                      short_repr(torque)).c_str());
              }
            }
            self.step(qv.data(), dqv.data(), *o, t);
            if (tau) {
              for (int i = 0; i < n; ++i) tau->data()[i] = o->torque[i];
            }
            return result;
          },
          "q"_a, "dq"_a, "t"_a = std::numeric_limits<double>::quiet_NaN(), nb::kw_only(),
          "out"_a = nb::none(), "torque"_a = nb::none(),
          "One servo cycle: device joint positions q (n,) and velocities dq (n,) in; returns a "
          "CycleOutput. t: the cycle's time stamp [s] for the watchdog (optional). out: a "
          "CycleOutput to fill in place (returned); torque: a float64 array (n,) to receive "
          "the joint torques. With both, and q, dq float64 arrays, a Python servo loop creates "
          "no object per cycle. Non-finite or implausible inputs give zero torque and a fault "
          "status, never an exception.")
      .def("reset", &Controller::reset, "Restart: placements from home, ramp-in from zero.")
      .def_prop_ro("device", [](const Controller& c) { return std::const_pointer_cast<Device>(c.device_ptr()); })
      .def_prop_ro("mechanism", [](const Controller& c) { return std::const_pointer_cast<Mechanism>(c.mechanism_ptr()); })
      .def_prop_ro("model", [](const Controller& c) { return model_dict(c.model()); },
                   "The resolved settings (every default filled in).")
      .def_prop_ro("last", [](const Controller& c) { return c.last(); }, "The last cycle's output.");

  nb::class_<MechanismSetOutput>(m, "MechanismSetOutput",
                                 "Everything one cycle of a MechanismSet reports.")
      .def(nb::init<>())
      .def_ro("cycle", &MechanismSetOutput::cycle,
              "The rendered member's CycleOutput, torque and wrench the set's output (member "
              "0's with zero force when none is engaged).")
      .def_ro("active", &MechanismSetOutput::active, "The member rendered, -1 for none.")
      .def_ro("switching", &MechanismSetOutput::switching,
              "The output is moving from one member's force to another's at the set rates.")
      .def_prop_ro("distance",
                   [](const MechanismSetOutput& o) {
                     return Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(o.distance.data(), o.size));
                   },
                   "Each member's distance from the handle [m] (0 for a unilateral member in "
                   "contact, its tip's height out of it).")
      .def_prop_ro("contact",
                   [](const MechanismSetOutput& o) {
                     nb::list l;
                     for (int i = 0; i < o.size; ++i) l.append(bool((o.contact >> i) & 1u));
                     return l;
                   },
                   "Per member: unilateral and in contact.")
      .def_prop_ro("torque", [](const MechanismSetOutput& o) { return Eigen::VectorXd(o.cycle.torque); },
                   "The set's joint torques (n,) [N·m or N] (cycle.torque).")
      .def_prop_ro("wrench", [](const MechanismSetOutput& o) { return o.cycle.wrench; },
                   "The set's wrench at the handle (6,) [N; N·m] (cycle.wrench).")
      .def_prop_ro("status", [](const MechanismSetOutput& o) { return o.cycle.status; },
                   "Status bits of the rendered member's cycle (virtmech.status).")
      .def_prop_ro("status_names", [](const MechanismSetOutput& o) { return status_names(o.cycle.status); },
                   "The names of the status bits set (virtmech.status).");

  nb::class_<MechanismSet>(
      m, "MechanismSet",
      "Several mechanisms on one device, at most one rendered per cycle: a member engages "
      "within snap_distance [m] and lets go beyond release_distance (hysteresis; a "
      "unilateral member's distance is its tip's height, 0 in contact); switching moves the "
      "force at most force_rate [N/s] and moment_rate [N m/s].")
      .def(
          "__init__",
          [](MechanismSet* self, std::shared_ptr<Device> device, int capacity,
             double snap_distance, double release_distance, double force_rate,
             double moment_rate, double period_s) {
            MechanismSetSettings s;
            s.snap_distance = snap_distance;
            s.release_distance = release_distance;
            s.force_rate = force_rate;
            s.moment_rate = moment_rate;
            s.period_s = period_s;
            new (self) MechanismSet(std::move(device), capacity, s);
          },
          "device"_a, "capacity"_a = 4, nb::kw_only(),
          "snap_distance"_a = MechanismSetSettings().snap_distance,
          "release_distance"_a = MechanismSetSettings().release_distance,
          "force_rate"_a = MechanismSetSettings().force_rate,
          "moment_rate"_a = MechanismSetSettings().moment_rate,
          "period_s"_a = MechanismSetSettings().period_s)
      .def(
          "add", [](MechanismSet& self, const Controller& member) { return self.add(member); },
          "member"_a,
          "Adds a member: a copy of a Controller of the set's device and the member's "
          "mechanism (its settings as Controller's). Returns its index.")
      .def(
          "step",
          [](MechanismSet& self, nb::handle q, nb::handle dq, double t, nb::handle out) {
            const int n = self.device().dof();
            const JointVector qv = joint_values("q", q, n);
            const JointVector dqv = joint_values("dq", dq, n);
            nb::object result;
            if (out.is_none()) {
              result = nb::cast(MechanismSetOutput());
            } else if (nb::isinstance<MechanismSetOutput>(out)) {
              result = nb::borrow(out);
            } else {
              throw nb::type_error(("out: expected a virtmech.MechanismSetOutput to fill, got " +
                                    short_repr(out)).c_str());
            }
            self.step(qv.data(), dqv.data(), *nb::inst_ptr<MechanismSetOutput>(result), t);
            return result;
          },
          "q"_a, "dq"_a, "t"_a = std::numeric_limits<double>::quiet_NaN(), nb::kw_only(),
          "out"_a = nb::none(), "One servo cycle of every member; returns a MechanismSetOutput.")
      .def("reset", &MechanismSet::reset)
      .def_prop_ro("size", &MechanismSet::size)
      .def_prop_ro("capacity", &MechanismSet::capacity)
      .def_prop_ro("active", &MechanismSet::active)
      .def_prop_ro("last", [](const MechanismSet& s) { return s.last(); },
                   "The last cycle's MechanismSetOutput.")
      .def_prop_ro("device", [](const MechanismSet& s) {
        return std::const_pointer_cast<Device>(s.member(0).device_ptr());
      })
      .def("member", [](const MechanismSet& s, int i) {
        if (i < 0 || i >= s.size()) {
          throw nb::index_error(("i: expected 0 <= i < " + std::to_string(s.size()) + ", got " +
                                 std::to_string(i)).c_str());
        }
        return std::const_pointer_cast<Mechanism>(s.member(i).mechanism_ptr());
      }, "i"_a, "The i-th member's mechanism.");

}
