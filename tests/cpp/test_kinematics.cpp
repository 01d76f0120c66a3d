// Kinematics: Jacobians against central differences, closed forms of eq. 2 and of the
// published PHANTOM Omni gimbal-centre formula.
#include <gtest/gtest.h>

#include <cmath>

#include "test_support.hpp"

using namespace virtmech;
using namespace vmtest;

namespace {

void expect_mechanism_jacobian(const Mechanism& m, unsigned seed) {
  std::mt19937 rng(seed);
  for (int trial = 0; trial < 50; ++trial) {
    const JointVector th = random_within(rng, m.lower(), m.upper(), 1.2);
    Pose T;
    Jacobian J;
    m.forward_jacobian(th.data(), T, J);
    const Jacobian Jn = numeric_jacobian(
        [&](const JointVector& x, Pose& out) { m.forward(x.data(), out); }, th);
    EXPECT_LT((J - Jn).cwiseAbs().maxCoeff(), 1e-7) << m.type_name() << " trial " << trial;
    Pose T2;
    m.forward(th.data(), T2);
    EXPECT_LT((T.matrix() - T2.matrix()).cwiseAbs().maxCoeff(), 1e-15);
  }
}

void expect_device_jacobian(const Device& d, unsigned seed) {
  std::mt19937 rng(seed);
  for (int trial = 0; trial < 50; ++trial) {
    const JointVector q = random_within(rng, d.lower(), d.upper(), 1.5);
    Pose T;
    Jacobian J;
    d.forward_jacobian(q.data(), T, J);
    const Jacobian Jn =
        numeric_jacobian([&](const JointVector& x, Pose& out) { d.forward(x.data(), out); }, q);
    EXPECT_LT((J - Jn).cwiseAbs().maxCoeff(), 1e-7) << d.name() << " trial " << trial;
  }
}

}  // namespace

TEST(Kinematics, MechanismJacobiansMatchCentralDifferences) {
  const Eigen::Vector3d n = Eigen::Vector3d(1, 2, 3).normalized();
  expect_mechanism_jacobian(PlanarArm({0.1, -0.2, 0.3}, n, 0.12, any_orthogonal(n)), 1);
  expect_mechanism_jacobian(Probe({0.0, 0.01, -0.05}, n, 0.1, Eigen::Vector3d::Zero()), 2);
  expect_mechanism_jacobian(PointPivot({0.0, 0.0, 0.0}, Eigen::Vector3d::UnitY(), 0.08,
                                       Eigen::Vector3d::Zero()), 3);
  expect_mechanism_jacobian(LineGuide({0.02, 0.0, 0.0}, Eigen::Vector3d::UnitX(), 0.09,
                                      Eigen::Vector3d::UnitY()), 4);
  std::vector<Joint> joints(3);
  joints[0].type = JointType::kPrismatic;
  joints[0].axis = {1, 1, 0};
  joints[1].axis = {0, 0, 1};
  joints[1].origin.translation() = Eigen::Vector3d(0.1, 0, 0);
  joints[2].axis = {0, 1, 0};
  joints[2].origin = Pose(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()));
  Pose handle = Pose::Identity();
  handle.translation() = Eigen::Vector3d(0.05, 0.02, 0.01);
  expect_mechanism_jacobian(SerialChain(joints, handle, Pose::Identity(), 0.1), 5);
}

TEST(Kinematics, DeviceJacobiansMatchCentralDifferences) {
  expect_device_jacobian(PhantomOmni(), 11);
  PhantomOmniParams p;
  p.gimbal_offset = {0.3, -0.2, 1.0};
  p.gimbal_sign = {-1.0, 1.0, -1.0};
  expect_device_jacobian(PhantomOmni(p), 12);
  expect_device_jacobian(Planar3R(0.2, 0.15, Pose::Identity(), 1.0, 5.0), 13);
  expect_device_jacobian(*six_dof_arm(), 14);
}

TEST(Kinematics, PlanarArmIsEquationTwo) {
  // eq. 2: x = L cos(theta), y = L sin(theta), orientation theta, in the x-y plane
  const double L = 0.1;
  PlanarArm arm(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), L, Eigen::Vector3d::UnitX());
  for (double th = -3.0; th <= 3.0; th += 0.25) {
    Pose T;
    arm.forward(&th, T);
    EXPECT_NEAR(T.translation().x(), L * std::cos(th), 1e-15);
    EXPECT_NEAR(T.translation().y(), L * std::sin(th), 1e-15);
    EXPECT_NEAR(T.translation().z(), 0.0, 1e-15);
    // the stylus points from the handle to the pivot; its in-plane angle advances with theta
    const Eigen::Vector3d z = T.linear().col(2);
    EXPECT_LT((z - Eigen::Vector3d(-std::cos(th), -std::sin(th), 0.0)).norm(), 1e-15);
    EXPECT_LT((T.linear().col(1) - Eigen::Vector3d::UnitZ()).norm(), 1e-15);
    const double th0 = 0.0;
    Pose T0;
    arm.forward(&th0, T0);
    const Eigen::Vector3d w = so3_log(T.linear() * T0.linear().transpose());
    EXPECT_NEAR(w.z(), th, 1e-12);
  }
}

