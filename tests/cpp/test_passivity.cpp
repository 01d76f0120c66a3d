// The passivity layer's observer against the motors' true work, the plausibility of dq, the
// ramp after a fault, and the settings the cycle refuses (docs/theory.md, 8 and 9).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "test_support.hpp"

namespace {

using namespace vmtest;

std::shared_ptr<const Mechanism> line_guide() {
  return std::make_shared<LineGuide>(Eigen::Vector3d(0, -0.04, -0.1), Eigen::Vector3d::UnitX(),
                                     0.1, Eigen::Vector3d::UnitY());
}

JointVector held_pose() {
  JointVector q(6);
  q << 0.1, 0.5, 0.3, 0.0, 0.8, 0.0;
  return q;
}

// --- plausibility of dq and the ramp after a fault -------------------------------------

// The force the cycles after a one-cycle velocity fault command, relative to the force
// held before it: zero on the faulted cycle, then a ramp of at least kMinimumFaultRampS.
void expect_fault_then_ramp(double bad_dq, double ramp_time_s) {
  auto omni = std::make_shared<PhantomOmni>();
  ControllerSettings s;
  s.ramp_time_s = ramp_time_s;
  Controller c(omni, line_guide(), s);
  const JointVector q = held_pose(), dq0 = JointVector::Zero(6);
  CycleOutput out;
  for (int k = 0; k < 1000; ++k) c.step(q.data(), dq0.data(), out);
  const double held = out.wrench.head<3>().norm();
  ASSERT_GT(held, 3.0);
  JointVector dq = dq0;
  dq[1] = bad_dq;
  c.step(q.data(), dq.data(), out);
  EXPECT_TRUE(out.status & status::kFaultImplausibleVelocity) << bad_dq;
  EXPECT_EQ(out.torque.norm(), 0.0);
  EXPECT_EQ(out.wrench.norm(), 0.0);
  // at least kMinimumFaultRampS (50 cycles at 1 kHz), ramp_time_s where that is longer
  const long ramp = c.model().fault_ramp_cycles;
  EXPECT_EQ(ramp, std::max(50L, std::lround(ramp_time_s / 1e-3)));
  double last = 0.0;
  for (long k = 1; k <= ramp + 5; ++k) {
    c.step(q.data(), dq0.data(), out);
    ASSERT_FALSE(out.status & status::kFaultMask);
    const double f = out.wrench.head<3>().norm();
    // (the guide's force at full ramp is `held`: the ramp scales it)
    EXPECT_LE(f, held * std::min(1.0, static_cast<double>(k) / ramp) + 1e-9) << "cycle " << k;
    EXPECT_LE(f - last, held / ramp + 1e-9) << "cycle " << k;
    last = f;
  }
  EXPECT_NEAR(last, held, 1e-9);
}

TEST(Plausibility, AVelocityBeyondTheDevicesSpeedIsAFaultThenTheForceRampsBack) {
  for (double bad : {50.0, -50.0, 1e4, 1e300, -1e300}) {
    for (double ramp : {1e-6, 1e-3, 0.25}) expect_fault_then_ramp(bad, ramp);
  }
}

TEST(Plausibility, TheBoundIsTheDevicesSpeedPlusTheMargin) {
  auto omni = std::make_shared<PhantomOmni>();
  ControllerSettings s;
  s.velocity_margin_rad_s = 2.0;
  Controller c(omni, line_guide(), s);
  const JointVector q = held_pose();
  CycleOutput out;
  for (int i = 0; i < 6; ++i) {
    const double bound = omni->max_velocity()[i] + 2.0;
    EXPECT_EQ(bound, c.model().dq_max[i]);
    JointVector dq = JointVector::Zero(6);
    dq[i] = 0.999 * bound;
    c.step(q.data(), dq.data(), out);
    EXPECT_FALSE(out.status & status::kFaultImplausibleVelocity) << i;
    dq[i] = -1.001 * bound;
    c.step(q.data(), dq.data(), out);
    EXPECT_TRUE(out.status & status::kFaultImplausibleVelocity) << i;
  }
  // the Omni's joints: 25 rad/s by default (a falling stylus swings its gimbal at ~12 rad/s)
  EXPECT_EQ(omni->max_velocity()[4], kMaxSpeedRevolute);
}

TEST(Plausibility, ADeviceRefusesAVelocityBoundThatIsNotPositive) {
  DeviceLimits L;
  L.actuated = {true, true};
  L.max_velocity = {1.0, 0.0};
  std::vector<Joint> j(2);
  for (auto& x : j) x.axis = Eigen::Vector3d::UnitZ();
  try {
    SerialDevice d("two", KinematicChain(Pose::Identity(), j, Pose::Identity()), L);
    FAIL() << "accepted a zero velocity bound";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_velocity[1]"), std::string::npos) << e.what();
  }
}

TEST(Settings, RampTimesThatCannotBeRepresentedAreRefusedByName) {
  auto omni = std::make_shared<PhantomOmni>();
  for (double bad : {0.0, -1.0, 1e16, 9.3e15, std::numeric_limits<double>::infinity(),
                     std::numeric_limits<double>::quiet_NaN()}) {
    ControllerSettings s;
    s.ramp_time_s = bad;
    try {
      Controller c(omni, line_guide(), s);
      ADD_FAILURE() << "accepted ramp_time_s = " << bad;
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()).rfind("ramp_time_s:", 0), 0u) << e.what();
    }
  }
  for (const char* name : {"passivity_fade_time_s", "passivity_budget_j",
                           "passivity_resolution_rad", "velocity_margin_rad_s"}) {
    ControllerSettings s;
    const std::string key = name;
    if (key == "passivity_fade_time_s") s.passivity_fade_time_s = 0.0;
    if (key == "passivity_budget_j") s.passivity_budget_j = -1.0;
    if (key == "passivity_resolution_rad") s.passivity_resolution_rad = -1e-3;
    if (key == "velocity_margin_rad_s") s.velocity_margin_rad_s = -1.0;
    try {
      Controller c(omni, line_guide(), s);
      ADD_FAILURE() << "accepted " << key;
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()).rfind(key + ":", 0), 0u) << e.what();
    }
  }
}

