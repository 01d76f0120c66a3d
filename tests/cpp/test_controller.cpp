// The control laws (eqs. 11, 26) and the safety layer.
#include <gtest/gtest.h>

#include <Eigen/SVD>
#include <cmath>

#include "test_support.hpp"

using namespace virtmech;
using namespace vmtest;

namespace {

ControllerSettings no_ramp() {
  ControllerSettings s;
  s.ramp_time_s = 1e-3;  // one period: no ramp-in
  return s;
}

// Planar3R with a PlanarArm circle of radius 0.1 about (0.25, 0) in its plane
struct PlanarScene {
  double l1 = 0.2, l2 = 0.2, R = 0.1;
  Eigen::Vector3d pivot{0.25, 0.0, 0.0};
  std::shared_ptr<Planar3R> robot = std::make_shared<Planar3R>(0.2, 0.2, Pose::Identity(), 50.0, 100.0);
  std::shared_ptr<PlanarArm> arm = std::make_shared<PlanarArm>(
      Eigen::Vector3d(0.25, 0.0, 0.0), Eigen::Vector3d::UnitZ(), 0.1, Eigen::Vector3d::UnitX());
  // handle at angle alpha on a circle of radius r about the pivot, stylus as the arm's at beta
  JointVector q(double r, double alpha, double beta) const {
    const Eigen::Vector3d p = pivot + r * Eigen::Vector3d(std::cos(alpha), std::sin(alpha), 0);
    return planar3r_ik(l1, l2, p.x(), p.y(), beta + M_PI);
  }
};

}  // namespace

TEST(Controller, PassiveJointTorquesAreExactlyZero) {
  auto omni = std::make_shared<PhantomOmni>();
  std::vector<std::shared_ptr<const Mechanism>> mechs = {
      std::make_shared<Probe>(Eigen::Vector3d(0, -0.05, 0), Eigen::Vector3d::UnitY(), 0.1,
                              Eigen::Vector3d::Zero()),
      std::make_shared<PlanarArm>(Eigen::Vector3d(0, 0.0, -0.1), Eigen::Vector3d::UnitZ(), 0.05,
                                  Eigen::Vector3d::UnitX())};
  std::mt19937 rng(51);
  std::normal_distribution<double> g(0.0, 0.5);
  for (const auto& m : mechs) {
    ControllerSettings s = no_ramp();
    s.passivity = Passivity::kOff;  // unrelated poses cycle after cycle: the laws themselves
    Controller c(omni, m, s);
    CycleOutput out;
    for (int trial = 0; trial < 500; ++trial) {
      const JointVector q = random_within(rng, omni->lower(), omni->upper());
      JointVector dq(6);
      for (int i = 0; i < 6; ++i) dq[i] = g(rng);
      c.step(q.data(), dq.data(), out);
      EXPECT_EQ(out.status & status::kFaultMask, 0u);
      EXPECT_EQ(out.torque[3], 0.0);
      EXPECT_EQ(out.torque[4], 0.0);
      EXPECT_EQ(out.torque[5], 0.0);
      EXPECT_GT(out.torque.head<3>().norm(), 0.0);
    }
  }
}

TEST(Controller, PlacedWithTheDevicesKinematicsGivenItIsPlacedAsAlone) {
  // place(q, dq, at_q, ...) with at_q = forward_jacobian(q) (what a MechanismSet hands its
  // members) is place(q, dq, ...), bit for bit, cycle after cycle along a smooth path
  // (warm starts, both placements), and so is the rendering after it
  auto omni = std::make_shared<PhantomOmni>();
  auto probe = std::make_shared<Probe>(Eigen::Vector3d(0, -0.03, 0), Eigen::Vector3d::UnitY(),
                                       0.1, Eigen::Vector3d::Zero(), true);
  Controller alone(omni, probe), given(omni, probe);
  std::mt19937 rng(53);
  const JointVector a = random_within(rng, omni->lower(), omni->upper());
  const JointVector b = random_within(rng, omni->lower(), omni->upper());
  CycleOutput o1, o2;
  DeviceKinematics at_q;
  for (int k = 0; k <= 300; ++k) {
    const double s = 0.5 - 0.5 * std::cos(M_PI * k / 300.0);
    const JointVector q = a + s * (b - a);
    const JointVector dq = (b - a) * (0.5 * M_PI / 300.0 * std::sin(M_PI * k / 300.0) / 1e-3);
    const double t = 1e-3 * k;
    omni->forward_jacobian(q.data(), at_q.pose, at_q.J);
    const std::uint32_t s1 = alone.place(q.data(), dq.data(), o1, t);
    const std::uint32_t s2 = given.place(q.data(), dq.data(), at_q, o2, t);
    ASSERT_EQ(s1, s2);
    ASSERT_EQ(o1.theta, o2.theta) << k;
    ASSERT_EQ(o1.theta_star, o2.theta_star) << k;
    ASSERT_EQ(o1.error, o2.error) << k;
    ASSERT_EQ(o1.error_star, o2.error_star) << k;
    ASSERT_TRUE(o1.handle_pose.matrix() == o2.handle_pose.matrix()) << k;
    ASSERT_EQ(alone.render(o1), given.render(o2));
    ASSERT_EQ(o1.torque, o2.torque) << k;
    ASSERT_EQ(o1.error_dot, o2.error_dot) << k;
  }
}

