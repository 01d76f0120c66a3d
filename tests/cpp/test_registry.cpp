// The registry of kinds: made objects and their descriptions, the generic fallbacks, and
// plugins (a kind from a shared library; files that are no plugin or were built against
// other headers refused naming the file).
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "virtmech/registry.hpp"
#include "virtmech/virtmech.hpp"

using namespace virtmech;

namespace {

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(Registry, BuiltInKindsMakeAndDescribeTheirObjects) {
  Params p("PlanarArm");
  p.set("pivot", Eigen::Vector3d(0.0, 0.0, -0.05)).set("length", 0.05);
  const auto arm = make_mechanism(p);
  const Params d = describe(*arm);
  EXPECT_EQ(d.type(), "PlanarArm");
  EXPECT_EQ(d.vector3("normal"), Eigen::Vector3d::UnitZ());  // its kind's default
  EXPECT_EQ(d.number("length"), 0.05);
  const auto again = make_mechanism(d);
  Pose a, b;
  const double x = 0.3;
  arm->forward(&x, a);
  again->forward(&x, b);
  EXPECT_TRUE(a.isApprox(b, 0.0));
  EXPECT_EQ(describe(PhantomOmni()).number("l1"), PhantomOmniParams().l1);
  EXPECT_EQ(kind_of(*arm)->name, "PlanarArm");
}

TEST(Registry, MistakesNameWhereAndTheParameter) {
  Params p("Probe");
  p.set("plane_point", Eigen::Vector3d::Zero()).set("plane_normal", Eigen::Vector3d::UnitZ());
  EXPECT_EQ(error_of([&] { make_mechanism(p, "members[2]"); }),
            "members[2].length: missing required parameter (the probe's length)");
  p.set("length", -1.0);
  EXPECT_EQ(error_of([&] { make_mechanism(p); }),
            "mechanism.length: expected a number > 0 and <= 10 [m], got -1");
  EXPECT_EQ(error_of([] { make_device(Params("Falcon")); }),
            "device.type: expected 'PhantomOmni', 'Planar3R', 'Device' or 'CartesianDevice', got "
            "'Falcon'");
}

TEST(Registry, AKindIsRegisteredOnce) {
  MechanismKind k = *registry().mechanism("Probe");
  EXPECT_NE(error_of([&] { registry().add(k); }).find("already registered"), std::string::npos);
  MechanismKind empty;
  empty.name = "Nothing";
  EXPECT_NE(error_of([&] { registry().add(empty); }).find("expected a name, a type, make and describe"),
            std::string::npos);
}

TEST(Registry, AKindWithoutAMeasureTakesThePlacementsErrorAndTheSampledPath) {
  Joint j;
  const SerialChain chain({j}, Pose(Eigen::Translation3d(0.1, 0.0, 0.0)), Pose::Identity(), 0.1);
  const Distances d = distance(chain, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(),
                               Eigen::Vector3d(3e-3, 4e-3, 0.0));
  EXPECT_DOUBLE_EQ(d.dist, 5e-3);
  EXPECT_TRUE(std::isnan(d.dist_normal) && std::isnan(d.dist_across));
  EXPECT_TRUE(constrained_directions(chain, Eigen::Vector3d::Zero()).empty());
  const Sketch s = sketch(chain);
  ASSERT_EQ(s.lines.size(), 1u);
  for (const auto& p : s.lines[0]) EXPECT_NEAR(p.head<2>().norm(), 0.1, 1e-15);
}

TEST(Plugins, APluginAddsItsKindToTheHostsRegistry) {
  load_plugin(VIRTMECH_RING_PLUGIN);
  load_plugin(VIRTMECH_RING_PLUGIN);  // a second time: nothing happens
  const MechanismKind* k = registry().mechanism("RingArm");
  ASSERT_NE(k, nullptr);
  Params p("RingArm");
  p.set("radius", 0.2);
  const auto ring = make_mechanism(p);
  EXPECT_EQ(ring->type_name(), "RingArm");
  EXPECT_EQ(describe(*ring).number("radius"), 0.2);
  const Distances d = distance(*ring, Eigen::Vector3d(0.3, 0.0, 0.0), Eigen::Vector3d::UnitZ(),
                               Eigen::Vector3d::Zero());
  EXPECT_NEAR(d.dist_signed, 0.1, 1e-15);
  // the plugin's class runs the host's controller
  Controller c(std::make_shared<PhantomOmni>(), ring);
  CycleOutput out;
  const double q[6] = {0.1, 0.4, 0.3, 0.0, 0.5, 0.0}, dq[6] = {0, 0, 0, 0, 0, 0};
  EXPECT_EQ(c.step(q, dq, out) & status::kFaultMask, 0u);
  p.set("radius", 2.0);
  EXPECT_EQ(error_of([&] { make_mechanism(p); }),
            "mechanism.radius: expected a number > 0 and <= 1 [m], got 2");
}

TEST(Plugins, FilesThatAreNoPluginOrFromAnotherBuildAreRefused) {
  const std::string foreign = VIRTMECH_FOREIGN_PLUGIN;
  const std::string e = error_of([&] { load_plugin(foreign); });
  EXPECT_EQ(e.rfind(foreign + ": built against virtmech 0.0.1; registry 0; another build, but "
                              "this virtmech is " VIRTMECH_ABI_TAG, 0),
            0u)
      << e;
  EXPECT_NE(error_of([] { load_plugin("/no/such/plugin.so"); }).find("no such plugin file"),
            std::string::npos);
  EXPECT_NE(error_of([] { load_plugin(VIRTMECH_TEST_SOURCE); }).find("cannot be loaded as a plugin"),
            std::string::npos);
}
