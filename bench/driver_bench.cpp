// The device driver's own cost per tick: the whole tick (device read, velocity estimate, the
// controller's step, safety, the record, device write) minus the controller's step, from the
// tick records (both measured by the driver's clock, the processor's time-stamp counter).
// Prints median, p99, p99.9 and worst [µs] for each case, and the step's median beside them.
//
//   virtmech_driver_bench [--ticks N] [--seconds S]
//
// Cases:
//   servo        DeviceDriver::tick with an in-process device (its read and write are copies),
//                ticked back to back: the driver's own work alone, its caches warm
//   servo@1kHz   the same, ticked at 1 kHz (sleeping between ticks): its caches cold, as in
//                a device's servo
//   openhaptics  OpenHapticsDriver ticked by the stand-in HD library's 1 kHz scheduler
//                (tests/standin; built with the tests): HD's frame, reads, writes and error
//                checks through the loaded library included (the stand-in's own work in
//                them is a few copies)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "virtmech/drivers/device_driver.hpp"
#include "virtmech/drivers/openhaptics.hpp"
#include "virtmech/virtmech.hpp"

using namespace virtmech;
using namespace virtmech::drivers;

namespace {

// a device in this process: it reads the Omni's joints wandering near the circle (a table,
// so that its read is a copy) and keeps the torques it is sent
class InProcessDevice final : public DeviceDriver {
 public:
  InProcessDevice() {
    const double base[6] = {0.1, 0.45, 0.25, 0.0, 0.6, 0.0};
    for (int k = 0; k < kRows; ++k) {
      for (int i = 0; i < 6; ++i) table_[k][i] = base[i] + 0.1 * std::sin(1.3e-3 * k + i);
    }
  }
  std::string describe_error(std::uint32_t code) const override {
    return "error " + std::to_string(code);
  }

 protected:
  void open_device(const Device& model, DeviceInfo& info) override {
    info.model = "in-process " + model.name();
    info.input_dof = model.dof();
  }
  Calibration calibrate_device() override { return Calibration::kOk; }
  void start_servo() override {}
  void stop_servo() noexcept override {}
  void close_device() noexcept override {}
  std::uint32_t read_joints(double* q) noexcept override {
    const double* row = table_[k_++ % kRows];
    for (int i = 0; i < 6; ++i) q[i] = row[i];
    return 0;
  }
  std::uint32_t write_torques(const double* tau) noexcept override {
    for (int i = 0; i < 6; ++i) sent_[i] = tau[i];
    return 0;
  }

