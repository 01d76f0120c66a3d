// Per-cycle latency of the servo cycle: median, p99, p99.9 and worst over >= 1e6 timed
// cycles for each case of bench_cases.hpp, with every heap allocation made while the cycles
// run counted (a counting global operator new, and on glibc a counting malloc as well, since
// Eigen allocates with malloc). Prints a table, or one JSON object with --json.
//
//   virtmech_cycle_bench [--cycles N] [--warmup N] [--case NAME]... [--cpu K] [--json]
//
// Installed with the Python package (virtmech/bin/), where `virtmech bench` runs it.
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <new>
#include <sstream>
#include <string>
#include <vector>

#if defined(__linux__)
#include <sched.h>
#include <unistd.h>
#endif

#include "bench_cases.hpp"
#include "virtmech/version.hpp"

// ---------------------------------------------------------------------------------------
// counting allocators

namespace {
std::atomic<long> g_new_calls{0};
std::atomic<long> g_malloc_calls{0};
std::atomic<bool> g_counting{false};
}  // namespace

#if defined(__GLIBC__)
extern "C" {
void* __libc_malloc(size_t);
void* __libc_calloc(size_t, size_t);
void* __libc_realloc(void*, size_t);
void* __libc_memalign(size_t, size_t);
void __libc_free(void*);

void* malloc(size_t n) {
  if (g_counting.load(std::memory_order_relaxed)) g_malloc_calls.fetch_add(1);
  return __libc_malloc(n);
}
void* calloc(size_t n, size_t s) {
  if (g_counting.load(std::memory_order_relaxed)) g_malloc_calls.fetch_add(1);
  return __libc_calloc(n, s);
}
void* realloc(void* p, size_t n) {
  if (g_counting.load(std::memory_order_relaxed)) g_malloc_calls.fetch_add(1);
  return __libc_realloc(p, n);
}
void* memalign(size_t a, size_t n) {
  if (g_counting.load(std::memory_order_relaxed)) g_malloc_calls.fetch_add(1);
  return __libc_memalign(a, n);
}
void* aligned_alloc(size_t a, size_t n) { return memalign(a, n); }
int posix_memalign(void** out, size_t a, size_t n) {
  void* p = memalign(a, n);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
void free(void* p) { __libc_free(p); }
}
#define VMBENCH_RAW_MALLOC __libc_malloc
#define VMBENCH_RAW_FREE __libc_free
static constexpr bool kCountsMalloc = true;
#else
#define VMBENCH_RAW_MALLOC std::malloc
#define VMBENCH_RAW_FREE std::free
static constexpr bool kCountsMalloc = false;
#endif

void* operator new(std::size_t size) {
  if (g_counting.load(std::memory_order_relaxed)) g_new_calls.fetch_add(1);
  if (void* p = VMBENCH_RAW_MALLOC(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  if (g_counting.load(std::memory_order_relaxed)) g_new_calls.fetch_add(1);
  return VMBENCH_RAW_MALLOC(size == 0 ? 1 : size);
}
void* operator new[](std::size_t size, const std::nothrow_t& t) noexcept {
  return operator new(size, t);
}
void operator delete(void* p) noexcept { VMBENCH_RAW_FREE(p); }
void operator delete[](void* p) noexcept { VMBENCH_RAW_FREE(p); }
void operator delete(void* p, std::size_t) noexcept { VMBENCH_RAW_FREE(p); }
void operator delete[](void* p, std::size_t) noexcept { VMBENCH_RAW_FREE(p); }

// ---------------------------------------------------------------------------------------

namespace {

using Clock = std::chrono::steady_clock;

struct Options {
  long cycles = 1000000;
  long warmup = 2000;
  std::vector<std::string> cases;
  int cpu = -1;
  bool json = false;
};

struct CaseResult {
  std::string name;
  int device_dof = 0, mechanism_dof = 0;
  long cycles = 0;
  double median_us = 0, p99_us = 0, p999_us = 0, max_us = 0, mean_us = 0, min_us = 0;
  long allocations = 0, new_calls = 0, malloc_calls = 0;
  double mean_iterations = 0, mean_iterations_star = 0;
  int max_iterations_seen = 0;
  int p99_iterations = 0, p999_iterations = 0;  // of both placements together
  long not_converged = 0, faults = 0;
};

[[noreturn]] void usage(const char* msg) {
  std::fprintf(stderr,
               "virtmech_cycle_bench: %s\nusage: virtmech_cycle_bench [--cycles N] "
               "[--warmup N] [--case NAME]... [--cpu K] [--json]\n",
               msg);
  std::exit(2);
}

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage(("missing value after " + a).c_str());
      return argv[++i];
    };
    if (a == "--cycles") {
      o.cycles = std::atol(value().c_str());
      if (o.cycles < 1) usage("--cycles: expected >= 1");
    } else if (a == "--warmup") {
      o.warmup = std::atol(value().c_str());
      if (o.warmup < 1) usage("--warmup: expected >= 1");
    } else if (a == "--case") {
      o.cases.push_back(value());
    } else if (a == "--cpu") {
      o.cpu = std::atoi(value().c_str());
    } else if (a == "--json") {
      o.json = true;
    } else if (a == "-h" || a == "--help") {
      usage("per-cycle latency of the virtmech servo cycle");
    } else {
      usage(("unknown argument " + a).c_str());
    }
  }
  return o;
}

double quantile_us(const std::vector<float>& sorted_ns, double p) {
  const size_t n = sorted_ns.size();
  size_t k = static_cast<size_t>(std::ceil(p * static_cast<double>(n))) ;
  k = std::min(n - 1, k == 0 ? 0 : k - 1);
  return sorted_ns[k] * 1e-3;
}

CaseResult run_case(vmbench::BenchCase& c, const Options& o) {
  using namespace virtmech;
  Controller& ctl = *c.controller;
  const int n = ctl.device().dof();
  const double period = ctl.model().period_s;
  CaseResult r;
  r.name = c.name;
  r.device_dof = n;
  r.mechanism_dof = ctl.mechanism().dof();
  r.cycles = o.cycles;
  std::vector<float> ns(static_cast<size_t>(o.cycles));
  std::vector<int> its(static_cast<size_t>(o.cycles));
  JointVector q(n), dq(n);
  CycleOutput out;
  long k = 0;
  MechanismSet* set = c.set.get();
  MechanismSetOutput set_out;
  for (; k < o.warmup; ++k) {  // first cycle's initial placement and the caches, untimed
    vmbench::joint_state(c, k, period, q, dq);
    if (set) {
      set->step(q.data(), dq.data(), set_out);
    } else {
      ctl.step(q.data(), dq.data(), out);
    }
  }
  long iterations = 0, iterations_star = 0;
  g_new_calls = 0;
  g_malloc_calls = 0;
  g_counting = true;
  for (long i = 0; i < o.cycles; ++i, ++k) {
    vmbench::joint_state(c, k, period, q, dq);
    const auto t0 = Clock::now();
    if (set) {
      set->step(q.data(), dq.data(), set_out);
    } else {
      ctl.step(q.data(), dq.data(), out);
    }
    const auto t1 = Clock::now();
    if (set) out = set_out.cycle;  // (outside the timing)
    ns[static_cast<size_t>(i)] =
        static_cast<float>(std::chrono::duration<double, std::nano>(t1 - t0).count());
    iterations += out.iterations;
    iterations_star += out.iterations_star;
    its[static_cast<size_t>(i)] = out.iterations + out.iterations_star;
    r.max_iterations_seen = std::max(r.max_iterations_seen, std::max(out.iterations, out.iterations_star));
    if (out.status & status::kNotConverged) ++r.not_converged;
    if (out.status & status::kFaultMask) ++r.faults;
  }
  g_counting = false;
  r.new_calls = g_new_calls.load();
  r.malloc_calls = g_malloc_calls.load();
  r.allocations = r.new_calls + r.malloc_calls;
  double sum = 0.0;
  for (float x : ns) sum += x;
  r.mean_us = sum / static_cast<double>(ns.size()) * 1e-3;
  std::sort(ns.begin(), ns.end());
  r.min_us = ns.front() * 1e-3;
  r.median_us = quantile_us(ns, 0.5);
  r.p99_us = quantile_us(ns, 0.99);
  r.p999_us = quantile_us(ns, 0.999);
  r.max_us = ns.back() * 1e-3;
  std::sort(its.begin(), its.end());
  r.p99_iterations = its[std::min(its.size() - 1, static_cast<size_t>(0.99 * static_cast<double>(its.size())))];
  r.p999_iterations = its[std::min(its.size() - 1, static_cast<size_t>(0.999 * static_cast<double>(its.size())))];
  r.mean_iterations = static_cast<double>(iterations) / static_cast<double>(o.cycles);
  r.mean_iterations_star = static_cast<double>(iterations_star) / static_cast<double>(o.cycles);
  return r;
}

double timer_overhead_ns() {
  std::vector<double> d(100000);
  for (double& x : d) {
    const auto t0 = Clock::now();
    const auto t1 = Clock::now();
    x = std::chrono::duration<double, std::nano>(t1 - t0).count();
  }
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  return d[d.size() / 2];
}

std::string cpu_model() {
  std::ifstream f("/proc/cpuinfo");
  std::string line;
  while (std::getline(f, line)) {
    if (line.rfind("model name", 0) == 0) {
      const auto p = line.find(':');
      if (p != std::string::npos) return line.substr(p + 2);
    }
  }
  return "unknown";
}

std::string load_average() {
  std::ifstream f("/proc/loadavg");
  std::string a, b, c;
  if (f >> a >> b >> c) return a + " " + b + " " + c;
  return "unknown";
}

std::string json_escape(const std::string& s) {
  std::string o;
  for (char ch : s) {
    if (ch == '"' || ch == '\\') o += '\\';
    if (static_cast<unsigned char>(ch) >= 0x20) o += ch;
  }
  return o;
}

std::string compiler() {
#if defined(__clang__)
  return std::string("clang ") + __clang_version__;
#elif defined(__GNUC__)
  return std::string("gcc ") + __VERSION__;
#else
  return "unknown";
#endif
}

}  // namespace

