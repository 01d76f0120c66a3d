// A test-only mechanism that allocates inside the servo cycle: a real Probe whose
// forward_jacobian also takes heap memory. The real-time tests run it to show that they
// would catch an allocation added to the cycle (their negative tests).
#pragma once

#include <cstdlib>
#include <memory>
#include <utility>
#include <vector>

#include "virtmech/virtmech.hpp"

namespace vmtest {

/// How AllocatingProbe::forward_jacobian takes heap memory.
enum class HeapUse {
  kMalloc,          //!< std::malloc / std::free, which an operator-new counter never sees
  kEigenTemporary,  //!< a dynamic-size Eigen vector, which EIGEN_RUNTIME_NO_MALLOC guards
};

/// Where the allocated memory escapes to, so the compiler cannot elide the allocation.
inline const void* volatile g_heap_sink = nullptr;

/// The wrapped Probe's joints, limits, home and length scale, and its pose and Jacobian,
/// plus one heap allocation per forward_jacobian call.
class AllocatingProbe final : public virtmech::Mechanism {
 public:
  AllocatingProbe(std::shared_ptr<const virtmech::Probe> probe, HeapUse use)
      : Mechanism("AllocatingProbe", kinds_of(*probe), probe->lower(), probe->upper(),
                  probe->home(), probe->length_scale()),
        probe_(std::move(probe)), use_(use) {}

  void forward_jacobian(const double* x, virtmech::Pose& T,
                        virtmech::Jacobian& J) const noexcept override {
    probe_->forward_jacobian(x, T, J);
    if (use_ == HeapUse::kMalloc) {
      void* p = std::malloc(64);
      g_heap_sink = p;
      std::free(p);
    } else {
      const Eigen::VectorXd first_row = J.row(0).transpose();  // heap: dynamic size
      g_heap_sink = first_row.data();
    }
  }

 private:
  static std::vector<virtmech::JointType> kinds_of(const virtmech::Mechanism& m) {
    std::vector<virtmech::JointType> kinds;
    for (int i = 0; i < m.dof(); ++i) kinds.push_back(m.joint_type(i));
    return kinds;
  }

  std::shared_ptr<const virtmech::Probe> probe_;
  HeapUse use_;
};

}  // namespace vmtest
