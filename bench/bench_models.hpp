// The models the benchmark cases share with the C++ tests: a fully actuated 6R arm, a
// rational bicubic patch and a rational cubic letter. Shipped with the benchmark
// (virtmech_cycle_bench); tests/cpp/test_support.hpp uses them from here.
#pragma once

#include <cmath>
#include <memory>
#include <vector>

#include "virtmech/virtmech.hpp"

namespace vmbench {

using namespace virtmech;

/// A fully actuated 6R arm (anthropomorphic, spherical wrist), its stylus along +x.
inline std::shared_ptr<SerialDevice> six_dof_arm() {
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

}  // namespace vmbench