int main(int argc, char** argv) {
  const Options o = parse(argc, argv);
  int pinned = -1;
#if defined(__linux__)
  if (o.cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(o.cpu, &set);
    if (sched_setaffinity(0, sizeof set, &set) == 0) pinned = o.cpu;
  }
#endif
  std::vector<vmbench::BenchCase> all = vmbench::make_cases();
  std::vector<vmbench::BenchCase*> chosen;
  for (auto& c : all) {
    if (o.cases.empty() || std::find(o.cases.begin(), o.cases.end(), c.name) != o.cases.end()) {
      chosen.push_back(&c);
    }
  }
  for (const std::string& name : o.cases) {
    bool known = false;
    for (auto& c : all) known = known || c.name == name;
    if (!known) usage(("unknown case " + name).c_str());
  }
  // the counter works: this allocation must be seen
  g_new_calls = 0;
  g_malloc_calls = 0;
  g_counting = true;
  auto* probe = new std::vector<double>(64);
  g_counting = false;
  delete probe;
  const bool counter_works = g_new_calls.load() + g_malloc_calls.load() > 0;

  const std::string load_before = load_average();
  const double timer_ns = timer_overhead_ns();
  std::vector<CaseResult> results;
  for (auto* c : chosen) results.push_back(run_case(*c, o));
  const std::string load_after = load_average();

  using namespace virtmech;
  const size_t sz_model = sizeof(ControllerModel), sz_controller = sizeof(Controller),
               sz_output = sizeof(CycleOutput), sz_omni = sizeof(PhantomOmni),
               sz_probe = sizeof(Probe);
#if defined(__linux__)
  const long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
#else
  const long ncpu = -1;
#endif
  if (o.json) {
    std::ostringstream js;
    js.precision(6);
    js << "{\n  \"harness\": \"virtmech_cycle_bench\",\n  \"virtmech_version\": \""
       << VIRTMECH_VERSION_STRING << "\",\n  \"machine\": {\"cpu\": \"" << json_escape(cpu_model())
       << "\", \"logical_cpus\": " << ncpu << ", \"pinned_cpu\": " << pinned
       << ", \"load_average_before\": \"" << load_before << "\", \"load_average_after\": \""
       << load_after << "\", \"compiler\": \"" << json_escape(compiler())
       << "\", \"eigen\": \"" << EIGEN_WORLD_VERSION << "." << EIGEN_MAJOR_VERSION << "."
       << EIGEN_MINOR_VERSION << "\", \"timer_overhead_ns\": " << timer_ns << "},\n"
       << "  \"cycles\": " << o.cycles << ",\n  \"allocation_counter\": {\"operator_new\": true, "
       << "\"malloc\": " << (kCountsMalloc ? "true" : "false") << ", \"self_test_passed\": "
       << (counter_works ? "true" : "false") << "},\n"
       << "  \"sizeof\": {\"ControllerModel\": " << sz_model << ", \"Controller\": " << sz_controller
       << ", \"CycleOutput\": " << sz_output << ", \"PhantomOmni\": " << sz_omni
       << ", \"Probe\": " << sz_probe << "},\n  \"cases\": [";
    for (size_t i = 0; i < results.size(); ++i) {
      const CaseResult& r = results[i];
      js << (i ? ",\n" : "\n") << "    {\"name\": \"" << r.name << "\", \"device_dof\": " << r.device_dof
         << ", \"mechanism_dof\": " << r.mechanism_dof << ", \"cycles\": " << r.cycles
         << ", \"median_us\": " << r.median_us << ", \"p99_us\": " << r.p99_us
         << ", \"p999_us\": " << r.p999_us << ", \"max_us\": " << r.max_us
         << ", \"mean_us\": " << r.mean_us << ", \"min_us\": " << r.min_us
         << ", \"allocations\": " << r.allocations << ", \"new_calls\": " << r.new_calls
         << ", \"malloc_calls\": " << r.malloc_calls
         << ", \"mean_iterations\": " << r.mean_iterations
         << ", \"mean_iterations_star\": " << r.mean_iterations_star
         << ", \"max_iterations\": " << r.max_iterations_seen
         << ", \"p99_iterations\": " << r.p99_iterations
         << ", \"p999_iterations\": " << r.p999_iterations
         << ", \"not_converged_cycles\": " << r.not_converged << ", \"fault_cycles\": " << r.faults
         << "}";
    }
    js << "\n  ]\n}\n";
    std::fputs(js.str().c_str(), stdout);
    return counter_works ? 0 : 1;
  }
  std::printf("virtmech %s cycle benchmark: %ld timed cycles per case (after %ld untimed)\n",
              VIRTMECH_VERSION_STRING, o.cycles, o.warmup);
  std::printf("machine: %s, %ld logical CPUs, pinned to %d, load %s -> %s\n", cpu_model().c_str(),
              ncpu, pinned, load_before.c_str(), load_after.c_str());
  std::printf("compiler: %s; Eigen %d.%d.%d; timer overhead %.0f ns (included in the figures)\n",
              compiler().c_str(), EIGEN_WORLD_VERSION, EIGEN_MAJOR_VERSION, EIGEN_MINOR_VERSION,
              timer_ns);
  std::printf("sizeof: ControllerModel %zu B, Controller (model + state + buffers) %zu B, "
              "CycleOutput %zu B, PhantomOmni %zu B, Probe %zu B\n",
              sz_model, sz_controller, sz_output, sz_omni, sz_probe);
  std::printf("\n%-22s %9s %9s %9s %9s %9s %8s %8s %8s\n", "case", "median", "p99", "p99.9", "max",
              "mean", "iters", "iters", "allocs");
  std::printf("%-22s %9s %9s %9s %9s %9s %8s %8s %8s\n", "", "[us]", "[us]", "[us]", "[us]", "[us]",
              "mean", "p99.9", "");
  for (const CaseResult& r : results) {
    std::printf("%-22s %9.3f %9.3f %9.3f %9.2f %9.3f %8.2f %8d %8ld\n", r.name.c_str(), r.median_us,
                r.p99_us, r.p999_us, r.max_us, r.mean_us,
                r.mean_iterations + r.mean_iterations_star, r.p999_iterations, r.allocations);
  }
  if (!counter_works) std::printf("\nWARNING: the allocation counter saw nothing; counts invalid\n");
  return counter_works ? 0 : 1;
}
