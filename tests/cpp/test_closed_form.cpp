// The certificates that end a line-held stylus's search early (src/closed_form.hpp): on
// random problems, every direction whose cost is at most the certified value lies in a
// certified cap, and on each cap the cost is strictly convex, checked with Hessians taken by
// finite differences of the cost written out here on its own (in the chart the two caps
// use, and on the sphere through its exponential map for the others).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>

#include <Eigen/Eigenvalues>

#include "../../src/closed_form.hpp"

namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;
using virtmech::detail::LineCaps;
using virtmech::detail::TipSet;

struct Problem {
  TipSet line;
  Vector3d p_R, u_R;
  double L = 0.1, w_p = 1.0, w_r = 1.0;

  // w_p |tip's offset from the line|^2 + w_r angle(u, u_R)^2, tip = p_R - L u
  double cost(const Vector3d& u_in) const {
    const Vector3d u = u_in.normalized();
    Vector3d r = p_R - L * u - line.point;
    r -= r.dot(line.free) * line.free;
    const double angle = std::atan2(u.cross(u_R).norm(), u.dot(u_R));
    return w_p * r.squaredNorm() + w_r * angle * angle;
  }
};

Vector3d random_unit(std::mt19937& rng) {
  std::normal_distribution<double> n;
  return Vector3d(n(rng), n(rng), n(rng)).normalized();
}

// two unit vectors completing e to an orthonormal basis
void basis(const Vector3d& e, Vector3d& a, Vector3d& b) {
  a = (std::abs(e.x()) < 0.9 ? Vector3d::UnitX() : Vector3d::UnitY()).cross(e).normalized();
  b = e.cross(a);
}

// the least eigenvalue of the Hessian of g: R^2 -> R at 0, by central differences of step h
template <typename G>
double least_curvature(const G& g, double h) {
  const double g0 = g(Vector2d::Zero());
  Eigen::Matrix2d H;
  for (int i = 0; i < 2; ++i) {
    const Vector2d di = h * Vector2d::Unit(i);
    H(i, i) = (g(di) - 2.0 * g0 + g(-di)) / (h * h);
  }
  const Vector2d d0 = h * Vector2d::Unit(0), d1 = h * Vector2d::Unit(1);
  H(0, 1) = H(1, 0) = (g(d0 + d1) - g(d0 - d1) - g(-d0 + d1) + g(-d0 - d1)) / (4.0 * h * h);
  return Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(H).eigenvalues()[0];
}

// the Riemannian Hessian's least eigenvalue at u: of f(exp_u(v)) at v = 0 (the exponential
// map is a second-order retraction, so this is the Riemannian Hessian away from critical
// points too)
double sphere_curvature(const Problem& p, const Vector3d& u) {
  Vector3d t1, t2;
  basis(u, t1, t2);
  return least_curvature(
      [&](const Vector2d& v) {
        const Vector3d w = v[0] * t1 + v[1] * t2;
        const double a = w.norm();
        return p.cost(a > 0.0 ? Vector3d(std::cos(a) * u + std::sin(a) / a * w) : u);
      },
      1e-4);
}

// A problem on a random line through the origin, the handle `distance` from it along
// `radial` (a random direction normal to it) and up to half a stylus length along it.
Problem line_problem(std::mt19937& rng, double distance, Vector3d& radial) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  Problem p;
  p.line.free = random_unit(rng);
  Vector3d a, b;
  basis(p.line.free, a, b);
  const double phi = 2.0 * M_PI * U(rng);
  radial = std::cos(phi) * a + std::sin(phi) * b;
  p.p_R = distance * radial + (U(rng) - 0.5) * p.L * p.line.free;
  return p;
}

// A random problem: the handle up to 1.6 stylus lengths from the line (beyond the reach
// too), weights from nearly position-only to nearly rotation-only; `value` the cost of a
// direction near one a placement would reach.
Problem random_problem(std::mt19937& rng, double& value) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  Vector3d radial;
  Problem p = line_problem(rng, 1.6 * Problem().L * U(rng), radial);
  p.u_R = random_unit(rng);
  p.w_r = std::pow(10.0, -8.0 + 10.0 * U(rng)) * p.L * p.L;
  // near a tip-on-line direction, the handle's offset from the line, or u_R
  const Vector3d w = p.p_R - p.p_R.dot(p.line.free) * p.line.free;
  Vector3d near = p.u_R;
  const double pick = U(rng), x = w.norm() / p.L;
  if (pick < 0.5 && x < 1.0) {
    near = w / p.L + (U(rng) < 0.5 ? 1.0 : -1.0) * std::sqrt(1.0 - x * x) * p.line.free;
  } else if (pick < 0.75) {
    near = w.normalized();
  }
  const double spread = std::pow(10.0, -5.0 + 4.5 * U(rng));
  value = p.cost(near + spread * random_unit(rng));
  return p;
}

