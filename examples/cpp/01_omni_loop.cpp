// The same loop as examples/c/01_omni_loop.c, through the C++ API, with a probe sliding on
// a horizontal plane (the paper's Fig. 3 mechanism).
#include <cmath>
#include <cstdio>
#include <memory>

#include "virtmech/virtmech.hpp"

int main() {
  using namespace virtmech;
  auto omni = std::make_shared<PhantomOmni>();
  // a table 3 cm below the handle's zero height; a 10 cm probe
  auto probe = std::make_shared<Probe>(Eigen::Vector3d(0.0, -0.03, 0.0), Eigen::Vector3d::UnitY(),
                                       0.1, Eigen::Vector3d::Zero());
  ControllerSettings settings;
  settings.ramp_time_s = 0.1;
  Controller controller(omni, probe, settings);

  JointVector q = JointVector::Zero(6), dq = JointVector::Zero(6);
  CycleOutput out;
  std::printf("virtmech %s, Omni + Probe\n", VIRTMECH_VERSION_STRING);
  std::printf("%8s %10s %10s %10s %8s %9s\n", "t [s]", "tau0", "tau1", "tau2", "|f| [N]", "cycle[us]");
  for (int k = 0; k <= 1000; ++k) {
    const double t = k * 1e-3;
    q << 0.2 * std::sin(2.0 * t), 0.5 + 0.1 * std::sin(3.0 * t), 0.3, 0.0, 0.8, 0.0;
    dq << 0.4 * std::cos(2.0 * t), 0.3 * std::cos(3.0 * t), 0.0, 0.0, 0.0, 0.0;
    controller.step(q.data(), dq.data(), out, t);
    if (k % 100 == 0) {
      std::printf("%8.3f %10.5f %10.5f %10.5f %8.4f %9.2f\n", t, out.torque[0], out.torque[1],
                  out.torque[2], out.wrench.head<3>().norm(), out.computation_time_us);
    }
  }
  return 0;
}
