// The device-driver layer: the record ring (order, drops, a concurrent producer and
// consumer), the servo tick (the controller's torque on the filtered velocity, bit for bit;
// every way to zero torque) and the OpenHaptics driver against the stand-in HD library
// (tests/standin): opening, the checks that refuse a device, calibration, a run, an error
// mid-run.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "test_support.hpp"
#include "virtmech/drivers/driver_servo.hpp"
#include "virtmech/drivers/openhaptics.hpp"
#include "virtmech/velocity_filter.hpp"

using namespace virtmech;
using namespace virtmech::drivers;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kT = 1e-3;

// --- record ring ----------------------------------------------------------------------------

TEST(SpscRing, KeepsOrderAndRefusesWhenFull) {
  SpscRing<int> ring(5);
  EXPECT_EQ(ring.capacity(), 8u);
  for (int i = 0; i < 8; ++i) EXPECT_TRUE(ring.push(i));
  EXPECT_FALSE(ring.push(8));
  int out[16];
  EXPECT_EQ(ring.pop(out, 3), 3u);
  EXPECT_EQ(out[0], 0);
  EXPECT_EQ(out[2], 2);
  EXPECT_TRUE(ring.push(8));
  EXPECT_EQ(ring.pop(out, 16), 6u);
  for (int i = 0; i < 6; ++i) EXPECT_EQ(out[i], 3 + i);
  EXPECT_EQ(ring.pop(out, 16), 0u);
  EXPECT_THROW(SpscRing<int>(0), std::invalid_argument);
}

TEST(SpscRing, ConcurrentConsumerSeesEveryRecordNotDroppedInOrder) {
  SpscRing<long> ring(64);
  constexpr long kCount = 2000000;
  long dropped = 0;
  std::atomic<bool> done{false};
  std::vector<long> seen;
  seen.reserve(kCount);
  std::thread consumer([&] {
    long buffer[32];
    for (;;) {
      const bool finished = done.load(std::memory_order_acquire);
      const std::size_t n = ring.pop(buffer, 32);
      seen.insert(seen.end(), buffer, buffer + n);
      if (n == 0 && finished) break;
    }
  });
  for (long i = 0; i < kCount; ++i) dropped += ring.push(i) ? 0 : 1;
  done.store(true, std::memory_order_release);
  consumer.join();
  EXPECT_EQ(static_cast<long>(seen.size()) + dropped, kCount);
  for (std::size_t i = 1; i < seen.size(); ++i) ASSERT_LT(seen[i - 1], seen[i]) << i;
}

// --- the servo tick -------------------------------------------------------------------------

ControllerSettings driver_settings() {
  ControllerSettings s;
  s.watchdog_s = 0.003;
  return s;
}

std::shared_ptr<PlanarArm> circle() {
  return std::make_shared<PlanarArm>(Eigen::Vector3d(0, 0, -0.1), Eigen::Vector3d::UnitZ(),
                                     0.05, Eigen::Vector3d::UnitX());
}

// the Omni's joints wandering near the circle
void omni_q(int k, double* q) {
  const double t = k * kT;
  const double base[6] = {0.1, 0.45, 0.25, 0.0, 0.6, 0.0};
  for (int i = 0; i < 6; ++i) q[i] = base[i] + 0.1 * std::sin(1.3 * t + i);
}

struct ServoScene {
  std::shared_ptr<PhantomOmni> omni = std::make_shared<PhantomOmni>();
  Controller controller{omni, circle(), driver_settings()};
};

TEST(DriverServo, RefusesARampInThatStepsOntoTheHand) {
  auto omni = std::make_shared<PhantomOmni>();
  ControllerSettings s = driver_settings();
  s.ramp_time_s = 1e-3;  // one period: the whole force on the first tick
  Controller step(omni, circle(), s);
  try {
    DriverServo servo(step);
    FAIL() << "a one-period ramp-in was accepted";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind("ramp_time_s: expected at least 0.02 s", 0), 0u) << what;
    EXPECT_NE(what.find("got a ramp-in of 0.001 s"), std::string::npos) << what;
  }
  s.ramp_time_s = kMinimumDeviceRampS;
  Controller ramped(omni, circle(), s);
  EXPECT_NO_THROW(DriverServo{ramped});
  // 20 ms at 667 Hz: 13 periods (19.5 ms), the nearest whole number: the minimum as written
  s.period_s = 0.0015;
  Controller slower(omni, circle(), s);
  ServoSettings at_667_hz;
  at_667_hz.period_s = 0.0015;
  EXPECT_NO_THROW(DriverServo(slower, at_667_hz));
}

