#include "virtmech.h"

#include <cmath>
#include <cstring>
#include <exception>
#include <limits>
#include <memory>
#include <new>
#include <string>

#include "c_api_handles.hpp"
#include "virtmech/params.hpp"
#include "virtmech/validate.hpp"
#include "virtmech/virtmech.hpp"

using namespace virtmech;

// the C status bits are the C++ ones
static_assert(VM_STATUS_OK == status::kOk);
static_assert(VM_STATUS_RAMPING == status::kRamping);
static_assert(VM_STATUS_FORCE_CLAMPED == status::kForceClamped);
static_assert(VM_STATUS_TORQUE_CLAMPED == status::kTorqueClamped);
static_assert(VM_STATUS_NOT_CONVERGED == status::kNotConverged);
static_assert(VM_STATUS_WATCHDOG == status::kWatchdog);
static_assert(VM_STATUS_PASSIVITY == status::kPassivity);
static_assert(VM_STATUS_SWITCHING == status::kSwitching);
static_assert(VM_STATUS_FAULT_NONFINITE_INPUT == status::kFaultNonFiniteInput);
static_assert(VM_STATUS_FAULT_NONFINITE_OUTPUT == status::kFaultNonFiniteOutput);
static_assert(VM_STATUS_FAULT_BAD_SIZE == status::kFaultBadSize);
static_assert(VM_STATUS_FAULT_OUT_OF_RANGE == status::kFaultOutOfRange);
static_assert(VM_STATUS_FAULT_IMPLAUSIBLE_VELOCITY == status::kFaultImplausibleVelocity);
static_assert(VM_STATUS_FAULT_MASK == status::kFaultMask);
static_assert(VM_MAX_DOF == kMaxDof);
static_assert(VM_MAX_SET_MEMBERS == kMaxSetMembers);

struct vm_controller {
  Controller controller;
  CycleOutput out;
  vm_controller(std::shared_ptr<const Device> d, std::shared_ptr<const Mechanism> m,
                const ControllerSettings& s)
      : controller(std::move(d), std::move(m), s) {
    out.torque = JointVector::Zero(controller.device().dof());
  }
};

// A curve or a surface (exactly one of them non-null).
struct vm_shape {
  std::shared_ptr<const Curve> curve;
  std::shared_ptr<const Surface> surface;
};

struct vm_mechanism_set {
  std::shared_ptr<const Device> device;  // the set's, for building members
  MechanismSet set;
  MechanismSetOutput out;
  vm_mechanism_set(std::shared_ptr<const Device> d, int capacity, const MechanismSetSettings& s)
      : device(d), set(std::move(d), capacity, s) {
    out.cycle.torque = JointVector::Zero(set.device().dof());
  }
};

namespace {

Pose pose_from(const double* rm) {
  Eigen::Matrix4d M;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) M(r, c) = rm[4 * r + c];
  Pose T;
  T.matrix() = M;
  return T;
}

void pose_to(const Pose& T, double* rm) {
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) rm[4 * r + c] = T.matrix()(r, c);
}

void identity16(double* m) {
  for (int i = 0; i < 16; ++i) m[i] = (i % 5 == 0) ? 1.0 : 0.0;
}

// identity poses, z axes, no limits
void init_chain(vm_chain& c) {
  identity16(c.base);
  identity16(c.handle);
  for (auto& j : c.joints) {
    identity16(j.origin);
    j.axis[2] = 1.0;
    j.lower = -HUGE_VAL;
    j.upper = HUGE_VAL;
  }
}

Eigen::Vector3d v3(const double* v) { return Eigen::Vector3d(v[0], v[1], v[2]); }

Pose checked_pose(const std::string& name, const double* rm) {
  const Pose T = pose_from(rm);
  require_pose(name, T);
  return T;
}

KinematicChain chain_from(const vm_chain& c) {
  if (c.dof < 1 || c.dof > VM_MAX_DOF) {
    throw std::invalid_argument("chain.dof: expected 1 to " + std::to_string(VM_MAX_DOF) +
                                ", got " + std::to_string(c.dof));
  }
  std::vector<Joint> joints;
  for (int i = 0; i < c.dof; ++i) {
    Joint j;
    j.type = enum_from_int<JointType>("chain.joints[" + std::to_string(i) + "].type",
                                      c.joints[i].type);
    j.axis = v3(c.joints[i].axis);
    j.origin = pose_from(c.joints[i].origin);
    j.lower = c.joints[i].lower;
    j.upper = c.joints[i].upper;
    joints.push_back(j);
  }
  return KinematicChain(pose_from(c.base), joints, pose_from(c.handle));
}

