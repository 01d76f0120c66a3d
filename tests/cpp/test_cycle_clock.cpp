// The cycle's clock (computation_time_us) against std::chrono::steady_clock.
#include <gtest/gtest.h>

#include <chrono>
#include <random>

#include "../../src/cycle_clock.hpp"
#include "test_support.hpp"

using virtmech::detail::CycleClock;
using Steady = std::chrono::steady_clock;

TEST(CycleClock, MeasuresTheIntervalSteadyClockMeasures) {
  // busy intervals of 0.5 to 4 ms, each timed by both clocks from inside the other's reads
  CycleClock::calibrate();
  for (const double ms : {0.5, 1.0, 2.0, 4.0}) {
    const Steady::time_point t0 = Steady::now();
    const std::uint64_t c0 = CycleClock::now();
    Steady::time_point t = t0;
    while (std::chrono::duration<double, std::milli>(t - t0).count() < ms) t = Steady::now();
    const std::uint64_t c1 = CycleClock::now();
    const Steady::time_point t1 = Steady::now();
    const double outer_us = std::chrono::duration<double, std::micro>(t1 - t0).count();
    const double inner_us = std::chrono::duration<double, std::micro>(t - t0).count();
    const double us = CycleClock::microseconds(c0, c1);
    // the cycle clock's interval lies between the two steady ones, to its calibration (1e-3)
    EXPECT_LE(us, outer_us * (1.0 + 1e-3)) << ms;
    EXPECT_GE(us, inner_us * (1.0 - 1e-3) - 0.1) << ms;
  }
  EXPECT_EQ(CycleClock::microseconds(10, 5), 0.0);  // backwards: no negative time
}

TEST(CycleClock, AStepsComputationTimeLiesWithinTheCall) {
  using namespace virtmech;
  const auto omni = std::make_shared<PhantomOmni>();
  const auto probe = std::make_shared<Probe>(Eigen::Vector3d(0, -0.03, 0), Eigen::Vector3d::UnitY(),
                                             0.1, Eigen::Vector3d::Zero());
  Controller c(omni, probe, ControllerSettings());
  JointVector q = omni->home(), dq = JointVector::Zero(6);
  CycleOutput out;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.01, 0.01);
  for (int k = 0; k < 200; ++k) {
    for (int i = 0; i < 6; ++i) q[i] = omni->home()[i] + u(rng);
    const Steady::time_point t0 = Steady::now();
    c.step(q.data(), dq.data(), out);
    const Steady::time_point t1 = Steady::now();
    const double call_us = std::chrono::duration<double, std::micro>(t1 - t0).count();
    EXPECT_GT(out.computation_time_us, 0.0) << k;
    EXPECT_LE(out.computation_time_us, call_us * (1.0 + 1e-3)) << k;
  }
}