TEST(DriverServo, TorqueIsTheControllersOnTheFilteredVelocity) {
  ServoScene a, b;  // b: the same controller stepped by hand
  DriverServo servo(a.controller);
  servo.reset();
  b.controller.reset();
  // the filter written out: dq += alpha ((q - q_prev) / T - dq), zero on the first sample
  const double alpha = kT / (kT + 1.0 / (2.0 * kPi * 100.0));
  double prev[6], dq[6] = {0, 0, 0, 0, 0, 0};
  CycleOutput out;
  for (int k = 0; k < 600; ++k) {
    double q[6], tau[6];
    omni_q(k, q);
    const std::uint32_t flags = servo.tick(q, k * kT, tau);
    servo.end_tick(0, std::nan(""));
    if (k > 0) {
      for (int i = 0; i < 6; ++i) dq[i] += alpha * ((q[i] - prev[i]) / kT - dq[i]);
    }
    std::copy(q, q + 6, prev);
    b.controller.step(q, dq, out, k * kT);
    ASSERT_EQ(flags, 0u) << k;
    for (int i = 0; i < 6; ++i) ASSERT_EQ(tau[i], out.torque[i]) << "tick " << k << " joint " << i;
  }
  EXPECT_GT(out.torque.norm(), 0.0);
  EXPECT_EQ(out.ramp, 1.0);  // the run ramped in fully
}

TEST(DriverServo, MechanismSetTorqueIsTheSetsOnTheFilteredVelocity) {
  auto omni = std::make_shared<PhantomOmni>();
  MechanismSet a(omni, 2), b(omni, 2);
  for (MechanismSet* s : {&a, &b}) {
    s->add(circle(), driver_settings());
    s->add(std::make_shared<Probe>(Eigen::Vector3d(0, -0.02, 0), Eigen::Vector3d::UnitY(), 0.1,
                                   Eigen::Vector3d::Zero()),
           driver_settings());
  }
  DriverServo servo(a);
  servo.reset();
  VelocityFilter filter(6, kT, VelocityFilter::alpha_for_cutoff(kT, 100.0));
  MechanismSetOutput out;
  for (int k = 0; k < 300; ++k) {
    double q[6], tau[6];
    omni_q(k, q);
    servo.tick(q, k * kT, tau);
    servo.end_tick(0, std::nan(""));
    b.step(q, filter.update(q).data(), out, k * kT);
    for (int i = 0; i < 6; ++i) ASSERT_EQ(tau[i], out.cycle.torque[i]) << k;
  }
}

// ticks k0 .. k1 - 1 at 1 ms; returns the last tick's flags and torque
std::uint32_t run_ticks(DriverServo& servo, int k0, int k1, double* tau, double t_offset = 0.0) {
  std::uint32_t flags = 0;
  for (int k = k0; k < k1; ++k) {
    double q[6];
    omni_q(k, q);
    flags = servo.tick(q, k * kT + t_offset, tau);
    servo.end_tick(0, std::nan(""));
  }
  return flags;
}

bool all_zero(const double* tau) {
  for (int i = 0; i < 6; ++i) {
    if (tau[i] != 0.0) return false;
  }
  return true;
}

// a servo that has run 400 ticks (ramped in), tau the last tick's torque
class Running : public testing::Test {
 protected:
  void SetUp() override {
    servo.reset();
    run_ticks(servo, 0, 400, tau);
  }
  ServoScene scene;
  DriverServo servo{scene.controller};
  double tau[6] = {0, 0, 0, 0, 0, 0}, q[6] = {0, 0, 0, 0, 0, 0};
};

TEST_F(Running, StopRequestZeroesFromTheNextTickOn) {
  EXPECT_FALSE(all_zero(tau));
  servo.request_stop();
  EXPECT_EQ(servo.reason(), StopReason::kRequested);
  const std::uint32_t flags = run_ticks(servo, 400, 410, tau);
  EXPECT_TRUE(all_zero(tau));
  EXPECT_TRUE(flags & driver_flag::kStopping);
  EXPECT_EQ(servo.stats().zero_ticks, 10u);
  EXPECT_EQ(servo.stats().force_n, 0.0);
}

