// Shared helpers for the C++ tests.
#pragma once

#include <random>
#include <vector>

#include "../../bench/bench_models.hpp"  // the 6R arm, the test patch and letter
#include "virtmech/virtmech.hpp"

namespace vmtest {

using namespace virtmech;
using vmbench::six_dof_arm;
using vmbench::test_letter;
using vmbench::test_patch;

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

}  // namespace vmtest
