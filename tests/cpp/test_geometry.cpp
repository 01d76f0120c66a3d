// Geometry objects: a closed form (the quarter circle as a rational quadratic NURBS) and
// evaluation without heap allocation (the counter of heap_counter.hpp sees every call).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
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

// --- the global closest point on large surfaces -------------------------------------

namespace {

// An n x n net over the unit square, heights `bump` * a seeded random field (or a spherical
// cap of radius 0.5 about the origin: `cap`), random weights in [0.5, 2], clamped uniform
// knots of degree p (a knot of multiplicity p in the middle of u: `crease`).
NurbsSurface large_surface(int n, int p, unsigned seed, bool cap = false, bool crease = false) {
  std::mt19937 gen(seed);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  Eigen::MatrixX3d P(n * n, 3);
  Eigen::MatrixXd W(n, n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double x = i / (n - 1.0), y = j / (n - 1.0);
      if (cap) {
        const double a = 1.2 * (x - 0.5), b = 1.2 * (y - 0.5);
        P.row(i * n + j) << 0.5 * std::sin(a) * std::cos(b), 0.5 * std::sin(b),
            0.5 * std::cos(a) * std::cos(b);
        W(i, j) = 1.0;
      } else {
        P.row(i * n + j) << x, y, 0.1 * std::sin(6.0 * x + 2.0 * y) + 0.02 * uni(gen);
        W(i, j) = 1.25 + 0.75 * uni(gen);
      }
    }
  }
  Eigen::VectorXd k(n + p + 1);
  for (int i = 0; i < n + p + 1; ++i) k[i] = std::clamp(double(i - p) / (n - p), 0.0, 1.0);
  Eigen::VectorXd ku = k;
  if (crease) {
    const int mid = (n + p + 1) / 2;
    for (int r = 1; r < p; ++r) ku[mid + r] = ku[mid];
  }
  return NurbsSurface(P, W, ku, k, p, p);
}

// The least distance from x over a dense grid of the parameters (count x count), each grid
// point refined by the local search from it where it is the grid's nearest: a reference
// that looks at the whole surface.
double dense_search(const NurbsSurface& s, const Eigen::Vector3d& x, int count) {
  const Eigen::Vector2d lo = s.lower(), hi = s.upper();
  double best = kInf;
  Eigen::Vector2d at = lo;
  for (int a = 0; a < count; ++a) {
    for (int b = 0; b < count; ++b) {
      const Eigen::Vector2d uv(lo[0] + (hi[0] - lo[0]) * a / (count - 1.0),
                               lo[1] + (hi[1] - lo[1]) * b / (count - 1.0));
      const double d = (s.evaluate(uv[0], uv[1]) - x).norm();
      if (d < best) best = d, at = uv;
    }
  }
  Eigen::Vector3d point;
  s.closest_point_from(x, at, lo, hi, point);
  return std::min(best, (point - x).norm());
}

}  // namespace

TEST(Geometry, LargeSurfaceClosestPointIsNeverWorseThanADenseSearch) {
  // deep hierarchies (up to 33 x 33 control points, some 64 k samples): points near the
  // surface, far above and below it, beyond its edges and corners, and, on the cap, at its
  // centre (every sample nearly as near as every other)
  struct Case {
    int n, p;
    bool cap, crease;
  };
  const Case cases[] = {{33, 3, false, false}, {24, 2, false, true}, {30, 3, true, false}};
  std::mt19937 gen(11);
  std::uniform_real_distribution<double> uni(0.0, 1.0), off(-0.4, 0.4);
  for (const Case& c : cases) {
    const NurbsSurface s = large_surface(c.n, c.p, 5u + c.n, c.cap, c.crease);
    for (int k = 0; k < 60; ++k) {
      Eigen::Vector3d x;
      if (k == 0) {
        x = Eigen::Vector3d::Zero();  // the cap's centre
      } else if (k % 3 == 0) {
        x = Eigen::Vector3d(2.0 * uni(gen) - 0.5, 2.0 * uni(gen) - 0.5, off(gen));
      } else {
        const double u = uni(gen), v = uni(gen);
        x = s.evaluate(u, v) + off(gen) * s.normal(u, v);
      }
      Eigen::Vector3d point;
      const Eigen::Vector2d uv = s.closest_point(x, point);
      const double d = (point - x).norm();
      EXPECT_EQ((s.evaluate(uv[0], uv[1]) - point).norm(), 0.0);
      EXPECT_LE(d, dense_search(s, x, 161) + 1e-12)
          << "n " << c.n << " p " << c.p << " x " << x.transpose();
    }
  }
}

TEST(Geometry, LargeSurfaceClosestPointAllocatesNothing) {
  if (!heap_counter_sees_malloc()) GTEST_SKIP() << "the C allocator is not interposed here";
  // the cap's centre keeps more cells than the search holds on its stack (its second walk)
  const NurbsSurface s = large_surface(40, 3, 3u), cap = large_surface(40, 3, 3u, true);
  std::mt19937 gen(3);
  std::uniform_real_distribution<double> uni(0.0, 1.0), off(-0.3, 0.3);
  std::vector<Eigen::Vector3d> xs = {Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 0.1)};
  for (int k = 0; k < 100; ++k) {
    const double u = uni(gen), v = uni(gen);
    xs.push_back(s.evaluate(u, v) + off(gen) * s.normal(u, v));
  }
  double sink = 0.0;
  const HeapCount count = heap_count_of([&] {
    Eigen::Vector3d point;
    for (const Eigen::Vector3d& x : xs) {
      sink += s.closest_point(x, point)[0] + cap.closest_point(x, point)[1];
    }
  });
  EXPECT_TRUE(std::isfinite(sink));
  EXPECT_EQ(count.allocations, 0);
  EXPECT_EQ(count.frees, 0);
}

TEST(Geometry, SurfaceOfTooManySamplesIsRefusedByName) {
  // 1000 x 1000 bicubic: 7977 x 7977 samples, past kMaxNurbsSurfaceSamples
  const int n = 1000;
  Eigen::MatrixX3d P(n * n, 3);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) P.row(i * n + j) << i, j, 0.0;
  const Eigen::MatrixXd W = Eigen::MatrixXd::Ones(n, n);
  Eigen::VectorXd k(n + 4);
  for (int i = 0; i < n + 4; ++i) k[i] = std::clamp(double(i - 3) / (n - 3), 0.0, 1.0);
  std::string message;
  try {
    NurbsSurface(P, W, k, k, 3, 3);
  } catch (const std::invalid_argument& e) {
    message = e.what();
  }
  EXPECT_EQ(message.rfind("control_points:", 0), 0u) << message;
  EXPECT_NE(message.find("1000 x 1000"), std::string::npos) << message;
  EXPECT_NE(message.find("7977 x 7977"), std::string::npos) << message;
  EXPECT_NE(message.find(std::to_string(kMaxNurbsSurfaceSamples)), std::string::npos) << message;
}
