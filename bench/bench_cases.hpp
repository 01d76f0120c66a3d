// The benchmark cases of the cycle and the joint trajectory that drives them.
// python/virtmech/bench.py builds the same cases and the same trajectory for its NumPy
// baseline and its Python-call timing: keep the two in step.
#pragma once

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "bench_models.hpp"
#include "virtmech/virtmech.hpp"

namespace vmbench {

using namespace virtmech;

/// A controller and the joint trajectory of its device:
/// q_i(t) = center_i + amplitude_i sin(w_i t + i), w_i = 1 + 0.37 i [rad/s].
struct BenchCase {
  std::string name;
  std::unique_ptr<Controller> controller;  // the case's controller; or, for a set, member 0
  JointVector center, amplitude;
  std::unique_ptr<MechanismSet> set;  // a MechanismSet case: the set is what steps
};

/// Device joint state at cycle k (t = k * period_s).
inline void joint_state(const BenchCase& c, long k, double period_s, JointVector& q,
                        JointVector& dq) noexcept {
  const double t = static_cast<double>(k) * period_s;
  for (Eigen::Index i = 0; i < c.center.size(); ++i) {
    const double w = 1.0 + 0.37 * static_cast<double>(i);
    q[i] = c.center[i] + c.amplitude[i] * std::sin(w * t + static_cast<double>(i));
    dq[i] = c.amplitude[i] * w * std::cos(w * t + static_cast<double>(i));
  }
}

/// A 5-joint serial mechanism (PPRRR, axes x y z x y), as tests/cpp/test_allocation.cpp.
inline std::shared_ptr<Mechanism> serial5() {
  std::vector<Joint> j(5);
  for (int i = 0; i < 5; ++i) {
    j[static_cast<size_t>(i)].type = i < 2 ? JointType::kPrismatic : JointType::kRevolute;
    j[static_cast<size_t>(i)].axis = Eigen::Vector3d::Unit(i % 3);
  }
  Pose handle = Pose::Identity();
  handle.translation() = Eigen::Vector3d(0.3, 0, 0.2);
  return std::make_shared<SerialChain>(j, handle, Pose::Identity(), 0.1);
}

inline JointVector values(std::initializer_list<double> v) {
  JointVector out(static_cast<Eigen::Index>(v.size()));
  Eigen::Index i = 0;
  for (double x : v) out[i++] = x;
  return out;
}

/// The Omni's frame turned so that a shape made in the local xy-plane lies horizontal,
/// its local +z up (the Omni's +y): local (x, y, z) -> world (x, z, -y).
inline Eigen::Matrix3d omni_horizontal() {
  Eigen::Matrix3d R;
  R << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  return R;
}

/// The cases (four device-mechanism pairs and one stress case, then the mechanisms on a
/// geometry, C++ only), in the order the reports list them.
inline std::vector<BenchCase> make_cases() {
  std::vector<BenchCase> cases;
  auto omni = std::make_shared<PhantomOmni>();
  // waist, shoulder, absolute elbow, gimbal yaw, pitch, roll: the hand wanders over the
  // middle of the workspace and turns the stylus
  const JointVector omni_center = values({0.0, 0.5, 0.3, 0.0, 0.8, 0.0});
  const JointVector omni_amplitude = values({0.3, 0.2, 0.2, 0.4, 0.3, 0.5});
  // the probe's tip on a table 1 cm above the handle's zero height: the handle stays 3 to
  // 9 cm above the table, within the 10 cm probe's reach
  cases.push_back({"omni+probe",
                   std::make_unique<Controller>(
                       omni, std::make_shared<Probe>(Eigen::Vector3d(0.0, 0.01, 0.0),
                                                     Eigen::Vector3d::UnitY(), 0.1,
                                                     Eigen::Vector3d::Zero())),
                   omni_center, omni_amplitude});
  cases.push_back({"omni+planar_arm",
                   std::make_unique<Controller>(
                       omni, std::make_shared<PlanarArm>(Eigen::Vector3d(0.0, 0.0, -0.05),
                                                         Eigen::Vector3d::UnitZ(), 0.05,
                                                         Eigen::Vector3d::UnitX())),
                   omni_center, omni_amplitude});
  cases.push_back({"planar3r+planar_arm",
                   std::make_unique<Controller>(
                       std::make_shared<Planar3R>(0.2, 0.2, Pose::Identity(), 50.0, 100.0),
                       std::make_shared<PlanarArm>(Eigen::Vector3d(0.25, 0.0, 0.0),
                                                   Eigen::Vector3d::UnitZ(), 0.1,
                                                   Eigen::Vector3d::UnitX())),
                   values({-0.5, 1.6, 0.5}), values({0.2, 0.2, 0.3})});
  // the same with the table 3 cm below: half the time the handle is lifted beyond the
  // probe's reach, where the placement's Gauss-Newton model is poor (a stress case)
  cases.push_back({"omni+probe_lifted",
                   std::make_unique<Controller>(
                       omni, std::make_shared<Probe>(Eigen::Vector3d(0.0, -0.03, 0.0),
                                                     Eigen::Vector3d::UnitY(), 0.1,
                                                     Eigen::Vector3d::Zero())),
                   omni_center, omni_amplitude});
  cases.push_back({"arm6+serial5", std::make_unique<Controller>(six_dof_arm(), serial5()),
                   JointVector::Constant(6, 0.3), JointVector::Constant(6, 0.4)});
  // a probe on a NURBS patch under the wandering tip (bump +-1.2 cm about y = 0): the tip
  // passes 5 cm below to 3 cm above it
  const Eigen::Matrix3d H = omni_horizontal();
  const auto patch = test_patch(Eigen::Vector3d(0.0, 0.0, -0.02), H);
  cases.push_back({"omni+surface_probe",
                   std::make_unique<Controller>(omni, std::make_shared<SurfaceProbe>(patch, 0.1)),
                   omni_center, omni_amplitude});
  // a probe whose tip may lift off a sphere (radius 5 cm, its top 1 cm above the handle's
  // zero height: the handle wanders 3 to 9 cm above it), as in the omni-surface-sphere
  // scenario
  cases.push_back({"omni+surface_sphere",
                   std::make_unique<Controller>(
                       omni, std::make_shared<SurfaceProbe>(
                                 std::make_shared<Sphere>(Eigen::Vector3d(0.0, -0.04, 0.01), 0.05,
                                                          Eigen::Vector3d::UnitZ()),
                                 0.1, true)),
                   omni_center, omni_amplitude});
  // a tip held to a horizontal line 1 cm above the handle's zero height, as in omni-snap
  cases.push_back({"omni+line_guide",
                   std::make_unique<Controller>(
                       omni, std::make_shared<LineGuide>(Eigen::Vector3d(0.0, 0.01, 0.0),
                                                         Eigen::Vector3d::UnitX(), 0.1,
                                                         Eigen::Vector3d::UnitY())),
                   omni_center, omni_amplitude});
  // four members: the patch (unilateral), a table 3 cm below, two letter paths
  MechanismSetSettings ss;
  ss.snap_distance = 0.005;
  ss.release_distance = 0.01;
  auto set = std::make_unique<MechanismSet>(omni, 4, ss);
  set->add(std::make_shared<SurfaceProbe>(patch, 0.1, true));
  set->add(std::make_shared<Probe>(Eigen::Vector3d(0.0, -0.03, 0.0), Eigen::Vector3d::UnitY(),
                                   0.1, Eigen::Vector3d::Zero(), true));
  const Eigen::Vector3d up = Eigen::Vector3d::UnitY();
  set->add(std::make_shared<CurveGuide>(test_letter(Eigen::Vector3d(0, 0.01, -0.02), H),
                                        0.1, up));
  set->add(std::make_shared<CurveGuide>(
      test_letter(Eigen::Vector3d(0.03, -0.01, -0.03), H), 0.1, up));
  auto member0 = std::make_unique<Controller>(set->member(0));
  cases.push_back({"omni+set4", std::move(member0), omni_center, omni_amplitude, std::move(set)});
  return cases;
}

}  // namespace vmbench
