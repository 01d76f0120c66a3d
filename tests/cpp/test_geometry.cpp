// Geometry objects: a closed form (the quarter circle as a rational quadratic NURBS) and
// evaluation without heap allocation (the counter of heap_counter.hpp sees every call).
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "heap_counter.hpp"
#include "virtmech/geometry.hpp"

using namespace virtmech;
using namespace vmtest;

namespace {

NurbsCurve quarter_circle() {
  Eigen::MatrixX3d P(3, 3);
  P << 1, 0, 0, 1, 1, 0, 0, 1, 0;
  Eigen::VectorXd w(3);
  w << 1, std::sqrt(0.5), 1;
  Eigen::VectorXd U(6);
  U << 0, 0, 0, 1, 1, 1;
  return NurbsCurve(P, w, U, 2);
}

// a bicubic patch, rational, with a repeated interior knot
NurbsSurface bumpy_patch() {
  const int nu = 5, nv = 6;
  Eigen::MatrixX3d P(nu * nv, 3);
  Eigen::MatrixXd W(nu, nv);
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j) {
      P.row(i * nv + j) << i / 4.0, j / 5.0, 0.2 * std::sin(1.0 + i * j);
      W(i, j) = 1.0 + 0.1 * ((i + 2 * j) % 5);
    }
  Eigen::VectorXd Uu(nu + 4), Uv(nv + 4);
  Uu << 0, 0, 0, 0, 0.5, 1, 1, 1, 1;
  Uv << 0, 0, 0, 0, 0.4, 0.4, 1, 1, 1, 1;
  return NurbsSurface(P, W, Uu, Uv, 3, 3);
}

}  // namespace

TEST(Geometry, QuarterCircleIsOnTheUnitCircle) {
  const NurbsCurve c = quarter_circle();
  CurveDerivatives d;
  for (int k = 0; k <= 100; ++k) {
    const double u = k / 100.0;
    EXPECT_NEAR(c.evaluate(u).norm(), 1.0, 1e-15) << "u = " << u;
    EXPECT_NEAR(c.curvature(u), 1.0, 1e-12) << "u = " << u;
    c.derivatives(u, 2, d);
    EXPECT_NEAR(d.col(0).dot(d.col(1)), 0.0, 1e-14);  // tangent orthogonal to the radius
  }
  Eigen::Vector3d point;
  const double u = c.closest_point(Eigen::Vector3d(3.0, 3.0, 0.5), point);
  EXPECT_NEAR(u, 0.5, 1e-12);
  EXPECT_NEAR(point.x(), std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(point.y(), std::sqrt(0.5), 1e-12);
  // outside the domain: clamped; beyond an end the end is closest
  EXPECT_NEAR((c.evaluate(-2.0) - Eigen::Vector3d(1, 0, 0)).norm(), 0.0, 1e-15);
  EXPECT_DOUBLE_EQ(c.closest_point(Eigen::Vector3d(1.0, -1.0, 0.0), point), 0.0);
}

TEST(Geometry, SurfaceNormalAndClosestPointAreConsistent) {
  const NurbsSurface s = bumpy_patch();
  Eigen::Vector3d point;
  const Eigen::Vector3d q = s.evaluate(0.3, 0.6) + 0.05 * s.normal(0.3, 0.6);
  const Eigen::Vector2d uv = s.closest_point(q, point);
  EXPECT_NEAR(uv[0], 0.3, 1e-9);
  EXPECT_NEAR(uv[1], 0.6, 1e-9);
}

TEST(Geometry, EvaluationAllocatesNothing) {
  if (!heap_counter_sees_malloc()) GTEST_SKIP() << "the C allocator is not interposed here";
  const NurbsCurve c = quarter_circle();
  const NurbsSurface s = bumpy_patch();
  const Sphere sphere(Eigen::Vector3d(0, 0, 0), 0.5);
  const Cylinder cylinder(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0, 0, 1), 0.2);
  const Plane plane(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0, 1, 1));
  const std::vector<const Surface*> surfaces = {&s, &sphere, &cylinder, &plane};
  double sink = 0.0;
  CurveDerivatives cd;
  SurfaceDerivatives sd;
  const HeapCount count = heap_count_of([&] {
    for (int k = 0; k < 50; ++k) {
      const double t = k / 49.0;
      Eigen::Vector3d point;
      sink += c.evaluate(t).x() + c.curvature(t) + c.tangent(t).y();
      c.derivatives(t, 2, cd);
      sink += cd(0, 2) + c.closest_point(Eigen::Vector3d(t, 2.0 * t - 0.5, 0.1), point);
      for (const Surface* x : surfaces) {
        sink += x->evaluate(t, 1.0 - t).z() + x->normal(t, 0.5).x();
        x->derivatives(t, 0.3, 2, sd);
        sink += sd(1, 1).x() + x->curvature(t, 0.2).mean;
        sink += x->closest_point(Eigen::Vector3d(t, 0.5 - t, 0.3), point)[0] + point.x();
      }
    }
  });
  EXPECT_TRUE(std::isfinite(sink));
  EXPECT_EQ(count.allocations, 0);
  EXPECT_EQ(count.frees, 0);
}

TEST(Geometry, ConstructorsNameTheBadParameter) {
  Eigen::MatrixX3d P(3, 3);
  P << 1, 0, 0, 1, 1, 0, 0, 1, 0;
  Eigen::VectorXd w(3), U(5);
  w << 1, -1, 1;
  U << 0, 0, 0, 1, 1;
  const auto message = [](auto&& f) {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  Eigen::VectorXd U6(6);
  U6 << 0, 0, 0, 1, 1, 1;
  EXPECT_EQ(message([&] { NurbsCurve(P, w, U6, 2); }).rfind("weights:", 0), 0u);
  w << 1, 1, 1;
  EXPECT_EQ(message([&] { NurbsCurve(P, w, U, 2); }).rfind("knots:", 0), 0u);
  EXPECT_EQ(message([&] { NurbsCurve(P, w, U6, 8); }).rfind("degree:", 0), 0u);
  EXPECT_EQ(message([&] { Sphere(Eigen::Vector3d::Zero(), 0.0); }).rfind("radius", 0), 0u);
}
