// The servo cycle's floating-point mode: subnormal numbers flushed to zero inside the cycle
// (src/flush_denormals.hpp), the caller's mode as it was afterwards.
#include <gtest/gtest.h>

#include <cfenv>
#include <memory>
#include <utility>
#include <vector>

#include "../../src/flush_denormals.hpp"
#include "test_support.hpp"
#include "virtmech/virtmech.hpp"

namespace {

using namespace virtmech;

// 1e-300 * 1e-20 is the subnormal 1e-320 unless subnormal results are flushed to zero
bool flushing() noexcept {
  volatile double tiny = 1e-300, factor = 1e-20;
  return tiny * factor == 0.0;
}

int g_calls = 0, g_flushed = 0;
bool g_divide = false;

// A Probe whose pose and Jacobian record the floating-point mode they run in (it has no
// closed-form placement, so the cycle's Gauss-Newton calls them)
class ModeProbe final : public Mechanism {
 public:
  explicit ModeProbe(std::shared_ptr<const Probe> probe)
      : Mechanism("ModeProbe", vmtest::joint_kinds(*probe), probe->lower(), probe->upper(), probe->home(),
                  probe->length_scale()),
        probe_(std::move(probe)) {}

  void forward_jacobian(const double* x, Pose& T, Jacobian& J) const noexcept override {
    probe_->forward_jacobian(x, T, J);
    ++g_calls;
    g_flushed += flushing() ? 1 : 0;
    if (g_divide) {  // raises the divide-by-zero flag
      volatile double zero = 0.0;
      volatile double inf = 1.0 / zero;
      (void)inf;
    }
  }

 private:
  std::shared_ptr<const Probe> probe_;
};

}  // namespace

#if defined(VIRTMECH_FLUSH_DENORMALS_SSE) || defined(VIRTMECH_FLUSH_DENORMALS_AARCH64)

TEST(FloatingPoint, TheCycleFlushesSubnormalsAndRestoresTheCallersMode) {
  auto omni = std::make_shared<PhantomOmni>();
  auto probe = std::make_shared<Probe>(Eigen::Vector3d(0.0, -0.05, 0.0),
                                       Eigen::Vector3d(Eigen::Vector3d::UnitY()), 0.1,
                                       Eigen::Vector3d(Eigen::Vector3d::Zero()));
  Controller controller(omni, std::make_shared<ModeProbe>(probe));
  MechanismSet set(omni, 1);
  set.add(controller);
  const JointVector q = (JointVector(6) << 0.1, 0.4, 0.3, 0.2, 0.7, -0.1).finished();
  const JointVector dq = JointVector::Constant(6, 0.05);
  CycleOutput out;
  MechanismSetOutput set_out;

  ASSERT_FALSE(flushing());  // the test's own mode keeps subnormals
  const auto each_way = [&](const char* what, auto&& run) {
    g_calls = g_flushed = 0;
    run();
    EXPECT_GT(g_calls, 0) << what;
    EXPECT_EQ(g_flushed, g_calls) << what << ": every call inside the cycle flushes";
  };
  each_way("step", [&] { controller.step(q.data(), dq.data(), out); });
  EXPECT_FALSE(flushing()) << "step restores the caller's mode";
  each_way("place", [&] { controller.place(q.data(), dq.data(), out); });
  EXPECT_FALSE(flushing()) << "place restores the caller's mode";
  controller.render(out);
  EXPECT_FALSE(flushing()) << "render restores the caller's mode";
  each_way("set", [&] { set.step(q.data(), dq.data(), set_out); });
  EXPECT_FALSE(flushing()) << "a set's step restores the caller's mode";

  // the exception flags raised inside the cycle stay raised for the caller (only the two
  // mode bits are restored)
  std::feclearexcept(FE_ALL_EXCEPT);
  g_divide = true;
  controller.step(q.data(), dq.data(), out);
  g_divide = false;
  EXPECT_TRUE(std::fetestexcept(FE_DIVBYZERO));
  std::feclearexcept(FE_ALL_EXCEPT);

  {  // a caller that flushes already keeps flushing
    const detail::FlushDenormals caller;
    ASSERT_TRUE(flushing());
    controller.step(q.data(), dq.data(), out);
    EXPECT_TRUE(flushing());
  }
  EXPECT_FALSE(flushing());
}

#endif
