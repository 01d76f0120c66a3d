// CartesianDevice: the SDK's pose as coordinates, its exact Jacobian, the SDK's velocities
// and the wrench of the coordinate torques, and each model's actuation and limits.
#include <gtest/gtest.h>

#include <random>
#include <stdexcept>
#include <string>

#include "test_support.hpp"
#include "virtmech/cartesian_device.hpp"

namespace {

using namespace vmtest;

const std::vector<std::string> kModels = {"omega.3", "omega.6", "omega.7", "sigma.7", "falcon"};

// the x-y-z gimbal written with Eigen's angle-axis rotations (independent of the device's
// own product): R = Rx(a) Ry(b) Rz(c), and its axes x, Rx(a) y, Rx(a) Ry(b) z
Eigen::Matrix3d gimbal(double a, double b, double c) {
  using A = Eigen::AngleAxisd;
  return (A(a, Eigen::Vector3d::UnitX()) * A(b, Eigen::Vector3d::UnitY()) *
          A(c, Eigen::Vector3d::UnitZ()))
      .toRotationMatrix();
}

Eigen::Matrix3d gimbal_axes(double a, double b) {
  using A = Eigen::AngleAxisd;
  Eigen::Matrix3d W;
  W.col(0) = Eigen::Vector3d::UnitX();
  W.col(1) = A(a, Eigen::Vector3d::UnitX()) * Eigen::Vector3d::UnitY();
  W.col(2) = A(a, Eigen::Vector3d::UnitX()) * A(b, Eigen::Vector3d::UnitY()) *
             Eigen::Vector3d::UnitZ();
  return W;
}

class EachModel : public testing::TestWithParam<std::string> {};

TEST_P(EachModel, JacobianMatchesFiniteDifferencesAndTheClosedForm) {
  const CartesianDevice d(GetParam());
  std::mt19937 rng(31);
  for (int k = 0; k < 50; ++k) {
    const JointVector q = random_within(rng, d.lower(), d.upper());
    Pose T;
    Jacobian J;
    d.forward_jacobian(q.data(), T, J);
    const Jacobian Jn = numeric_jacobian([&](const JointVector& x, Pose& P) { d.forward(x.data(), P); }, q);
    EXPECT_LT((J - Jn).cwiseAbs().maxCoeff(), 1e-8) << "q = " << q.transpose();
    // the closed form: position = the slides, R = Rx(a) Ry(b) Rz(c) R_h, J = [I 0; 0 W]
    Jacobian Jc = Jacobian::Zero(6, d.dof());
    Jc.topLeftCorner<3, 3>().setIdentity();
    Eigen::Matrix3d R = d.handle_rotation();
    if (d.dof() == 6) {
      Jc.bottomRightCorner<3, 3>() = gimbal_axes(q[3], q[4]);
      R = gimbal(q[3], q[4], q[5]) * d.handle_rotation();
    }
    EXPECT_LT((J - Jc).cwiseAbs().maxCoeff(), 1e-14);
    EXPECT_LT((T.linear() - R).cwiseAbs().maxCoeff(), 1e-14);
    EXPECT_LT((T.translation() - q.head<3>()).cwiseAbs().maxCoeff(), 1e-15);
    // and the chain walk of the same chain
    Pose Tc;
    Jacobian Jw;
    d.SerialDevice::forward_jacobian(q.data(), Tc, Jw);
    EXPECT_LT((J - Jw).cwiseAbs().maxCoeff(), 1e-14);
    EXPECT_LT((T.matrix() - Tc.matrix()).cwiseAbs().maxCoeff(), 1e-14);
  }
}

TEST_P(EachModel, CoordinatesOfTheSdkPoseRoundTrip) {
  const CartesianDevice d(GetParam());
  std::mt19937 rng(7);
  for (int k = 0; k < 50; ++k) {
    const JointVector q = random_within(rng, d.lower(), d.upper());
    const Eigen::Vector3d p = q.head<3>();
    const Eigen::Matrix3d R = d.dof() == 6 ? gimbal(q[3], q[4], q[5]) : gimbal(0.3, 0.2, 0.1);
    JointVector back(d.dof());
    d.coordinates(p, R, nullptr, back.data());
    EXPECT_LT((back - q).cwiseAbs().maxCoeff(), 1e-12) << "q = " << q.transpose();
    Eigen::Vector3d p2;
    Eigen::Matrix3d R2;
    d.sdk_pose(q.data(), p2, R2);
    EXPECT_EQ(p2, p);
    if (d.dof() == 6) {
      EXPECT_LT((R2 - R).cwiseAbs().maxCoeff(), 1e-14);
    } else {
      EXPECT_EQ(R2, Eigen::Matrix3d::Identity());  // no orientation sensed
    }
  }
}

TEST(CartesianDevice, AnglesFollowThePreviousReadingAcrossAHalfTurn) {
  const CartesianDevice d("omega.6");
  // the roll passes pi: the reading nearest the previous one keeps turning (3.2, not -3.08)
  const double prev[6] = {0, 0, 0, 0.1, 0.2, 3.1};
  double q[6];
  d.coordinates(Eigen::Vector3d::Zero(), gimbal(0.1, 0.2, 3.2), prev, q);
  EXPECT_NEAR(q[5], 3.2, 1e-12);
  d.coordinates(Eigen::Vector3d::Zero(), gimbal(0.1, 0.2, 3.2), nullptr, q);
  EXPECT_NEAR(q[5], 3.2 - 2.0 * M_PI, 1e-12);
}

TEST_P(EachModel, RatesOfTheSdkVelocitiesGiveTheTwist) {
  const CartesianDevice d(GetParam());
  std::mt19937 rng(3);
  std::normal_distribution<double> g;
  for (int k = 0; k < 30; ++k) {
    const JointVector q = random_within(rng, d.lower(), d.upper());
    const Eigen::Vector3d v(g(rng), g(rng), g(rng)), w(g(rng), g(rng), g(rng));
    JointVector dq(d.dof());
    ASSERT_TRUE(d.rates(q.data(), v, w, dq.data()));
    Pose T;
    Jacobian J;
    d.forward_jacobian(q.data(), T, J);
    const Vector6 twist = J * dq;
    EXPECT_LT((twist.head<3>() - v).cwiseAbs().maxCoeff(), 1e-12);
    if (d.dof() == 6) {
      EXPECT_LT((twist.tail<3>() - w).cwiseAbs().maxCoeff(), 1e-12);
    }
  }
}

TEST_P(EachModel, WrenchOfTheCoordinateTorques) {
  const CartesianDevice d(GetParam());
  std::mt19937 rng(5);
  std::normal_distribution<double> g;
  for (int k = 0; k < 30; ++k) {
    const JointVector q = random_within(rng, d.lower(), d.upper());
    Vector6 w;
    w << g(rng), g(rng), g(rng), g(rng), g(rng), g(rng);
    if (d.dof() == 3) w.tail<3>().setZero();
    Pose T;
    Jacobian J;
    d.forward_jacobian(q.data(), T, J);
    const JointVector tau = J.transpose() * w;
    Eigen::Vector3d f, m;
    ASSERT_TRUE(d.wrench(q.data(), tau.data(), f, m));
    EXPECT_LT((f - w.head<3>()).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_LT((m - w.tail<3>()).cwiseAbs().maxCoeff(), 1e-12);
  }
}

INSTANTIATE_TEST_SUITE_P(Models, EachModel, testing::ValuesIn(kModels),
                         [](const testing::TestParamInfo<std::string>& info) {
                           std::string s = info.param;
                           for (char& c : s) c = c == '.' ? '_' : c;
                           return s;
                         });

TEST(CartesianDevice, GimbalLockIsReportedNotDividedBy) {
  const CartesianDevice d("sigma.7");
  const double q[6] = {0, 0, 0, 0.2, M_PI / 2, 0.1};
  const double tau[6] = {1, 2, 3, 0.1, 0.2, 0.3};
  Eigen::Vector3d f, m;
  EXPECT_FALSE(d.wrench(q, tau, f, m));
  EXPECT_EQ(m, Eigen::Vector3d::Zero());
  double dq[6];
  EXPECT_FALSE(d.rates(q, Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(1, 1, 1), dq));
  EXPECT_EQ(dq[0], 1.0);
  EXPECT_EQ(dq[5], 0.0);
  // the wrist's range keeps away from it on every model
  for (const CartesianModel& model : cartesian_models()) {
    if (!model.orientation_sensed) continue;
    EXPECT_LT(model.angle_upper[1], M_PI / 2 - 0.2) << model.name;
    EXPECT_GT(model.angle_lower[1], -M_PI / 2 + 0.2) << model.name;
  }
}

TEST(CartesianDevice, ActuationAndLimitsByModel) {
  struct Expect {
    const char* name;
    int dof;
    bool torque;
    double force, torque_limit;
  };
  for (const Expect& e : {Expect{"omega.3", 3, false, 12.0, 0.0}, Expect{"omega.6", 6, false, 12.0, 0.0},
                          Expect{"omega.7", 6, false, 12.0, 0.0}, Expect{"sigma.7", 6, true, 12.0, 0.2},
                          Expect{"falcon", 3, false, 8.0, 0.0}}) {
    const CartesianDevice d(e.name);
    SCOPED_TRACE(e.name);
    EXPECT_EQ(d.name(), e.name);
    EXPECT_EQ(d.dof(), e.dof);
    EXPECT_EQ(d.max_force(), e.force);
    EXPECT_EQ(d.max_torque(), e.torque ? e.torque_limit : kInf);
    for (int i = 0; i < d.dof(); ++i) {
      const bool slide = i < 3;
      EXPECT_EQ(d.joint_type(i), slide ? JointType::kPrismatic : JointType::kRevolute);
      EXPECT_EQ(d.actuated(i), slide || e.torque);
      EXPECT_EQ(d.torque_limit()[i], slide ? e.force : (e.torque ? e.torque_limit : 0.0));
      EXPECT_LT(d.lower()[i], 0.0);  // the SDK's origin inside the range
      EXPECT_GT(d.upper()[i], 0.0);
    }
    EXPECT_EQ(d.fully_actuated(), d.dof() == 3 || e.torque);
  }
}

TEST(CartesianDevice, UnknownModelNamesTheKeyAndTheChoices) {
  try {
    CartesianDevice d("omega.9");
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind("model: ", 0), 0u) << what;
    EXPECT_NE(what.find("omega.9"), std::string::npos) << what;
    EXPECT_NE(what.find("'sigma.7'"), std::string::npos) << what;
  }
  Eigen::Matrix3d shear = Eigen::Matrix3d::Identity();
  shear(0, 1) = 0.1;
  EXPECT_THROW(CartesianDevice("omega.6", shear), std::invalid_argument);
  EXPECT_THROW(CartesianDevice("omega.6", -Eigen::Matrix3d::Identity()), std::invalid_argument);
}

// the controller's torque on the coordinates is the wrench it commands at the handle: the
// force on the slides, nothing on an omega.6's wrist, J_w^T m on a sigma.7's
TEST(CartesianDevice, ControllerTorqueIsTheHandleWrench) {
  for (const std::string model : {"omega.6", "sigma.7", "falcon"}) {
    SCOPED_TRACE(model);
    auto d = std::make_shared<CartesianDevice>(model);
    auto probe = std::make_shared<Probe>(Eigen::Vector3d(0, 0, -0.04), Eigen::Vector3d::UnitZ(),
                                         0.05, Eigen::Vector3d::Zero());
    ControllerSettings s;
    s.ramp_time_s = 1e-3;  // one cycle: full force at once
    Controller c(d, probe, s);
    JointVector q = JointVector::Zero(d->dof()), dq = JointVector::Zero(d->dof());
    q.head<3>() << 0.01, -0.02, -0.005;  // the tip 15 mm inside the plane
    if (d->dof() == 6) q.tail<3>() << 0.2, -0.3, 0.4;
    CycleOutput out;
    c.step(q.data(), dq.data(), out, 0.0);
    ASSERT_EQ(out.status & status::kFaultMask, 0u);
    Eigen::Vector3d f, m;
    ASSERT_TRUE(d->wrench(q.data(), out.torque.data(), f, m));
    EXPECT_GT(f.norm(), 1.0);
    EXPECT_LT((f - out.wrench.head<3>()).norm(), 1e-9 * f.norm());
    if (model == "sigma.7") {
      EXPECT_LT((m - out.wrench.tail<3>()).norm(), 1e-9);
    } else {
      EXPECT_EQ(m, Eigen::Vector3d::Zero());
      for (int i = 3; i < d->dof(); ++i) EXPECT_EQ(out.torque[i], 0.0);
    }
  }
}

}  // namespace
