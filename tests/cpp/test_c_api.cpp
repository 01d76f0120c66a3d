// The C API creates every device and mechanism the C++ (and so the Python) API can, with
// every option, and its cycle is the C++ cycle bit for bit.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>

#include "test_support.hpp"
#include "virtmech.h"

using namespace virtmech;

namespace {

struct Case {
  std::string name;
  vm_device_desc device;
  vm_mechanism_desc mechanism;
  std::shared_ptr<const Device> cpp_device;
  std::shared_ptr<const Mechanism> cpp_mechanism;
};

void row_major(const Pose& T, double* out) {
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) out[4 * r + c] = T.matrix()(r, c);
}

Pose planar_base() {
  Pose B = Pose::Identity();
  B.translation() = Eigen::Vector3d(0.01, -0.02, 0.03);
  B.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return B;
}

// the joint state the test drives: a slow wandering inside the device's range
void joint_state(const Device& d, int k, JointVector& q, JointVector& dq) {
  for (int i = 0; i < d.dof(); ++i) {
    const double lo = std::isfinite(d.lower()[i]) ? d.lower()[i] : -1.0;
    const double hi = std::isfinite(d.upper()[i]) ? d.upper()[i] : 1.0;
    const double mid = 0.5 * (lo + hi), half = 0.3 * (hi - lo);
    q[i] = mid + half * std::sin(0.01 * k + i);
    dq[i] = 0.01 * half * std::cos(0.01 * k + i) * 1e3;
  }
}