TEST_F(Running, ReadErrorZeroesThatTickAndEveryLaterOne) {
  omni_q(400, q);
  servo.device_error(0x0302);
  EXPECT_TRUE(servo.tick(q, 0.4, tau) & driver_flag::kDeviceError);
  servo.end_tick(0, std::nan(""));
  EXPECT_TRUE(all_zero(tau));
  run_ticks(servo, 401, 450, tau);
  EXPECT_TRUE(all_zero(tau));
  const ServoStats st = servo.stats();
  EXPECT_EQ(st.stop, StopReason::kDeviceError);
  EXPECT_EQ(st.device_error, 0x0302u);
  // a later stop request does not hide the cause
  servo.request_stop();
  EXPECT_EQ(servo.reason(), StopReason::kDeviceError);
}

TEST_F(Running, WriteErrorZeroesFromTheNextTick) {
  omni_q(400, q);
  servo.tick(q, 0.4, tau);
  EXPECT_FALSE(all_zero(tau));  // the frame went out before the error was known
  servo.end_tick(0x0204, std::nan(""));
  EXPECT_TRUE(run_ticks(servo, 401, 402, tau) & driver_flag::kDeviceError);
  EXPECT_TRUE(all_zero(tau));
  EXPECT_EQ(servo.stats().device_error, 0x0204u);
}

TEST_F(Running, LateTickBeyondTheWatchdogZeroesAndRampsBack) {
  // the next tick comes 5 ms after the last (watchdog 3 ms)
  const std::uint32_t flags = run_ticks(servo, 400, 401, tau, 0.004);
  EXPECT_TRUE(flags & driver_flag::kWatchdog);
  EXPECT_TRUE(flags & driver_flag::kLate);
  EXPECT_TRUE(all_zero(tau));
  // then the force ramps in again, from near zero, rising
  std::vector<TickRecord> r(512);
  const std::size_t n0 = servo.read_records(r.data(), r.size());
  EXPECT_EQ(n0, 401u);
  run_ticks(servo, 401, 450, tau, 0.004);
  const std::size_t n = servo.read_records(r.data(), r.size());
  ASSERT_EQ(n, 49u);
  EXPECT_LT(r[0].ramp, 0.05);
  for (std::size_t i = 1; i < n; ++i) EXPECT_GT(r[i].ramp, r[i - 1].ramp);
  EXPECT_EQ(servo.stats().watchdog, 1u);
  EXPECT_EQ(servo.stats().late, 1u);
}

TEST_F(Running, LateTickWithinTheWatchdogIsCountedOnly) {
  const std::uint32_t flags = run_ticks(servo, 400, 401, tau, 0.001);  // a 2 ms gap
  EXPECT_EQ(flags, driver_flag::kLate);
  EXPECT_FALSE(all_zero(tau));
  EXPECT_NEAR(servo.stats().worst_gap_s, 0.002, 1e-12);
}

TEST(DriverServo, ImplausibleReadingsZeroTheTorqueThenEndTheRun) {
  ServoScene s;
  ServoSettings settings;
  settings.fault_limit_s = 0.05;
  DriverServo servo(s.controller, settings);
  servo.reset();
  double tau[6], q[6];
  run_ticks(servo, 0, 300, tau);
  // one non-finite reading: zero torque, the estimate restarted, the run goes on
  omni_q(300, q);
  q[1] = std::nan("");
  EXPECT_TRUE(servo.tick(q, 0.3, tau) & driver_flag::kBadReading);
  servo.end_tick(0, std::nan(""));
  EXPECT_TRUE(all_zero(tau));
  run_ticks(servo, 301, 600, tau);
  EXPECT_FALSE(all_zero(tau));
  EXPECT_EQ(servo.reason(), StopReason::kNone);
  // the gimbal read far outside its range (a wrong calibration) for longer than the limit
  for (int k = 600; k < 700; ++k) {
    omni_q(k, q);
    q[5] = 4.0;
    servo.tick(q, k * kT, tau);
    servo.end_tick(0, std::nan(""));
    EXPECT_TRUE(all_zero(tau)) << k;
  }
  const ServoStats st = servo.stats();
  EXPECT_EQ(st.stop, StopReason::kFaultHeld);
  EXPECT_EQ(st.fault_status, status::kFaultOutOfRange);
  run_ticks(servo, 700, 710, tau);  // plausible again: the run has ended all the same
  EXPECT_TRUE(all_zero(tau));
}

