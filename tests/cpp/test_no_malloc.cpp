// The servo cycle under Eigen's run-time heap guard: the core compiled with
// EIGEN_RUNTIME_NO_MALLOC and live assertions (tests/cpp/realtime.cmake), cycles run with
// Eigen::internal::set_is_malloc_allowed(false), so any Eigen heap allocation in the cycle
// (a dynamic-size temporary, a resize past a fixed capacity) aborts the test.
#include <gtest/gtest.h>

#include <string>

#include "allocating_probe.hpp"
#include "cycle_scenes.hpp"
#include "virtmech.h"

#if !defined(EIGEN_RUNTIME_NO_MALLOC) || defined(NDEBUG)
#error "test_no_malloc.cpp must be compiled with EIGEN_RUNTIME_NO_MALLOC and without NDEBUG"
#endif

namespace vmtest {
bool core_has_heap_guard() noexcept;  // no_malloc_build.cpp, compiled with the core
}  // namespace vmtest

using namespace virtmech;
using namespace vmtest;

namespace {

constexpr int kCycles = 10000;
constexpr const char* kGuardMessage = "heap allocation is forbidden";

// Eigen heap allocation forbidden for the scope's lifetime.
class NoEigenHeap {
 public:
  NoEigenHeap() { Eigen::internal::set_is_malloc_allowed(false); }
  ~NoEigenHeap() { Eigen::internal::set_is_malloc_allowed(true); }
  NoEigenHeap(const NoEigenHeap&) = delete;
  NoEigenHeap& operator=(const NoEigenHeap&) = delete;
};

// `cycles` cycles of c from its first with the guard on (see run_cycles).
void run_guarded(Controller& c, int cycles, CycleOutput& out) {
  JointVector q(c.device().dof()), dq(c.device().dof());
  NoEigenHeap guard;
  run_cycles(c, cycles, q, dq, out);
}

std::shared_ptr<Probe> table_probe() {
  return std::make_shared<Probe>(Eigen::Vector3d(0, -0.02, 0), Eigen::Vector3d::UnitY(), 0.1,
                                 Eigen::Vector3d::Zero());
}

}  // namespace

TEST(NoMalloc, CoreIsBuiltWithTheGuard) {
  EXPECT_TRUE(core_has_heap_guard());
}

TEST(NoMallocDeathTest, GuardAbortsOnAnEigenHeapVector) {
  EXPECT_DEATH(
      {
        NoEigenHeap guard;
        Eigen::VectorXd v(100);
        g_heap_sink = v.data();
      },
      kGuardMessage);
}

// negative test: the guarded cycle aborts when the mechanism allocates through Eigen
TEST(NoMallocDeathTest, CycleWithAnEigenTemporaryAborts) {
  Controller c(std::make_shared<PhantomOmni>(),
               std::make_shared<AllocatingProbe>(table_probe(), HeapUse::kEigenTemporary));
  CycleOutput out;
  EXPECT_DEATH(run_guarded(c, 10, out), kGuardMessage);
}

class CycleNoMalloc : public testing::TestWithParam<std::string> {};

TEST_P(CycleNoMalloc, RunsWithEigenHeapForbidden) {
  const Scene s = make_scene(GetParam());
  Controller c(s.device, s.mechanism, cycle_settings());
  CycleOutput out;
  run_guarded(c, kCycles, out);  // an Eigen allocation or a failed eigen_assert aborts here
  EXPECT_EQ(out.status & status::kFaultMask, 0u);
  EXPECT_TRUE(out.torque.allFinite());
}

INSTANTIATE_TEST_SUITE_P(Scenes, CycleNoMalloc, testing::ValuesIn(scene_names()),
                         [](const testing::TestParamInfo<std::string>& info) {
                           return info.param;
                         });

TEST(NoMalloc, MechanismSetOfFour) {
  MechanismSet set = make_set();
  MechanismSetOutput out;
  JointVector q(6), dq(6);
  {
    NoEigenHeap guard;
    run_set_cycles(set, kCycles, q, dq, out);
  }
  EXPECT_EQ(out.cycle.status & status::kFaultMask, 0u);
}

TEST(NoMalloc, CApiStepAndDiagnostics) {
  for (vm_mechanism_type type : kCApiMechanisms) {
    CApiLoop loop(type);
    {
      NoEigenHeap guard;
      loop.run(kCycles);
    }
    EXPECT_EQ(loop.diagnostics().status & VM_STATUS_FAULT_MASK, 0u) << "mechanism type " << type;
  }
}