std::vector<Case> cases() {
  std::vector<Case> out;
  // devices: the Omni calibrated (links, motors, gimbal offsets and signs, gains)
  vm_device_desc omni;
  vm_device_desc_init(&omni, VM_DEVICE_PHANTOM_OMNI);
  omni.link1 = 0.14;
  omni.link2 = 0.13;
  omni.max_force = 3.0;
  omni.torque_limit[0] = 0.4;
  omni.torque_limit[1] = 0.45;
  omni.torque_limit[2] = 0.5;
  omni.gimbal_offset[0] = 0.1;
  omni.gimbal_offset[1] = -0.2;
  omni.gimbal_offset[2] = 0.05;
  omni.gimbal_sign[0] = -1.0;
  omni.gimbal_sign[2] = -1.0;
  omni.stiffness = 400.0;
  omni.damping = 0.8;
  PhantomOmniParams p;
  p.l1 = 0.14;
  p.l2 = 0.13;
  p.max_force = 3.0;
  p.motor_torque_limit = {{0.4, 0.45, 0.5}};
  p.gimbal_offset = {{0.1, -0.2, 0.05}};
  p.gimbal_sign = {{-1.0, 1.0, -1.0}};
  p.stiffness = 400.0;
  p.damping = 0.8;
  auto cpp_omni = std::make_shared<PhantomOmni>(p);

  vm_device_desc planar;
  vm_device_desc_init(&planar, VM_DEVICE_PLANAR3R);
  planar.link1 = 0.25;
  planar.link2 = 0.15;
  planar.torque_limit[0] = 2.0;
  planar.max_force = 7.0;
  row_major(planar_base(), planar.base);
  auto cpp_planar = std::make_shared<Planar3R>(0.25, 0.15, planar_base(), 2.0, 7.0);

  const auto arm = vmtest::six_dof_arm();
  vm_device_desc serial;
  vm_device_desc_init(&serial, VM_DEVICE_SERIAL);
  serial.chain.dof = arm->dof();
  for (int i = 0; i < arm->dof(); ++i) {
    const Joint& j = arm->chain().joint(i);
    serial.chain.joints[i].type = j.type == JointType::kRevolute ? 0 : 1;
    for (int a = 0; a < 3; ++a) serial.chain.joints[i].axis[a] = j.axis[a];
    row_major(j.origin, serial.chain.joints[i].origin);
    serial.chain.joints[i].lower = j.lower;
    serial.chain.joints[i].upper = j.upper;
    serial.actuated[i] = 1;
    serial.torque_limit[i] = arm->torque_limit()[i];
  }
  row_major(arm->chain().base(), serial.chain.base);
  row_major(arm->chain().handle(), serial.chain.handle);
  serial.max_force = arm->max_force();
  serial.max_torque = arm->max_torque();
  serial.stiffness = arm->stiffness();
  serial.damping = arm->damping();
  std::strcpy(serial.name, "Arm6R");

  struct Dev {
    const char* name;
    vm_device_desc desc;
    std::shared_ptr<const Device> cpp;
  };
  const std::vector<Dev> devices = {{"omni", omni, cpp_omni},
                                    {"planar3r", planar, cpp_planar},
                                    {"serial", serial, arm}};

  // mechanisms, each with and without the unilateral option where it has one
  const Eigen::Vector3d pt(0.01, -0.03, 0.02), n = Eigen::Vector3d(0.1, 1.0, 0.2).normalized();
  const Eigen::Vector3d t = n.cross(Eigen::Vector3d::UnitX()).normalized();
  auto mech = [&](vm_mechanism_type type, int unilateral) {
    vm_mechanism_desc m;
    vm_mechanism_desc_init(&m, type);
    for (int a = 0; a < 3; ++a) {
      m.point[a] = pt[a];
      m.normal[a] = n[a];
      m.direction[a] = t[a];
    }
    m.length = 0.08;
    m.unilateral = unilateral;
    return m;
  };
  std::vector<std::pair<vm_mechanism_desc, std::shared_ptr<const Mechanism>>> mechanisms;
  mechanisms.push_back({mech(VM_MECHANISM_PLANAR_ARM, 0), std::make_shared<PlanarArm>(pt, n, 0.08, t)});
  for (int u : {0, 1}) {
    mechanisms.push_back({mech(VM_MECHANISM_PROBE, u), std::make_shared<Probe>(pt, n, 0.08, t, u == 1)});
    mechanisms.push_back(
        {mech(VM_MECHANISM_POINT_PIVOT, u), std::make_shared<PointPivot>(pt, n, 0.08, t, u == 1)});
    // LineGuide: point, direction = t, normal = n
    mechanisms.push_back(
        {mech(VM_MECHANISM_LINE_GUIDE, u), std::make_shared<LineGuide>(pt, t, 0.08, n, u == 1)});
  }
  vm_mechanism_desc chain = mech(VM_MECHANISM_SERIAL, 0);
  chain.chain.dof = 2;
  chain.chain.joints[0].type = 1;
  chain.chain.joints[0].lower = -0.05;
  chain.chain.joints[0].upper = 0.05;
  chain.chain.joints[1].axis[0] = 1.0;
  chain.chain.joints[1].axis[2] = 0.0;
  chain.chain.handle[3] = 0.1;  // row-major: x translation of the handle
  chain.length_scale = 0.12;
  std::vector<Joint> js(2);
  js[0].type = JointType::kPrismatic;
  js[0].lower = -0.05;
  js[0].upper = 0.05;
  js[1].axis = Eigen::Vector3d::UnitX();
  Pose H = Pose::Identity();
  H.translation().x() = 0.1;
  mechanisms.push_back({chain, std::make_shared<SerialChain>(js, H, Pose::Identity(), 0.12)});

  for (const auto& d : devices) {
    for (const auto& [md, mc] : mechanisms) {
      out.push_back({std::string(d.name) + "/" + mc->type_name() +
                         (md.unilateral ? "/unilateral" : ""),
                     d.desc, md, d.cpp, mc});
    }
  }
  return out;
}

}  // namespace

