// The core's own numerical helpers, each on its own against an independent reference: the
// arctangent series and the rotation's logarithm from its axis part (src/trig.hpp,
// src/rotation_log.hpp) against long double, the small Cholesky solve (src/small_cholesky.hpp)
// against long double elimination, and Newton's early stop (src/newton_stop.hpp) against the
// steps Newton's method really takes.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "../../src/newton_stop.hpp"
#include "../../src/rotation_log.hpp"
#include "../../src/small_cholesky.hpp"
#include "../../src/trig.hpp"

namespace {

using virtmech::JointMatrix;
using virtmech::JointVector;
using virtmech::kMaxDof;

constexpr double kEps = std::numeric_limits<double>::epsilon();

}  // namespace

TEST(AtanSeries, IsAtanOverItsArgumentToRounding) {
  // 1 + z P(z) = atan(u) / u, z = u^2 in [0, 1/4]
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int i = 0; i <= 200000; ++i) {
    const double z = i == 0 ? 0.0 : (i == 1 ? virtmech::detail::kAtanSeriesMaxZ
                                            : virtmech::detail::kAtanSeriesMaxZ * unit(rng));
    const long double u = std::sqrt(static_cast<long double>(z));
    const long double exact = u == 0.0L ? 1.0L : std::atan(u) / u;
    const long double got = 1.0L + z * static_cast<long double>(virtmech::detail::atan_series(z));
    ASSERT_LE(std::abs(got - exact), 1.5L * kEps) << "z = " << z;
  }
  EXPECT_NEAR(virtmech::detail::atan_series(0.0), -1.0 / 3.0, kEps);
}

namespace {

// angle * axis from d = 2 sin(angle) axis and tr1 = 2 + 2 cos(angle), in long double
Eigen::Matrix<long double, 3, 1> log_reference(const Eigen::Vector3d& d, double tr1) {
  const Eigen::Matrix<long double, 3, 1> dl = d.cast<long double>();
  const long double n = dl.norm();
  return (2.0L * std::atan2(n, static_cast<long double>(tr1)) / n) * dl;
}

}  // namespace

TEST(RotationLog, FromTheAxisPartIsTheRotationVectorToRounding) {
  // both routes (below and above 2 atan(1/2), 53 degrees) up to 2 pi / 3, and small angles
  std::mt19937_64 rng(22);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> angle(0.0, 2.0 * M_PI / 3.0), decades(-300.0, -1.0);
  for (int i = 0; i < 200000; ++i) {
    Eigen::Vector3d axis(normal(rng), normal(rng), normal(rng));
    axis.normalize();
    const double a = i % 4 == 0 ? std::pow(10.0, decades(rng)) : angle(rng);
    const Eigen::Vector3d d = 2.0 * std::sin(a) * axis;
    const double tr1 = 2.0 + 2.0 * std::cos(a);
    const Eigen::Vector3d got = virtmech::detail::log_from_axis_part(d, tr1);
    const Eigen::Matrix<long double, 3, 1> exact = log_reference(d, tr1);
    ASSERT_LE((got.cast<long double>() - exact).norm(), 4.0L * kEps * exact.norm())
        << "angle " << a;
  }
}

TEST(RotationLog, FromTheAxisPartIsContinuousWhereItsRoutesMeet) {
  // |d|^2 = tr1^2 / 4 (u = tan(angle / 2) = 1/2) and a few ulps either side
  const double tr1 = 1.7;
  double dd = virtmech::detail::kAtanSeriesMaxZ * tr1 * tr1;
  for (int i = 0; i < 8; ++i) dd = std::nextafter(dd, 0.0);
  for (int i = 0; i < 17; ++i, dd = std::nextafter(dd, 1.0)) {
    const Eigen::Vector3d d(std::sqrt(dd), 0.0, 0.0);
    const Eigen::Vector3d got = virtmech::detail::log_from_axis_part(d, tr1);
    const Eigen::Matrix<long double, 3, 1> exact = log_reference(d, tr1);
    EXPECT_LE((got.cast<long double>() - exact).norm(), 4.0L * kEps * exact.norm()) << dd;
  }
}

namespace {

// x solving A x = b by Gaussian elimination with partial pivoting in long double
Eigen::Matrix<long double, Eigen::Dynamic, 1> solve_reference(const JointMatrix& A,
                                                             const JointVector& b) {
  const int n = static_cast<int>(A.rows());
  Eigen::Matrix<long double, Eigen::Dynamic, Eigen::Dynamic> M = A.cast<long double>();
  Eigen::Matrix<long double, Eigen::Dynamic, 1> x = b.cast<long double>();
  for (int k = 0; k < n; ++k) {
    int p = k;
    for (int i = k + 1; i < n; ++i)
      if (std::abs(M(i, k)) > std::abs(M(p, k))) p = i;
    M.row(k).swap(M.row(p));
    std::swap(x[k], x[p]);
    for (int i = k + 1; i < n; ++i) {
      const long double f = M(i, k) / M(k, k);
      M.row(i) -= f * M.row(k);
      x[i] -= f * x[k];
    }
  }
  for (int i = n - 1; i >= 0; --i) {
    long double s = x[i];
    for (int j = i + 1; j < n; ++j) s -= M(i, j) * x[j];
    x[i] = s / M(i, i);
  }
  return x;
}

}  // namespace

