// The device / mechanism pairs the real-time tests run the servo cycle over, and the one
// cycle loop they share: a slow wandering of every joint, both step overloads, a fault
// (non-finite input), a watchdog gap and a reset, so every branch of the cycle is taken.
#pragma once

#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "test_support.hpp"
#include "virtmech.h"

namespace vmtest {

struct Scene {
  std::shared_ptr<const Device> device;
  std::shared_ptr<const Mechanism> mechanism;
};

/// Names of the scenes make_scene builds (gtest parameter values).
inline std::vector<std::string> scene_names() {
  return {"OmniProbe",      "OmniProbeUnilateral", "OmniPlanarArm",
          "OmniPointPivot", "OmniLineGuide",       "Arm6RSerialChain",
          "Arm6RProbeUnilateral", "Planar3RPlanarArm", "OmniSurfaceProbeNurbs",
          "OmniSurfaceProbeSphereUnilateral", "Arm6RSurfaceProbeNurbs", "OmniCurveGuide",
          "Arm6RHandlePath", "Omega6PlanarArm", "Sigma7Probe", "FalconProbeUnilateral"};
}

inline Scene make_scene(const std::string& name) {
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY(),
                        z = Eigen::Vector3d::UnitZ(), zero = Eigen::Vector3d::Zero();
  auto omni = std::make_shared<PhantomOmni>();
  if (name == "OmniProbe") return {omni, std::make_shared<Probe>(-0.02 * y, y, 0.1, zero)};
  if (name == "OmniProbeUnilateral")
    return {omni, std::make_shared<Probe>(-0.02 * y, y, 0.1, zero, /*unilateral=*/true)};
  if (name == "OmniPlanarArm") return {omni, std::make_shared<PlanarArm>(-0.05 * z, z, 0.05, x)};
  if (name == "OmniPointPivot")
    return {omni, std::make_shared<PointPivot>(Eigen::Vector3d(0, -0.02, -0.1), y, 0.1, zero)};
  if (name == "OmniLineGuide")
    return {omni, std::make_shared<LineGuide>(Eigen::Vector3d(0, -0.02, -0.1), x, 0.1, y)};
  if (name == "Arm6RSerialChain") {
    // PPRRR about the handle: a chain the fully actuated arm renders on every axis
    std::vector<Joint> j(5);
    for (int i = 0; i < 5; ++i) {
      j[i].type = i < 2 ? JointType::kPrismatic : JointType::kRevolute;
      j[i].axis = Eigen::Vector3d::Unit(i % 3);
    }
    Pose handle = Pose::Identity();
    handle.translation() = Eigen::Vector3d(0.3, 0, 0.2);
    return {six_dof_arm(), std::make_shared<SerialChain>(j, handle, Pose::Identity(), 0.1)};
  }
  if (name == "Arm6RProbeUnilateral") {
    // a wall facing the arm's handle (stylus along +x at q = 0)
    return {six_dof_arm(),
            std::make_shared<Probe>(Eigen::Vector3d(0.6, 0, 0.15), -x, 0.1, zero, true)};
  }
  if (name == "Planar3RPlanarArm") {
    return {std::make_shared<Planar3R>(0.2, 0.2, Pose::Identity(), 50.0, 100.0),
            std::make_shared<PlanarArm>(Eigen::Vector3d(0.25, 0, 0), z, 0.1, x)};
  }
  if (name == "OmniSurfaceProbeNurbs") {
    return {omni, std::make_shared<SurfaceProbe>(test_patch(Eigen::Vector3d(0, 0, -0.12)), 0.1)};
  }
  if (name == "OmniSurfaceProbeSphereUnilateral") {
    return {omni, std::make_shared<SurfaceProbe>(
                      std::make_shared<Sphere>(Eigen::Vector3d(0, -0.05, -0.1), 0.04, x), 0.1,
                      true)};
  }
  if (name == "Arm6RSurfaceProbeNurbs") {
    return {six_dof_arm(),
            std::make_shared<SurfaceProbe>(test_patch(Eigen::Vector3d(0.45, 0, 0.1)), 0.1)};
  }
  if (name == "OmniCurveGuide") {
    return {omni, std::make_shared<CurveGuide>(test_letter(Eigen::Vector3d(0, 0, -0.1)), 0.1, z)};
  }
  if (name == "Omega6PlanarArm") {
    return {std::make_shared<CartesianDevice>("omega.6"),
            std::make_shared<PlanarArm>(0.06 * z, x, 0.08, -z)};
  }
  if (name == "Sigma7Probe") {
    return {std::make_shared<CartesianDevice>("sigma.7"),
            std::make_shared<Probe>(-0.05 * z, z, 0.05, x)};
  }
  if (name == "FalconProbeUnilateral") {
    return {std::make_shared<CartesianDevice>("falcon"),
            std::make_shared<Probe>(-0.05 * z, z, 0.05, x, /*unilateral=*/true)};
  }
  if (name == "Arm6RHandlePath") {
    return {six_dof_arm(),
            std::make_shared<HandlePath>(test_letter(Eigen::Vector3d(0.3, 0, 0.2)), z, 0.1)};
  }
  throw std::invalid_argument("make_scene: unknown scene " + name);
}

/// Settings of the real-time runs: the watchdog on, so the timed path is taken.
inline ControllerSettings cycle_settings() {
  ControllerSettings s;
  s.watchdog_s = 0.01;
  return s;
}

/// Joint state of cycle k [rad or m; per s]: every joint wanders slowly, a revolute one
/// over 0.3 +- 0.4 rad, a prismatic one of a device over +-40 mm.
inline void joint_state(int k, JointVector& q, JointVector& dq, const Device* device = nullptr) {
  const double t = k * 1e-3;
  for (int i = 0; i < q.size(); ++i) {
    q[i] = 0.3 + 0.4 * std::sin(0.7 * t + i);
    dq[i] = 0.28 * std::cos(0.7 * t + i);
    if (device != nullptr && device->joint_type(i) == JointType::kPrismatic) {
      q[i] = 0.1 * (q[i] - 0.3);
      dq[i] *= 0.1;
    }
  }
}

/// Joint state of cycle k over (95 % of) the device's whole range [rad or m; per s]: the
/// handle far off the mechanism, through its singular and saturated poses and its limits.
inline void sweep_state(const Device& d, int k, JointVector& q, JointVector& dq) {
  const double t = k * 1e-3;
  for (int i = 0; i < q.size(); ++i) {
    const double lo = std::isfinite(d.lower()[i]) ? d.lower()[i] : -1.0;
    const double hi = std::isfinite(d.upper()[i]) ? d.upper()[i] : 1.0;
    const double mid = 0.5 * (lo + hi), half = 0.475 * (hi - lo), w = 1.3 + 0.4 * i;
    q[i] = mid + half * std::sin(w * t + i);
    dq[i] = half * w * std::cos(w * t + i);
  }
}

/// The cycle loop's joint state at cycle k of `cycles`: the slow wandering, for the second
/// eighth a sweep over the whole range, a third in a velocity the device cannot make (a
/// fault) and 100 cycles later a one-cycle glitch of 0.01 rad.
inline void cycle_state(const Device& d, int k, int cycles, JointVector& q, JointVector& dq) {
  joint_state(k, q, dq, &d);
  if (k >= cycles / 8 && k < cycles / 4) sweep_state(d, k, q, dq);
  if (k == cycles / 3) dq[0] = 1e300;
  if (k == cycles / 3 + 100) q[q.size() > 2 ? 2 : 0] += 0.01;
}

/// Runs `cycles` servo cycles of c, from its first; q, dq, out are the caller's so that
/// nothing here allocates. Even cycles use the pointer overload, odd ones the checked one.
/// The joints follow cycle_state; half-way one cycle has a non-finite input (a fault),
/// three quarters in the clock jumps (the watchdog) and the controller is reset.
inline void run_cycles(Controller& c, int cycles, JointVector& q, JointVector& dq,
                       CycleOutput& out) {
  const Eigen::Index n = q.size();
  for (int k = 0; k < cycles; ++k) {
    cycle_state(c.device(), k, cycles, q, dq);
    double t = k * 1e-3;
    if (k == cycles / 2) q[0] = std::numeric_limits<double>::quiet_NaN();
    if (k >= 3 * cycles / 4) t += 1.0;
    if (k == 3 * cycles / 4) c.reset();
    if (k % 2 == 0) {
      c.step(q.data(), dq.data(), out, t);
    } else {
      c.step(Eigen::Map<const Eigen::VectorXd>(q.data(), n),
             Eigen::Map<const Eigen::VectorXd>(dq.data(), n), out, t);
    }
  }
}

/// A MechanismSet of four members on the Omni (a NURBS SurfaceProbe, a unilateral plane
/// Probe, two CurveGuides), as the real-time tests run it.
inline MechanismSet make_set() {
  const Eigen::Vector3d y = Eigen::Vector3d::UnitY(), z = Eigen::Vector3d::UnitZ();
  auto omni = std::make_shared<PhantomOmni>();
  MechanismSetSettings ss;
  ss.snap_distance = 0.01;
  ss.release_distance = 0.02;
  MechanismSet set(omni, 4, ss);
  set.add(std::make_shared<SurfaceProbe>(test_patch(Eigen::Vector3d(0, 0, -0.12)), 0.1),
          cycle_settings());
  set.add(std::make_shared<Probe>(-0.02 * y, y, 0.1, Eigen::Vector3d::Zero(), true),
          cycle_settings());
  set.add(std::make_shared<CurveGuide>(test_letter(Eigen::Vector3d(0, 0, -0.1)), 0.1, z),
          cycle_settings());
  set.add(std::make_shared<CurveGuide>(test_letter(Eigen::Vector3d(0.02, 0.01, -0.08)), 0.1, z),
          cycle_settings());
  return set;
}

/// run_cycles for a set.
inline void run_set_cycles(MechanismSet& set, int cycles, JointVector& q, JointVector& dq,
                           MechanismSetOutput& out) {
  for (int k = 0; k < cycles; ++k) {
    cycle_state(set.device(), k, cycles, q, dq);
    double t = k * 1e-3;
    if (k == cycles / 2) q[0] = std::numeric_limits<double>::quiet_NaN();
    if (k >= 3 * cycles / 4) t += 1.0;
    if (k == 3 * cycles / 4) set.reset();
    set.step(q.data(), dq.data(), out, t);
  }
}

/// The C API's servo loop over the Omni with one mechanism type: created on construction
/// (outside any count), `run` steps and reads the diagnostics, the destructor frees.
class CApiLoop {
 public:
  explicit CApiLoop(vm_mechanism_type type) {
    vm_device_desc dev;
    vm_device_desc_init(&dev, VM_DEVICE_PHANTOM_OMNI);
    vm_mechanism_desc mech;
    vm_mechanism_desc_init(&mech, type);
    mech.point[1] = -0.02;
    char err[256];
    if (vm_controller_create(&dev, &mech, nullptr, &c_, err, sizeof err) != VM_OK) {
      throw std::runtime_error(err);
    }
  }
  ~CApiLoop() { vm_controller_destroy(c_); }
  CApiLoop(const CApiLoop&) = delete;
  CApiLoop& operator=(const CApiLoop&) = delete;

  /// `cycles` calls of vm_controller_step and vm_controller_diagnostics, a reset halfway.
  void run(int cycles) {
    for (int k = 0; k < cycles; ++k) {
      joint_state(k, q_, dq_);
      if (k == cycles / 2) vm_controller_reset(c_);
      vm_controller_step(c_, q_.data(), dq_.data(), 6, k * 1e-3, tau_);
      vm_controller_diagnostics(c_, &diag_);
    }
  }
  const vm_diagnostics& diagnostics() const { return diag_; }
  const double* torque() const { return tau_; }

 private:
  vm_controller* c_ = nullptr;
  JointVector q_ = JointVector::Zero(6), dq_ = JointVector::Zero(6);
  double tau_[6] = {0, 0, 0, 0, 0, 0};
  vm_diagnostics diag_{};
};

inline constexpr vm_mechanism_type kCApiMechanisms[] = {
    VM_MECHANISM_PROBE, VM_MECHANISM_PLANAR_ARM, VM_MECHANISM_POINT_PIVOT,
    VM_MECHANISM_LINE_GUIDE};

}  // namespace vmtest