// A problem where the angle term bends a cap most: the handle's stylus along one direction
// that puts the tip on the line (the value about 0), so the other cap, which u_R points
// away from, carries the angle term's negative curvature, 1 / z^3 in the chart, with the
// stylus 6 to 30 degrees from square to the line and weights up to a third of L^2.
Problem adverse_problem(std::mt19937& rng, double& value) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  const double z0 = 0.1 + 0.4 * U(rng), r0 = std::sqrt(1.0 - z0 * z0);
  Vector3d radial;
  Problem p = line_problem(rng, Problem().L * r0, radial);
  const Vector3d x0 = r0 * radial;
  p.u_R = (x0 + (U(rng) < 0.5 ? z0 : -z0) * p.line.free + 1e-4 * random_unit(rng)).normalized();
  p.w_r = std::pow(10.0, -3.0 + 2.5 * U(rng)) * p.L * p.L;
  value = p.cost(p.u_R);
  return p;
}

constexpr int kProblems = 4000;

// a random problem and its caps; false where it has none
bool certified_problem(std::mt19937& rng, Problem& p, LineCaps& caps, double& value,
                       bool adverse = false) {
  p = adverse ? adverse_problem(rng, value) : random_problem(rng, value);
  caps = virtmech::detail::line_caps(p.line, p.p_R, p.u_R, p.L, p.w_p, p.w_r, value);
  return caps.count > 0;
}

TEST(LineCertificates, EveryDirectionAsLowAsTheValueLiesInACap) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  int certified = 0, checked = 0, on_cap = 0;
  double max_ratio = 0.0;
  for (int k = 0; k < kProblems; ++k) {
    Problem p;
    LineCaps caps;
    double value;
    if (!certified_problem(rng, p, caps, value)) continue;
    ++certified;
    // directions about each cap's centre out to three times its size; those as low as the
    // value must be on a cap
    const double size = caps.rho >= 0.0 ? caps.rho : caps.eps * 4.0 + 1e-3;
    for (int i = 0; i < caps.count; ++i) {
      for (int j = 0; j < 200; ++j) {
        const Vector3d u =
            (caps.centre[i] + 3.0 * size * U(rng) * random_unit(rng)).normalized();
        if (!(p.cost(u) <= value)) continue;
        ++checked;
        const bool on = virtmech::detail::cap_holds(caps, 0, u, p.line.free) ||
                        (caps.count == 2 && virtmech::detail::cap_holds(caps, 1, u, p.line.free));
        ASSERT_TRUE(on) << "problem " << k << " cap " << i;
      }
      // and every direction on a cap within its chord of the centre (which rules a cap out
      // where even that near u_R costs more than the value)
      for (int j = 0; j < 200; ++j) {
        const Vector3d u =
            (caps.centre[i] + 3.0 * size * U(rng) * random_unit(rng)).normalized();
        if (!virtmech::detail::cap_holds(caps, i, u, p.line.free)) continue;
        ++on_cap;
        ASSERT_LE((u - caps.centre[i]).norm(), caps.chord * (1.0 + 1e-12)) << "problem " << k;
        max_ratio = std::max(max_ratio, (u - caps.centre[i]).norm() / caps.chord);
      }
    }
  }
  EXPECT_GT(certified, kProblems / 3);
  EXPECT_GT(checked, 10000);
  EXPECT_GT(on_cap, 10000);
  EXPECT_GT(max_ratio, 0.5);  // the bound is not loose by more than a factor of two
}

TEST(LineCertificates, TheCostIsStrictlyConvexOnEveryCertifiedCap) {
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  int two = 0, one = 0, adverse = 0;
  for (int k = 0; k < 2 * kProblems; ++k) {
    Problem p;
    LineCaps caps;
    double value;
    if (!certified_problem(rng, p, caps, value, k >= kProblems)) continue;
    adverse += k >= kProblems;
    const Vector3d& e = p.line.free;
    Vector3d a, b;
    basis(e, a, b);
    // a tolerance for the differences' rounding, far below the bounds' margins
    const double tol = 1e-6 * (2.0 * p.w_p * p.L * p.L + 2.0 * p.w_r);
    for (int j = 0; j < 60; ++j) {
      if (caps.count == 2) {
        // the chart x -> x + s sqrt(1 - |x|^2) e over the disk |x - x0| <= eps
        const int i = j % 2;
        const double s = i == 0 ? 1.0 : -1.0;
        const double r = caps.eps * std::sqrt(U(rng)), t = 2.0 * M_PI * U(rng);
        const Vector3d x = caps.x0 + r * (std::cos(t) * a + std::sin(t) * b);
        const double h = 1e-3 * std::sqrt(1.0 - x.squaredNorm());
        const double c = least_curvature(
            [&](const Vector2d& v) {
              const Vector3d y = x + v[0] * a + v[1] * b;
              return p.cost(y + s * std::sqrt(1.0 - y.squaredNorm()) * e);
            },
            h);
        ASSERT_GT(c, -tol) << "problem " << k << " cap " << i;
        ++two;
      } else {
        // the cap of chord rho about its centre
        const double chord = caps.rho * std::sqrt(U(rng));
        const Vector3d t = random_unit(rng);
        Vector3d tangent = t - t.dot(caps.centre[0]) * caps.centre[0];
        tangent.normalize();
        const double angle = 2.0 * std::asin(0.5 * chord);
        const Vector3d u = std::cos(angle) * caps.centre[0] + std::sin(angle) * tangent;
        ASSERT_GT(sphere_curvature(p, u), -tol) << "problem " << k;
        ++one;
      }
    }
  }
  EXPECT_GT(two, 10000);
  EXPECT_GT(one, 3000);
  EXPECT_GT(adverse, kProblems / 4);
}