TEST(DriverServo, RecordsCarryEachTickAndDropsAreCounted) {
  ServoScene s;
  ServoSettings settings;
  settings.record_capacity = 64;
  DriverServo servo(s.controller, settings);
  servo.reset();
  double tau[6], q[6];
  for (int k = 0; k < 100; ++k) {
    omni_q(k, q);
    servo.tick(q, k * kT, tau);
    servo.end_tick(0, 12.5);
  }
  std::vector<TickRecord> r(128);
  ASSERT_EQ(servo.read_records(r.data(), r.size()), 64u);
  const ServoStats st = servo.stats();
  EXPECT_EQ(st.ticks, 100u);
  EXPECT_EQ(st.dropped, 36u);
  EXPECT_NEAR(st.rate_hz, 1000.0, 1e-6);
  EXPECT_EQ(st.worst_tick_us, 12.5);
  omni_q(63, q);
  EXPECT_EQ(r[63].tick, 63.0);
  EXPECT_EQ(r[63].t_s, 63 * kT);
  EXPECT_EQ(r[63].tick_us, 12.5);
  for (int i = 0; i < 6; ++i) EXPECT_EQ(r[63].q[i], q[i]);
  EXPECT_EQ(r[63].q[6], 0.0);
  EXPECT_EQ(r[0].gap_s != r[0].gap_s, true);  // NaN on the first tick
  EXPECT_NEAR(r[1].gap_s, kT, 1e-15);
  // a field table that covers the record exactly
  int count = 0;
  const RecordField* f = record_fields(&count);
  int next = 0;
  for (int i = 0; i < count; ++i) {
    EXPECT_EQ(f[i].offset, next) << f[i].name;
    next += f[i].width;
  }
  EXPECT_EQ(next, kTickRecordWidth);
}

TEST(DriverServo, RefusesAControllerWithoutWatchdog) {
  auto omni = std::make_shared<PhantomOmni>();
  Controller c(omni, circle());
  try {
    DriverServo servo(c);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("watchdog_s"), std::string::npos);
  }
}

// --- the OpenHaptics driver against the stand-in HD library ---------------------------------

#ifdef VM_STANDIN_HD

// a stand-in configuration written to a file the stand-in reads (VIRTMECH_STANDIN_CONFIG)
class Standin {
 public:
  explicit Standin(const std::string& lines) {
    static int count = 0;
    base_ = testing::TempDir() + "standin_" + std::to_string(::getpid()) + "_" +
            std::to_string(count++);
    std::ofstream(base_ + ".cfg") << "trace " << base_ << ".trace\n" << lines;
    setenv("VIRTMECH_STANDIN_CONFIG", (base_ + ".cfg").c_str(), 1);
  }
  ~Standin() { unsetenv("VIRTMECH_STANDIN_CONFIG"); }
  // the trace's summary, key -> the rest of its line
  std::map<std::string, std::string> summary() const {
    std::map<std::string, std::string> out;
    std::ifstream in(base_ + ".trace");
    std::string key, rest;
    while (in >> key && std::getline(in, rest)) out[key] = rest.substr(rest.empty() ? 0 : 1);
    return out;
  }

 private:
  std::string base_;
};

OpenHapticsSettings standin_library() {
  OpenHapticsSettings s;
  s.library = VM_STANDIN_HD;
  return s;
}

template <typename F>
DriverError driver_error_of(F&& f) {
  try {
    f();
  } catch (const DriverError& e) {
    return e;
  }
  ADD_FAILURE() << "expected a DriverError";
  return DriverError(DriverError::Kind::kDevice, "none");
}

TEST(OpenHaptics, MissingLibraryIsALibraryErrorNamingThePath) {
  OpenHapticsSettings s;
  s.library = "/nonexistent/libHD.so";
  OpenHapticsDriver d(s);
  PhantomOmni omni;
  const DriverError e = driver_error_of([&] { d.open(omni); });
  EXPECT_EQ(e.kind(), DriverError::Kind::kLibrary);
  EXPECT_NE(std::string(e.what()).find("/nonexistent/libHD.so"), std::string::npos);
  EXPECT_NE(std::string(e.what()).find("OpenHaptics"), std::string::npos);
}