std::shared_ptr<const Device> device_from(const vm_device_desc& d) {
  switch (d.type) {
    case VM_DEVICE_PHANTOM_OMNI: {
      PhantomOmniParams p;
      p.l1 = d.link1;
      p.l2 = d.link2;
      p.max_force = d.max_force;
      for (int i = 0; i < 3; ++i) {
        p.motor_torque_limit[static_cast<size_t>(i)] = d.torque_limit[i];
        p.gimbal_offset[static_cast<size_t>(i)] = d.gimbal_offset[i];
        p.gimbal_sign[static_cast<size_t>(i)] = d.gimbal_sign[i];
      }
      p.stiffness = d.stiffness;
      p.damping = d.damping;
      return std::make_shared<PhantomOmni>(p);
    }
    case VM_DEVICE_PLANAR3R:
      return std::make_shared<Planar3R>(d.link1, d.link2, checked_pose("device.base", d.base),
                                        d.torque_limit[0], d.max_force);
    case VM_DEVICE_SERIAL: {
      const KinematicChain chain = chain_from(d.chain);
      DeviceLimits L;
      for (int i = 0; i < chain.dof(); ++i) {
        L.actuated.push_back(d.actuated[i] != 0);
        L.torque_limit.push_back(d.torque_limit[i] > 0.0 ? d.torque_limit[i] : kInf);
      }
      L.max_force = d.max_force > 0.0 ? d.max_force : kInf;
      L.max_torque = d.max_torque > 0.0 ? d.max_torque : kInf;
      L.stiffness = d.stiffness;
      L.damping = d.damping;
      const size_t len = strnlen(d.name, sizeof d.name);
      if (len == sizeof d.name) {
        throw std::invalid_argument("device.name: expected a NUL-terminated string of at most " +
                                    std::to_string(sizeof d.name - 1) + " characters");
      }
      return std::make_shared<SerialDevice>(len ? std::string(d.name, len) : "SerialDevice",
                                            chain, L);
    }
  }
  throw std::invalid_argument("device.type: expected VM_DEVICE_PHANTOM_OMNI, VM_DEVICE_PLANAR3R "
                              "or VM_DEVICE_SERIAL, got " + std::to_string(d.type));
}

bool unilateral_from(const vm_mechanism_desc& m) {
  if (m.type == VM_MECHANISM_PLANAR_ARM || m.type == VM_MECHANISM_SERIAL ||
      m.type == VM_MECHANISM_CURVE_GUIDE || m.type == VM_MECHANISM_HANDLE_PATH) {
    if (m.unilateral != 0) {
      throw std::invalid_argument(
          "mechanism.unilateral: expected 0 (a PlanarArm, CurveGuide, HandlePath or serial "
          "chain has no lift-off joint; give a serial chain a joint limit instead), got " +
          std::to_string(m.unilateral));
    }
    return false;
  }
  if (m.unilateral != 0 && m.unilateral != 1) {
    throw std::invalid_argument("mechanism.unilateral: expected 0 or 1, got " +
                                std::to_string(m.unilateral));
  }
  return m.unilateral == 1;
}

const char* shape_kind(const vm_shape* s) {
  return !s ? "NULL" : s->surface ? "a surface" : "a curve";
}

std::shared_ptr<const Surface> surface_of(const vm_mechanism_desc& m) {
  if (m.shape && m.shape->surface) return m.shape->surface;
  throw std::invalid_argument(
      std::string("mechanism.shape: expected a surface (vm_nurbs_surface_create, "
                  "vm_sphere_create, vm_cylinder_create or vm_plane_create), got ") +
      shape_kind(m.shape));
}

std::shared_ptr<const Curve> curve_of(const vm_mechanism_desc& m) {
  if (m.shape && m.shape->curve) return m.shape->curve;
  throw std::invalid_argument(
      std::string("mechanism.shape: expected a curve (vm_nurbs_curve_create), got ") +
      shape_kind(m.shape));
}