TEST(LineCertificates, TheCapAboutTheHandleIsConvexWhereCertified) {
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  int certified = 0;
  for (int k = 0; k < kProblems; ++k) {
    double value;
    const Problem p = random_problem(rng, value);
    if (!virtmech::detail::handle_cap_certified(p.line, p.p_R, p.u_R, p.L, p.w_p, p.w_r,
                                                value)) {
      continue;
    }
    ++certified;
    const double radius = std::sqrt(value / p.w_r);  // every minimiser this near u_R
    const double tol = 1e-6 * (2.0 * p.w_p * p.L * p.L + 2.0 * p.w_r);
    for (int j = 0; j < 30; ++j) {
      Vector3d tangent = random_unit(rng);
      tangent = (tangent - tangent.dot(p.u_R) * p.u_R).normalized();
      const double angle = radius * std::sqrt(U(rng));
      const Vector3d u = std::cos(angle) * p.u_R + std::sin(angle) * tangent;
      ASSERT_GT(sphere_curvature(p, u), -tol) << "problem " << k;
    }
  }
  EXPECT_GT(certified, kProblems / 20);
}

}  // namespace

#include "test_support.hpp"
#include "virtmech/virtmech.hpp"

// A place() hook returns the pose, Jacobian and pose error it builds from its solution
// (without walking the chain): they must be the mechanism's own forward_jacobian and
// pose_error at the joint values it returns, for every mechanism with a hook.
namespace {

const Vector3d kHookNormal = Vector3d(0.2, 1.0, -0.3).normalized(), kHookPoint(0.01, -0.02, 0.03);

// The cycle's two weightings for a length scale L (one block dominant, the other at the
// secondary weight 1e-6), and both blocks alike (where Newton takes several steps)
std::array<virtmech::Vector6, 3> cycle_weights(double L) {
  const double sw = 1e-6, L2 = L * L;
  return {(virtmech::Vector6() << 1, 1, 1, sw * L2, sw * L2, sw * L2).finished(),
          (virtmech::Vector6() << sw, sw, sw, L2, L2, L2).finished(),
          (virtmech::Vector6() << 1, 1, 1, L2, L2, L2).finished()};
}

// every mechanism with a place() hook, about kHookPoint
std::vector<std::pair<const char*, std::shared_ptr<virtmech::Mechanism>>> hook_mechanisms() {
  using namespace virtmech;
  const Vector3d n = kHookNormal, p0 = kHookPoint;
  const Vector3d t = n.cross(Vector3d::UnitZ()).normalized();
  return {
      {"PlanarArm", std::make_shared<PlanarArm>(p0, n, 0.1, t)},
      {"Probe", std::make_shared<Probe>(p0, n, 0.1, Vector3d(Vector3d::Zero()))},
      {"Probe/unilateral", std::make_shared<Probe>(p0, n, 0.1, Vector3d(Vector3d::Zero()), true)},
      {"PointPivot", std::make_shared<PointPivot>(p0, n, 0.1, Vector3d(Vector3d::Zero()))},
      {"LineGuide", std::make_shared<LineGuide>(p0, t, 0.1, n)},
      {"LineGuide/unilateral", std::make_shared<LineGuide>(p0, t, 0.1, n, true)},
      {"SurfaceProbe/sphere",
       std::make_shared<SurfaceProbe>(std::make_shared<Sphere>(p0 - 0.05 * n, 0.05, t), 0.1)},
      {"CurveGuide", std::make_shared<CurveGuide>(
                         vmtest::test_letter(Vector3d(0.0, 0.0, -0.02)), 0.1,
                         Vector3d(Vector3d::UnitZ()))},
  };
}

}  // namespace

TEST(PlaceHooks, ReturnTheChainsPoseJacobianAndError) {
  using namespace virtmech;
  const Vector3d p0 = kHookPoint;
  const auto mechanisms = hook_mechanisms();
  std::mt19937 rng(23);
  std::normal_distribution<double> g(0.0, 1.0);
  for (const auto& [name, mech] : mechanisms) {
    const auto weights = cycle_weights(0.1);
    int placed = 0;
    for (int k = 0; k < 200; ++k) {
      Pose target = Pose::Identity();
      target.linear() = so3_exp(Vector3d(g(rng), g(rng), g(rng)));
      target.translation() = p0 + 0.04 * Vector3d(g(rng), g(rng), g(rng));
      const Vector6& w = weights[static_cast<size_t>(k % 3)];
      JointVector theta;
      Pose T;
      Jacobian J;
      Vector6 e;
      if (!mech->place(target, w, mech->home(), theta, T, J, e)) continue;
      ++placed;
      Pose T_chain;
      Jacobian J_chain;
      mech->forward_jacobian(theta.data(), T_chain, J_chain);
      ASSERT_EQ(J.cols(), J_chain.cols()) << name;
      EXPECT_LE((T.matrix() - T_chain.matrix()).norm(), 1e-12) << name << " " << k;
      EXPECT_LE((J - J_chain).norm(), 1e-12) << name << " " << k;
      EXPECT_LE((e - pose_error(target, T_chain)).norm(), 1e-14) << name << " " << k;
    }
    EXPECT_GT(placed, 50) << name;  // (CurveGuide's Newton declines some, from home)
  }
}

