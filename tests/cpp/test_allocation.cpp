// The servo cycle allocates nothing: a counting global allocator over 1e5 cycles.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>

#include "test_support.hpp"
#include "virtmech.h"

namespace {
std::atomic<long> g_allocations{0};
std::atomic<bool> g_counting{false};
}  // namespace

void* operator new(std::size_t size) {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

using namespace virtmech;

namespace {

constexpr int kCycles = 100000;

// a slow wandering of every joint, so placements and filters take varied paths
void joint_state(int k, JointVector& q, JointVector& dq) {
  const double t = k * 1e-3;
  for (int i = 0; i < q.size(); ++i) {
    q[i] = 0.3 + 0.4 * std::sin(0.7 * t + i);
    dq[i] = 0.28 * std::cos(0.7 * t + i);
  }
}

long count_cycles(Controller& c) {
  JointVector q(c.device().dof()), dq(c.device().dof());
  CycleOutput out;
  joint_state(0, q, dq);
  c.step(q.data(), dq.data(), out);  // warm up outside the count
  g_allocations = 0;
  g_counting = true;
  for (int k = 0; k < kCycles; ++k) {
    joint_state(k, q, dq);
    c.step(q.data(), dq.data(), out);
  }
  g_counting = false;
  return g_allocations.load();
}

}  // namespace

TEST(Allocation, CountingAllocatorSeesAllocations) {
  // the counter works: a vector allocates
  g_allocations = 0;
  g_counting = true;
  std::vector<double>* v = new std::vector<double>(100);
  g_counting = false;
  delete v;
  EXPECT_GE(g_allocations.load(), 2);
}

TEST(Allocation, OmniProbeCycleAllocatesNothing) {
  Controller c(std::make_shared<PhantomOmni>(),
               std::make_shared<Probe>(Eigen::Vector3d(0, -0.02, 0), Eigen::Vector3d::UnitY(), 0.1,
                                       Eigen::Vector3d::Zero()));
  EXPECT_EQ(count_cycles(c), 0);
}

TEST(Allocation, OmniPlanarArmCycleAllocatesNothing) {
  Controller c(std::make_shared<PhantomOmni>(),
               std::make_shared<PlanarArm>(Eigen::Vector3d(0, 0, -0.05), Eigen::Vector3d::UnitZ(),
                                           0.05, Eigen::Vector3d::UnitX()));
  EXPECT_EQ(count_cycles(c), 0);
}

TEST(Allocation, FullyActuatedSerialCycleAllocatesNothing) {
  auto arm = vmtest::six_dof_arm();
  std::vector<Joint> j(5);
  for (int i = 0; i < 5; ++i) {
    j[i].type = i < 2 ? JointType::kPrismatic : JointType::kRevolute;
    j[i].axis = Eigen::Vector3d::Unit(i % 3);
  }
  Pose handle = Pose::Identity();
  handle.translation() = Eigen::Vector3d(0.3, 0, 0.2);
  Controller c(arm, std::make_shared<SerialChain>(j, handle, Pose::Identity(), 0.1));
  EXPECT_EQ(count_cycles(c), 0);
}

TEST(Allocation, CApiStepAllocatesNothing) {
  for (vm_mechanism_type type : {VM_MECHANISM_PROBE, VM_MECHANISM_PLANAR_ARM}) {
    vm_device_desc dev;
    vm_device_desc_init(&dev, VM_DEVICE_PHANTOM_OMNI);
    vm_mechanism_desc mech;
    vm_mechanism_desc_init(&mech, type);
    mech.point[1] = -0.02;
    vm_controller* c = nullptr;
    char err[256];
    ASSERT_EQ(vm_controller_create(&dev, &mech, nullptr, &c, err, sizeof err), VM_OK) << err;
    double q[6], dq[6], tau[6];
    JointVector qv(6), dqv(6);
    vm_diagnostics d;
    g_allocations = 0;
    g_counting = true;
    for (int k = 0; k < kCycles; ++k) {
      joint_state(k, qv, dqv);
      for (int i = 0; i < 6; ++i) {
        q[i] = qv[i];
        dq[i] = dqv[i];
      }
      vm_controller_step(c, q, dq, k * 1e-3, tau);
      vm_controller_diagnostics(c, &d);
    }
    g_counting = false;
    EXPECT_EQ(g_allocations.load(), 0);
    EXPECT_EQ(tau[3], 0.0);
    vm_controller_destroy(c);
  }
}

TEST(CApi, CreateReportsTheBadField) {
  vm_device_desc dev;
  vm_device_desc_init(&dev, VM_DEVICE_PHANTOM_OMNI);
  vm_mechanism_desc mech;
  vm_mechanism_desc_init(&mech, VM_MECHANISM_PLANAR_ARM);
  mech.length = -0.1;
  vm_controller* c = nullptr;
  char err[256];
  EXPECT_EQ(vm_controller_create(&dev, &mech, nullptr, &c, err, sizeof err), VM_ERROR_ARGUMENT);
  EXPECT_EQ(c, nullptr);
  EXPECT_NE(std::string(err).find("length"), std::string::npos);
}

TEST(CApi, DiagnosticsMatchTheCppCycle) {
  vm_device_desc dev;
  vm_device_desc_init(&dev, VM_DEVICE_PHANTOM_OMNI);
  vm_mechanism_desc mech;
  vm_mechanism_desc_init(&mech, VM_MECHANISM_PLANAR_ARM);
  mech.point[2] = -0.1;
  mech.length = 0.05;
  vm_settings settings;
  vm_settings_init(&settings);
  settings.ramp_time_s = 0.0;
  vm_controller* c = nullptr;
  ASSERT_EQ(vm_controller_create(&dev, &mech, &settings, &c, nullptr, 0), VM_OK);
  ControllerSettings cs;
  cs.ramp_time_s = 0.0;
  Controller ref(std::make_shared<PhantomOmni>(),
                 std::make_shared<PlanarArm>(Eigen::Vector3d(0, 0, -0.1), Eigen::Vector3d::UnitZ(),
                                             0.05, Eigen::Vector3d::UnitX()),
                 cs);
  JointVector q(6), dq(6);
  CycleOutput out;
  vm_diagnostics d;
  double tau[6];
  for (int k = 0; k < 200; ++k) {
    joint_state(k * 10, q, dq);
    const std::uint32_t s = vm_controller_step(c, q.data(), dq.data(), NAN, tau);
    ref.step(q.data(), dq.data(), out);
    vm_controller_diagnostics(c, &d);
    ASSERT_EQ(s, out.status);
    for (int i = 0; i < 6; ++i) {
      ASSERT_EQ(tau[i], out.torque[i]);
      ASSERT_EQ(d.wrench[i], out.wrench[i]);
      ASSERT_EQ(d.error[i], out.error[i]);
    }
    ASSERT_EQ(d.theta[0], out.theta[0]);
    ASSERT_EQ(d.mechanism_dof, 1);
    ASSERT_EQ(d.handle_pose[3], out.handle_pose.translation().x());  // row-major
  }
  vm_controller_destroy(c);
}