// a zero normal means +z (CurveGuide, HandlePath)
Eigen::Vector3d normal_or_z(const double* n) {
  const Eigen::Vector3d v = v3(n);
  return v.isZero(0.0) ? Eigen::Vector3d::UnitZ() : v;
}

std::shared_ptr<const Mechanism> mechanism_from(const vm_mechanism_desc& m) {
  switch (m.type) {
    case VM_MECHANISM_PLANAR_ARM:
      unilateral_from(m);
      return std::make_shared<PlanarArm>(v3(m.point), v3(m.normal), m.length, v3(m.direction));
    case VM_MECHANISM_PROBE:
      return std::make_shared<Probe>(v3(m.point), v3(m.normal), m.length, v3(m.direction),
                                     unilateral_from(m));
    case VM_MECHANISM_POINT_PIVOT:
      return std::make_shared<PointPivot>(v3(m.point), v3(m.normal), m.length, v3(m.direction),
                                          unilateral_from(m));
    case VM_MECHANISM_LINE_GUIDE:
      return std::make_shared<LineGuide>(v3(m.point), v3(m.direction), m.length, v3(m.normal),
                                         unilateral_from(m));
    case VM_MECHANISM_SERIAL:
      unilateral_from(m);
      return std::make_shared<SerialChain>(chain_from(m.chain), m.length_scale);
    case VM_MECHANISM_SURFACE_PROBE:
      return std::make_shared<SurfaceProbe>(surface_of(m), m.length, unilateral_from(m));
    case VM_MECHANISM_CURVE_GUIDE:
      unilateral_from(m);
      return std::make_shared<CurveGuide>(curve_of(m), m.length, normal_or_z(m.normal));
    case VM_MECHANISM_HANDLE_PATH:
      unilateral_from(m);
      return std::make_shared<HandlePath>(curve_of(m), normal_or_z(m.normal),
                                          m.length_scale == 0.0 ? 0.1 : m.length_scale);
  }
  throw std::invalid_argument("mechanism.type: expected a vm_mechanism_type, got " +
                              std::to_string(m.type));
}

Vector6 v6(const double* v) {
  Vector6 out;
  for (int i = 0; i < 6; ++i) out[i] = v[i];
  return out;
}