// The same for a SurfaceProbe on a NURBS patch (its Newton's method places a tip in contact
// from a start near the optimum): targets a few millimetres off poses of the probe.
TEST(PlaceHooks, SurfaceProbeOnANurbsPatchReturnsTheChainsPoseJacobianAndError) {
  using namespace virtmech;
  const double L = 0.1;
  const std::vector<Vector6> weights = {
      (Vector6() << 1e-6, 1e-6, 1e-6, L * L, L * L, L * L).finished(),
      (Vector6() << 1, 1, 1, L * L, L * L, L * L).finished()};
  std::mt19937 rng(29);
  std::normal_distribution<double> g(0.0, 1.0);
  for (const bool unilateral : {false, true}) {
    const SurfaceProbe mech(vmtest::test_patch(Vector3d(0.01, -0.02, 0.03)), L, unilateral);
    const int wrist = unilateral ? 3 : 2;
    int placed = 0, lifted = 0;
    for (int k = 0; k < 200; ++k) {
      JointVector x = mech.home();
      x[0] += 0.2 * g(rng);
      x[1] += 0.2 * g(rng);
      for (int i = 0; i < 3; ++i) x[wrist + i] = 0.5 * g(rng);
      Pose target;
      mech.forward(x.data(), target);
      target.linear() = so3_exp(0.1 * Vector3d(g(rng), g(rng), g(rng))) * target.linear();
      // pressed 3 mm in along the stylus, moved about 2 mm; one-sided, every third pulled
      // back 8 mm off the surface and every other started lifted 5 mm
      target.translation() += 0.003 * target.linear().col(2) +
                              0.002 * Vector3d(g(rng), g(rng), g(rng));
      if (unilateral && k % 3 == 0) target.translation() -= 0.011 * target.linear().col(2);
      JointVector start = x;
      for (int i = 0; i < 3; ++i) start[wrist + i] += 0.05 * g(rng);
      if (unilateral && k % 2 == 1) start[2] = 0.005;
      JointVector theta;
      Pose T;
      Jacobian J;
      Vector6 e;
      if (!mech.place(target, weights[static_cast<size_t>(k % 2)], start, theta, T, J, e)) {
        continue;
      }
      ++placed;
      if (unilateral && theta[2] > 0.0) {
        ++lifted;
        EXPECT_LE(e.norm(), 1e-12) << k;  // lifted: the handle's own pose
      }
      Pose T_chain;
      Jacobian J_chain;
      mech.forward_jacobian(theta.data(), T_chain, J_chain);
      ASSERT_EQ(J.cols(), J_chain.cols());
      EXPECT_LE((T.matrix() - T_chain.matrix()).norm(), 1e-12) << unilateral << " " << k;
      EXPECT_LE((J - J_chain).norm(), 1e-12) << unilateral << " " << k;
      EXPECT_LE((e - pose_error(target, T_chain)).norm(), 1e-10) << unilateral << " " << k;
    }
    EXPECT_GT(placed, 80) << unilateral;  // (declined: near an edge)
    if (unilateral) EXPECT_GT(lifted, 30);
  }
}

