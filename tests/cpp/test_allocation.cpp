// The servo cycle allocates nothing and throws nothing. A counting allocator sees every
// heap call of the process: the C allocator (malloc, calloc, realloc, free and the aligned
// forms, interposed in this executable and forwarded to glibc's) and operator new / delete
// (routed through that malloc), so an allocation through Eigen or a C library counts too.
// The counter is defined here and declared in heap_counter.hpp for the executable's other
// test files.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <fstream>
#include <string>
#include <thread>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

// the C allocator is interposed on glibc, unless a sanitizer owns it (AddressSanitizer,
// ThreadSanitizer: its runtime allocates before it can trace an interposed malloc)
#if defined(__GLIBC__) && !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
#define VM_INTERPOSE_MALLOC 1
#include <malloc.h>
#endif

#include "allocating_probe.hpp"
#include "c_api_support.hpp"
#include "cycle_scenes.hpp"
#include "heap_counter.hpp"
#include "virtmech.h"
#include "virtmech/drivers/driver_servo.hpp"
#include "virtmech/drivers/force_dimension.hpp"
#include "virtmech/drivers/openhaptics.hpp"
#include "virtmech_driver.h"

namespace {

std::atomic<bool> g_counting{false};
std::atomic<long> g_allocations{0};  // every block handed out (new goes through malloc)
std::atomic<long> g_frees{0};        // every non-null block given back
std::atomic<long> g_news{0};         // operator new calls among the allocations
std::atomic<long> g_deletes{0};      // operator delete calls (non-null) among the frees
thread_local bool t_in_hook = false;  // recursion guard of the C allocator hooks

void count(std::atomic<long>& counter) noexcept {
  if (g_counting.load(std::memory_order_relaxed)) counter.fetch_add(1, std::memory_order_relaxed);
}

// Marks a hook as entered; a call made from inside a hook (the C library calling back into
// malloc) is forwarded without counting.
class HookScope {
 public:
  HookScope() noexcept : nested_(t_in_hook) { t_in_hook = true; }
  ~HookScope() { t_in_hook = nested_; }
  HookScope(const HookScope&) = delete;
  HookScope& operator=(const HookScope&) = delete;
  void count(std::atomic<long>& counter) const noexcept {
    if (!nested_) ::count(counter);
  }

 private:
  bool nested_;
};

}  // namespace

#if defined(VM_INTERPOSE_MALLOC)
// glibc's own allocator entry points: the interposed symbols below forward to them (the
// replacement glibc documents in "Replacing malloc").
extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t n, std::size_t size);
void* __libc_realloc(void* p, std::size_t size);
void __libc_free(void* p);
void* __libc_memalign(std::size_t alignment, std::size_t size);
void* __libc_valloc(std::size_t size);
void* __libc_pvalloc(std::size_t size);

void* malloc(std::size_t size) noexcept {
  HookScope h;
  h.count(g_allocations);
  return __libc_malloc(size);
}
void* calloc(std::size_t n, std::size_t size) noexcept {
  HookScope h;
  h.count(g_allocations);
  return __libc_calloc(n, size);
}
// one allocation, plus one free when it gives back an existing block
void* realloc(void* p, std::size_t size) noexcept {
  HookScope h;
  h.count(g_allocations);
  if (p) h.count(g_frees);
  return __libc_realloc(p, size);
}
void free(void* p) noexcept {
  HookScope h;
  if (p) h.count(g_frees);
  __libc_free(p);
}
void* memalign(std::size_t alignment, std::size_t size) noexcept {
  HookScope h;
  h.count(g_allocations);
  return __libc_memalign(alignment, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) noexcept {
  HookScope h;
  h.count(g_allocations);
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) noexcept {
  HookScope h;
  h.count(g_allocations);
  if (alignment % sizeof(void*) != 0 || (alignment & (alignment - 1)) != 0) return EINVAL;
  void* p = __libc_memalign(alignment, size);
  if (!p) return ENOMEM;
  *out = p;
  return 0;
}
void* valloc(std::size_t size) noexcept {
  HookScope h;
  h.count(g_allocations);
  return __libc_valloc(size);
}
void* pvalloc(std::size_t size) noexcept {
  HookScope h;
  h.count(g_allocations);
  return __libc_pvalloc(size);
}
}  // extern "C"
constexpr bool kSeesMalloc = true;
#else
constexpr bool kSeesMalloc = false;  // only operator new / delete are counted
#endif
constexpr const char* kNotInterposed = "malloc is interposed on glibc without sanitizers only";