// One conversion per row of VM_CONTROLLER_SETTINGS; an enumeration's int is checked
// before it becomes the C++ enumeration.
ControllerSettings settings_from(const vm_settings& s) {
  ControllerSettings c;
#define VM_FROM_VEC6(name, unit, doc) \
  if (s.has_##name) c.name = v6(s.name);
#define VM_FROM_REAL(name, value, min, max, flags, unit, doc) c.name = s.name;
#define VM_FROM_INT(name, value, min, max, unit, doc) c.name = s.name;
#define VM_FROM_ENUM(name, Type, value, doc) c.name = enum_from_int<Type>(#name, s.name);
  VM_CONTROLLER_SETTINGS(VM_FROM_VEC6, VM_FROM_REAL, VM_FROM_INT, VM_FROM_ENUM)
#undef VM_FROM_VEC6
#undef VM_FROM_INT
#undef VM_FROM_ENUM
  return c;
}

MechanismSetSettings set_settings_from(const vm_set_settings& s) {
  MechanismSetSettings c;
  VM_SET_SETTINGS(VM_FROM_REAL)
  return c;
}
#undef VM_FROM_REAL

// The C++ constructors name their own parameters ("zero_direction: expected ..."); a C
// caller fills struct fields: the message names the field ("mechanism.direction: ...").
std::string c_field(const std::string& table, const std::string& name) {
  static const std::pair<const char*, const char*> kMechanism[] = {
      {"pivot", "point"},          {"plane_point", "point"}, {"plane_normal", "normal"},
      {"zero_direction", "direction"}, {"tangent", "direction"}, {"length_scale", "length_scale"}};
  static const std::pair<const char*, const char*> kDevice[] = {
      {"l1", "link1"}, {"l2", "link2"}, {"motor_torque_limit", "torque_limit"}};
  if (table == "mechanism") {
    for (const auto& [cpp, c] : kMechanism)
      if (name == cpp) return c;
  } else if (table == "device") {
    for (const auto& [cpp, c] : kDevice)
      if (name == cpp) return c;
  }
  return name;
}

template <typename Desc, typename Make>
auto in_c_terms(const char* table, const Desc& desc, Make make) -> decltype(make(desc)) {
  try {
    return make(desc);
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    if (msg.rfind(std::string(table) + ".", 0) == 0) throw;  // already in C terms
    // "name[i]...: rest" -> "table.c_name[i]...: rest"
    const size_t colon = msg.find(':');
    const size_t end = std::min(colon, msg.find('['));
    if (colon == std::string::npos || end == 0) throw;
    const std::string name = msg.substr(0, end);
    throw std::invalid_argument(std::string(table) + "." + c_field(table, name) +
                                msg.substr(end));
  }
}

void write_error(char* error, size_t size, const char* msg) {
  if (!error || size == 0) return;
  std::strncpy(error, msg, size - 1);
  error[size - 1] = '\0';
}

void copy_vec(const Eigen::Ref<const Eigen::VectorXd>& v, double* out, int n) {
  for (int i = 0; i < n; ++i) out[i] = i < v.size() ? v[i] : 0.0;
}

// Runs a setup call: its result (VM_OK or an index) on success and an empty error; a thrown
// std::invalid_argument is VM_ERROR_ARGUMENT, any other exception (out of memory)
// VM_ERROR_INTERNAL, with the message in error.
template <typename Call>
int c_call(char* error, size_t error_size, Call call) {
  try {
    const int result = call();
    write_error(error, error_size, "");
    return result;
  } catch (const std::invalid_argument& e) {
    write_error(error, error_size, e.what());
    return VM_ERROR_ARGUMENT;
  } catch (const std::exception& e) {
    write_error(error, error_size, e.what());
    return VM_ERROR_INTERNAL;
  }
}

// A creator: *out = make() (a new object), or NULL and an error.
template <typename T, typename Make>
int create_into(T** out, const char* what, char* error, size_t error_size, Make make) {
  if (!out) {
    write_error(error, error_size,
                (std::string("out: expected a pointer to receive the ") + what + ", got NULL")
                    .c_str());
    return VM_ERROR_ARGUMENT;
  }
  *out = nullptr;
  return c_call(error, error_size, [&] {
    *out = make();
    return VM_OK;
  });
}

void require_array(const char* name, const void* p, const std::string& size) {
  if (!p) {
    throw std::invalid_argument(std::string(name) + ": expected " + size + " values, got NULL");
  }
}

void require_count(const char* name, int n, int least, const char* what) {
  if (n < least) {
    throw std::invalid_argument(std::string(name) + ": expected at least " +
                                std::to_string(least) + " " + what + ", got " +
                                std::to_string(n));
  }
}

// checked before a knot array's length n + degree + 1 is read (the constructors check it
// again with the same message)
void require_degree(const char* name, int p) {
  if (p < 1 || p > kMaxNurbsDegree) {
    throw std::invalid_argument(std::string(name) + ": expected 1 to " +
                                std::to_string(kMaxNurbsDegree) + ", got " + std::to_string(p));
  }
}

using RowPoints = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>;
using Values = Eigen::Map<const Eigen::VectorXd>;

// Copies the C++ cycle output into the C diagnostics (a controller's and a set's).
void copy_diagnostics(const CycleOutput& o, int device_dof, int mechanism_dof,
                      vm_diagnostics* d) {
  d->device_dof = device_dof;
  d->mechanism_dof = mechanism_dof;
#define VM_COPY_JOINTS(name, doc) copy_vec(o.name, d->name, VM_MAX_DOF);
#define VM_COPY_VEC6(name, doc) copy_vec(o.name, d->name, 6);
#define VM_COPY_POSE(name, doc) pose_to(o.name, d->name);
#define VM_COPY_VALUE(name, ...) d->name = o.name;
  VM_CYCLE_OUTPUT(VM_COPY_JOINTS, VM_COPY_VEC6, VM_COPY_POSE, VM_COPY_VALUE, VM_COPY_VALUE,
                  VM_COPY_VALUE, VM_COPY_VALUE)
#undef VM_COPY_JOINTS
#undef VM_COPY_VEC6
#undef VM_COPY_POSE
#undef VM_COPY_VALUE
}

// Zeroes tau[0..n) for a call the cycle cannot run (NULL pointers, a wrong n).
void zero_torque(double* tau, int n) {
  if (tau) for (int i = 0; i < n; ++i) tau[i] = 0.0;
}

}  // namespace

