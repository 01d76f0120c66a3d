// The simulation's servo-rate loop (virtmech_sim) on a one-hinge MuJoCo model compiled from
// a string: the hand's push gives the closed-form angular acceleration, a spring-only hand
// conserves energy, the layouts are checked, and MuJoCo's timer callback is restored.
#include <gtest/gtest.h>
#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "virtmech/sim/servo_loop.hpp"

using namespace virtmech;
using namespace virtmech::sim;

namespace {

constexpr double kL = 0.1;        // handle on the link, m from the hinge
constexpr double kMass = 0.2;     // link mass at the handle [kg]
constexpr double kIzz = 1e-4;     // its own inertia about z [kg m^2]
constexpr double kDt = 0.25e-3;   // physics step [s]
constexpr int kSubsteps = 4;      // per 1 ms control cycle
const double kI = kIzz + kMass * kL * kL;  // about the hinge

// a free hinge about z, no gravity, damping, friction, armature or contacts; its motor
// transmits nothing (gear 0: a device needs a motor, the tests need a free hinge)
const char* kHingeXml = R"(
<mujoco>
  <option timestep="0.00025" gravity="0 0 0"><flag contact="disable"/></option>
  <worldbody>
    <body>
      <joint name="hinge" type="hinge" axis="0 0 1"/>
      <inertial pos="0.1 0 0" mass="0.2" diaginertia="1e-4 1e-4 1e-4"/>
    </body>
  </worldbody>
  <actuator><motor joint="hinge" gear="0"/></actuator>
</mujoco>)";

struct Model {
  mjModel* m = nullptr;
  mjData* d = nullptr;
  explicit Model(const char* text = kHingeXml) {
    mjVFS vfs;
    mj_defaultVFS(&vfs);
    const std::string xml(text);
    EXPECT_EQ(mj_addBufferVFS(&vfs, "hinge.xml", xml.data(), int(xml.size())), 0);
    char err[1000] = "";
    m = mj_loadXML("hinge.xml", &vfs, err, sizeof(err));
    mj_deleteVFS(&vfs);
    if (m == nullptr) throw std::runtime_error(err);
    d = mj_makeData(m);
  }
  ~Model() {
    mj_deleteData(d);
    mj_deleteModel(m);
  }
};

// the one-joint device of the model: handle at (L, 0, 0) on the link
std::shared_ptr<SerialDevice> hinge_device() {
  Pose handle = Pose::Identity();
  handle.translation() = Eigen::Vector3d(kL, 0.0, 0.0);
  DeviceLimits lim;
  lim.actuated = {true};
  lim.torque_limit = {1.0};
  return std::make_shared<SerialDevice>("Hinge", KinematicChain(Pose::Identity(), {Joint{}},
                                                                handle), lim);
}

std::unique_ptr<Controller> controller() {
  auto arm = std::make_shared<PlanarArm>(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), kL,
                                         Eigen::Vector3d::UnitX());
  return std::make_unique<Controller>(hinge_device(), arm);
}

LoopSettings settings() {
  LoopSettings s;
  s.coupling_inv = Eigen::MatrixXd::Identity(1, 1);
  s.coupling_offset = Eigen::VectorXd::Zero(1);
  s.substeps = kSubsteps;
  s.period_s = 1e-3;
  s.actuated = {0};
  return s;
}

// the same hinge with a hand body (mass at the handle) that the loop can release
const char* kHandXml = R"(
<mujoco>
  <option timestep="0.00025" gravity="0 0 0"><flag contact="disable"/></option>
  <worldbody>
    <body>
      <joint name="hinge" type="hinge" axis="0 0 1"/>
      <inertial pos="0.1 0 0" mass="0.2" diaginertia="1e-4 1e-4 1e-4"/>
      <body name="hand" pos="0.1 0 0">
        <inertial pos="0 0 0" mass="0.3" diaginertia="2e-4 2e-4 2e-4"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor joint="hinge" gear="0"/></actuator>