TEST(Settings, TheStartRampIsRampTimeSAndTheFaultRampAtLeastTheMinimum) {
  auto omni = std::make_shared<PhantomOmni>();
  ControllerSettings s;
  s.ramp_time_s = 1e-3;  // one period: no ramp at the start
  Controller c(omni, line_guide(), s);
  EXPECT_EQ(c.model().ramp_cycles, 1);
  EXPECT_EQ(c.model().fault_ramp_cycles, 50);
  s.ramp_time_s = 0.25;
  Controller d(omni, line_guide(), s);
  EXPECT_EQ(d.model().ramp_cycles, 250);
  EXPECT_EQ(d.model().fault_ramp_cycles, 250);
}

// --- the observer ------------------------------------------------------------------------

// The Omni's joints wander smoothly; the readings the controller gets are the true joints
// quantised to encoder counts, dq the drivers' filtered difference of them (as the
// simulation's sensors make it). The motors' true work is the torque held over each cycle
// times the true joint motion.
struct Encoders {
  double count = 2.0 * M_PI / 15000.0, alpha = 1e-3 / (1e-3 + 1.0 / (2.0 * M_PI * 100.0));
  JointVector last, dq;
  void read(const JointVector& q_true, JointVector& q, JointVector& v) {
    q = (q_true / count).array().round().matrix() * count;
    if (last.size() == 0) {
      last = q;
      dq = JointVector::Zero(q.size());
    }
    dq += alpha * ((q - last) / 1e-3 - dq);
    last = q;
    v = dq;
  }
};

