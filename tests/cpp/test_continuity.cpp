// Continuity of the commanded force (docs/theory.md, "Continuity, switch by switch"): smooth
// joint paths over the device's whole range, the handle often centimetres off the mechanism
// where the force saturates, give a force whose one-cycle change is what the change of the
// errors e, e* explains through the spring law, give or take a small margin: no rank
// decision, active set, tank factor, clamp or contact steps it. A one-cycle glitch of a
// joint reading changes the force by what the spring law says for the glitched pose and
// switches nothing off.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "cycle_scenes.hpp"

namespace {

using namespace vmtest;

// Every mechanism kind: the real-time scenes, and the two kinds those run on the 6R arm
// (SerialChain, HandlePath) on the Omni as well.
std::vector<std::string> continuity_scenes() {
  std::vector<std::string> names = scene_names();
  names.push_back("OmniSerialChain");
  names.push_back("OmniHandlePath");
  return names;
}

Scene continuity_scene(const std::string& name) {
  const Eigen::Vector3d z = Eigen::Vector3d::UnitZ();
  if (name == "OmniSerialChain") {
    // PPRRR: a probe's tip on the plane y = -0.02 (x, z slide; three wrist turns), its
    // handle 0.1 m back along the stylus
    std::vector<Joint> j(5);
    const Eigen::Vector3d axes[5] = {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitZ(),
                                     Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitX(),
                                     Eigen::Vector3d::UnitZ()};
    for (int i = 0; i < 5; ++i) {
      j[i].type = i < 2 ? JointType::kPrismatic : JointType::kRevolute;
      j[i].axis = axes[i];
    }
    Pose base = Pose::Identity();
    base.translation() = Eigen::Vector3d(0.0, -0.12, 0.0);
    Pose handle = Pose::Identity();
    handle.translation() = Eigen::Vector3d(0.0, 0.1, 0.0);
    handle.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()).toRotationMatrix();
    return {std::make_shared<PhantomOmni>(),
            std::make_shared<SerialChain>(j, handle, base, 0.1)};
  }
  if (name == "OmniHandlePath") {
    return {std::make_shared<PhantomOmni>(),
            std::make_shared<HandlePath>(test_letter(Eigen::Vector3d(0, -0.02, -0.05)), z, 0.1)};
  }
  return make_scene(name);
}

// A smooth random path over (95 % of) every joint's range: three sines per joint.
struct SmoothPath {
  std::vector<double> center, amplitude, rate, phase;
  SmoothPath(const Device& d, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int i = 0; i < d.dof(); ++i) {
      const double lo = std::isfinite(d.lower()[i]) ? d.lower()[i] : -1.0;
      const double hi = std::isfinite(d.upper()[i]) ? d.upper()[i] : 1.0;
      center.push_back(0.5 * (lo + hi));
      for (int j = 0; j < 3; ++j) {
        amplitude.push_back(0.95 * (hi - lo) / 6.0 * (0.5 + 0.5 * u(rng)));
        rate.push_back(0.3 + 2.0 * u(rng));  // [rad/s]
        phase.push_back(2.0 * M_PI * u(rng));
      }
    }
  }
  void at(double t, JointVector& q, JointVector& dq) const {
    for (Eigen::Index i = 0; i < q.size(); ++i) {
      q[i] = center[static_cast<size_t>(i)];
      dq[i] = 0.0;
      for (int j = 0; j < 3; ++j) {
        const size_t k = static_cast<size_t>(3 * i + j);
        q[i] += amplitude[k] * std::sin(rate[k] * t + phase[k]);
        dq[i] += amplitude[k] * rate[k] * std::cos(rate[k] * t + phase[k]);
      }
    }
  }
};

// The force change the spring law gives for a change of the error e: Kp e's force, and its
// moment over the length scale (a moment is a force at the lever L).
double spring_change(const ControllerModel& m, const Vector6& de) {
  return m.kp.head<3>().cwiseProduct(de.head<3>()).norm() +
         m.kp.tail<3>().cwiseProduct(de.tail<3>()).norm() / m.length_scale;
}

// A pose change as one length: position, and rotation times the length scale.
double pose_change(const Pose& a, const Pose& b, double L) {
  const Vector6 d = pose_error(a, b);
  return d.head<3>().norm() + L * d.tail<3>().norm();
}