TEST(Controller, OmniWrenchCarriesNoMomentAndIsExplainedByTorques) {
  // the applied wrench is renderable: J_R^T f = tau with zero passive torques
  auto omni = std::make_shared<PhantomOmni>();
  auto probe = std::make_shared<Probe>(Eigen::Vector3d(0, -0.03, 0), Eigen::Vector3d::UnitY(), 0.1,
                                       Eigen::Vector3d::Zero());
  Controller c(omni, probe, no_ramp());
  std::mt19937 rng(52);
  CycleOutput out;
  for (int trial = 0; trial < 200; ++trial) {
    const JointVector q = random_within(rng, omni->lower(), omni->upper());
    c.step(q.data(), JointVector::Zero(6).eval().data(), out);
    Pose T;
    Jacobian J;
    omni->forward_jacobian(q.data(), T, J);
    EXPECT_LT(out.wrench.tail<3>().norm(), 1e-12);
    EXPECT_LT((J.transpose() * out.wrench - out.torque).cwiseAbs().maxCoeff(), 1e-12);
  }
}

TEST(Controller, PlanarUnderActuatedPullsTowardMechanismAtHandleAngle) {
  // paper section V: with W_e* on the un-powered joint, the range-space term moves the
  // handle along the circle to the mechanism position at the handle's own angle
  PlanarScene s;
  Controller c(s.robot, s.arm, no_ramp());
  CycleOutput out;
  for (double alpha : {-0.8, -0.2, 0.4, 1.1}) {
    for (double delta : {-0.5, -0.2, 0.2, 0.5}) {
      c.reset();
      const JointVector q = s.q(s.R, alpha, alpha + delta);
      c.step(q.data(), JointVector::Zero(3).eval().data(), out);
      const Eigen::Vector3d f = out.wrench.head<3>();
      const Eigen::Vector3d tangent(-std::sin(alpha), std::cos(alpha), 0.0);
      // on the circle: the force runs along the path toward the handle's angle
      EXPECT_GT(f.normalized().dot(tangent) * (delta > 0 ? 1.0 : -1.0), 0.99) << alpha << " " << delta;
      const Eigen::Vector3d target =
          s.pivot + s.R * Eigen::Vector3d(std::cos(alpha + delta), std::sin(alpha + delta), 0.0);
      EXPECT_GT(f.normalized().dot((target - out.handle_pose.translation()).normalized()),
                std::cos(std::abs(delta) / 2.0) - 1e-3);
      // the un-powered placement is the arm at the handle's angle
      EXPECT_NEAR(out.theta_star[0], alpha + delta, 1e-6);
      EXPECT_EQ(out.torque[2], 0.0);
    }
  }
}

TEST(Controller, PlanarFarStartPullsToCircleSlightlyTowardHandleAngle) {
  // paper Fig. 10: far from the circle, a large force brings the handle to the circle,
  // directed slightly toward the mechanism position at the handle's angle
  PlanarScene s;
  Controller c(s.robot, s.arm, no_ramp());
  CycleOutput out;
  const double alpha = 0.3, delta = 0.1;
  const JointVector q = s.q(s.R + 0.03, alpha, alpha + delta);
  c.step(q.data(), JointVector::Zero(3).eval().data(), out);
  const Eigen::Vector3d f = out.wrench.head<3>();
  const Eigen::Vector3d radial(std::cos(alpha), std::sin(alpha), 0.0);
  const Eigen::Vector3d tangent(-std::sin(alpha), std::cos(alpha), 0.0);
  EXPECT_LT(f.dot(radial), 0.0);                        // toward the circle
  EXPECT_GT(std::abs(f.dot(radial)), std::abs(f.dot(tangent)));  // mostly toward it
  EXPECT_GT(f.dot(tangent), 0.0);                       // and slightly toward the handle angle
  // the null-space law alone (paper Fig. 9) has no tangential pull
  ControllerSettings ns = no_ramp();
  ns.law = ControlLaw::kNullSpace;
  Controller c9(s.robot, s.arm, ns);
  c9.step(q.data(), JointVector::Zero(3).eval().data(), out);
  EXPECT_LT(std::abs(out.wrench.head<3>().normalized().dot(tangent)), 1e-6);
}