TEST(OpenHaptics, OpensAndIdentifiesTheDevice) {
  Standin standin("model_type Touch\nserial 42\nnominal_max_force 3.3\n");
  OpenHapticsDriver d(standin_library());
  PhantomOmni omni;
  d.open(omni);
  EXPECT_EQ(d.info().model, "Touch");
  EXPECT_EQ(d.info().serial, "42");
  EXPECT_EQ(d.info().input_dof, 6);
  EXPECT_EQ(d.info().output_dof, 3);
  EXPECT_EQ(d.info().nominal_max_force_n, 3.3);
  EXPECT_EQ(d.info().nominal_max_stiffness_n_per_m, 500.0);  // 0.5 N/mm
  EXPECT_EQ(d.info().library, VM_STANDIN_HD);
  d.stop();
  EXPECT_EQ(standin.summary()["disable_calls"], "1");
}

TEST(OpenHaptics, RefusesADeviceThatIsNotTheModel) {
  PhantomOmni omni;
  auto full = std::make_shared<SerialDevice>("PhantomOmni", omni.chain(),
                                             DeviceLimits{std::vector<bool>(6, true),
                                                          std::vector<double>(6, 0.4),
                                                          {}, {}, 3.3, kInf, {}, 1200, 1},
                                             omni.coupling(), omni.coupling_offset());
  struct Case {
    const char* config;
    const Device* model;
    const char* says;
  } cases[] = {{"model_type Touch X\n", &omni, "Touch X"},
               {"input_dof 3\n", &omni, "HD_INPUT_DOF"},
               {"output_dof 3\n", full.get(), "HD_OUTPUT_DOF"}};
  for (const Case& c : cases) {
    Standin standin(c.config);
    OpenHapticsDriver d(standin_library());
    const DriverError e = driver_error_of([&] { d.open(*c.model); });
    EXPECT_EQ(e.kind(), DriverError::Kind::kMismatch) << c.config;
    EXPECT_NE(std::string(e.what()).find(c.says), std::string::npos) << e.what();
    EXPECT_FALSE(d.is_open());
    EXPECT_EQ(standin.summary()["disable_calls"], "1") << "the device is closed again";
  }
}

TEST(OpenHaptics, FailingInitDeviceNamesTheError) {
  Standin standin("init_error 0x0303 -7\n");
  OpenHapticsDriver d(standin_library());
  PhantomOmni omni;
  const DriverError e = driver_error_of([&] { d.open(omni); });
  EXPECT_EQ(e.kind(), DriverError::Kind::kDevice);
  EXPECT_EQ(e.code(), 0x0303u);
  EXPECT_NE(std::string(e.what()).find("HD_COMM_CONFIG_ERROR (0x0303)"), std::string::npos)
      << e.what();
}

TEST(OpenHaptics, OpensANamedDeviceOnly) {
  Standin standin("device_names Left\n");
  PhantomOmni omni;
  OpenHapticsSettings s = standin_library();
  s.device_name = "Right";
  OpenHapticsDriver wrong(s);
  const DriverError e = driver_error_of([&] { wrong.open(omni); });
  EXPECT_NE(std::string(e.what()).find("\"Right\""), std::string::npos) << e.what();
  s.device_name = "Left";
  OpenHapticsDriver right(s);
  right.open(omni);
  EXPECT_EQ(right.info().device_name, "Left");
}

TEST(OpenHaptics, CalibratesOrAsksForTheInkwell) {
  PhantomOmni omni;
  {
    Standin standin("calibration needs_update\ncalibration_style 6\n");
    OpenHapticsDriver d(standin_library());
    d.open(omni);
    EXPECT_EQ(d.calibrate(), Calibration::kUpdated);
    EXPECT_EQ(d.calibrate(), Calibration::kOk);
    d.stop();
    const auto s = standin.summary();
    EXPECT_EQ(s.at("calibration_updates"), "1");
    EXPECT_EQ(s.at("calibration_checks_outside_frame"), "0");
  }
  {
    // the stylus goes in the inkwell after a few checks
    Standin standin("calibration needs_manual_input\ninkwell_after_checks 3\ncalibration_style 4\n");
    OpenHapticsDriver d(standin_library());
    d.open(omni);
    for (int i = 0; i < 3; ++i) EXPECT_EQ(d.calibrate(), Calibration::kNeedsInkwell);
    EXPECT_EQ(d.calibrate(), Calibration::kUpdated);
    EXPECT_EQ(d.calibrate(), Calibration::kOk);
  }
}

