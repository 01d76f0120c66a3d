// A user-defined virtual mechanism: the handle held to a helix, the stylus free to turn
// (helix_guide.hpp: one subclass of virtmech::Mechanism), driven by the unchanged
// Controller on the PHANTOM Omni model. At start-up the analytic Jacobian is checked
// against central differences of forward(); the program exits non-zero if they disagree or
// a cycle faults. The same class registered as a kind (helix_plugin.cpp) runs from a
// scenario file: helix.toml.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <vector>

#include "helix_guide.hpp"
#include "virtmech/virtmech.hpp"

namespace {

using namespace virtmech;
using helix::HelixGuide;
using helix::HelixParams;

// Largest difference between m's analytic Jacobian and central differences of m.forward
// at x, and between the pose forward_jacobian returns and forward's.
double jacobian_mismatch(const Mechanism& m, const JointVector& x) {
  const double h = 1e-6;  // [rad]
  Pose T, Tp, Tm;
  Jacobian J;
  m.forward_jacobian(x.data(), T, J);
  m.forward(x.data(), Tp);
  double worst = (T.matrix() - Tp.matrix()).cwiseAbs().maxCoeff();
  for (int i = 0; i < m.dof(); ++i) {
    JointVector xp = x, xm = x;
    xp[i] += h;
    xm[i] -= h;
    m.forward(xp.data(), Tp);
    m.forward(xm.data(), Tm);
    const Vector6 numeric = pose_error(Tp, Tm) / (2.0 * h);
    worst = std::max(worst, (numeric - J.col(i)).cwiseAbs().maxCoeff());
  }
  return worst;
}

}  // namespace

int main() {
  auto omni = std::make_shared<PhantomOmni>();
  auto helix = std::make_shared<HelixGuide>(HelixParams());

  // the example is also a test: a wrong Jacobian would make the controller wrong silently
  JointVector x(4);
  const double checks[3][4] = {{0.0, 0.0, 0.0, 0.0}, {0.7, 0.3, -0.4, 1.1}, {-5.0, -1.0, 0.8, -2.5}};
  for (const auto& c : checks) {
    x << c[0], c[1], c[2], c[3];
    const double d = jacobian_mismatch(*helix, x);
    if (!(d <= 1e-6)) {
      std::fprintf(stderr, "HelixGuide: analytic Jacobian differs from central differences by %g"
                           " (> 1e-6) at [%g %g %g %g]\n", d, c[0], c[1], c[2], c[3]);
      return 1;
    }
  }

  ControllerSettings settings;
  settings.ramp_time_s = 0.1;
  Controller controller(omni, helix, settings);

  // the user swings the handle about the waist, level (synthetic motion): the helix
  // descends as phi falls, so the device pulls the hand down onto it
  JointVector q = JointVector::Zero(6), dq = JointVector::Zero(6);
  CycleOutput out;
  std::printf("virtmech %s, Omni + HelixGuide (user-defined mechanism)\n", VIRTMECH_VERSION_STRING);
  std::printf("%8s %9s %9s %8s %10s %10s %10s\n", "t [s]", "phi [rad]", "|e| [mm]", "|f| [N]",
              "tau0", "tau1", "tau2");
  for (int k = 0; k <= 500; ++k) {
    const double t = k * 1e-3;
    q << 0.5 * std::sin(2.0 * t), 0.3, 0.2, 0.0, 0.8, 0.0;
    dq << 1.0 * std::cos(2.0 * t), 0.0, 0.0, 0.0, 0.0, 0.0;
    const std::uint32_t s = controller.step(q.data(), dq.data(), out, t);
    if (s & status::kFaultMask) {
      std::fprintf(stderr, "cycle %d: fault status 0x%x\n", k, static_cast<unsigned>(s));
      return 1;
    }
    if (k % 100 == 0) {
      std::printf("%8.3f %9.4f %9.3f %8.4f %10.5f %10.5f %10.5f\n", t, out.theta[0],
                  1e3 * out.error.head<3>().norm(), out.wrench.head<3>().norm(), out.torque[0],
                  out.torque[1], out.torque[2]);
    }
  }
  return 0;
}