// place_pair() is place() for each of its two weightings, bit for bit (the shared setup is
// the same arithmetic), where a mechanism has it (PlanarArm, Probe); false where either
// weighting has no closed form, and false by default.
TEST(PlaceHooks, PlacePairIsPlaceForEachWeighting) {
  using namespace virtmech;
  const Vector3d p0 = kHookPoint;
  std::mt19937 rng(29);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  const double L = 0.1;
  const Vector6 w_e = cycle_weights(L)[0], w_star = cycle_weights(L)[1];
  const Vector6 mixed = (Vector6() << 1, 2, 1, L * L, L * L, L * L).finished();  // no closed form
  int paired = 0;
  for (const auto& [name, mech] : hook_mechanisms()) {
    const std::string type = mech->type_name();
    const bool has_pair = type == "PlanarArm" || type == "Probe";
    for (int k = 0; k < 300; ++k) {
      Pose target = Pose::Identity();
      target.linear() = so3_exp(Vector3d(g(rng), g(rng), g(rng)));
      target.translation() = p0 + 0.04 * Vector3d(g(rng), g(rng), g(rng));
      // random weights too, isotropic per block, on a third of the trials
      Vector6 wa = w_e, wb = w_star;
      if (k % 3 == 2) {
        const double a = std::exp(u(rng)), b = std::exp(u(rng));
        wa << a, a, a, b, b, b;
        wb << b, b, b, a, a, a;
      }
      JointVector sa(mech->dof()), sb(mech->dof());
      for (int i = 0; i < mech->dof(); ++i) sa[i] = 0.3 * g(rng), sb[i] = 0.3 * g(rng);
      JointVector theta_a, theta_b, ref_a, ref_b;
      Pose Ta, Tb, Ra, Rb;
      Jacobian Ja, Jb, JRa, JRb;
      Vector6 ea, eb, rea, reb;
      const PlacementIO io_a{&wa, &sa, &theta_a, &Ta, &Ja, &ea};
      const PlacementIO io_b{&wb, &sb, &theta_b, &Tb, &Jb, &eb};
      if (!has_pair) {
        EXPECT_FALSE(mech->place_pair(target, io_a, io_b)) << name;  // the default
        continue;
      }
      ++paired;
      ASSERT_TRUE(mech->place_pair(target, io_a, io_b)) << name;
      ASSERT_TRUE(mech->place(target, wa, sa, ref_a, Ra, JRa, rea));
      ASSERT_TRUE(mech->place(target, wb, sb, ref_b, Rb, JRb, reb));
      EXPECT_EQ(theta_a, ref_a) << name << " " << k;
      EXPECT_EQ(theta_b, ref_b) << name << " " << k;
      EXPECT_TRUE(Ta.matrix() == Ra.matrix() && Tb.matrix() == Rb.matrix()) << name << " " << k;
      EXPECT_EQ(Ja, JRa) << name << " " << k;
      EXPECT_EQ(Jb, JRb) << name << " " << k;
      EXPECT_EQ(ea, rea) << name << " " << k;
      EXPECT_EQ(eb, reb) << name << " " << k;
      // either weighting without a closed form: no pair
      const PlacementIO io_mixed{&mixed, &sb, &theta_b, &Tb, &Jb, &eb};
      EXPECT_FALSE(mech->place_pair(target, io_a, io_mixed)) << name;
      EXPECT_FALSE(mech->place_pair(target, io_mixed, io_a)) << name;
    }
  }
  EXPECT_EQ(paired, 900);  // PlanarArm, Probe and the unilateral Probe
}

// The Probe's tilt (the stylus's angle phi from the plane's normal) is the minimiser of
// f(phi) = w_p (d - L cos phi)^2 + w_r (phi - phi_R)^2 to rounding: its Newton's method stops
// only where the step leaves an error below rounding (also on its first step, by f''').
// Reference: f' = 0 bisected in long double between g's minimiser and phi_R.
TEST(PlaceHooks, ProbesTiltIsTheMinimiserToRounding) {
  using namespace virtmech;
  const Vector3d n = kHookNormal, p0 = kHookPoint;
  const double L = 0.1;
  const Probe probe(p0, n, L, Vector3d(Vector3d::Zero()));
  std::mt19937 rng(31);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(-0.9, 0.9);
  const auto weights = cycle_weights(L);
  double worst = 0.0;
  for (int k = 0; k < 600; ++k) {
    Pose target = Pose::Identity();
    target.linear() = so3_exp(Vector3d(g(rng), g(rng), g(rng)));
    const Vector3d off = 0.04 * Vector3d(g(rng), g(rng), g(rng));
    target.translation() = p0 + off - off.dot(n) * n + u(rng) * L * n;  // |d| < 0.9 L
    const Vector6& w = weights[k % 3];
    JointVector theta;
    Pose T;
    Jacobian J;
    Vector6 e;
    ASSERT_TRUE(probe.place(target, w, probe.home(), theta, T, J, e));
    // the 1-D problem in long double
    using LD = long double;
    const LD d = n.dot(target.translation() - p0), wp = w[0], wr = w[3];
    const Vector3d u_r = -target.linear().col(2);
    const LD phi_r = std::atan2(static_cast<LD>(u_r.cross(n).norm()), static_cast<LD>(u_r.dot(n)));
    const LD phi0 = std::acos(std::min<LD>(1, std::max<LD>(-1, d / L)));
    auto f1 = [&](LD phi) {
      return wp * 2 * (d - L * std::cos(phi)) * L * std::sin(phi) + 2 * wr * (phi - phi_r);
    };
    LD lo = std::min(phi0, phi_r), hi = std::max(phi0, phi_r);
    ASSERT_LT(f1(lo), 0) << k;
    ASSERT_GT(f1(hi), 0) << k;
    for (int it = 0; it < 200; ++it) {
      const LD mid = (lo + hi) / 2;
      (f1(mid) < 0 ? lo : hi) = mid;
    }
    const double turn_ref = static_cast<double>(std::abs((lo + hi) / 2 - phi_r));
    const double err = std::abs(e.tail<3>().norm() - turn_ref);  // e's rotation: -turn
    worst = std::max(worst, err);
    EXPECT_LE(err, 4e-15 * (1.0 + turn_ref)) << k;  // (the inputs' own rounding: ~1e-15)
  }
  RecordProperty("worst_error", std::to_string(worst));
}