TEST(CApi, EveryDeviceMechanismAndOptionMatchesTheCppCycle) {
  vm_settings settings;
  vm_settings_init(&settings);
  settings.ramp_time_s = 0.01;
  settings.range_margin_rad = 0.2;
  settings.secondary_weight = 2e-6;
  ControllerSettings cs;
  cs.ramp_time_s = 0.01;
  cs.range_margin_rad = 0.2;
  cs.secondary_weight = 2e-6;
  for (const Case& k : cases()) {
    SCOPED_TRACE(k.name);
    vm_controller* c = nullptr;
    char err[256];
    ASSERT_EQ(vm_controller_create(&k.device, &k.mechanism, &settings, &c, err, sizeof err), VM_OK)
        << err;
    Controller ref(k.cpp_device, k.cpp_mechanism, cs);
    ASSERT_EQ(vm_controller_dof(c), ref.device().dof());
    const int n = ref.device().dof();
    JointVector q(n), dq(n);
    CycleOutput out;
    vm_diagnostics diag;
    double tau[VM_MAX_DOF];
    for (int step = 0; step < 300; ++step) {
      joint_state(ref.device(), step, q, dq);
      const std::uint32_t s = vm_controller_step(c, q.data(), dq.data(), n, NAN, tau);
      ref.step(q.data(), dq.data(), out);
      ASSERT_EQ(s, out.status) << step;
      vm_controller_diagnostics(c, &diag);
      ASSERT_EQ(diag.mechanism_dof, ref.mechanism().dof());
      for (int i = 0; i < n; ++i) ASSERT_EQ(tau[i], out.torque[i]) << step;
      for (int i = 0; i < 6; ++i) ASSERT_EQ(diag.wrench[i], out.wrench[i]) << step;
      for (int i = 0; i < 6; ++i) ASSERT_EQ(diag.wrench_passivity[i], out.wrench_passivity[i]);
      ASSERT_EQ(diag.energy, out.energy) << step;
      ASSERT_EQ(diag.stored_energy, out.stored_energy) << step;
      ASSERT_EQ(diag.passivity_scale, out.passivity_scale) << step;
      ASSERT_EQ(diag.active, out.active);
      ASSERT_EQ(diag.active_star, out.active_star);
    }
    vm_controller_destroy(c);
  }
}

TEST(CApi, NullControllerAndWrongSizesZeroTheTorque) {
  double q[6] = {0}, dq[6] = {0}, tau[6];
  for (double& x : tau) x = 7.0;
  EXPECT_NE(vm_controller_step(nullptr, q, dq, 6, NAN, tau) & VM_STATUS_FAULT_MASK, 0u);
  for (double x : tau) EXPECT_EQ(x, 0.0);

  vm_device_desc dev;
  vm_device_desc_init(&dev, VM_DEVICE_PHANTOM_OMNI);
  vm_mechanism_desc mech;
  vm_mechanism_desc_init(&mech, VM_MECHANISM_PROBE);
  vm_controller* c = nullptr;
  ASSERT_EQ(vm_controller_create(&dev, &mech, nullptr, &c, nullptr, 0), VM_OK);
  for (double& x : tau) x = 7.0;
  EXPECT_EQ(vm_controller_step(c, q, dq, 5, NAN, tau), VM_STATUS_FAULT_BAD_SIZE);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(tau[i], 0.0);
  EXPECT_EQ(tau[5], 7.0);  // never written past the length given
  for (double& x : tau) x = 7.0;
  EXPECT_NE(vm_controller_step(c, nullptr, dq, 6, NAN, tau) & VM_STATUS_FAULT_MASK, 0u);
  for (double x : tau) EXPECT_EQ(x, 0.0);
  vm_controller_destroy(c);
}