extern "C" {

void vm_device_desc_init(vm_device_desc* desc, int type) {
  std::memset(desc, 0, sizeof(*desc));
  desc->type = type;
  identity16(desc->base);
  init_chain(desc->chain);
  const DeviceLimits serial;
  desc->stiffness = serial.stiffness;
  desc->damping = serial.damping;
  if (type == VM_DEVICE_PHANTOM_OMNI) {
    const PhantomOmniParams p;
    desc->link1 = p.l1;
    desc->link2 = p.l2;
    desc->max_force = p.max_force;
    for (int i = 0; i < 3; ++i) {
      desc->torque_limit[i] = p.motor_torque_limit[static_cast<size_t>(i)];
      desc->gimbal_offset[i] = p.gimbal_offset[static_cast<size_t>(i)];
      desc->gimbal_sign[i] = p.gimbal_sign[static_cast<size_t>(i)];
    }
    desc->stiffness = p.stiffness;
    desc->damping = p.damping;
  } else if (type == VM_DEVICE_PLANAR3R) {
    desc->link1 = Planar3RDefaults::kLink;
    desc->link2 = Planar3RDefaults::kLink;
    desc->torque_limit[0] = Planar3RDefaults::kTorqueLimit;
    desc->max_force = Planar3RDefaults::kMaxForce;
  }
}

void vm_mechanism_desc_init(vm_mechanism_desc* desc, int type) {
  std::memset(desc, 0, sizeof(*desc));
  desc->type = type;
  desc->normal[2] = 1.0;
  desc->length = 0.1;
  desc->length_scale = 0.1;
  if (type == VM_MECHANISM_LINE_GUIDE) desc->direction[0] = 1.0;  // PlanarArm: automatic
  init_chain(desc->chain);
  desc->shape = nullptr;
}

void vm_settings_init(vm_settings* s) {
  std::memset(s, 0, sizeof(*s));
  const ControllerSettings d;
#define VM_INIT_VEC6(name, unit, doc)
#define VM_INIT_REAL(name, value, min, max, flags, unit, doc) s->name = d.name;
#define VM_INIT_INT(name, value, min, max, unit, doc) s->name = d.name;
#define VM_INIT_ENUM(name, Type, value, doc) s->name = static_cast<int>(d.name);
  VM_CONTROLLER_SETTINGS(VM_INIT_VEC6, VM_INIT_REAL, VM_INIT_INT, VM_INIT_ENUM)
#undef VM_INIT_VEC6
#undef VM_INIT_INT
#undef VM_INIT_ENUM
}

int vm_controller_create(const vm_device_desc* device, const vm_mechanism_desc* mechanism,
                         const vm_settings* settings, vm_controller** out, char* error,
                         size_t error_size) {
  return create_into(out, "controller", error, error_size, [&] {
    if (!device || !mechanism) {
      throw std::invalid_argument("device/mechanism: expected descriptions, got NULL");
    }
    vm_settings defaults;
    vm_settings_init(&defaults);
    auto dev = in_c_terms("device", *device, device_from);
    auto mech = in_c_terms("mechanism", *mechanism, mechanism_from);
    // the settings are checked against the device and mechanism by the controller itself
    return in_c_terms("settings", settings ? *settings : defaults, [&](const vm_settings& s) {
      return new vm_controller(dev, mech, settings_from(s));
    });
  });
}

void vm_controller_destroy(vm_controller* controller) { delete controller; }

int vm_controller_dof(const vm_controller* c) { return c ? c->controller.device().dof() : 0; }

uint32_t vm_controller_step(vm_controller* c, const double* q, const double* dq, int n,
                            double t_s, double* tau) {
  if (!c || !q || !dq || n != c->controller.device().dof()) {
    zero_torque(tau, n);
    if (!c) return VM_STATUS_FAULT_BAD_SIZE;
    // through the controller, so that it ramps in again once the calls are right
    const Eigen::Map<const Eigen::VectorXd> none(nullptr, 0);
    return c->controller.step(none, none, c->out, t_s);
  }
  const uint32_t s = c->controller.step(q, dq, c->out, t_s);
  if (tau) for (int i = 0; i < n; ++i) tau[i] = c->out.torque[i];
  return s;
}

void vm_controller_reset(vm_controller* c) {
  if (c) c->controller.reset();
}

void vm_controller_diagnostics(const vm_controller* c, vm_diagnostics* d) {
  if (!c || !d) return;
  copy_diagnostics(c->out, c->controller.device().dof(), c->controller.mechanism().dof(), d);
}

// ---- shapes ------------------------------------------------------------------------------

int vm_nurbs_curve_create(const double* control_points, const double* weights, int n,
                          const double* knots, int degree, vm_shape** out, char* error,
                          size_t error_size) {
  return create_into(out, "shape", error, error_size, [&] {
    require_count("n", n, 1, "control point");
    require_degree("degree", degree);
    require_array("control_points", control_points, "n x 3");
    require_array("weights", weights, "n");
    require_array("knots", knots, "n + degree + 1");
    auto curve = std::make_shared<NurbsCurve>(RowPoints(control_points, n, 3),
                                              Values(weights, n), Values(knots, n + degree + 1),
                                              degree);
    return new vm_shape{std::move(curve), nullptr};
  });
}

int vm_nurbs_surface_create(const double* control_points, const double* weights, int nu,
                            int nv, const double* knots_u, const double* knots_v, int degree_u,
                            int degree_v, vm_shape** out, char* error, size_t error_size) {
  return create_into(out, "shape", error, error_size, [&] {
    require_count("nu", nu, 1, "control point");
    require_count("nv", nv, 1, "control point");
    require_degree("degree_u", degree_u);
    require_degree("degree_v", degree_v);
    require_array("control_points", control_points, "nu * nv x 3");
    require_array("weights", weights, "nu * nv");
    require_array("knots_u", knots_u, "nu + degree_u + 1");
    require_array("knots_v", knots_v, "nv + degree_v + 1");
    using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    const Eigen::MatrixXd W = Eigen::Map<const RowMatrix>(weights, nu, nv);
    auto surface = std::make_shared<NurbsSurface>(
        RowPoints(control_points, static_cast<Eigen::Index>(nu) * nv, 3), W,
        Values(knots_u, nu + degree_u + 1), Values(knots_v, nv + degree_v + 1), degree_u,
        degree_v);
    return new vm_shape{nullptr, std::move(surface)};
  });
}

int vm_sphere_create(const double center[3], double radius, const double axis[3],
                     vm_shape** out, char* error, size_t error_size) {
  return create_into(out, "shape", error, error_size, [&] {
    require_array("center", center, "3");
    auto sphere = std::make_shared<Sphere>(v3(center), radius,
                                           axis ? v3(axis) : Eigen::Vector3d::UnitZ());
    return new vm_shape{nullptr, std::move(sphere)};
  });
}

int vm_cylinder_create(const double point[3], const double direction[3], double radius,
                       vm_shape** out, char* error, size_t error_size) {
  return create_into(out, "shape", error, error_size, [&] {
    require_array("point", point, "3");
    require_array("direction", direction, "3");
    auto cylinder = std::make_shared<Cylinder>(v3(point), v3(direction), radius);
    return new vm_shape{nullptr, std::move(cylinder)};
  });
}

int vm_plane_create(const double point[3], const double normal[3], vm_shape** out, char* error,
                    size_t error_size) {
  return create_into(out, "shape", error, error_size, [&] {
    require_array("point", point, "3");
    require_array("normal", normal, "3");
    return new vm_shape{nullptr, std::make_shared<Plane>(v3(point), v3(normal))};
  });
}

void vm_shape_destroy(vm_shape* shape) { delete shape; }

// ---- mechanism sets ----------------------------------------------------------------------

void vm_set_settings_init(vm_set_settings* s) {
  const MechanismSetSettings d;
  VM_SET_SETTINGS(VM_INIT_REAL)
}
#undef VM_INIT_REAL

int vm_mechanism_set_create(const vm_device_desc* device, int capacity,
                            const vm_set_settings* settings, vm_mechanism_set** out,
                            char* error, size_t error_size) {
  return create_into(out, "mechanism set", error, error_size, [&] {
    if (!device) throw std::invalid_argument("device: expected a description, got NULL");
    auto dev = in_c_terms("device", *device, device_from);
    const MechanismSetSettings s = settings ? set_settings_from(*settings) : MechanismSetSettings();
    try {
      return new vm_mechanism_set(dev, capacity, s);
    } catch (const std::invalid_argument& e) {
      // the set names capacity (a parameter) or a settings field
      if (std::strncmp(e.what(), "capacity:", 9) == 0) throw;
      throw std::invalid_argument(std::string("settings.") + e.what());
    }
  });
}

int vm_mechanism_set_add(vm_mechanism_set* set, const vm_mechanism_desc* mechanism,
                         const vm_settings* settings, char* error, size_t error_size) {
  return c_call(error, error_size, [&] {
    if (!set) throw std::invalid_argument("set: expected a mechanism set, got NULL");
    if (!mechanism) throw std::invalid_argument("mechanism: expected a description, got NULL");
    vm_settings defaults;
    vm_settings_init(&defaults);
    auto mech = in_c_terms("mechanism", *mechanism, mechanism_from);
    const Controller member =
        in_c_terms("settings", settings ? *settings : defaults, [&](const vm_settings& s) {
          return Controller(set->device, mech, settings_from(s));
        });
    return set->set.add(member);  // "member: the set is full (capacity ...)"
  });
}

void vm_mechanism_set_destroy(vm_mechanism_set* set) { delete set; }

int vm_mechanism_set_dof(const vm_mechanism_set* set) { return set ? set->set.device().dof() : 0; }

uint32_t vm_mechanism_set_step(vm_mechanism_set* set, const double* q, const double* dq, int n,
                               double t_s, double* tau) {
  if (!set || !q || !dq || n != set->set.device().dof()) {
    zero_torque(tau, n);
    if (!set) return VM_STATUS_FAULT_BAD_SIZE;
    // through the set with a non-finite joint state, so that every member faults (and ramps
    // in again once the calls are right); reported as the bad call it is
    static constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
    static constexpr double kNone[VM_MAX_DOF] = {kNan, kNan, kNan, kNan, kNan, kNan, kNan, kNan};
    set->set.step(kNone, kNone, set->out, t_s);
    set->out.cycle.status =
        (set->out.cycle.status & ~status::kFaultNonFiniteInput) | status::kFaultBadSize;
    return set->out.cycle.status;
  }
  const uint32_t s = set->set.step(q, dq, set->out, t_s);
  if (tau) for (int i = 0; i < n; ++i) tau[i] = set->out.cycle.torque[i];
  return s;
}

void vm_mechanism_set_reset(vm_mechanism_set* set) {
  if (set) set->set.reset();
}

void vm_mechanism_set_diagnostics(const vm_mechanism_set* set, vm_set_diagnostics* d) {
  if (!set || !d) return;
  const MechanismSetOutput& o = set->out;
  // the member whose cycle o.cycle is: the rendered one, else member 0
  const int shown = o.active >= 0 ? o.active : 0;
  const int mechanism_dof = shown < set->set.size() ? set->set.member(shown).mechanism().dof() : 0;
  copy_diagnostics(o.cycle, set->set.device().dof(), mechanism_dof, &d->cycle);
  d->active = o.active;
  d->size = o.size;
  for (int i = 0; i < VM_MAX_SET_MEMBERS; ++i) d->distance[i] = o.distance[static_cast<size_t>(i)];
  d->contact = o.contact;
  d->switching = o.switching ? 1 : 0;
}

const char* vm_version(void) { return VIRTMECH_VERSION_STRING; }

}  // extern "C"

// the C++ objects behind the handles (c_api_handles.hpp)
Controller& virtmech::detail::controller_of(vm_controller* controller) noexcept {
  return controller->controller;
}
MechanismSet& virtmech::detail::set_of(vm_mechanism_set* set) noexcept { return set->set; }
