// Compiled into virtmech_no_malloc with the core's sources and flags: reports whether that
// build has Eigen's heap guard and live assertions (test_no_malloc.cpp checks it).
#include <Eigen/Core>

namespace vmtest {

bool core_has_heap_guard() noexcept {
#if defined(EIGEN_RUNTIME_NO_MALLOC) && !defined(NDEBUG)
  return true;
#else
  return false;
#endif
}

}  // namespace vmtest