TEST(Observer, BooksTheMotorsTrueWorkToWithinTheQuantisationBound) {
  // a PlanarArm on the Omni: eq. 26's range term does work on the joints' wandering
  auto omni = std::make_shared<PhantomOmni>();
  auto arm = std::make_shared<PlanarArm>(Eigen::Vector3d(0, 0, -0.05), Eigen::Vector3d::UnitZ(),
                                         0.05, Eigen::Vector3d::UnitX());
  ControllerSettings s;
  s.passivity_max_energy_j = std::numeric_limits<double>::infinity();  // no cap
  s.passivity_budget_j = 1e3;  // the range term always on: the observer only observes
  Controller c(omni, arm, s);
  Encoders enc;
  const int cycles = 20000;
  std::vector<JointVector> q_true(cycles), tau(cycles);
  JointVector q(6), dq(6);
  CycleOutput out;
  double first_level = 0.0, fastest = 0.0;
  for (int k = 0; k < cycles; ++k) {
    const double t = k * 1e-3;
    q_true[k].resize(6);
    for (int i = 0; i < 6; ++i) {
      const double w = 0.5 + 0.3 * i;
      q_true[k][i] = 0.3 * (i == 1 || i == 4) + 0.2 * std::sin(w * t + i);
      fastest = std::max(fastest, 0.2 * w);
    }
    enc.read(q_true[k], q, dq);
    c.step(q.data(), dq.data(), out);
    if (k == 0) first_level = out.energy;
    tau[k] = out.torque;
  }
  // the level has booked the intervals [k, k + 1] up to k = cycles - 3: the true work over
  // them, and the torque's variation over them
  double true_work = 0.0, variation = 0.0;
  for (int k = 0; k + 2 < cycles; ++k) {
    true_work += tau[k].dot(q_true[k + 1] - q_true[k]);
    if (k > 0) variation += (tau[k] - tau[k - 1]).cwiseAbs().sum();
  }
  const double booked = first_level - out.energy;
  // |p - q_true| <= rho: the play (half a count), the reading's half count, and one cycle's
  // motion where the median of three readings differs from the middle one
  const double rho = 0.5 * enc.count + 0.5 * enc.count + fastest * 1e-3;
  const double bound =
      rho * (variation + tau[0].cwiseAbs().sum() + tau[cycles - 3].cwiseAbs().sum());
  std::printf("booked %.6f J, true %.6f J, bound %.6f J\n", booked, true_work, bound);
  EXPECT_GT(std::abs(true_work), 1e-3);  // the motion exchanged real energy
  EXPECT_LE(std::abs(booked - true_work), bound);
}

TEST(Observer, EncoderDitherAndGlitchesAreNotBookedAsWork) {
  auto omni = std::make_shared<PhantomOmni>();
  Controller c(omni, line_guide());
  JointVector q = held_pose(), dq = JointVector::Zero(6);
  CycleOutput out;
  for (int k = 0; k < 500; ++k) c.step(q.data(), dq.data(), out);
  const double level = out.energy;
  ASSERT_GT(out.torque.norm(), 0.05);  // the guide pulls: every motion would book work
  const double count = 2.0 * M_PI / 15000.0;
  const double once = 0.5 * count * out.torque.head<3>().cwiseAbs().sum() * 1.2;
  std::mt19937 rng(3);
  double after_first_flips = 0.0;
  for (int k = 0; k < 5000; ++k) {
    JointVector qk = q;
    for (int i = 0; i < 3; ++i) qk[i] += count * static_cast<double>(rng() % 2);  // dither
    if (k % 500 == 250) qk[2] += 0.01;                                           // a glitch
    c.step(qk.data(), dq.data(), out);
    if (k == 100) after_first_flips = out.energy;
  }
  // the observer's displacement moves half a count onto the boundary between the two counts
  // once (the play is half a count), and then neither dither nor glitches move it
  EXPECT_LE(std::abs(after_first_flips - level), once);
  EXPECT_NEAR(out.energy, after_first_flips, 1e-9);
  EXPECT_EQ(out.passivity_scale, 1.0);
}

}  // namespace