TEST(SmallCholesky, SolvesSymmetricPositiveDefiniteSystemsToRounding) {
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int trial = 0; trial < 2000; ++trial) {
    const int n = 1 + trial % kMaxDof;
    JointMatrix B(n, n);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) B(i, j) = unit(rng);
    // condition number at most 100 n
    JointMatrix A = B * B.transpose();
    A.diagonal().array() += 1e-2 * A.trace() / n + 1e-3;
    JointVector b(n);
    for (int i = 0; i < n; ++i) b[i] = unit(rng);
    JointMatrix L = A;
    ASSERT_TRUE(virtmech::detail::cholesky_in_place(L)) << n;
    // the factor: L L^T = A (the lower triangle read)
    const JointMatrix Lower = L.triangularView<Eigen::Lower>();
    EXPECT_LE((Lower * Lower.transpose() - A).norm(), 8.0 * n * kEps * A.trace()) << n;
    JointVector x = b;
    virtmech::detail::cholesky_solve_in_place(L, x);
    const auto exact = solve_reference(A, b);
    EXPECT_LE((x.cast<long double>() - exact).norm(), 1e-11L * exact.norm()) << n;
  }
}

TEST(SmallCholesky, RefusesMatricesThatAreNotPositiveDefinite) {
  JointMatrix indefinite(2, 2);
  indefinite << 1.0, 2.0, 2.0, 1.0;  // eigenvalues 3 and -1
  EXPECT_FALSE(virtmech::detail::cholesky_in_place(indefinite));
  JointMatrix negative = -JointMatrix::Identity(3, 3);
  EXPECT_FALSE(virtmech::detail::cholesky_in_place(negative));
  JointMatrix zero = JointMatrix::Zero(4, 4);
  EXPECT_FALSE(virtmech::detail::cholesky_in_place(zero));
  JointMatrix nan = JointMatrix::Identity(3, 3);
  nan(1, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(virtmech::detail::cholesky_in_place(nan));
  JointMatrix spd = JointMatrix::Identity(3, 3);
  spd(2, 2) = 4.0;
  ASSERT_TRUE(virtmech::detail::cholesky_in_place(spd));
  EXPECT_EQ(spd(2, 2), 2.0);  // sqrt(4), exactly
}

namespace {

// Newton's method on f (derivative df) from x0; whenever next_newton_step_below calls the
// next step negligible (below tol), the step Newton's method then takes is checked, as is
// every step the predicate did not skip but that turned out at rounding level
template <typename F, typename DF>
void check_stops(const F& f, const DF& df, double x0, double tol, int& stops) {
  double x = x0, last = 0.0;
  for (int it = 0; it < 200; ++it) {
    const double step = std::abs(f(x) / df(x));
    const double next_x = x - f(x) / df(x);
    if (virtmech::detail::next_newton_step_below(step, last, tol)) {
      const double next_step = std::abs(f(next_x) / df(next_x));
      // the estimate step^3 / last^2 is that of a quadratically converging iteration
      EXPECT_LE(next_step, 4.0 * tol) << "x0 = " << x0 << ", step " << it;
      ++stops;
      return;
    }
    if (step == 0.0) return;
    x = next_x;
    last = step;
  }
  ADD_FAILURE() << "Newton's method from " << x0 << " never stopped";
}

}  // namespace

TEST(NewtonStop, SkipsOnlyAStepAtRoundingLevel) {
  int stops = 0;
  for (const double a : {2.0, 3.0, 10.0, 1e-6, 1e6, 0.37}) {
    const double root = std::sqrt(a);
    check_stops([a](double x) { return x * x - a; }, [](double x) { return 2.0 * x; },
                a + 1.0, 1e-15 * root, stops);
  }
  for (const double c : {0.3, -1.1, 1.4}) {  // atan(x) = c
    check_stops([c](double x) { return std::atan(x) - c; },
                [](double x) { return 1.0 / (1.0 + x * x); }, 0.0,
                1e-15 * std::abs(std::tan(c)), stops);
  }
  EXPECT_EQ(stops, 9);  // (every run ended by the predicate, not by a zero step)
}

TEST(NewtonStop, NeedsAFullStepBefore) {
  EXPECT_FALSE(virtmech::detail::next_newton_step_below(1e-30, 0.0, 1e-15));
  EXPECT_TRUE(virtmech::detail::next_newton_step_below(1e-10, 1e-2, 1e-15));   // 1e-26
  EXPECT_FALSE(virtmech::detail::next_newton_step_below(1e-5, 1e-3, 1e-15));    // 1e-9
  EXPECT_TRUE(virtmech::detail::next_newton_step_below(0.0, 1e-3, 0.0));
}