// heap_counter.hpp
bool vmtest::heap_counter_sees_malloc() noexcept { return kSeesMalloc; }

void vmtest::start_heap_count() noexcept {
  g_allocations = 0;
  g_frees = 0;
  g_news = 0;
  g_deletes = 0;
  g_counting = true;
}

vmtest::HeapCount vmtest::stop_heap_count() noexcept {
  g_counting = false;
  return {g_allocations.load(), g_frees.load(), g_news.load(), g_deletes.load()};
}

void* operator new(std::size_t size) {
  count(g_news);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
void* operator new(std::size_t size, std::align_val_t alignment) {
  count(g_news);
  const auto a = static_cast<std::size_t>(alignment);
  void* p = nullptr;
  if (posix_memalign(&p, a < sizeof(void*) ? sizeof(void*) : a, size == 0 ? 1 : size) == 0) {
    return p;
  }
  throw std::bad_alloc();
}
void* operator new[](std::size_t size, std::align_val_t alignment) {
  return operator new(size, alignment);
}
void operator delete(void* p) noexcept {
  if (p) count(g_deletes);
  std::free(p);
}
void operator delete[](void* p) noexcept { operator delete(p); }
void operator delete(void* p, std::size_t) noexcept { operator delete(p); }
void operator delete[](void* p, std::size_t) noexcept { operator delete(p); }
void operator delete(void* p, std::align_val_t) noexcept { operator delete(p); }
void operator delete[](void* p, std::align_val_t) noexcept { operator delete(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { operator delete(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { operator delete(p); }

using namespace virtmech;
using namespace vmtest;

namespace {

constexpr int kCycles = 100000;

// The heap calls of `cycles` servo cycles of c from its first (see run_cycles).
HeapCount count_cycles(Controller& c, int cycles, CycleOutput& out) {
  JointVector q(c.device().dof()), dq(c.device().dof());
  start_heap_count();
  run_cycles(c, cycles, q, dq, out);
  return stop_heap_count();
}

std::shared_ptr<Probe> table_probe() {
  return std::make_shared<Probe>(Eigen::Vector3d(0, -0.02, 0), Eigen::Vector3d::UnitY(), 0.1,
                                 Eigen::Vector3d::Zero());
}

}  // namespace

// --- the counter sees every kind of heap call ---------------------------------------

TEST(Allocation, CounterSeesMallocAndFree) {
  if (!kSeesMalloc) GTEST_SKIP() << kNotInterposed;
  void* p = nullptr;
  const HeapCount a = heap_count_of([&] { g_heap_sink = p = std::malloc(64); });
  const HeapCount f = heap_count_of([&] { std::free(p); });
  EXPECT_EQ(a.allocations, 1);
  EXPECT_EQ(a.frees, 0);
  EXPECT_EQ(a.news, 0);
  EXPECT_EQ(f.allocations, 0);
  EXPECT_EQ(f.frees, 1);
}

TEST(Allocation, CounterSeesCalloc) {
  if (!kSeesMalloc) GTEST_SKIP() << kNotInterposed;
  void* p = nullptr;
  const HeapCount a = heap_count_of([&] { g_heap_sink = p = std::calloc(8, sizeof(double)); });
  std::free(p);
  EXPECT_EQ(a.allocations, 1);
}

TEST(Allocation, CounterSeesRealloc) {
  if (!kSeesMalloc) GTEST_SKIP() << kNotInterposed;
  void* p = std::malloc(16);
  const HeapCount a = heap_count_of([&] { g_heap_sink = p = std::realloc(p, 1 << 16); });
  std::free(p);
  EXPECT_EQ(a.allocations, 1);
  EXPECT_EQ(a.frees, 1);  // the old block
}

TEST(Allocation, CounterSeesAlignedAllocations) {
#if !defined(VM_INTERPOSE_MALLOC)
  GTEST_SKIP() << kNotInterposed;
#else
  void* p[4] = {nullptr, nullptr, nullptr, nullptr};
  const HeapCount a = heap_count_of([&] {
    g_heap_sink = p[0] = aligned_alloc(64, 256);
    ASSERT_EQ(posix_memalign(&p[1], 64, 256), 0);
    g_heap_sink = p[1];
    g_heap_sink = p[2] = memalign(64, 256);
    g_heap_sink = p[3] = valloc(256);
  });
  const HeapCount f = heap_count_of([&] {
    for (void* q : p) std::free(q);
  });
  EXPECT_EQ(a.allocations, 4);
  EXPECT_EQ(f.frees, 4);
#endif
}

TEST(Allocation, CounterSeesEigenHeapVector) {
  if (!kSeesMalloc) GTEST_SKIP() << kNotInterposed;
  const HeapCount a = heap_count_of([] {
    Eigen::VectorXd v(100);
    g_heap_sink = v.data();
  });
  EXPECT_GE(a.allocations, 1);
  EXPECT_GE(a.frees, 1);
}

TEST(Allocation, CounterSeesNewVector) {
  // a vector object and its buffer: two news, each a malloc too
  const HeapCount a = heap_count_of([] {
    std::vector<double>* v = new std::vector<double>(100);
    g_heap_sink = v;
    delete v;
  });
  EXPECT_GE(a.news, 2);
  EXPECT_GE(a.deletes, 2);
  if (kSeesMalloc) {
    EXPECT_GE(a.allocations, 2);
    EXPECT_GE(a.frees, 2);
  }
}

// --- the counter fails when the cycle allocates (negative tests) --------------------

TEST(Allocation, CounterSeesMallocInTheCycle) {
  if (!kSeesMalloc) GTEST_SKIP() << kNotInterposed;
  Controller c(std::make_shared<PhantomOmni>(),
               std::make_shared<AllocatingProbe>(table_probe(), HeapUse::kMalloc));
  CycleOutput out;
  const HeapCount n = count_cycles(c, 100, out);
  EXPECT_GT(n.allocations, 0);
  EXPECT_GT(n.frees, 0);
  EXPECT_EQ(n.news, 0);  // a counter of operator new alone would have passed this cycle
}

TEST(Allocation, CounterSeesEigenTemporaryInTheCycle) {
  if (!kSeesMalloc) GTEST_SKIP() << kNotInterposed;
  Controller c(std::make_shared<PhantomOmni>(),
               std::make_shared<AllocatingProbe>(table_probe(), HeapUse::kEigenTemporary));
  CycleOutput out;
  const HeapCount n = count_cycles(c, 100, out);
  EXPECT_GT(n.allocations, 0);
  EXPECT_GT(n.frees, 0);
}

// --- the cycle allocates and frees nothing ------------------------------------------

class CycleAllocation : public testing::TestWithParam<std::string> {};

TEST_P(CycleAllocation, AllocatesAndFreesNothing) {
  const Scene s = make_scene(GetParam());
  Controller c(s.device, s.mechanism, cycle_settings());
  CycleOutput out;
  const HeapCount n = count_cycles(c, kCycles, out);
  EXPECT_EQ(n.allocations, 0);
  EXPECT_EQ(n.frees, 0);
  EXPECT_EQ(n.news, 0);
  EXPECT_EQ(out.status & status::kFaultMask, 0u);  // the run ended in ordinary cycles
  EXPECT_TRUE(out.torque.allFinite());
}

INSTANTIATE_TEST_SUITE_P(Scenes, CycleAllocation, testing::ValuesIn(scene_names()),
                         [](const testing::TestParamInfo<std::string>& info) {
                           return info.param;
                         });

TEST(Allocation, MechanismSetOfFourAllocatesAndFreesNothing) {
  MechanismSet set = make_set();
  MechanismSetOutput out;
  JointVector q(6), dq(6);
  start_heap_count();
  run_set_cycles(set, kCycles, q, dq, out);
  const HeapCount n = stop_heap_count();
  EXPECT_EQ(n.allocations, 0);
  EXPECT_EQ(n.frees, 0);
  EXPECT_EQ(n.news, 0);
  EXPECT_EQ(out.cycle.status & status::kFaultMask, 0u);
  EXPECT_TRUE(out.cycle.torque.allFinite());
}

TEST(Allocation, RecoveryOnALargeNurbsSurfaceAllocatesNothing) {
  // a probe on a 60 x 60 bicubic patch (the test patch's bump and saddle over 12 cm x 9 cm,
  // 2.3e5 closest-point samples in a deep hierarchy) under the Omni's tip, with a fault
  // every 50 cycles: each recovery places the probe by the surface's global closest point
  const int n = 60;
  Eigen::MatrixX3d P(n * n, 3);
  Eigen::MatrixXd W(n, n);
  Eigen::Matrix3d R;
  R << 1, 0, 0, 0, 0, 1, 0, -1, 0;  // the patch's normal along the Omni's +y
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double x = 0.12 * i / (n - 1) - 0.06, y = 0.09 * j / (n - 1) - 0.045;
      const Eigen::Vector3d local(
          x, y, 0.012 * std::cos(2.0 * x / 0.06) * std::cos(y / 0.045) + 0.2 * x * y);
      P.row(i * n + j) = (Eigen::Vector3d(0, 0, -0.12) + R * local).transpose();
      W(i, j) = 1.0 + 0.1 * ((i + j) % 3);
    }
  }
  Eigen::VectorXd k(n + 4);
  for (int i = 0; i < n + 4; ++i) k[i] = std::clamp((i - 3.0) / (n - 3), 0.0, 1.0);
  auto surface = std::make_shared<NurbsSurface>(P, W, k, k, 3, 3);
  Controller c(std::make_shared<PhantomOmni>(), std::make_shared<SurfaceProbe>(surface, 0.1),
               cycle_settings());
  JointVector q(6), dq(6);
  CycleOutput out;
  int faults = 0;  // the non-finite inputs (the path also leaves the joint range at times)
  start_heap_count();
  for (int cycle = 0; cycle < 5000; ++cycle) {
    joint_state(cycle, q, dq);
    if (cycle % 50 == 25) q[0] = std::numeric_limits<double>::quiet_NaN();
    const std::uint32_t st = c.step(q.data(), dq.data(), out, cycle * 1e-3);
    faults += (st & status::kFaultNonFiniteInput) != 0u;
  }
  const HeapCount count = stop_heap_count();
  EXPECT_EQ(count.allocations, 0);
  EXPECT_EQ(count.frees, 0);
  EXPECT_EQ(count.news, 0);
  EXPECT_EQ(faults, 100);
  EXPECT_TRUE(out.torque.allFinite());
}

TEST(Allocation, CApiStepAndDiagnosticsAllocateNothing) {
  for (vm_mechanism_type type : kCApiMechanisms) {
    CApiLoop loop(type);
    start_heap_count();
    loop.run(kCycles);
    const HeapCount n = stop_heap_count();
    EXPECT_EQ(n.allocations, 0) << "mechanism type " << type;
    EXPECT_EQ(n.frees, 0) << "mechanism type " << type;
    EXPECT_EQ(loop.torque()[3], 0.0);
    EXPECT_EQ(loop.diagnostics().status & VM_STATUS_FAULT_MASK, 0u);
  }
}

TEST(Allocation, CApiShapeProbeAndSetStepAndDiagnosticsAllocateNothing) {
  // a SurfaceProbe on the NURBS test patch (its shape released at once) and the set of four,
  // both through the C API; the cycles include a reset and a call with a wrong n
  vm_device_desc dev;
  vm_device_desc_init(&dev, VM_DEVICE_PHANTOM_OMNI);
  vm_shape* patch = c_nurbs_surface(*test_patch(Eigen::Vector3d(0, 0, -0.12)));
  vm_mechanism_desc mech;
  vm_mechanism_desc_init(&mech, VM_MECHANISM_SURFACE_PROBE);
  mech.shape = patch;
  vm_controller* c = nullptr;
  char err[256];
  ASSERT_EQ(vm_controller_create(&dev, &mech, nullptr, &c, err, sizeof err), VM_OK) << err;
  vm_shape_destroy(patch);
  vm_mechanism_set* set = c_make_set(4);
  JointVector q = JointVector::Zero(6), dq = JointVector::Zero(6);
  double tau[6] = {0, 0, 0, 0, 0, 0}, set_tau[6] = {0, 0, 0, 0, 0, 0};
  vm_diagnostics diag{};
  vm_set_diagnostics set_diag{};
  const int cycles = kCycles / 5;  // the set steps four NURBS members a cycle
  start_heap_count();
  for (int k = 0; k < cycles; ++k) {
    joint_state(k, q, dq);
    if (k == cycles / 2) {
      vm_controller_reset(c);
      vm_mechanism_set_reset(set);
    }
    const int n = k == cycles / 4 ? 5 : 6;
    vm_controller_step(c, q.data(), dq.data(), n, k * 1e-3, tau);
    vm_controller_diagnostics(c, &diag);
    vm_mechanism_set_step(set, q.data(), dq.data(), n, k * 1e-3, set_tau);
    vm_mechanism_set_diagnostics(set, &set_diag);
  }
  const HeapCount n = stop_heap_count();
  EXPECT_EQ(n.allocations, 0);
  EXPECT_EQ(n.frees, 0);
  EXPECT_EQ(n.news, 0);
  EXPECT_EQ(diag.status & VM_STATUS_FAULT_MASK, 0u);
  EXPECT_EQ(set_diag.cycle.status & VM_STATUS_FAULT_MASK, 0u);
  EXPECT_EQ(set_diag.size, 4);
  for (double x : set_tau) EXPECT_TRUE(std::isfinite(x));
  vm_controller_destroy(c);
  vm_mechanism_set_destroy(set);
}

// --- a device driver's tick allocates and frees nothing ----------------------------

namespace {

// the Omni's joints wandering within their range
void omni_state(int k, JointVector& q) {
  const double base[6] = {0.1, 0.45, 0.25, 0.0, 0.6, 0.0};
  for (int i = 0; i < 6; ++i) q[i] = base[i] + 0.1 * std::sin(1.3e-3 * k + i);
}

// driver ticks over the Omni's wandering joints: a late tick past the watchdog, a
// non-finite reading, the records read every 50 ticks, a stop requested near the end
template <typename Renderer>
HeapCount count_driver_ticks(Renderer& renderer, int ticks) {
  drivers::ServoSettings settings;
  settings.record_capacity = 256;
  drivers::DriverServo servo(renderer, settings);
  servo.reset();
  std::vector<drivers::TickRecord> records(256);
  JointVector q(6);
  double tau[kMaxDof];
  long read = 0;
  start_heap_count();
  for (int k = 0; k < ticks; ++k) {
    omni_state(k, q);
    if (k == ticks / 3) q[2] = std::numeric_limits<double>::quiet_NaN();
    const double t = k * 1e-3 + (k >= ticks / 2 ? 0.02 : 0.0);
    if (k == 9 * ticks / 10) servo.request_stop();
    servo.tick(q.data(), t, tau);
    servo.end_tick(0, std::numeric_limits<double>::quiet_NaN());
    if (k % 50 == 49) read += static_cast<long>(servo.read_records(records.data(), 256));
  }
  const HeapCount n = stop_heap_count();
  EXPECT_EQ(read, ticks);
  EXPECT_EQ(servo.stats().watchdog, 1u);
  return n;
}

}  // namespace

TEST(Allocation, DriverTicksAllocateAndFreeNothing) {
  const Scene s = make_scene("OmniPlanarArm");
  Controller c(s.device, s.mechanism, cycle_settings());
  const HeapCount n = count_driver_ticks(c, kCycles);
  EXPECT_EQ(n.allocations, 0);
  EXPECT_EQ(n.frees, 0);
  EXPECT_EQ(n.news, 0);
  MechanismSet set = make_set();
  const HeapCount m = count_driver_ticks(set, kCycles / 5);
  EXPECT_EQ(m.allocations, 0);
  EXPECT_EQ(m.frees, 0);
}

TEST(Allocation, CApiDriverTickAllocatesNothing) {
  vm_device_desc dev;
  vm_device_desc_init(&dev, VM_DEVICE_PHANTOM_OMNI);
  vm_mechanism_desc mech;
  vm_mechanism_desc_init(&mech, VM_MECHANISM_PROBE);
  mech.point[1] = -0.02;
  vm_settings settings;
  vm_settings_init(&settings);
  settings.watchdog_s = 0.003;
  vm_controller* c = nullptr;
  ASSERT_EQ(vm_controller_create(&dev, &mech, &settings, &c, nullptr, 0), VM_OK);
  vm_driver* d = nullptr;
  ASSERT_EQ(vm_driver_create(c, nullptr, &d, nullptr, 0), VM_OK);
  vm_driver_record records[64];
  vm_driver_stats stats;
  JointVector q(6);
  double tau[6];
  start_heap_count();
  for (int k = 0; k < kCycles; ++k) {
    omni_state(k, q);
    vm_driver_tick(d, q.data(), 6, k * 1e-3, tau);
    if (k % 32 == 31) {
      vm_driver_read_records(d, records, 64);
      vm_driver_statistics(d, &stats);
    }
  }
  vm_driver_device_error(d, 0x0302);
  vm_driver_tick(d, q.data(), 6, kCycles * 1e-3, tau);
  const HeapCount n = stop_heap_count();
  EXPECT_EQ(n.allocations, 0);
  EXPECT_EQ(n.frees, 0);
  EXPECT_EQ(tau[0], 0.0);
  vm_driver_statistics(d, &stats);
  EXPECT_EQ(stats.stop, VM_DRIVER_STOP_DEVICE_ERROR);
  vm_driver_destroy(d);
  vm_controller_destroy(c);
}

#if defined(VM_STANDIN_HD) || defined(VM_STANDIN_DHD)
// A running driver's ticks over 0.4 s (after 50 ms), its records read on this thread: every
// heap call of the process counted; `ticks`: how many ticks ran meanwhile.
HeapCount count_running_driver(drivers::DeviceDriver& driver, std::uint64_t& ticks) {
  std::vector<drivers::TickRecord> records(1024);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const std::uint64_t ticks0 = driver.servo()->stats().ticks;
  start_heap_count();
  for (int i = 0; i < 40; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    driver.servo()->read_records(records.data(), records.size());
  }
  const HeapCount n = stop_heap_count();
  ticks = driver.servo()->stats().ticks - ticks0;
  return n;
}
#endif

#ifdef VM_STANDIN_HD
TEST(Allocation, OpenHapticsTickAllocatesNothing) {
  // the driver's tick in the stand-in HD library's scheduler thread (its HD calls included),
  // the records read on this thread, for 0.4 s: every heap call of the process is counted
  const std::string base = testing::TempDir() + "alloc_standin";
  std::ofstream(base + ".cfg") << "trace " << base << ".trace\nmax_ticks 4000\n";
  setenv("VIRTMECH_STANDIN_CONFIG", (base + ".cfg").c_str(), 1);
  drivers::OpenHapticsSettings hd;
  hd.library = VM_STANDIN_HD;
  drivers::OpenHapticsDriver driver(hd);
  const Scene s = make_scene("OmniPlanarArm");
  Controller c(s.device, s.mechanism, cycle_settings());
  driver.open(*s.device);
  ASSERT_EQ(driver.calibrate(), drivers::Calibration::kOk);
  driver.start(c);
  std::uint64_t ticks = 0;
  const HeapCount n = count_running_driver(driver, ticks);
  driver.stop();
  unsetenv("VIRTMECH_STANDIN_CONFIG");
  EXPECT_GT(ticks, 200u);
  EXPECT_EQ(n.allocations, 0);
  EXPECT_EQ(n.frees, 0);
  EXPECT_EQ(n.news, 0);
}
#endif

#ifdef VM_STANDIN_DHD
TEST(Allocation, ForceDimensionTickAllocatesNothing) {
  // the driver's tick in its own loop thread (its DHD calls included, on the stand-in DHD
  // library serving an omega.6 held with the wrist turned), the records read on this thread,
  // for 0.4 s: every heap call of the process is counted
  const std::string base = testing::TempDir() + "alloc_standin_dhd";
  std::ofstream(base + ".cfg") << "trace " << base << ".trace\nmax_ticks 4000\n"
                               << "position 0.01 -0.02 0.006\nrotation 0.2 -0.15 0.4\n";
  setenv("VIRTMECH_STANDIN_CONFIG", (base + ".cfg").c_str(), 1);
  drivers::ForceDimensionSettings fd;
  fd.library = VM_STANDIN_DHD;
  drivers::ForceDimensionDriver driver(fd);
  const Scene s = make_scene("Omega6PlanarArm");
  Controller c(s.device, s.mechanism, cycle_settings());
  driver.open(*s.device);
  driver.start(c);
  std::uint64_t ticks = 0;
  const HeapCount n = count_running_driver(driver, ticks);
  const drivers::ServoStats st = driver.servo()->stats();
  driver.stop();
  unsetenv("VIRTMECH_STANDIN_CONFIG");
  EXPECT_GT(ticks, 200u);
  EXPECT_EQ(st.stop, drivers::StopReason::kNone);
  EXPECT_GT(st.force_n, 0.0);  // the mechanism is rendered
  EXPECT_EQ(n.allocations, 0);
  EXPECT_EQ(n.frees, 0);
  EXPECT_EQ(n.news, 0);
}
#endif

// --- the cycle's calls cannot throw (checked when this file compiles) ---------------

TEST(Realtime, CycleCallsAreNoexcept) {
  // A virtual declared noexcept binds every override: one that could throw fails to
  // compile, so checking the interfaces covers every device and mechanism.
  using Ref = Eigen::Ref<const Eigen::VectorXd>;  // bound by the caller, before the call
  Controller* c = nullptr;
  const Mechanism* m = nullptr;
  const Device* d = nullptr;
  const KinematicChain* k = nullptr;
  const double* x = nullptr;
  CycleOutput* out = nullptr;
  Pose* T = nullptr;
  Jacobian* J = nullptr;
  static_assert(noexcept(c->step(x, x, *out)), "Controller::step(pointers) may throw");
  static_assert(noexcept(c->step(x, x, *out, 0.0)), "Controller::step(pointers, t) may throw");
  static_assert(noexcept(c->step(std::declval<const Ref&>(), std::declval<const Ref&>(), *out)),
                "Controller::step(Ref) may throw");
  static_assert(noexcept(c->step(std::declval<const Ref&>(), std::declval<const Ref&>(), *out,
                                 0.0)),
                "Controller::step(Ref, t) may throw");
  static_assert(noexcept(c->reset()), "Controller::reset may throw");
  MechanismSet* set = nullptr;
  MechanismSetOutput* set_out = nullptr;
  static_assert(noexcept(set->step(x, x, *set_out)), "MechanismSet::step may throw");
  static_assert(noexcept(set->reset()), "MechanismSet::reset may throw");
  static_assert(noexcept(m->seed(*T, std::declval<const Vector6&>(),
                                 std::declval<JointVector&>())),
                "Mechanism::seed may throw");
  static_assert(noexcept(m->forward_jacobian(x, *T, *J)), "Mechanism::forward_jacobian may throw");
  static_assert(noexcept(m->forward(x, *T)), "Mechanism::forward may throw");
  static_assert(noexcept(d->forward_jacobian(x, *T, *J)), "Device::forward_jacobian may throw");
  static_assert(noexcept(d->forward(x, *T)), "Device::forward may throw");
  static_assert(noexcept(k->forward_jacobian(x, *T, *J)),
                "KinematicChain::forward_jacobian may throw");
  static_assert(noexcept(k->forward(x, *T)), "KinematicChain::forward may throw");
  static_assert(noexcept(k->joint(0)), "KinematicChain::joint may throw");
  drivers::DriverServo* servo = nullptr;
  drivers::DeviceDriver* driver = nullptr;
  double* y = nullptr;
  drivers::TickRecord* records = nullptr;
  static_assert(noexcept(servo->tick(x, 0.0, y)), "DriverServo::tick may throw");
  static_assert(noexcept(servo->end_tick(0, 0.0)), "DriverServo::end_tick may throw");
  static_assert(noexcept(servo->device_error(0)), "DriverServo::device_error may throw");
  static_assert(noexcept(servo->request_stop()), "DriverServo::request_stop may throw");
  static_assert(noexcept(servo->read_records(records, 1)), "read_records may throw");
  static_assert(noexcept(driver->tick()), "DeviceDriver::tick may throw");
  SUCCEED();
}

// --- the C API reports a bad description and matches the C++ cycle -----------------

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
  settings.ramp_time_s = 1e-3;  // one period: no ramp-in
  vm_controller* c = nullptr;
  ASSERT_EQ(vm_controller_create(&dev, &mech, &settings, &c, nullptr, 0), VM_OK);
  ControllerSettings cs;
  cs.ramp_time_s = 1e-3;  // one period: no ramp-in
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
    const std::uint32_t s = vm_controller_step(c, q.data(), dq.data(), 6, NAN, tau);
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
