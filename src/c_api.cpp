#include "virtmech.h"

#include <cmath>
#include <cstring>
#include <exception>
#include <memory>
#include <new>
#include <string>

#include "virtmech/virtmech.hpp"

using namespace virtmech;

struct vm_controller {
  Controller controller;
  CycleOutput out;
  vm_controller(std::shared_ptr<const Device> d, std::shared_ptr<const Mechanism> m,
                const ControllerSettings& s)
      : controller(std::move(d), std::move(m), s) {
    out.torque = JointVector::Zero(controller.device().dof());
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

KinematicChain chain_from(const vm_chain& c) {
  if (c.dof < 1 || c.dof > VM_MAX_DOF) {
    throw std::invalid_argument("chain.dof: expected 1 to " + std::to_string(VM_MAX_DOF) +
                                ", got " + std::to_string(c.dof));
  }
  std::vector<Joint> joints;
  for (int i = 0; i < c.dof; ++i) {
    Joint j;
    if (c.joints[i].type != 0 && c.joints[i].type != 1) {
      throw std::invalid_argument("chain.joints[" + std::to_string(i) +
                                  "].type: expected 0 (revolute) or 1 (prismatic), got " +
                                  std::to_string(c.joints[i].type));
    }
    j.type = c.joints[i].type == 0 ? JointType::kRevolute : JointType::kPrismatic;
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
    case VM_DEVICE_PHANTOM_OMNI:
      return std::make_shared<PhantomOmni>();
    case VM_DEVICE_PLANAR3R:
      return std::make_shared<Planar3R>(d.link1, d.link2, Pose::Identity(), d.torque_limit[0],
                                        d.max_force);
    case VM_DEVICE_SERIAL: {
      const KinematicChain chain = chain_from(d.chain);
      DeviceLimits L;
      for (int i = 0; i < chain.dof(); ++i) {
        L.actuated.push_back(d.actuated[i] != 0);
        L.torque_limit.push_back(d.torque_limit[i] > 0.0 ? d.torque_limit[i] : kInf);
      }
      L.max_force = d.max_force > 0.0 ? d.max_force : kInf;
      L.max_torque = d.max_torque > 0.0 ? d.max_torque : kInf;
      if (d.stiffness > 0.0) L.stiffness = d.stiffness;
      if (d.damping > 0.0) L.damping = d.damping;
      return std::make_shared<SerialDevice>("SerialDevice", chain, L);
    }
  }
  throw std::invalid_argument("device.type: expected VM_DEVICE_PHANTOM_OMNI, VM_DEVICE_PLANAR3R "
                              "or VM_DEVICE_SERIAL, got " + std::to_string(static_cast<int>(d.type)));
}

std::shared_ptr<const Mechanism> mechanism_from(const vm_mechanism_desc& m) {
  switch (m.type) {
    case VM_MECHANISM_PLANAR_ARM:
      return std::make_shared<PlanarArm>(v3(m.point), v3(m.normal), m.length, v3(m.direction));
    case VM_MECHANISM_PROBE:
      return std::make_shared<Probe>(v3(m.point), v3(m.normal), m.length, v3(m.direction));
    case VM_MECHANISM_POINT_PIVOT:
      return std::make_shared<PointPivot>(v3(m.point), v3(m.normal), m.length, v3(m.direction));
    case VM_MECHANISM_LINE_GUIDE:
      return std::make_shared<LineGuide>(v3(m.point), v3(m.direction), m.length, v3(m.normal));
    case VM_MECHANISM_SERIAL:
      return std::make_shared<SerialChain>(chain_from(m.chain), m.length_scale);
  }
  throw std::invalid_argument("mechanism.type: expected a vm_mechanism_type, got " +
                              std::to_string(static_cast<int>(m.type)));
}

Vector6 v6(const double* v) {
  Vector6 out;
  for (int i = 0; i < 6; ++i) out[i] = v[i];
  return out;
}

ControllerSettings settings_from(const vm_settings& s) {
  ControllerSettings c;
  if (s.has_kp) c.kp = v6(s.kp);
  if (s.has_kv) c.kv = v6(s.kv);
  if (s.has_w_a) c.w_a = v6(s.w_a);
  if (s.has_w_e) c.w_e = v6(s.w_e);
  if (s.has_w_e_star) c.w_e_star = v6(s.w_e_star);
  c.length_scale = s.length_scale;
  if (s.law < 0 || s.law > 2) {
    throw std::invalid_argument("settings.law: expected 0, 1 or 2, got " + std::to_string(s.law));
  }
  c.law = static_cast<ControlLaw>(s.law);
  if (s.error_velocity < 0 || s.error_velocity > 1) {
    throw std::invalid_argument("settings.error_velocity: expected 0 or 1, got " +
                                std::to_string(s.error_velocity));
  }
  c.error_velocity = static_cast<ErrorVelocity>(s.error_velocity);
  c.period_s = s.period_s;
  c.ramp_time_s = s.ramp_time_s;
  c.watchdog_s = s.watchdog_s;
  c.max_force = s.max_force;
  c.max_torque = s.max_torque;
  c.max_iterations = s.max_iterations;
  c.max_iterations_initial = s.max_iterations_initial;
  return c;
}

void write_error(char* error, size_t size, const char* msg) {
  if (!error || size == 0) return;
  std::strncpy(error, msg, size - 1);
  error[size - 1] = '\0';
}

void copy_vec(const Eigen::Ref<const Eigen::VectorXd>& v, double* out, int n) {
  for (int i = 0; i < n; ++i) out[i] = i < v.size() ? v[i] : 0.0;
}

}  // namespace

extern "C" {

void vm_device_desc_init(vm_device_desc* desc, vm_device_type type) {
  std::memset(desc, 0, sizeof(*desc));
  desc->type = type;
  if (type == VM_DEVICE_PLANAR3R) {
    desc->link1 = 0.2;
    desc->link2 = 0.2;
    desc->torque_limit[0] = 1.0;
    desc->max_force = 5.0;
  }
  init_chain(desc->chain);
}

void vm_mechanism_desc_init(vm_mechanism_desc* desc, vm_mechanism_type type) {
  std::memset(desc, 0, sizeof(*desc));
  desc->type = type;
  desc->normal[2] = 1.0;
  desc->length = 0.1;
  desc->length_scale = 0.1;
  if (type == VM_MECHANISM_PLANAR_ARM || type == VM_MECHANISM_LINE_GUIDE) desc->direction[0] = 1.0;
  init_chain(desc->chain);
}

void vm_settings_init(vm_settings* s) {
  std::memset(s, 0, sizeof(*s));
  const ControllerSettings d;
  s->length_scale = d.length_scale;
  s->law = static_cast<int>(d.law);
  s->error_velocity = static_cast<int>(d.error_velocity);
  s->period_s = d.period_s;
  s->ramp_time_s = d.ramp_time_s;
  s->watchdog_s = d.watchdog_s;
  s->max_force = d.max_force;
  s->max_torque = d.max_torque;
  s->max_iterations = d.max_iterations;
  s->max_iterations_initial = d.max_iterations_initial;
}

int vm_controller_create(const vm_device_desc* device, const vm_mechanism_desc* mechanism,
                         const vm_settings* settings, vm_controller** out, char* error,
                         size_t error_size) {
  if (!out) {
    write_error(error, error_size, "out: expected a pointer to receive the controller, got NULL");
    return VM_ERROR_ARGUMENT;
  }
  *out = nullptr;
  if (!device || !mechanism) {
    write_error(error, error_size, "device/mechanism: expected descriptions, got NULL");
    return VM_ERROR_ARGUMENT;
  }
  try {
    vm_settings defaults;
    vm_settings_init(&defaults);
    *out = new vm_controller(device_from(*device), mechanism_from(*mechanism),
                             settings_from(settings ? *settings : defaults));
    write_error(error, error_size, "");
    return VM_OK;
  } catch (const std::invalid_argument& e) {
    write_error(error, error_size, e.what());
    return VM_ERROR_ARGUMENT;
  } catch (const std::exception& e) {
    write_error(error, error_size, e.what());
    return VM_ERROR_INTERNAL;
  }
}

void vm_controller_destroy(vm_controller* controller) { delete controller; }

int vm_controller_dof(const vm_controller* c) { return c ? c->controller.device().dof() : 0; }

uint32_t vm_controller_step(vm_controller* c, const double* q, const double* dq, double t_s,
                            double* tau) {
  if (!c) return VM_STATUS_FAULT_BAD_SIZE;
  const int n = c->controller.device().dof();
  if (!q || !dq) {
    if (tau) for (int i = 0; i < n; ++i) tau[i] = 0.0;
    return VM_STATUS_FAULT_BAD_SIZE;
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
  const CycleOutput& o = c->out;
  d->device_dof = c->controller.device().dof();
  d->mechanism_dof = c->controller.mechanism().dof();
  copy_vec(o.torque, d->torque, VM_MAX_DOF);
  copy_vec(o.wrench, d->wrench, 6);
  copy_vec(o.wrench_null, d->wrench_null, 6);
  copy_vec(o.wrench_range, d->wrench_range, 6);
  copy_vec(o.wrench_unrendered, d->wrench_unrendered, 6);
  copy_vec(o.theta, d->theta, VM_MAX_DOF);
  copy_vec(o.theta_star, d->theta_star, VM_MAX_DOF);
  copy_vec(o.error, d->error, 6);
  copy_vec(o.error_dot, d->error_dot, 6);
  copy_vec(o.error_star, d->error_star, 6);
  copy_vec(o.error_star_dot, d->error_star_dot, 6);
  pose_to(o.handle_pose, d->handle_pose);
  pose_to(o.mechanism_pose, d->mechanism_pose);
  d->iterations = o.iterations;
  d->iterations_star = o.iterations_star;
  d->ramp = o.ramp;
  d->limit_scale = o.limit_scale;
  d->status = o.status;
  d->computation_time_us = o.computation_time_us;
}

const char* vm_version(void) { return VIRTMECH_VERSION_STRING; }

}  // extern "C"
