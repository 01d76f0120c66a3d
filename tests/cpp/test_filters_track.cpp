// Filters (eqs. 5, 9) and the placement solver (eqs. 18-23).
#include <gtest/gtest.h>

#include "test_support.hpp"

using namespace virtmech;
using namespace vmtest;

TEST(Filters, RangeFilterIsIdempotentAndNullFilterAnnihilatesFreeMotion) {
  std::mt19937 rng(31);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const int n = 1 + trial % 5;
    Jacobian J(6, n);
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < n; ++j) J(i, j) = g(rng);
    Vector6 W;
    for (int i = 0; i < 6; ++i) W[i] = (trial % 3 == 0 && i % 2 == 0) ? 0.0 : std::abs(g(rng)) + 0.1;
    const Matrix6 P = range_filter(J, W);
    EXPECT_LT((P * P - P).cwiseAbs().maxCoeff(), 1e-9) << trial;
    for (int i = 0; i < 6; ++i) {
      if (W[i] == 0.0) EXPECT_EQ(P.row(i).cwiseAbs().maxCoeff(), 0.0);
    }
    const Matrix6 N = null_filter(J, W);
    const JointMatrix H = J.transpose() * W.asDiagonal() * J;
    const Eigen::MatrixXd Hd = H;
    Eigen::FullPivLU<Eigen::MatrixXd> lu(Hd);
    if (lu.rank() == n) {
      EXPECT_LT((J.transpose() * N).cwiseAbs().maxCoeff(), 1e-9) << trial;
    }
  }
}

TEST(Filters, RankDeficientWeightsStayFinite) {
  // a 1-dof mechanism whose only motion is a rotation, filtered with translational weights
  Jacobian J(6, 1);
  J << 0, 0, 0, 0, 0, 1;
  Vector6 W;
  W << 1, 1, 1, 0, 0, 0;
  const Matrix6 P = range_filter(J, W);
  EXPECT_TRUE(P.allFinite());
  EXPECT_EQ(P.cwiseAbs().maxCoeff(), 0.0);  // nothing to project onto
  EXPECT_TRUE(null_filter(J, W).isIdentity(0.0));
}

TEST(Track, ConvergedPlacementSatisfiesEquation23) {
  const Eigen::Vector3d n(0, 0, 1);
  Probe probe({0.0, 0.0, 0.0}, n, 0.1, Eigen::Vector3d::Zero());
  std::mt19937 rng(41);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  Vector6 W;
  W << 1, 2, 0.5, 0.01, 0.01, 0.01;  // isotropic rotational weight
  for (int trial = 0; trial < 100; ++trial) {
    JointVector th(5);
    th << u(rng), u(rng), u(rng), u(rng), u(rng);
    Pose target;
    probe.forward(th.data(), target);
    target.translation() += Eigen::Vector3d(u(rng), u(rng), u(rng)) * 0.05;  // off the plane
    target.linear() = Eigen::AngleAxisd(u(rng), Eigen::Vector3d(u(rng), u(rng), 1).normalized()) *
                      target.linear();
    JointVector out;
    const TrackResult r = track(probe, target, JointVector::Zero(5), W, TrackOptions(), out);
    EXPECT_TRUE(r.converged) << trial;
    Pose T;
    Jacobian J;
    probe.forward_jacobian(out.data(), T, J);
    const Vector6 e = pose_error(target, T);
    EXPECT_LT((J.transpose() * W.asDiagonal() * e).cwiseAbs().maxCoeff(), 1e-10) << trial;
    EXPECT_NEAR(r.residual, std::sqrt(e.dot(W.cwiseProduct(e))), 1e-12);
  }
}

TEST(Track, RespectsJointLimits) {
  std::vector<Joint> j(1);
  j[0].axis = Eigen::Vector3d::UnitZ();
  j[0].lower = -0.2;
  j[0].upper = 0.2;
  Pose handle = Pose::Identity();
  handle.translation() = Eigen::Vector3d(0.1, 0, 0);
  SerialChain arm(j, handle, Pose::Identity(), 0.1);
  const double th = 1.0;
  Pose target;
  arm.forward(&th, target);  // reachable only beyond the limit
  JointVector out;
  const TrackResult r =
      track(arm, target, JointVector::Zero(1), Vector6::Ones(), TrackOptions(), out);
  EXPECT_TRUE(r.converged);
  EXPECT_DOUBLE_EQ(out[0], 0.2);
}