namespace {

// The 6R arm's pose at q0 (T0), and a circle mechanism through it: pivot one length L ahead
// on the stylus, the plane normal the handle's y axis.
struct ArmCircle {
  JointVector q0 = (JointVector(6) << 0.2, -0.4, 0.9, 0.3, 0.7, -0.2).finished();
  Pose T0;
  double L = 0.08;
  std::shared_ptr<PlanarArm> mech;
  explicit ArmCircle(const Device& arm) {
    arm.forward(q0.data(), T0);
    mech = std::make_shared<PlanarArm>(T0.translation() + L * T0.linear().col(2),
                                       T0.linear().col(1), L, -T0.linear().col(2));
  }
};

}  // namespace

TEST(Controller, FullyActuatedFreeAlongMechanismStiffAcross) {
  auto arm6 = six_dof_arm();
  const ArmCircle scene(*arm6);
  const JointVector& q0 = scene.q0;
  const Pose& T0 = scene.T0;
  const double L = scene.L;
  const auto mech = scene.mech;
  Controller c(arm6, mech, no_ramp());
  EXPECT_FALSE(c.model().under_actuated_term);
  CycleOutput out;
  const JointVector zero = JointVector::Zero(6);
  // resting on the mechanism
  c.step(q0.data(), zero.data(), out);
  EXPECT_LT(out.wrench.norm(), 1e-9);
  // moved along the free direction (the circle), by a large amount
  for (double th : {0.05, 0.3, -0.6}) {
    Pose Tm;
    mech->forward(&th, Tm);
    const JointVector q = inverse_kinematics(*arm6, Tm, q0);
    c.step(q.data(), zero.data(), out);
    EXPECT_LT(out.wrench.norm(), 1e-7) << th;
    // moving along it at speed meets no damping either
    Pose Tp;
    Jacobian Jm, JR;
    mech->forward_jacobian(&th, Tp, Jm);
    arm6->forward_jacobian(q.data(), Tp, JR);
    const Eigen::VectorXd dq =
        Eigen::MatrixXd(JR).completeOrthogonalDecomposition().solve(Eigen::VectorXd(Jm * 0.5));
    c.step(q.data(), dq.data(), out);
    EXPECT_LT(out.wrench.norm(), 1e-7) << th;
  }
  // pushed across: radially, along the plane normal, and tilted about the radial axis
  const Vector6 kp = c.model().kp;
  const Eigen::Vector3d radial = -T0.linear().col(2), normal = T0.linear().col(1);
  for (int dir = 0; dir < 3; ++dir) {
    Pose Tx = T0;
    Vector6 expected = Vector6::Zero();
    const double d = 1e-3;
    if (dir == 0) {
      Tx.translation() += d * radial;
      expected.head<3>() = -kp[0] * d * radial;
    } else if (dir == 1) {
      Tx.translation() += d * normal;
      expected.head<3>() = -kp[0] * d * normal;
    } else {
      Tx.linear() = Eigen::AngleAxisd(d, radial).toRotationMatrix() * T0.linear();
      expected.tail<3>() = -kp[3] * d * radial;
    }
    const JointVector q = inverse_kinematics(*arm6, Tx, q0);
    c.step(q.data(), zero.data(), out);
    EXPECT_LT((out.wrench - expected).norm(), 1e-3 * expected.norm()) << dir;
  }
}

