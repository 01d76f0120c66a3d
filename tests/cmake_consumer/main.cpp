// Exits 0 when an installed virtmech builds, links and renders a force.
#include <cstdio>
#include <memory>

#include "virtmech.h"
#include "virtmech/virtmech.hpp"

int main() {
  using namespace virtmech;
  Controller c(std::make_shared<PhantomOmni>(),
               std::make_shared<PlanarArm>(Eigen::Vector3d(0, 0, -0.1), Eigen::Vector3d::UnitZ(),
                                           0.05, Eigen::Vector3d::UnitX()));
  JointVector q(6), dq = JointVector::Zero(6);
  q << 0.1, 0.5, 0.2, 0.0, 0.6, 0.0;
  CycleOutput out;
  c.step(q.data(), dq.data(), out);
  const bool ok = out.torque[3] == 0.0 && out.torque.head<3>().norm() > 0.0;
  std::printf("consumer: virtmech %s, |tau| = %g, %s\n", vm_version(), out.torque.norm(),
              ok ? "ok" : "FAILED");
  return ok ? 0 : 1;
}