class Continuity : public ::testing::TestWithParam<std::string> {};

// The largest one-cycle change of the commanded force beyond what the errors' change
// explains through the spring law, over 1e5 cycles of a smooth random path: at most 6 % of
// the device's force limit (0.2 N on the Omni's 3.3 N). Cycles a placement did not finish
// (it hit its iteration cap: the mechanism is still on its way to the optimum) or jumped
// (it moved more than five times as far as the handle: a branch of a shape's nearest
// point switched, and e with it) are left out and counted; they are a small fraction.
TEST_P(Continuity, SmoothPathsGiveASmoothForce) {
  const Scene s = continuity_scene(GetParam());
  Controller c(s.device, s.mechanism);
  const ControllerModel& m = c.model();
  const SmoothPath path(*s.device, 7);
  const int n = s.device->dof();
  JointVector q(n), dq(n);
  CycleOutput out, last;
  constexpr int kCycles = 100000, kSettle = 1000;
  double worst = 0.0, worst_unfinished = 0.0;
  int worst_cycle = -1, unfinished = 0, jumps = 0, passes = 0;
  for (int k = 0; k < kCycles; ++k) {
    const double t = k * 1e-3;
    path.at(t, q, dq);
    c.step(q.data(), dq.data(), out, t);
    ASSERT_FALSE(out.status & status::kFaultMask) << "cycle " << k << " status " << out.status;
    if (k > kSettle) {
      const double moved = pose_change(out.handle_pose, last.handle_pose, m.length_scale);
      const bool jumped =
          pose_change(out.mechanism_pose, last.mechanism_pose, m.length_scale) > 5.0 * moved + 1e-4 ||
          pose_change(out.mechanism_pose_star, last.mechanism_pose_star, m.length_scale) >
              5.0 * moved + 1e-4;
      const double df = (out.wrench.head<3>() - last.wrench.head<3>()).norm();
      const double excess = df - spring_change(m, out.error - last.error) -
                            spring_change(m, out.error_star - last.error_star);
      if (jumped) {
        ++jumps;
      } else if ((out.status | last.status) & status::kNotConverged) {
        ++unfinished;
        worst_unfinished = std::max(worst_unfinished, excess);
      } else {
        ++passes;
        if (excess > worst) worst = excess, worst_cycle = k;
      }
    }
    last = out;
  }
  std::printf("[ %s ] largest excess %.3f N at cycle %d; %d cycles unfinished (largest excess "
              "%.3f N), %d jumps\n",
              GetParam().c_str(), worst, worst_cycle, unfinished, worst_unfinished, jumps);
  EXPECT_LE(worst, 0.06 * m.max_force) << "at cycle " << worst_cycle;
  EXPECT_GT(passes + unfinished, kCycles * 9 / 10);
  // where a placement is still on its way to the optimum the force follows it, and the
  // filters turn with its Jacobian; within the bound too, except on the placements that
  // crawl far off their shape: a NURBS SurfaceProbe beyond the Omni's reach (up to 3.3 N),
  // a HandlePath on the 6R arm (14 N of its 40 N), the PPRRR chain on the Omni (unfinished
  // on 84 % of the cycles, up to 1.0 N)
  if (GetParam() != "OmniSurfaceProbeNurbs" && GetParam() != "Arm6RHandlePath" &&
      GetParam() != "OmniSerialChain") {
    EXPECT_LE(worst_unfinished, 0.06 * m.max_force);
  }
}

INSTANTIATE_TEST_SUITE_P(EveryMechanism, Continuity, ::testing::ValuesIn(continuity_scenes()),
                         [](const auto& info) { return info.param; });

// A handle held still with the guide pulling it at the force limit; one cycle the elbow's
// reading is off by 0.01 rad (inside the plausibility margin), then right again.
struct Glitch {
  Vector6 before, during, after;  // forces [N; N·m] of the cycles around the glitch
  Vector6 e_before, e_during, e_star_before, e_star_during;
  double least_scale_after = 1.0;  // the range term's factor over the next 5 s
  std::uint32_t active_before = 0, active_after_min = ~0u;
  double largest_change_after = 0.0;  // |f - before| over the next 5 s, from 2 cycles on
};