TEST(Controller, FuzzedInputsNeverGiveNonFiniteOrOverLimitTorques) {
  auto omni = std::make_shared<PhantomOmni>();
  auto probe = std::make_shared<Probe>(Eigen::Vector3d(0, -0.05, 0), Eigen::Vector3d::UnitY(), 0.1,
                                       Eigen::Vector3d::Zero());
  Controller c(omni, probe, no_ramp());
  std::mt19937 rng(61);
  const double specials[] = {std::nan(""), kInf, -kInf, 1e300, -1e300, 1e12, 0.0, -3.0, 40.0};
  std::uniform_int_distribution<int> pick(0, 8), idx(0, 5);
  std::normal_distribution<double> g(0.0, 2.0);
  CycleOutput out;
  for (int trial = 0; trial < 20000; ++trial) {
    JointVector q(6), dq(6);
    for (int i = 0; i < 6; ++i) {
      q[i] = g(rng);
      dq[i] = 10.0 * g(rng);
    }
    if (trial % 2) (trial % 4 == 1 ? q : dq)[idx(rng)] = specials[pick(rng)];
    const std::uint32_t st = c.step(q.data(), dq.data(), out);
    ASSERT_TRUE(out.torque.allFinite());
    ASSERT_TRUE(out.wrench.allFinite());
    for (int i = 0; i < 6; ++i) ASSERT_LE(std::abs(out.torque[i]), omni->torque_limit()[i] * (1 + 1e-12));
    ASSERT_LE(out.wrench.head<3>().norm(), omni->max_force() * (1 + 1e-12));
    if (!q.allFinite() || !dq.allFinite()) {
      ASSERT_TRUE(st & status::kFaultNonFiniteInput);
      ASSERT_EQ(out.torque.cwiseAbs().maxCoeff(), 0.0);
    }
  }
}

TEST(Controller, RampInBoundsTheFirstCyclesAndRestartsAfterAFault) {
  auto omni = std::make_shared<PhantomOmni>();
  auto arm = std::make_shared<PlanarArm>(Eigen::Vector3d(0, 0, -0.05), Eigen::Vector3d::UnitZ(),
                                         0.05, Eigen::Vector3d::UnitX());
  ControllerSettings s;
  s.ramp_time_s = 0.1;
  Controller c(omni, arm, s);
  const long N = c.model().ramp_cycles;
  ASSERT_EQ(N, 100);
  JointVector q(6);
  q << 0.3, 0.9, 0.6, 0.0, 0.5, 0.0;  // far from the circle: force saturates
  const JointVector dq = JointVector::Zero(6);
  CycleOutput out;
  for (long k = 1; k <= 150; ++k) {
    c.step(q.data(), dq.data(), out);
    const double bound = omni->max_force() * std::min(1.0, double(k) / N);
    EXPECT_LE(out.wrench.head<3>().norm(), bound * (1 + 1e-12)) << k;
    EXPECT_EQ(bool(out.status & status::kRamping), k < N) << k;
  }
  EXPECT_NEAR(out.wrench.head<3>().norm(), omni->max_force(), 1e-9);
  JointVector bad = q;
  bad[1] = std::nan("");
  c.step(bad.data(), dq.data(), out);
  EXPECT_TRUE(out.status & status::kFaultNonFiniteInput);
  c.step(q.data(), dq.data(), out);
  EXPECT_LE(out.wrench.head<3>().norm(), omni->max_force() / N * (1 + 1e-12));
}

TEST(Controller, WatchdogRestartsRampAfterAGap) {
  auto omni = std::make_shared<PhantomOmni>();
  auto arm = std::make_shared<PlanarArm>(Eigen::Vector3d(0, 0, -0.05), Eigen::Vector3d::UnitZ(),
                                         0.05, Eigen::Vector3d::UnitX());
  ControllerSettings s;
  s.ramp_time_s = 0.01;
  s.watchdog_s = 0.005;
  Controller c(omni, arm, s);
  JointVector q(6);
  q << 0.3, 0.9, 0.6, 0.0, 0.5, 0.0;
  const JointVector dq = JointVector::Zero(6);
  CycleOutput out;
  double t = 0.0;
  for (int k = 0; k < 20; ++k, t += 1e-3) c.step(q.data(), dq.data(), out, t);
  EXPECT_FALSE(out.status & status::kRamping);
  c.step(q.data(), dq.data(), out, t + 0.1);  // the loop stalled for 100 ms
  EXPECT_TRUE(out.status & status::kWatchdog);
  EXPECT_TRUE(out.status & status::kRamping);
}

TEST(Controller, BadSettingsNameTheField) {
  auto omni = std::make_shared<PhantomOmni>();
  auto arm = std::make_shared<PlanarArm>(Eigen::Vector3d(0, 0, -0.05), Eigen::Vector3d::UnitZ(),
                                         0.05, Eigen::Vector3d::UnitX());
  ControllerSettings s;
  Vector6 kp = Vector6::Ones();
  kp[2] = -1.0;
  s.kp = kp;
  try {
    Controller c(omni, arm, s);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("kp"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("-1"), std::string::npos);
  }
}