TEST(Kinematics, OmniGimbalCentreIsJarilloSilvaFormula) {
  PhantomOmni omni;
  const double l1 = omni.params().l1, l2 = omni.params().l2;
  std::mt19937 rng(21);
  for (int trial = 0; trial < 200; ++trial) {
    const JointVector q = random_within(rng, omni.lower(), omni.upper());
    Pose T;
    omni.forward(q.data(), T);
    const double t1 = q[0], t2 = q[1], t3 = q[2];
    const double x = -std::sin(t1) * (l1 * std::cos(t2) + l2 * std::sin(t3));
    const double y = l1 * std::sin(t2) - l2 * std::cos(t3) + l2;
    const double z = -l1 + std::cos(t1) * (l1 * std::cos(t2) + l2 * std::sin(t3));
    EXPECT_LT((T.translation() - Eigen::Vector3d(x, y, z)).norm(), 1e-14) << trial;
  }
}

TEST(Kinematics, OmniGimbalAxesMeetAtHandleOrigin) {
  // the passive joints produce no linear velocity of the handle origin
  PhantomOmni omni;
  std::mt19937 rng(22);
  for (int trial = 0; trial < 100; ++trial) {
    const JointVector q = random_within(rng, omni.lower(), omni.upper());
    Pose T;
    Jacobian J;
    omni.forward_jacobian(q.data(), T, J);
    EXPECT_LT(J.block(0, 3, 3, 3).cwiseAbs().maxCoeff(), 1e-15);
    EXPECT_FALSE(omni.actuated(3) || omni.actuated(4) || omni.actuated(5));
    EXPECT_TRUE(omni.actuated(0) && omni.actuated(1) && omni.actuated(2));
  }
}

TEST(Kinematics, InvalidConstructionNamesTheParameter) {
  auto message = [](auto&& make) {
    try {
      make();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  EXPECT_NE(message([] { PlanarArm({0, 0, 0}, {0, 0, 1}, -1.0, {1, 0, 0}); }).find("length"),
            std::string::npos);
  EXPECT_NE(message([] { PlanarArm({0, 0, 0}, {0, 0, 2}, 1.0, {1, 0, 0}); }).find("normal"),
            std::string::npos);
  EXPECT_NE(message([] { Probe({0, 0, 0}, {0, 0, 0}, 0.1, {0, 0, 0}); }).find("plane_normal"),
            std::string::npos);
  EXPECT_NE(message([] { PlanarArm({0, 0, 0}, {0, 0, 1}, 1.0, {0, 0, 1}); }).find("zero_direction"),
            std::string::npos);
}

TEST(Kinematics, OmniClosedFormIsItsChainWalked) {
  // the Omni's written-out pose and Jacobian against its own chain and joint map walked by
  // the generic SerialDevice, over its range and beyond, with a driver's gimbal convention
  PhantomOmniParams custom;
  custom.gimbal_offset = {0.3, -0.2, 1.0};
  custom.gimbal_sign = {-1.0, 1.0, -1.0};
  custom.l1 = 0.21;
  std::mt19937 rng(23);
  for (const PhantomOmniParams& p : {PhantomOmniParams(), custom}) {
    const PhantomOmni omni(p);
    DeviceLimits L;
    L.actuated = {true, true, true, false, false, false};
    L.torque_limit = {1.0, 1.0, 1.0, 0.0, 0.0, 0.0};
    const SerialDevice walked("walked", omni.chain(), L, omni.coupling(), omni.coupling_offset());
    for (int trial = 0; trial < 300; ++trial) {
      const JointVector q = random_within(rng, omni.lower(), omni.upper(), 2.0);
      Pose T, Tw, Tp;
      Jacobian J, Jw;
      omni.forward_jacobian(q.data(), T, J);
      walked.forward_jacobian(q.data(), Tw, Jw);
      omni.forward(q.data(), Tp);
      EXPECT_LT((T.matrix() - Tw.matrix()).cwiseAbs().maxCoeff(), 1e-15) << trial;
      EXPECT_LT((J - Jw).cwiseAbs().maxCoeff(), 1e-15) << trial;
      EXPECT_EQ(T.matrix(), Tp.matrix()) << trial;
    }
  }
}

TEST(Se3, LogIsTheRotationVectorToRounding) {
  // R from axis and angle by Rodrigues' formula in long double, rounded once; angles from
  // 1e-12 to pi - 1e-6, dense about 2 pi / 3 (where the log changes route) and pi
  std::mt19937 rng(31);
  std::normal_distribution<double> g;
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double worst = 0.0;
  for (int trial = 0; trial < 60000; ++trial) {
    Eigen::Vector3d a(g(rng), g(rng), g(rng));
    a.normalize();
    const int kind = trial % 4;
    const double th = kind == 0   ? std::pow(10.0, -12.0 + 12.0 * u(rng))
                      : kind == 1 ? 2.0 * M_PI / 3.0 + 1e-3 * (2.0 * u(rng) - 1.0)
                      : kind == 2 ? M_PI - std::pow(10.0, -6.0 + 5.0 * u(rng))
                                  : M_PI * u(rng);
    const long double c = std::cos(static_cast<long double>(th)),
                      s = std::sin(static_cast<long double>(th));
    Eigen::Matrix3d R;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        long double v = (1.0L - c) * a[i] * a[j] + (i == j ? c : 0.0L);
        const int k = 3 - i - j;  // the third index when i != j
        if (i != j) v += ((i + 1) % 3 == j ? -1.0L : 1.0L) * s * a[k];
        R(i, j) = static_cast<double>(v);
      }
    }
    const Eigen::Vector3d w = so3_log(R);
    // within rounding of R's entries: 2e-15 rad, and near pi 2e-16 / (pi - angle) for the
    // axis (an ill-conditioned direction there)
    const double tol = 2e-15 + 2e-16 / (M_PI - th);
    const double err = (w - th * a).norm();
    worst = std::max(worst, err / tol);
    ASSERT_LE(err, tol) << "angle " << th << " trial " << trial;
  }
  EXPECT_GT(worst, 1e-3);
}
