#include "virtmech/device_pose.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <sstream>
#include <stdexcept>

#include "virtmech/se3.hpp"
#include "virtmech/validate.hpp"

namespace virtmech {

namespace {

// The weighted pose error W e at q: e = pose_error(target, device.forward(q)), W = [1 1 1 L L
// L] (so that |W e|^2 is the cost e^T diag(1, 1, 1, L^2, L^2, L^2) e).
Vector6 weighted_error(const Device& device, const Pose& target, const JointVector& q,
                       const Vector6& W) {
  Pose T;
  device.forward(q.data(), T);
  return pose_error(target, T).cwiseProduct(W);
}

JointVector clamped(const Device& device, const JointVector& q) {
  return q.cwiseMax(device.lower()).cwiseMin(device.upper());
}

// Levenberg-Marquardt from one start: damped Gauss-Newton steps (J^T J + lambda I) dq =
// J^T e, projected onto the joint limits, taken where they lower the cost (lambda falls by
// 0.3) and refused where they do not (lambda rises tenfold); stops at a weighted error below
// 1e-12 or where lambda passes 1e8.
JointVector levenberg_marquardt(const Device& device, const Pose& target, JointVector q,
                                const Vector6& W, int max_iterations) {
  const int n = device.dof();
  double lambda = 1e-3;
  Pose T;
  Jacobian J;
  for (int it = 0; it < max_iterations; ++it) {
    device.forward_jacobian(q.data(), T, J);
    const Vector6 e = pose_error(target, T).cwiseProduct(W);
    const Eigen::MatrixXd Jw = W.asDiagonal() * J;
    const Eigen::MatrixXd A =
        Jw.transpose() * Jw + lambda * Eigen::MatrixXd::Identity(n, n);
    const Eigen::VectorXd step = A.partialPivLu().solve(Jw.transpose() * e);
    const JointVector next = clamped(device, q + step);
    const Vector6 e_next = weighted_error(device, target, next, W);
    if (e_next.squaredNorm() < e.squaredNorm()) {
      q = next;
      lambda = std::max(lambda * 0.3, 1e-12);
    } else {
      lambda *= 10.0;
    }
    if (e_next.norm() < 1e-12 || lambda > 1e8) break;
  }
  return q;
}

}  // namespace

DevicePose reach(const Device& device, const Pose& target, const std::vector<JointVector>& seeds,
                 double length_scale, int max_iterations) {
  require_positive("length_scale", length_scale);
  if (seeds.empty()) throw std::invalid_argument("seeds: expected at least one, got none");
  if (max_iterations < 1) {
    throw std::invalid_argument("max_iterations: expected >= 1, got " +
                                std::to_string(max_iterations));
  }
  Vector6 W;
  W << 1.0, 1.0, 1.0, length_scale, length_scale, length_scale;
  DevicePose best;
  double best_norm = kInf;
  for (size_t k = 0; k < seeds.size(); ++k) {
    if (seeds[k].size() != device.dof()) {
      std::ostringstream os;
      os << "seeds[" << k << "]: expected " << device.dof() << " values, got " << seeds[k].size();
      throw std::invalid_argument(os.str());
    }
    const JointVector q =
        levenberg_marquardt(device, target, clamped(device, seeds[k]), W, max_iterations);
    const Vector6 we = weighted_error(device, target, q, W);
    if (we.norm() < best_norm) {
      best_norm = we.norm();
      best = DevicePose{q, we.cwiseQuotient(W), static_cast<int>(k)};
    }
    if (best_norm < 1e-12) break;  // the seeds are in order of preference: the first wins
  }
  return best;
}

}  // namespace virtmech