</mujoco>)";

// this test's own column order (the loop takes any): the plan permuted, a short log
PlanLayout plan_layout() {
  PlanLayout p;
  p.segment = 0;
  p.force_in_handle = 1;
  p.force = 2;
  p.k_t = 5;
  p.b_t = 6;
  p.k_r = 7;
  p.b_r = 8;
  p.anchor_w = 9;
  p.anchor_v = 12;
  p.anchor_R = 15;
  p.anchor_p = 24;
  p.moment = 27;
  p.hand_attached = 30;
  p.columns = 31;
  return p;
}

LogLayout log_layout() {
  LogLayout l;
  l.t = 0;
  l.q = 1;
  l.dq = 2;
  l.handle_p = 3;
  l.hand_wrench = 6;
  l.anchor = 12;
  l.columns = 15;
  return l;
}

// `rows` plan rows: anchor at p_a, identity orientation, gains, a push in world axes
std::vector<double> plan_rows(int rows, const Eigen::Vector3d& p_a, double k_t, double b_t,
                              const Eigen::Vector3d& push) {
  const PlanLayout P = plan_layout();
  std::vector<double> plan(size_t(rows * P.columns), 0.0);
  for (int r = 0; r < rows; ++r) {
    double* row = plan.data() + r * P.columns;
    for (int i = 0; i < 3; ++i) {
      row[P.anchor_p + i] = p_a[i];
      row[P.force + i] = push[i];
      row[P.anchor_R + 4 * i] = 1.0;
    }
    row[P.k_t] = k_t;
    row[P.b_t] = b_t;
    row[P.hand_attached] = 1.0;
  }
  return plan;
}

struct LoopLog {
  std::vector<double> log;
  int columns;
  double at(int row, int col) const { return log[size_t(row * columns + col)]; }
};

LoopLog run(Model& model, Controller& ctrl, int rows, const std::vector<double>& plan,
            int hand_body = -1) {
  LoopSettings s = settings();
  s.hand_body = hand_body;
  ServoLoop loop(ctrl, model.m, model.d, s, plan_layout(), log_layout());
  LoopLog r{std::vector<double>(size_t(rows * log_layout().columns), 0.0), log_layout().columns};
  std::vector<double> noise(size_t(rows), 0.0), dropout(size_t(rows), 0.0);
  loop.run(0, size_t(rows), plan.data(), noise.data(), dropout.data(), r.log.data());
  return r;
}

}  // namespace

// A constant push F (world y) at the handle of a hinge at rest: torque L F cos q, so for
// small q the angular velocity is (L F / I) t and the angle (L F / 2 I) t^2.
TEST(SimLoop, APushOnAFreeHingeGivesTheClosedFormAngularAcceleration) {
  Model model;
  auto ctrl = controller();
  const double F = 0.05;
  const int rows = 21;  // 20 ms: q stays below 0.01 rad (cos q = 1 to 5e-5)
  const LoopLog r = run(model, *ctrl, rows, plan_rows(rows, Eigen::Vector3d::Zero(), 0.0, 0.0,
                                                  Eigen::Vector3d(0.0, F, 0.0)));
  const double alpha = kL * F / kI;
  const int k = rows - 1;
  const double t = r.at(k, 0);
  EXPECT_DOUBLE_EQ(t, 0.02);
  EXPECT_NEAR(r.at(k, 2), alpha * t, 1e-4 * alpha * t);
  // semi-implicit Euler: q_k = alpha dt^2 k (k + 1) / 2 after k steps
  const double steps = t / kDt;
  EXPECT_NEAR(r.at(k, 1), 0.5 * alpha * kDt * kDt * steps * (steps + 1), 1e-4 * r.at(k, 1));
  EXPECT_DOUBLE_EQ(r.at(k, 7), F);  // the hand's force, logged
  EXPECT_GT(r.at(k, 1), 1e-4);      // it moved
}