Glitch glitch_run(Controller& c, const JointVector& q0) {
  const int n = c.device().dof();
  const JointVector dq = JointVector::Zero(n);
  CycleOutput out;
  Glitch g;
  for (int k = 0; k < 2000; ++k) c.step(q0.data(), dq.data(), out);
  g.before = out.wrench;
  g.e_before = out.error;
  g.e_star_before = out.error_star;
  g.active_before = out.active | (out.active_star << 16);
  JointVector q = q0;
  q[2] += 0.01;
  c.step(q.data(), dq.data(), out);
  g.during = out.wrench;
  g.e_during = out.error;
  g.e_star_during = out.error_star;
  for (int k = 0; k < 5000; ++k) {
    c.step(q0.data(), dq.data(), out);
    if (k == 0) g.after = out.wrench;
    g.least_scale_after = std::min(g.least_scale_after, out.passivity_scale);
    g.active_after_min &= out.active | (out.active_star << 16);
    if (k >= 1) {
      g.largest_change_after = std::max(g.largest_change_after, (out.wrench - g.before).norm());
    }
  }
  return g;
}

TEST(Glitch, AOneCycleGlitchChangesTheForceAsTheSpringLawSaysAndSwitchesNothingOff) {
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY();
  auto omni = std::make_shared<PhantomOmni>();
  // the handle 2 cm off a line guide: its range term pulls at the Omni's 3.3 N
  Controller c(omni, std::make_shared<LineGuide>(Eigen::Vector3d(0, -0.04, -0.1), x, 0.1, y));
  JointVector q0(6);
  q0 << 0.1, 0.5, 0.3, 0.0, 0.8, 0.0;
  const Glitch g = glitch_run(c, q0);
  ASSERT_GT(g.before.head<3>().norm(), 3.0);  // the guide pulls near the limit
  const ControllerModel& m = c.model();
  const double law = spring_change(m, g.e_during - g.e_before) +
                     spring_change(m, g.e_star_during - g.e_star_before);
  EXPECT_LE((g.during - g.before).head<3>().norm(), law + 1e-9);
  EXPECT_LE((g.after - g.before).head<3>().norm(), 0.05);  // back the next cycle
  EXPECT_LE(g.largest_change_after, 1e-6);                 // and stays there
  EXPECT_EQ(g.least_scale_after, 1.0);                     // the tank held nothing back
  EXPECT_EQ(g.active_after_min, g.active_before);          // no limit let go
}

TEST(Glitch, AGlitchInATwoMemberSetNeitherKicksNorDropsTheForce) {
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY();
  auto omni = std::make_shared<PhantomOmni>();
  MechanismSetSettings ss;
  ss.snap_distance = 0.1;
  ss.release_distance = 0.2;
  MechanismSet set(omni, 2, ss);
  set.add(std::make_shared<LineGuide>(Eigen::Vector3d(0, -0.04, -0.1), x, 0.1, y));
  set.add(std::make_shared<LineGuide>(Eigen::Vector3d(0, 0.06, -0.1), x, 0.1, y));
  JointVector q0(6), dq = JointVector::Zero(6);
  q0 << 0.1, 0.5, 0.3, 0.0, 0.8, 0.0;
  MechanismSetOutput out;
  for (int k = 0; k < 2000; ++k) set.step(q0.data(), dq.data(), out);
  ASSERT_EQ(out.active, 0);
  const Vector6 before = out.cycle.wrench;
  const Vector6 e = out.cycle.error, e_star = out.cycle.error_star;
  ASSERT_GT(before.head<3>().norm(), 3.0);
  JointVector q = q0;
  q[2] += 0.01;
  set.step(q.data(), dq.data(), out);
  EXPECT_EQ(out.active, 0);
  const ControllerModel& m = set.member(0).model();
  const double law =
      spring_change(m, out.cycle.error - e) + spring_change(m, out.cycle.error_star - e_star);
  EXPECT_LE((out.cycle.wrench - before).head<3>().norm(), law + 1e-9);
  double largest = 0.0;
  for (int k = 0; k < 1000; ++k) {
    set.step(q0.data(), dq.data(), out);
    EXPECT_EQ(out.active, 0);
    if (k >= 1) largest = std::max(largest, (out.cycle.wrench - before).norm());
  }
  EXPECT_LE(largest, 1e-6);
}

}  // namespace