// The PlanarArm's angle is a root of its weighted cost's derivative to rounding (its
// Newton's method, like the tilt's, stops by f'''): C'(x) changes sign within 2e-14 of it,
// C(x) = w_p |p_R - h(x)|^2 + w_r angle(R_R, R(x))^2 and C' written out in long double.
TEST(PlaceHooks, PlanarArmsAngleIsTheMinimiserToRounding) {
  using namespace virtmech;
  using LD = long double;
  using V3 = Eigen::Matrix<LD, 3, 1>;
  using M3 = Eigen::Matrix<LD, 3, 3>;
  const Vector3d n = kHookNormal, p0 = kHookPoint;
  const Vector3d d0 = n.cross(Vector3d::UnitZ()).normalized();
  const double L = 0.1;
  const PlanarArm arm(p0, n, L, d0);
  Pose rest;
  const double zero = 0.0;
  arm.forward(&zero, rest);
  const V3 nn = n.cast<LD>(), dd = d0.cast<LD>(), e2 = n.cross(d0).cast<LD>();
  const M3 R0 = rest.linear().cast<LD>();
  M3 N;
  N << 0, -nn.z(), nn.y(), nn.z(), 0, -nn.x(), -nn.y(), nn.x(), 0;
  std::mt19937 rng(37);
  std::normal_distribution<double> g(0.0, 1.0);
  const auto weights = cycle_weights(L);
  int checked = 0;
  for (int k = 0; k < 600; ++k) {
    Pose target = Pose::Identity();
    target.linear() = so3_exp(Vector3d(g(rng), g(rng), g(rng)));
    target.translation() = p0 + 0.06 * Vector3d(g(rng), g(rng), g(rng));
    const Vector6& w = weights[k % 3];
    JointVector theta;
    Pose T;
    Jacobian J;
    Vector6 e;
    ASSERT_TRUE(arm.place(target, w, arm.home(), theta, T, J, e));
    const V3 p_R = target.translation().cast<LD>();
    const M3 R_R = target.linear().cast<LD>();
    const LD wp = w[0], wr = w[3];
    auto dC = [&](LD x) {  // C'(x)
      const M3 Rn = Eigen::AngleAxis<LD>(x, nn).toRotationMatrix();
      const V3 h = p0.cast<LD>() + L * (std::cos(x) * dd + std::sin(x) * e2);
      const V3 h1 = L * (-std::sin(x) * dd + std::cos(x) * e2);
      const LD tr = (R_R.transpose() * Rn * R0).trace();
      const LD tr1 = (R_R.transpose() * N * Rn * R0).trace();
      const LD ang = std::acos(std::min<LD>(1, std::max<LD>(-1, (tr - 1) / 2)));
      return -2 * wp * (p_R - h).dot(h1) - wr * ang / std::sin(ang) * tr1;
    };
    const LD x = theta[0], delta = 2e-14 * (1.0 + std::abs(theta[0]));
    const LD ang = std::acos(std::min<LD>(1, std::max<LD>(-1, ((R_R.transpose() *
        Eigen::AngleAxis<LD>(x, nn).toRotationMatrix() * R0).trace() - 1) / 2)));
    if (ang < 1e-6 || ang > M_PI - 1e-6) continue;  // (the angle's derivative degenerates)
    ++checked;
    EXPECT_LT(dC(x - delta), 0) << k;
    EXPECT_GT(dC(x + delta), 0) << k;
  }
  EXPECT_GT(checked, 550);
}

// A SurfaceProbe's seed for a nearest placement (positions only): on a plane, the placements
// that put the handle exactly where it is form a circle of tips at sqrt(L^2 - h^2) from the
// handle's foot (h its height), and the least is the one whose stylus is nearest the
// handle's: its tip lies from the foot against the stylus's tangential part. The seed is
// that placement, by this closed form; Newton's method from it stays.
TEST(SurfaceProbeSeed, NearestSeedOnAPlaneIsTheReachCircleClosedForm) {
  using namespace virtmech;
  const double L = 0.1;
  const Vector3d n = Vector3d(0.2, -0.3, 1.0).normalized();
  const Vector3d o(0.01, 0.02, -0.03);
  const SurfaceProbe mech(std::make_shared<Plane>(o, n), L);
  const Vector6 w = (Vector6() << 1, 1, 1, 1e-8, 1e-8, 1e-8).finished();
  std::mt19937 rng(31);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> height(0.005, 0.095), tilt(0.05, 1.2);
  for (int k = 0; k < 100; ++k) {
    const double h = height(rng);
    const Vector3d foot = o + 0.05 * (Vector3d(g(rng), g(rng), g(rng)) -
                                      n.dot(Vector3d(g(rng), g(rng), g(rng))) * n);
    const Vector3d p = foot - n.dot(foot - o) * n + h * n;  // the handle, h above the plane
    // the handle's stylus: from the normal tilted about a random axis in the plane
    Vector3d axis = Vector3d(g(rng), g(rng), g(rng)).cross(n).normalized();
    Pose target = Pose::Identity();
    // handle z points from the handle to the tip: -u, u the tip-to-handle direction
    const Vector3d u_R = Eigen::AngleAxisd(tilt(rng), axis) * n;
    const Eigen::Matrix3d R =
        Eigen::Quaterniond::FromTwoVectors(Vector3d::UnitZ(), -u_R).toRotationMatrix();
    target.linear() = R;
    target.translation() = p;
    JointVector theta = mech.home();
    mech.seed(target, w, theta);
    Pose T;
    mech.forward(theta.data(), T);
    // the closed form
    const Vector3d side = (u_R - n.dot(u_R) * n).normalized();
    const Vector3d centre = p - h * n;
    const Vector3d tip = centre - std::sqrt(L * L - h * h) * side;
    const Vector3d tip_seed = T.translation() + L * T.linear().col(2);
    EXPECT_LE((T.translation() - p).norm(), 1e-12) << k;
    EXPECT_LE((tip_seed - tip).norm(), 1e-12) << k;
    // Newton's method from the seed: there but for the least position error that the
    // rotation term, 1e-8 against 1, trades for a smaller angle: w_r angle / (w_p L) < 4e-7 m
    JointVector placed;
    Pose T_p;
    Jacobian J;
    Vector6 e;
    ASSERT_TRUE(mech.place(target, w, theta, placed, T_p, J, e)) << k;
    EXPECT_LE((T_p.translation() + L * T_p.linear().col(2) - tip).norm(), 1e-6) << k;
  }
}