TEST(Controller, WrongSizedInputIsAFaultNotACrash) {
  auto omni = std::make_shared<PhantomOmni>();
  auto arm = std::make_shared<PlanarArm>(Eigen::Vector3d(0, 0, -0.05), Eigen::Vector3d::UnitZ(),
                                         0.05, Eigen::Vector3d::UnitX());
  Controller c(omni, arm, no_ramp());
  CycleOutput out;
  const Eigen::VectorXd q5 = Eigen::VectorXd::Constant(5, 0.3), dq6 = Eigen::VectorXd::Zero(6);
  const std::uint32_t s = c.step(q5, dq6, out);
  EXPECT_TRUE(s & status::kFaultBadSize);
  EXPECT_EQ(out.torque.size(), 6);
  EXPECT_EQ(out.torque.cwiseAbs().maxCoeff(), 0.0);
  const Eigen::VectorXd q6 = Eigen::VectorXd::Constant(6, 0.3);
  EXPECT_EQ(c.step(q6, dq6, out) & status::kFaultMask, 0u);
}

namespace {

// J theta_dot - v for the weighted least-squares fit theta_dot = argmin |S (J theta_dot - v)|,
// S = sqrt(diag(w)), by an SVD: an algorithm independent of the controller's
Vector6 svd_rate(const Jacobian& J_free, const Vector6& w, const Vector6& v) {
  const Eigen::MatrixXd S = w.cwiseSqrt().asDiagonal();
  const Eigen::MatrixXd J = J_free;
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(S * J, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::VectorXd theta_dot = svd.solve(S * v);
  return J * theta_dot - v;
}

Jacobian without(const Jacobian& J, std::uint32_t locked) {
  Jacobian out(6, 0);
  for (int i = 0; i < J.cols(); ++i) {
    if ((locked >> i) & 1u) continue;
    out.conservativeResize(6, out.cols() + 1);
    out.col(out.cols() - 1) = J.col(i);
  }
  return out;
}

// The placement's rate as docs/theory.md (6) defines it: the joints on a bound that the
// weighted cost presses past it are locked, each with the weight min(1, d_i / 0.1 mm), d_i =
// |J_i^T W e| |J_i|_U / (J_i^T W J_i); e_dot is the rate with every such joint locked,
// blended toward the rate with the partly locked ones free by their least weight.
Vector6 locked_rate(const Mechanism& mech, const JointVector& theta, const Jacobian& J,
                    const Vector6& w, const Vector6& e, const Vector6& v) {
  std::uint32_t locked = 0, partial = 0;
  double least = 1.0;
  const double L2 = mech.length_scale() * mech.length_scale();
  for (int i = 0; i < mech.dof(); ++i) {
    const double g = -J.col(i).dot(w.cwiseProduct(e));  // (e = X_V - X_R: -grad / 2)
    const bool lower = theta[i] <= mech.lower()[i] && g < 0.0;
    const bool upper = theta[i] >= mech.upper()[i] && g > 0.0;
    if (!lower && !upper) continue;
    locked |= 1u << i;
    const double length =
        std::sqrt(J.col(i).head<3>().squaredNorm() + L2 * J.col(i).tail<3>().squaredNorm());
    const double weight =
        std::min(1.0, std::abs(g) * length / J.col(i).dot(w.cwiseProduct(J.col(i))) / 1e-4);
    if (weight < 1.0) partial |= 1u << i, least = std::min(least, weight);
  }
  const Vector6 held = svd_rate(without(J, locked), w, v);
  if (!partial) return held;
  const Vector6 free = svd_rate(without(J, locked & ~partial), w, v);
  return free + least * (held - free);
}

}  // namespace

TEST(Controller, PlacementRatesAreTheWeightedFitsResidual) {
  // e_dot and e*_dot are J theta_dot - v_R for the weighted fit of the handle's twist by the
  // placements' unlocked joints (docs/theory.md, 3), on every cycle of random smooth paths:
  // a Probe's and a SurfaceProbe's rate comes from its constraint wrench, a PlanarArm's from
  // its one column, the rest from the factorisation
  auto omni = std::make_shared<PhantomOmni>();
  auto arm = six_dof_arm();
  const Eigen::Vector3d y = Eigen::Vector3d::UnitY();
  Eigen::Matrix3d horizontal;  // the patch's normal (local z) along world y
  horizontal << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  struct Scene {
    std::shared_ptr<const Device> device;
    std::shared_ptr<const Mechanism> mechanism;
  };
  const Scene scenes[] = {
      {omni, std::make_shared<Probe>(Eigen::Vector3d(0, -0.03, 0), y, 0.1, Eigen::Vector3d::Zero())},
      {omni, std::make_shared<Probe>(Eigen::Vector3d(0, -0.01, 0), y, 0.1, Eigen::Vector3d::Zero(),
                                     true)},
      {omni, std::make_shared<PlanarArm>(Eigen::Vector3d(0, 0.0, -0.05), Eigen::Vector3d::UnitZ(),
                                         0.05, Eigen::Vector3d::UnitX())},
      {omni, std::make_shared<LineGuide>(Eigen::Vector3d(0, -0.02, 0), Eigen::Vector3d::UnitX(),
                                         0.1, y)},
      {arm, std::make_shared<Probe>(Eigen::Vector3d(0.3, 0, 0.1), Eigen::Vector3d::UnitZ(), 0.1,
                                    Eigen::Vector3d::Zero(), true)},
      {omni, std::make_shared<SurfaceProbe>(test_patch(Eigen::Vector3d(0, -0.03, 0), horizontal),
                                            0.1)},
      {omni, std::make_shared<SurfaceProbe>(
                 std::make_shared<Sphere>(Eigen::Vector3d(0, -0.09, 0), 0.06, y), 0.1, true)},
  };
  std::mt19937 rng(61);
  std::normal_distribution<double> g(0.0, 0.3);
  int contact = 0, lifted = 0, checked = 0;
  for (const Scene& sc : scenes) {
    const Device& dev = *sc.device;
    const Mechanism& mech = *sc.mechanism;
    ControllerSettings s = no_ramp();
    // (the twists are arbitrary, up to 70 rad/s: no velocity fault)
    s.velocity_margin_rad_s = s.velocity_margin_m_s = 1e3;
    Controller c(sc.device, sc.mechanism, s);
    const ControllerModel& M = c.model();
    CycleOutput out;
    JointVector a = random_within(rng, dev.lower(), dev.upper());
    for (int segment = 0; segment < 6; ++segment) {
      const JointVector b = random_within(rng, dev.lower(), dev.upper());
      for (int k = 0; k < 100; ++k) {
        const JointVector q = a + (k / 100.0) * (b - a);
        JointVector dq = (b - a) * 10.0;
        for (int i = 0; i < dev.dof(); ++i) dq[i] += g(rng);
        c.step(q.data(), dq.data(), out);
        ASSERT_EQ(out.status & status::kFaultMask, 0u);
        Pose T;
        Jacobian J_R, J;
        dev.forward_jacobian(q.data(), T, J_R);
        const Vector6 v = J_R * dq;
        const double scale = 1e-9 * std::max(1.0, v.norm());
        mech.forward_jacobian(out.theta.data(), T, J);
        const Vector6 e_dot = locked_rate(mech, out.theta, J, M.w_e_effective, out.error, v);
        EXPECT_LE((out.error_dot - e_dot).norm(), scale) << mech.type_name() << " " << k;
        if (M.under_actuated_term) {
          mech.forward_jacobian(out.theta_star.data(), T, J);
          const Vector6 e_star_dot =
              locked_rate(mech, out.theta_star, J, M.w_e_star_effective, out.error_star, v);
          EXPECT_LE((out.error_star_dot - e_star_dot).norm(), scale) << mech.type_name() << k;
        }
        if (mech.contact_joint() >= 0) ++((out.active >> mech.contact_joint()) & 1u ? contact : lifted);
        ++checked;
      }
      a = b;
    }
  }
  EXPECT_EQ(checked, 4200);
  EXPECT_GT(contact, 50);  // the unilateral probes both pressed and lifted
  EXPECT_GT(lifted, 50);
}

TEST(Mechanism, ProbesConstraintWrenchDoesNoWorkOnItsMotion) {
  // J_free^T n = 0 wherever the probe reports one; none where J_free is not of rank 5
  std::mt19937 rng(62);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  const Eigen::Vector3d n = Eigen::Vector3d(0.2, 1.0, -0.3).normalized();
  for (const bool unilateral : {false, true}) {
    const Probe probe(Eigen::Vector3d(0.01, -0.02, 0.03), n, 0.12, Eigen::Vector3d::Zero(),
                      unilateral);
    const int wrist = unilateral ? 3 : 2;
    const std::uint32_t contact = unilateral ? 1u << 2 : 0u;
    for (int trial = 0; trial < 200; ++trial) {
      JointVector x(probe.dof());
      for (int i = 0; i < probe.dof(); ++i) x[i] = u(rng) * (i < wrist ? 0.05 : 1.0);
      if (unilateral) x[2] = 0.0;  // in contact
      Pose T;
      Jacobian J;
      probe.forward_jacobian(x.data(), T, J);
      Vector6 w;
      ASSERT_TRUE(probe.constraint_wrench(x.data(), T, J, contact, w));
      const Jacobian J_free = without(J, contact);
      EXPECT_LE((J_free.transpose() * w).norm(), 1e-14 * J_free.norm() * w.norm()) << trial;
      // its one constraint: J_free has rank 5 (and with it the lift-off column, rank 6)
      EXPECT_EQ(Eigen::JacobiSVD<Eigen::MatrixXd>(Eigen::MatrixXd(J_free)).rank(), 5);
      EXPECT_GT(w.norm(), 0.9);
      // another joint locked, or (unilateral) the tip free to lift: not one constraint
      EXPECT_FALSE(probe.constraint_wrench(x.data(), T, J, contact | 1u, w));
      if (unilateral) EXPECT_FALSE(probe.constraint_wrench(x.data(), T, J, 0u, w));
      // the wrist's gimbal lock (its middle angle at +-pi/2): J has rank 4
      x[wrist + 1] = trial % 2 ? M_PI / 2 : -M_PI / 2;
      probe.forward_jacobian(x.data(), T, J);
      EXPECT_FALSE(probe.constraint_wrench(x.data(), T, J, contact, w)) << trial;
      EXPECT_EQ(Eigen::JacobiSVD<Eigen::MatrixXd>(Eigen::MatrixXd(without(J, contact))).rank(), 4);
    }
  }
}

namespace {

// A mechanism that is `inner` without its place_pair() (and constraint wrench): the cycle
// places it one weighting at a time, by place()
class OneAtATime final : public Mechanism {
 public:
  explicit OneAtATime(std::shared_ptr<const Mechanism> inner)
      : Mechanism("OneAtATime", joint_kinds(*inner), inner->lower(), inner->upper(), inner->home(),
                  inner->length_scale()),
        inner_(std::move(inner)) {}
  void forward_jacobian(const double* x, Pose& T, Jacobian& J) const noexcept override {
    inner_->forward_jacobian(x, T, J);
  }
  bool place(const Pose& target, const Vector6& w, const JointVector& start, JointVector& theta,
             Pose& T, Jacobian& J, Vector6& e) const noexcept override {
    return inner_->place(target, w, start, theta, T, J, e);
  }
  bool constraint_wrench(const double* x, const Pose& T, const Jacobian& J,
                         std::uint32_t locked, Vector6& n) const noexcept override {
    return inner_->constraint_wrench(x, T, J, locked, n);
  }