TEST(CApi, CreateNamesTheBadOption) {
  vm_device_desc dev;
  vm_device_desc_init(&dev, VM_DEVICE_PHANTOM_OMNI);
  dev.gimbal_sign[1] = 0.5;
  vm_mechanism_desc mech;
  vm_mechanism_desc_init(&mech, VM_MECHANISM_PROBE);
  vm_controller* c = nullptr;
  char err[256];
  EXPECT_EQ(vm_controller_create(&dev, &mech, nullptr, &c, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_NE(std::string(err).find("device.gimbal_sign[1]"), std::string::npos) << err;
  // messages name the C fields, not the C++ parameters
  vm_mechanism_desc arm_dir;
  vm_mechanism_desc_init(&arm_dir, VM_MECHANISM_PLANAR_ARM);
  arm_dir.direction[0] = 2.0;  // not a unit vector
  vm_device_desc_init(&dev, VM_DEVICE_PHANTOM_OMNI);
  EXPECT_EQ(vm_controller_create(&dev, &arm_dir, nullptr, &c, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_EQ(std::string(err).rfind("mechanism.direction: ", 0), 0u) << err;
  dev.link1 = -1.0;
  vm_mechanism_desc_init(&arm_dir, VM_MECHANISM_PLANAR_ARM);
  EXPECT_EQ(vm_controller_create(&dev, &arm_dir, nullptr, &c, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_EQ(std::string(err).rfind("device.link1: ", 0), 0u) << err;
  vm_device_desc_init(&dev, VM_DEVICE_PHANTOM_OMNI);
  mech.unilateral = 2;
  EXPECT_EQ(vm_controller_create(&dev, &mech, nullptr, &c, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_NE(std::string(err).find("unilateral"), std::string::npos) << err;
  vm_mechanism_desc arm;
  vm_mechanism_desc_init(&arm, VM_MECHANISM_PLANAR_ARM);
  arm.unilateral = 1;  // a PlanarArm has no lift-off joint
  EXPECT_EQ(vm_controller_create(&dev, &arm, nullptr, &c, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_NE(std::string(err).find("mechanism.unilateral"), std::string::npos) << err;
  vm_settings s;
  vm_settings_init(&s);
  mech.unilateral = 0;
  s.range_margin_m = -1.0;
  EXPECT_EQ(vm_controller_create(&dev, &mech, &s, &c, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_EQ(std::string(err).rfind("settings.range_margin_m: ", 0), 0u) << err;
  vm_settings_init(&s);
  EXPECT_EQ(s.passivity, 1);  // passive by default
  s.passivity = 2;
  EXPECT_EQ(vm_controller_create(&dev, &mech, &s, &c, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_EQ(std::string(err).rfind("settings.passivity: ", 0), 0u) << err;
  vm_settings_init(&s);
  s.passivity_max_energy_j = -1.0;
  EXPECT_EQ(vm_controller_create(&dev, &mech, &s, &c, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_EQ(std::string(err).rfind("settings.passivity_max_energy_j: ", 0), 0u) << err;
  EXPECT_EQ(c, nullptr);
}

TEST(CApi, PlanarArmDefaultsLikeTheCppAndPythonApis) {
  // an unset zero direction is automatic: world x projected into the plane, or world y
  for (const Eigen::Vector3d n : {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(1, 0, 0),
                                  Eigen::Vector3d(0.3, 0.4, 0.5).normalized()}) {
    vm_device_desc dev;
    vm_device_desc_init(&dev, VM_DEVICE_PHANTOM_OMNI);
    vm_mechanism_desc arm;
    vm_mechanism_desc_init(&arm, VM_MECHANISM_PLANAR_ARM);
    for (int a = 0; a < 3; ++a) arm.normal[a] = n[a];
    arm.point[2] = -0.1;
    vm_controller* c = nullptr;
    char err[256];
    ASSERT_EQ(vm_controller_create(&dev, &arm, nullptr, &c, err, sizeof err), VM_OK) << err;
    const PlanarArm ref(Eigen::Vector3d(0, 0, -0.1), n, 0.1, Eigen::Vector3d::Zero());
    Eigen::Vector3d expected = Eigen::Vector3d::UnitX() - n.x() * n;
    if (expected.norm() < 1e-6) expected = Eigen::Vector3d::UnitY() - n.y() * n;
    EXPECT_LT((ref.zero_direction() - expected.normalized()).norm(), 1e-15);
    double q[6] = {0.1, 0.5, 0.2, 0.0, 0.6, 0.0}, dq[6] = {0}, tau[6];
    vm_controller_step(c, q, dq, 6, NAN, tau);
    Controller cpp(std::make_shared<PhantomOmni>(), std::make_shared<PlanarArm>(ref));
    CycleOutput out;
    cpp.step(q, dq, out);
    for (int i = 0; i < 6; ++i) EXPECT_EQ(tau[i], out.torque[i]);
    vm_controller_destroy(c);
  }
}