 private:
  static constexpr int kRows = 4096;
  double table_[kRows][6];
  long k_ = 0;
  double sent_[6] = {0, 0, 0, 0, 0, 0};
};

struct Figures {
  long ticks = 0;
  double median = 0, p99 = 0, p999 = 0, worst = 0, step_median = 0;
};

double quantile(std::vector<double>& v, double p) {
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(std::ceil(p * v.size())) - 1);
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

Figures figures(const std::vector<TickRecord>& records, size_t skip) {
  std::vector<double> own, step;
  for (size_t i = skip; i < records.size(); ++i) {
    own.push_back(records[i].tick_us - records[i].step_us);
    step.push_back(records[i].step_us);
  }
  Figures f;
  f.ticks = static_cast<long>(own.size());
  if (own.empty()) return f;
  f.median = quantile(own, 0.5);
  f.p99 = quantile(own, 0.99);
  f.p999 = quantile(own, 0.999);
  f.worst = *std::max_element(own.begin(), own.end());
  f.step_median = quantile(step, 0.5);
  return f;
}

void print(const char* name, const Figures& f) {
  std::printf("%-12s %9ld %9.3f %9.3f %9.3f %9.3f %12.3f\n", name, f.ticks, f.median, f.p99,
              f.p999, f.worst, f.step_median);
}

std::shared_ptr<PhantomOmni> omni() { return std::make_shared<PhantomOmni>(); }

Controller circle_controller(const std::shared_ptr<PhantomOmni>& device) {
  ControllerSettings s;
  s.watchdog_s = 0.003;
  return Controller(device,
                    std::make_shared<PlanarArm>(Eigen::Vector3d(0, 0, -0.1),
                                                Eigen::Vector3d::UnitZ(), 0.05,
                                                Eigen::Vector3d::UnitX()),
                    s);
}

// the in-process device ticked `ticks` times: back to back, or at 1 kHz (sleeping between
// ticks, so that the driver's caches go cold between them, as in a device's servo)
Figures servo_case(long ticks, bool paced) {
  auto device = omni();
  Controller c = circle_controller(device);
  auto owner = std::make_unique<InProcessDevice>();
  InProcessDevice& d = *owner;
  d.open(*device);
  ServoSettings s;
  s.record_capacity = static_cast<std::size_t>(ticks) + 16;
  d.start(c, s);
  // back to back the renderer's watchdog sees gaps of microseconds, never a trip
  auto next = std::chrono::steady_clock::now();
  for (long k = 0; k < ticks; ++k) {
    if (paced) std::this_thread::sleep_until(next += std::chrono::milliseconds(1));
    d.tick();
  }
  std::vector<TickRecord> records(static_cast<size_t>(ticks));
  records.resize(d.servo()->read_records(records.data(), records.size()));
  d.stop();
  return figures(records, paced ? 100 : 1000);
}

#ifdef VM_STANDIN_HD
Figures openhaptics_case(double seconds) {
  const std::string cfg = "/tmp/virtmech_driver_bench_standin.cfg";
  std::ofstream(cfg) << "mode script\nmax_ticks 10\n";
  setenv("VIRTMECH_STANDIN_CONFIG", cfg.c_str(), 1);
  auto device = omni();
  Controller c = circle_controller(device);
  OpenHapticsSettings hs;
  hs.library = VM_STANDIN_HD;
  OpenHapticsDriver d(hs);
  d.open(*device);
  d.calibrate();
  ServoSettings s;
  s.record_capacity = static_cast<std::size_t>(seconds * 1000) + 4096;
  d.start(c, s);
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  d.stop();
  std::vector<TickRecord> records(s.record_capacity);
  records.resize(d.servo()->read_records(records.data(), records.size()));
  const ServoStats st = d.servo()->stats();
  std::printf("# openhaptics: %lu ticks at %.1f Hz, %lu late, worst gap %.3f ms\n",
              static_cast<unsigned long>(st.ticks), st.rate_hz,
              static_cast<unsigned long>(st.late), st.worst_gap_s * 1e3);
  return figures(records, 100);
}
#endif

}  // namespace

int main(int argc, char** argv) {
  long ticks = 200000;
  double seconds = 10.0;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--ticks") ticks = std::atol(argv[i + 1]);
    if (a == "--seconds") seconds = std::atof(argv[i + 1]);
  }
  std::ifstream cpu("/proc/cpuinfo");
  std::string line, model = "unknown";
  while (std::getline(cpu, line)) {
    if (line.rfind("model name", 0) == 0) {
      model = line.substr(line.find(':') + 2);
      break;
    }
  }
  double load[3] = {0, 0, 0};
  if (std::FILE* f = std::fopen("/proc/loadavg", "r")) {
    if (std::fscanf(f, "%lf %lf %lf", &load[0], &load[1], &load[2]) != 3) load[0] = -1;
    std::fclose(f);
  }
  std::printf("# virtmech driver tick, beyond the controller's step [us]; %s, %u threads, "
              "load %.2f %.2f %.2f\n",
              model.c_str(), std::thread::hardware_concurrency(), load[0], load[1], load[2]);
  std::printf("%-12s %9s %9s %9s %9s %9s %12s\n", "case", "ticks", "median", "p99", "p99.9",
              "worst", "step median");
  print("servo", servo_case(ticks, false));
  print("servo@1kHz", servo_case(static_cast<long>(seconds * 1000), true));
#ifdef VM_STANDIN_HD
  print("openhaptics", openhaptics_case(seconds));
#else
  std::printf("openhaptics  (the stand-in HD library was not built: configure with the tests)\n");
#endif
  return 0;
}
