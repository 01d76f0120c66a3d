// Shared helpers for the C++ tests.
#pragma once

#include <random>
#include <vector>

#include "virtmech/virtmech.hpp"

namespace vmtest {

using namespace virtmech;

/// Joint values drawn uniformly within limits (or +-range where a limit is infinite).
inline JointVector random_within(std::mt19937& rng, const JointVector& lo, const JointVector& hi,
                                 double range = 1.0) {
  JointVector q(lo.size());
  for (Eigen::Index i = 0; i < lo.size(); ++i) {
    const double a = std::isfinite(lo[i]) ? lo[i] : -range;
    const double b = std::isfinite(hi[i]) ? hi[i] : range;
    q[i] = std::uniform_real_distribution<double>(a, b)(rng);
  }
  return q;
}

/// The joint kinds of a mechanism, for a test's wrapper of it (Mechanism's constructor).
inline std::vector<JointType> joint_kinds(const Mechanism& m) {
  std::vector<JointType> kinds;
  for (int i = 0; i < m.dof(); ++i) kinds.push_back(m.joint_type(i));
  return kinds;
}

/// Central-difference Jacobian of a forward-kinematics function: [v; w] in world axes.
template <typename Fk>
Jacobian numeric_jacobian(const Fk& fk, const JointVector& q, double h = 1e-6) {
  Jacobian J(6, q.size());
  for (Eigen::Index i = 0; i < q.size(); ++i) {
    JointVector qp = q, qm = q;
    qp[i] += h;
    qm[i] -= h;
    Pose Tp, Tm;
    fk(qp, Tp);
    fk(qm, Tm);
    J.col(i) = pose_error(Tp, Tm) / (2.0 * h);
  }
  return J;
}

inline std::shared_ptr<SerialDevice> six_dof_arm() {
  // a fully actuated 6R arm (anthropomorphic, spherical wrist)
  std::vector<Joint> j(6);
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY(),
                        z = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d axes[6] = {z, y, y, x, y, x};
  const Eigen::Vector3d offs[6] = {{0, 0, 0.1}, {0, 0, 0.05}, {0.25, 0, 0}, {0.1, 0, 0},
                                   {0.15, 0, 0}, {0, 0, 0}};
  for (int i = 0; i < 6; ++i) {
    j[i].axis = axes[i];
    j[i].origin = Pose::Identity();
    j[i].origin.translation() = offs[i];
    j[i].lower = -2.5;
    j[i].upper = 2.5;
  }
  Pose handle = Pose::Identity();
  handle.translation() = Eigen::Vector3d(0.05, 0, 0);
  handle.linear() = Eigen::AngleAxisd(M_PI / 2, y).toRotationMatrix();  // stylus along +x
  DeviceLimits L;
  L.actuated = std::vector<bool>(6, true);
  L.torque_limit = std::vector<double>(6, 20.0);
  L.max_force = 40.0;
  L.max_torque = 4.0;
  L.stiffness = 800.0;
  L.damping = 2.0;
  return std::make_shared<SerialDevice>("Arm6R", KinematicChain(Pose::Identity(), j, handle), L);
}

}  // namespace vmtest

namespace vmtest {

/// Joint values putting a fully actuated device's handle at `target` (Newton on the full
/// pose error; the device Jacobian must be square and regular near the answer).
inline JointVector inverse_kinematics(const Device& d, const Pose& target, JointVector q) {
  for (int it = 0; it < 100; ++it) {
    Pose T;
    Jacobian J;
    d.forward_jacobian(q.data(), T, J);
    const Vector6 e = pose_error(target, T);
    if (e.norm() < 1e-14) break;
    const Eigen::MatrixXd Jd = J;
    const Eigen::VectorXd step = Jd.completeOrthogonalDecomposition().solve(Eigen::VectorXd(e));
    q += step;
  }
  return q;
}

/// Planar3R joint values for handle position (x, y) in the base plane and stylus angle phi.
inline JointVector planar3r_ik(double l1, double l2, double x, double y, double phi) {
  const double c = (x * x + y * y - l1 * l1 - l2 * l2) / (2.0 * l1 * l2);
  const double q1 = std::acos(std::max(-1.0, std::min(1.0, c)));
  const double q0 = std::atan2(y, x) - std::atan2(l2 * std::sin(q1), l1 + l2 * std::cos(q1));
  JointVector q(3);
  q << q0, q1, phi - q0 - q1;
  return q;
}

/// A rational bicubic patch 12 cm x 9 cm (a bump and a saddle) in the local xy-plane, its
/// normal local +z, turned by R and moved to `origin`.
inline std::shared_ptr<const NurbsSurface> test_patch(
    const Eigen::Vector3d& origin, const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  const int nu = 5, nv = 4;
  Eigen::MatrixX3d P(nu * nv, 3);
  Eigen::MatrixXd W(nu, nv);
  for (int i = 0; i < nu; ++i) {
    for (int j = 0; j < nv; ++j) {
      const double x = 0.03 * i - 0.06, y = 0.03 * j - 0.045;
      const Eigen::Vector3d local(
          x, y, 0.012 * std::cos(2.0 * x / 0.06) * std::cos(y / 0.045) + 0.2 * x * y);
      P.row(i * nv + j) = (origin + R * local).transpose();
      W(i, j) = 1.0 + 0.1 * ((i + j) % 3);
    }
  }
  Eigen::VectorXd ku(9), kv(8);
  ku << 0, 0, 0, 0, 0.5, 1, 1, 1, 1;
  kv << 0, 0, 0, 0, 1, 1, 1, 1;
  return std::make_shared<NurbsSurface>(P, W, ku, kv, 3, 3);
}

/// A rational cubic 'S' about 8 cm tall in the local xy-plane, turned by R and moved to
/// `origin`.
inline std::shared_ptr<const NurbsCurve> test_letter(
    const Eigen::Vector3d& origin, const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  Eigen::MatrixX3d P(7, 3);
  P << 0.03, 0.04, 0, -0.01, 0.045, 0, -0.03, 0.02, 0, 0.0, 0.0, 0.005, 0.03, -0.02, 0, 0.01,
      -0.045, 0, -0.03, -0.04, 0;
  P = (P * R.transpose()).rowwise() + origin.transpose();
  Eigen::VectorXd w(7), knots(11);
  w << 1.0, 1.3, 0.8, 1.0, 1.2, 0.9, 1.0;
  knots << 0, 0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1, 1;
  return std::make_shared<NurbsCurve>(P, w, knots, 3);
}

}  // namespace vmtest