TEST(OpenHaptics, RefusesAForceLimitAboveTheDevicesNominalOne) {
  Standin standin("nominal_max_force 1.5\n");
  OpenHapticsDriver d(standin_library());
  auto omni = std::make_shared<PhantomOmni>();
  d.open(*omni);
  Controller strong(omni, circle(), driver_settings());  // max_force 3.3 N: the Omni's
  const DriverError e = driver_error_of([&] { d.start(strong); });
  EXPECT_EQ(e.kind(), DriverError::Kind::kMismatch);
  EXPECT_NE(std::string(e.what()).find("1.5"), std::string::npos) << e.what();
  ControllerSettings s = driver_settings();
  s.max_force = 1.5;
  Controller within(omni, circle(), s);
  d.start(within);
  d.stop();
}

TEST(OpenHaptics, RunsTheServoAndStopsWithZeroTorque) {
  Standin standin("");
  OpenHapticsDriver d(standin_library());
  auto omni = std::make_shared<PhantomOmni>();
  Controller c(omni, circle(), driver_settings());
  d.open(*omni);
  EXPECT_EQ(d.calibrate(), Calibration::kOk);
  d.start(c);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const ServoStats running = d.servo()->stats();
  d.stop();
  EXPECT_GT(running.ticks, 100u);
  EXPECT_GT(running.force_n, 0.0);
  EXPECT_EQ(running.stop, StopReason::kNone);
  const auto s = standin.summary();
  EXPECT_EQ(s.at("priorities"), "0 65535");  // the calibration check, then the servo
  EXPECT_EQ(s.at("sets_outside_frame"), "0");
  EXPECT_EQ(s.at("illegal_begin"), "0");
  EXPECT_EQ(s.at("illegal_end"), "0");
  EXPECT_EQ(s.at("frames_begun"), s.at("frames_ended"));
  EXPECT_EQ(s.at("torque_without_force_output"), "0");
  EXPECT_EQ(s.at("gimbal_sets"), "0");
  EXPECT_EQ(s.at("last_joint_torque"), "0 0 0");
  EXPECT_EQ(s.at("scheduler_running"), "0");
  EXPECT_EQ(s.at("unscheduled"), "1");
  EXPECT_EQ(s.at("disable_calls"), "1");
}

TEST(OpenHaptics, CommErrorMidRunEndsWithZeroTorque) {
  Standin standin("error_at 200 0x0302 5\n");
  OpenHapticsDriver d(standin_library());
  auto omni = std::make_shared<PhantomOmni>();
  Controller c(omni, circle(), driver_settings());
  d.open(*omni);
  d.start(c);
  for (int i = 0; i < 200 && d.servo()->reason() == StopReason::kNone; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const ServoStats st = d.servo()->stats();
  d.stop();
  EXPECT_EQ(st.stop, StopReason::kDeviceError);
  EXPECT_EQ(st.device_error, 0x0302u);
  EXPECT_EQ(d.describe_error(st.device_error).rfind("HD_COMM_ERROR (0x0302): ", 0), 0u);
  const auto s = standin.summary();
  EXPECT_EQ(s.at("error_tick"), "200");
  EXPECT_EQ(s.at("nonzero_torque_after_error"), "0");
}

TEST(OpenHaptics, GimbalTorqueOnlyWhereTheModelDrivesTheGimbal) {
  PhantomOmni omni;
  auto full = std::make_shared<SerialDevice>("PhantomOmni", omni.chain(),
                                             DeviceLimits{std::vector<bool>(6, true),
                                                          std::vector<double>(6, 0.4),
                                                          {}, {}, 3.3, kInf, {}, 1200, 1},
                                             omni.coupling(), omni.coupling_offset());
  Standin standin("output_dof 6\nmodel_type PHANTOM Omni\n");
  OpenHapticsDriver d(standin_library());
  Controller c(full, circle(), driver_settings());
  d.open(*full);
  d.start(c);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  d.stop();
  const auto s = standin.summary();
  EXPECT_NE(s.at("gimbal_sets"), "0");
  EXPECT_EQ(s.at("gimbal_sets"), s.at("torque_sets"));
}

#endif  // VM_STANDIN_HD

}  // namespace