// On a NURBS patch the nearest placement from the seed is the global least of the cost,
// checked against a brute-force scan of the patch (each sampled tip with the stylus toward
// the handle, its best there), and seed_pair() gives what seed() gives for each weighting.
TEST(SurfaceProbeSeed, NearestPlacementFromTheSeedIsTheGlobalLeastOnANurbsPatch) {
  using namespace virtmech;
  const double L = 0.1;
  const auto patch = vmtest::test_patch(Vector3d(0.01, -0.02, 0.03));
  const SurfaceProbe mech(patch, L);
  const Vector6 w = (Vector6() << 1, 1, 1, 1e-8, 1e-8, 1e-8).finished();
  const Vector6 w_star = (Vector6() << 1e-6, 1e-6, 1e-6, 0.01, 0.01, 0.01).finished();
  std::mt19937 rng(37);
  std::normal_distribution<double> g(0.0, 1.0);
  const Eigen::Vector2d lo = patch->lower(), hi = patch->upper();
  // the brute-force least of w_p (|p - S| - L)^2 over a fine grid: the stylus toward the
  // handle (the rotation term, 1e-8, is left out: it moves the least along the circle only)
  const auto least_gap = [&](const Vector3d& p) {
    double best = 1e300;
    for (int i = 0; i <= 400; ++i) {
      for (int j = 0; j <= 400; ++j) {
        const Vector3d S = patch->evaluate(lo[0] + (hi[0] - lo[0]) * i / 400.0,
                                           lo[1] + (hi[1] - lo[1]) * j / 400.0);
        best = std::min(best, std::abs((p - S).norm() - L));
      }
    }
    return best;
  };
  int checked = 0;
  for (int k = 0; k < 12; ++k) {
    JointVector x = mech.home();
    x[0] += 0.15 * g(rng);
    x[1] += 0.15 * g(rng);
    for (int i = 0; i < 3; ++i) x[2 + i] = 0.5 * g(rng);
    x = x.cwiseMax(mech.lower()).cwiseMin(mech.upper());
    Pose target;
    mech.forward(x.data(), target);
    target.translation() += 0.02 * Vector3d(g(rng), g(rng), g(rng));
    JointVector a = mech.home(), b = mech.home(), a1 = a, b1 = b;
    ASSERT_TRUE(mech.seed_pair(target, w, w_star, a, b));
    mech.seed(target, w, a1);
    mech.seed(target, w_star, b1);
    EXPECT_EQ(a, a1) << k;
    EXPECT_EQ(b, b1) << k;
    JointVector theta;
    TrackOptions opts;
    opts.max_iterations = 100;
    const TrackResult r =
        track(mech, target, a.cwiseMax(mech.lower()).cwiseMin(mech.upper()), w, opts, theta);
    (void)r;  // (where the circle leaves the patch, Gauss-Newton creeps along its edge)
    Pose T;
    mech.forward(theta.data(), T);
    const double gap = (T.translation() - target.translation()).norm();
    // within the grid's resolution of the scan's least (a grid step is under 0.4 mm)
    EXPECT_LE(gap, least_gap(target.translation()) + 4e-4) << k;
    ++checked;
  }
  EXPECT_EQ(checked, 12);
}