 private:
  std::shared_ptr<const Mechanism> inner_;
};

}  // namespace

TEST(Controller, PlacementsInOneClosedFormAreTheSingleOnes) {
  // the cycle's two placements by place_pair() give every output bit for bit as by place()
  // one at a time, cycle after cycle along random paths (warm starts included)
  auto omni = std::make_shared<PhantomOmni>();
  const Eigen::Vector3d y = Eigen::Vector3d::UnitY();
  const std::vector<std::shared_ptr<const Mechanism>> mechs = {
      std::make_shared<Probe>(Eigen::Vector3d(0, -0.03, 0), y, 0.1, Eigen::Vector3d::Zero()),
      std::make_shared<PlanarArm>(Eigen::Vector3d(0, 0.0, -0.05), Eigen::Vector3d::UnitZ(), 0.05,
                                  Eigen::Vector3d::UnitX())};
  std::mt19937 rng(67);
  for (const auto& m : mechs) {
    Controller pair(omni, m), single(omni, std::make_shared<OneAtATime>(m));
    CycleOutput o1, o2;
    JointVector a = random_within(rng, omni->lower(), omni->upper());
    for (int segment = 0; segment < 3; ++segment) {
      const JointVector b = random_within(rng, omni->lower(), omni->upper());
      for (int k = 0; k < 100; ++k) {
        const JointVector q = a + (k / 100.0) * (b - a);
        const JointVector dq = (b - a) * 10.0;
        ASSERT_EQ(pair.step(q.data(), dq.data(), o1), single.step(q.data(), dq.data(), o2));
        ASSERT_EQ(o1.theta, o2.theta) << m->type_name() << k;
        ASSERT_EQ(o1.theta_star, o2.theta_star) << m->type_name() << k;
        ASSERT_EQ(o1.error, o2.error) << m->type_name() << k;
        ASSERT_EQ(o1.error_star, o2.error_star) << m->type_name() << k;
        ASSERT_EQ(o1.error_dot, o2.error_dot) << m->type_name() << k;
        ASSERT_EQ(o1.torque, o2.torque) << m->type_name() << k;
        ASSERT_TRUE(o1.mechanism_pose_star.matrix() == o2.mechanism_pose_star.matrix());
      }
      a = b;
    }
  }
}

TEST(Mechanism, SurfaceProbesConstraintWrenchDoesNoWorkOnItsMotion) {
  // the surface's normal force at the tip: J_free^T n = 0 with J_free of rank 5, on a NURBS
  // patch and a sphere, bilateral and unilateral (tip on the surface); none with the tip free
  // to lift or another joint locked
  std::mt19937 rng(63);
  std::uniform_real_distribution<double> u01(0.0, 1.0), ang(-1.2, 1.2);
  const auto patch = test_patch(Eigen::Vector3d(0.01, -0.02, 0.03));
  const auto sphere = std::make_shared<Sphere>(Eigen::Vector3d(0.0, 0.0, -0.05), 0.05);
  int checked = 0;
  for (const std::shared_ptr<const Surface>& surface :
       std::vector<std::shared_ptr<const Surface>>{patch, sphere}) {
    for (const bool unilateral : {false, true}) {
      const SurfaceProbe probe(surface, 0.12, unilateral);
      const int wrist = unilateral ? 3 : 2;
      const std::uint32_t contact = unilateral ? 1u << 2 : 0u;
      const Eigen::Vector2d lo = surface->lower(), hi = surface->upper();
      for (int trial = 0; trial < 100; ++trial) {
        JointVector x(probe.dof());
        x[0] = lo[0] + (0.05 + 0.9 * u01(rng)) * (hi[0] - lo[0]);
        x[1] = lo[1] + (0.1 + 0.8 * u01(rng)) * (hi[1] - lo[1]);  // (away from a pole)
        if (unilateral) x[2] = 0.0;
        for (int i = wrist; i < wrist + 3; ++i) x[i] = ang(rng);
        Pose T;
        Jacobian J;
        probe.forward_jacobian(x.data(), T, J);
        Vector6 w;
        ASSERT_TRUE(probe.constraint_wrench(x.data(), T, J, contact, w)) << trial;
        ++checked;
        const Jacobian J_free = without(J, contact);
        EXPECT_LE((J_free.transpose() * w).norm(), 1e-13 * J_free.norm() * w.norm()) << trial;
        EXPECT_EQ(Eigen::JacobiSVD<Eigen::MatrixXd>(Eigen::MatrixXd(J_free)).rank(), 5);
        EXPECT_FALSE(probe.constraint_wrench(x.data(), T, J, contact | 1u, w));
        if (unilateral) EXPECT_FALSE(probe.constraint_wrench(x.data(), T, J, 0u, w));
      }
    }
  }
  EXPECT_EQ(checked, 400);
}

TEST(Controller, ForceLimitHoldsForForcesWhoseSquaresOverflow) {
  // a force limit of 1e200 N against a spring of 1e210 N/m pulled 5 cm: |f|^2 overflows,
  // and the limit still acts (limits this large are compared without squaring them; with
  // |f| itself overflowing, the scale is limit / inf = 0). The 6R arm with limits that
  // large (its own are 40 N and 20 N m), so that no other limit acts first.
  DeviceLimits big;
  big.actuated = std::vector<bool>(6, true);
  big.torque_limit = std::vector<double>(6, 1e300);
  big.max_force = 1e200;
  big.max_torque = 1e200;
  auto arm6 = std::make_shared<SerialDevice>("Arm6R", six_dof_arm()->chain(), big);
  const ArmCircle scene(*arm6);
  const JointVector& q0 = scene.q0;
  const Pose& T0 = scene.T0;
  const auto mech = scene.mech;
  ControllerSettings s = no_ramp();
  s.kp = Vector6::Constant(1e210);
  s.kv = Vector6::Zero();
  s.max_force = 1e200;
  s.max_torque = 1e200;
  s.passivity = Passivity::kOff;
  Controller c(arm6, mech, s);
  const JointVector zero = JointVector::Zero(6);
  CycleOutput out;
  c.step(q0.data(), zero.data(), out);
  Pose T = T0;
  T.translation() += 0.05 * T0.linear().col(1);  // along the plane normal: across
  const JointVector q = inverse_kinematics(*arm6, T, q0);
  c.step(q.data(), zero.data(), out);
  ASSERT_TRUE(out.wrench.allFinite());
  EXPECT_TRUE(out.status & status::kForceClamped);
  EXPECT_LE(out.wrench.head<3>().norm(), 1e200);
}