// A pure moment M about the hinge's axis at the handle: the angular acceleration M / I, and
// the hand's logged wrench has no force.
TEST(SimLoop, APureMomentGivesTheClosedFormAngularAccelerationAndNoForce) {
  Model model;
  auto ctrl = controller();
  const double M = 2e-3;
  const int rows = 21;
  std::vector<double> plan =
      plan_rows(rows, Eigen::Vector3d::Zero(), 0.0, 0.0, Eigen::Vector3d::Zero());
  const PlanLayout P = plan_layout();
  for (int r = 0; r < rows; ++r) plan[size_t(r * P.columns + P.moment + 2)] = M;
  const LoopLog r = run(model, *ctrl, rows, plan);
  const double alpha = M / kI;
  const int k = rows - 1;
  const double t = r.at(k, 0);
  EXPECT_NEAR(r.at(k, 2), alpha * t, 1e-9 * alpha * t);  // a moment: no cos q
  for (int i = 0; i < 3; ++i) EXPECT_EQ(r.at(k, 6 + i), 0.0);  // no force
  EXPECT_DOUBLE_EQ(r.at(k, 11), M);
}

// Released (hand_attached = 0), the hand pushes nothing and its mass is gone: the push is
// not felt; taking hold again, the push accelerates the link and the hand's mass together.
TEST(SimLoop, AReleasedHandHasNoWrenchAndNoMassUntilItTakesHoldAgain) {
  Model model(kHandXml);
  const int hand = mj_name2id(model.m, mjOBJ_BODY, "hand");
  ASSERT_GT(hand, 0);
  auto ctrl = controller();
  const double F = 0.05;
  const int rows = 41;
  std::vector<double> plan =
      plan_rows(rows, Eigen::Vector3d::Zero(), 0.0, 0.0, Eigen::Vector3d(0.0, F, 0.0));
  const PlanLayout P = plan_layout();
  for (int r = 0; r < 20; ++r) plan[size_t(r * P.columns + P.hand_attached)] = 0.0;
  LoopSettings s = settings();
  s.hand_body = hand;
  LoopLog r{std::vector<double>(size_t(rows * log_layout().columns), 0.0), log_layout().columns};
  {
    ServoLoop loop(*ctrl, model.m, model.d, s, plan_layout(), log_layout());
    std::vector<double> noise(size_t(rows), 0.0), dropout(size_t(rows), 0.0);
    loop.run(0, 20, plan.data(), noise.data(), dropout.data(), r.log.data());
    EXPECT_FALSE(loop.hand_attached());
    EXPECT_EQ(model.m->body_mass[hand], 0.0);
    EXPECT_EQ(model.m->body_subtreemass[1], 0.2);  // mj_setConst: as without the hand
    for (int k = 0; k < 20; ++k) {
      EXPECT_EQ(r.at(k, 1), 0.0);  // nothing moved it
      EXPECT_EQ(r.at(k, 7), 0.0);  // no hand wrench
    }
    loop.run(20, 21, plan.data() + 20 * P.columns, noise.data(), dropout.data(),
             r.log.data() + 20 * r.columns);
    EXPECT_TRUE(loop.hand_attached());
    EXPECT_EQ(model.m->body_mass[hand], 0.3);
  }
  const double I = kI + 0.3 * kL * kL + 2e-4;  // link, hand mass at L, hand inertia
  const double alpha = kL * F / I;
  const double t = r.at(rows - 1, 0) - 0.02;  // pushed from 20 ms on
  EXPECT_NEAR(r.at(rows - 1, 2), alpha * t, 1e-4 * alpha * t);
  EXPECT_DOUBLE_EQ(r.at(rows - 1, 7), F);
}