// The stylus Newton keeps a NURBS patch's parameters within their bounds by projected
// Newton: with the handle beyond an edge, the least lies on it, and Newton places it there
// (where it used to decline to Gauss-Newton) at a cost no higher than Gauss-Newton's own
// end (tracked with the closed form off), with the edge's KKT sign: the cost pushes out.
TEST(SurfaceProbeSeed, NewtonPlacesALeastOnAnEdgeOfThePatch) {
  using namespace virtmech;
  const double L = 0.1;
  const SurfaceProbe mech(vmtest::test_patch(Vector3d(0.01, -0.02, 0.03)), L);
  const Vector6 w = (Vector6() << 1, 1, 1, L * L, L * L, L * L).finished();
  std::mt19937 rng(41);
  std::normal_distribution<double> g(0.0, 1.0);
  TrackOptions gn;
  gn.closed_form = false;
  gn.max_iterations = 200;
  int on_edge = 0;
  for (int k = 0; k < 40; ++k) {
    // a pose of the probe on the edge u = 1 (or v = 0), the handle then moved 1-3 cm on
    // outward along the edge's outward tangent
    JointVector x = mech.home();
    const bool along_u = k % 2 == 0;
    x[0] = along_u ? 1.0 : 0.2 + 0.6 * std::abs(g(rng)) / 3.0;
    x[1] = along_u ? 0.2 + 0.6 * std::abs(g(rng)) / 3.0 : 0.0;
    for (int i = 0; i < 3; ++i) x[2 + i] = 0.3 * g(rng);
    Pose T0;
    Jacobian J0;
    mech.forward_jacobian(x.data(), T0, J0);
    const Vector3d out = (along_u ? 1.0 : -1.0) * J0.col(along_u ? 0 : 1).head<3>().normalized();
    Pose target = T0;
    target.translation() += (0.01 + 0.02 * std::abs(g(rng)) / 3.0) * out;
    JointVector start = x;
    start[along_u ? 0 : 1] = along_u ? 0.9 : 0.1;  // from inside
    JointVector theta;
    Pose T;
    Jacobian J;
    Vector6 e;
    if (!mech.place(target, w, start, theta, T, J, e)) continue;
    JointVector theta_gn;
    track(mech, target, start, w, gn, theta_gn);
    Pose T_gn;
    mech.forward(theta_gn.data(), T_gn);
    const Vector6 e_gn = pose_error(target, T_gn);
    const double cost = e.dot(w.cwiseProduct(e)), cost_gn = e_gn.dot(w.cwiseProduct(e_gn));
    EXPECT_LE(cost, cost_gn * (1 + 1e-9) + 1e-18) << k;
    const int i = along_u ? 0 : 1;
    if (theta[i] == (along_u ? 1.0 : 0.0)) {
      ++on_edge;
      // the cost's gradient in that parameter, -2 J_i^T W e, pushes out of the patch
      const double grad = -2.0 * J.col(i).dot(w.cwiseProduct(e));
      EXPECT_TRUE(along_u ? grad < 0.0 : grad > 0.0) << k << " " << grad;
    }
  }
  EXPECT_GE(on_edge, 30);
}

// A LineGuide's handle square to its line, the stylus shorter than its height plus reach:
// the tip may sit on either side of the handle's foot, two mirror placements of equal cost.
// The placement keeps the side its start is on (a tie within 1e-10 of the cost goes to the
// end nearer the start), so that rounding cannot make it alternate from cycle to cycle;
// where one side is truly lower (the handle tilted 1e-6 rad) it wins from either start.
TEST(LineGuideTie, MirrorPlacementsOfEqualCostKeepTheStartsSide) {
  using namespace virtmech;
  const double L = 0.1, h = 0.06;
  const LineGuide mech(Vector3d::Zero(), Vector3d::UnitX(), L, Vector3d::UnitZ());
  const Vector6 w = (Vector6() << 1, 1, 1, 1e-4, 1e-4, 1e-4).finished();
  // the handle h above the line's origin, its stylus (tip to handle) tilted by `tilt` about
  // y from straight up: the handle's z points from the handle toward the tip
  const auto handle = [&](double tilt) {
    Pose T = Pose::Identity();
    T.linear() = Eigen::AngleAxisd(M_PI + tilt, Vector3d::UnitY()).toRotationMatrix();
    T.translation() = Vector3d(0.0, 0.0, h);
    return T;
  };
  JointVector side[2];
  Pose T;
  Jacobian J;
  Vector6 e;
  for (int s = 0; s < 2; ++s) {  // a clear start on each side, from a handle tilted that way
    const Pose tilted = handle(s == 0 ? 0.3 : -0.3);
    ASSERT_TRUE(mech.place(tilted, w, mech.home(), side[s], T, J, e));
  }
  ASSERT_LT(side[0][0] * side[1][0], 0.0);  // the tips on either side of the foot
  for (const double tilt : {0.0, 1e-13, -1e-13, 1e-12, -1e-12}) {
    for (int s = 0; s < 2; ++s) {
      JointVector theta;
      ASSERT_TRUE(mech.place(handle(tilt), w, side[s], theta, T, J, e));
      EXPECT_GT(theta[0] * side[s][0], 0.0) << "tilt " << tilt << ", start on side " << s;
    }
  }
  for (const double tilt : {1e-6, -1e-6}) {  // a real preference: the same end from both
    JointVector a, b;
    ASSERT_TRUE(mech.place(handle(tilt), w, side[0], a, T, J, e));
    ASSERT_TRUE(mech.place(handle(tilt), w, side[1], b, T, J, e));
    EXPECT_GT(a[0] * b[0], 0.0) << tilt;
  }
}