// A spring-only hand (no damping anywhere): the handle oscillates about the anchor and
// kinetic plus spring energy stays what it was.
TEST(SimLoop, ASpringOnlyHandConservesEnergy) {
  Model model;
  model.d->qpos[0] = 0.5;  // start 0.5 rad from the anchor at q = 0
  auto ctrl = controller();
  const double k_t = 50.0;
  const Eigen::Vector3d p_a(kL, 0.0, 0.0);
  const int rows = 500;
  const LoopLog r = run(model, *ctrl, rows, plan_rows(rows, p_a, k_t, 0.0, Eigen::Vector3d::Zero()));
  auto energy = [&](int row) {
    const Eigen::Vector3d p(r.at(row, 3), r.at(row, 4), r.at(row, 5));
    return 0.5 * kI * r.at(row, 2) * r.at(row, 2) + 0.5 * k_t * (p_a - p).squaredNorm();
  };
  const double E0 = energy(0);
  double q_min = 1.0;
  for (int row = 0; row < rows; ++row) {
    EXPECT_NEAR(energy(row), E0, 2e-3 * E0) << "cycle " << row;
    q_min = std::min(q_min, r.at(row, 1));
  }
  EXPECT_LT(q_min, -0.45);  // it swung through to the other side
}

TEST(SimLoop, RefusesAModelThatIsNotTheDeviceAndALayoutOutsideTheRow) {
  Model model;
  auto ctrl = controller();
  LoopSettings two = settings();
  two.actuated = {0, 0};  // the model has one actuator
  EXPECT_THROW(ServoLoop(*ctrl, model.m, model.d, two, plan_layout(), log_layout()),
               std::invalid_argument);
  PlanLayout p = plan_layout();
  p.anchor_p = 29;  // 3 entries from 29 in a row of 31
  try {
    ServoLoop(*ctrl, model.m, model.d, settings(), p, log_layout());
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("plan.anchor_p"), std::string::npos) << e.what();
  }
  LogLayout l = log_layout();
  l.q = 15;
  EXPECT_THROW(ServoLoop(*ctrl, model.m, model.d, settings(), plan_layout(), l),
               std::invalid_argument);
}

namespace {
int timer_calls = 0;
mjtNum counting_timer() {
  ++timer_calls;
  return 0.0;
}
}  // namespace

TEST(SimLoop, TheTimerCallbackIsOffDuringARunAndRestoredOnReturnAndOnThrow) {
  Model model;
  auto ctrl = controller();
  const mjfTime before = mjcb_time;
  mjcb_time = counting_timer;
  mj_step(model.m, model.d);
  EXPECT_GT(timer_calls, 0);  // MuJoCo calls it: the checks below can fail
  timer_calls = 0;
  run(model, *ctrl, 5, plan_rows(5, Eigen::Vector3d::Zero(), 0.0, 0.0, Eigen::Vector3d::Zero()));
  EXPECT_EQ(timer_calls, 0);
  EXPECT_EQ(mjcb_time, &counting_timer);
  // an error inside MuJoCo during the run, thrown by the error handler (as the mujoco
  // Python package's handler does)
  mjcb_passive = [](const mjModel*, mjData*) { mju_error("a failure inside the loop"); };
  const auto saved_error = mju_user_error;
  mju_user_error = [](const char* msg) { throw std::runtime_error(msg); };
  EXPECT_THROW(run(model, *ctrl, 5,
                   plan_rows(5, Eigen::Vector3d::Zero(), 0.0, 0.0, Eigen::Vector3d::Zero())),
               std::runtime_error);
  mjcb_passive = nullptr;
  mju_user_error = saved_error;
  EXPECT_EQ(timer_calls, 0);
  EXPECT_EQ(mjcb_time, &counting_timer);
  try {
    TimerOff outer;
    EXPECT_EQ(mjcb_time, nullptr);
    {
      TimerOff inner;  // nested: the outer scope's end restores
    }
    EXPECT_EQ(mjcb_time, nullptr);
    throw std::runtime_error("a failure inside the loop");
  } catch (const std::runtime_error&) {
  }
  EXPECT_EQ(mjcb_time, &counting_timer);
  mjcb_time = before;
}
