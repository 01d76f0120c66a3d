// The cycle's own sine, cosine and atan2 (src/trig.hpp) against long double and the library's.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "../../src/trig.hpp"

namespace {

// |a - exact| in units in the last place of the exact value (as a double)
double ulps(double a, long double exact) {
  const double e = static_cast<double>(exact);
  const double ulp = std::nextafter(std::abs(e), std::numeric_limits<double>::infinity()) -
                     std::abs(e);
  return static_cast<double>(std::abs(static_cast<long double>(a) - exact)) / ulp;
}

}  // namespace

TEST(Arctangent, IsWithinTwoUlpsOfTheExactValueInEveryQuadrantAndScale) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> unit(-1.0, 1.0), decades(-250.0, 250.0);
  double worst = 0.0;
  for (long i = 0; i < 2000000; ++i) {
    // both at one scale (every angle), and at scales apart (angles near the axes)
    const double s = std::pow(10.0, decades(rng));
    const double y = unit(rng) * s;
    const double x = unit(rng) * (i % 4 == 0 ? std::pow(10.0, decades(rng)) : s);
    const long double exact = std::atan2(static_cast<long double>(y), static_cast<long double>(x));
    const double got = virtmech::detail::atan2_by_fit(y, x);
    if (exact == 0.0L) {
      ASSERT_EQ(got, 0.0) << y << " " << x;
      continue;
    }
    worst = std::max(worst, ulps(got, exact));
    ASSERT_LE(ulps(got, exact), 2.0) << "y=" << y << " x=" << x;
  }
  EXPECT_GT(worst, 0.5);  // (the test reaches the approximation's error)
}

TEST(Arctangent, IsExactAtTheReductionsSeams) {
  // the seams of the reduction (1/2, 1, the axes) from both sides, every quadrant
  const double half = 0.5;
  for (const double r : {half, std::nextafter(half, 0.0), std::nextafter(half, 1.0), 1.0,
                         std::nextafter(1.0, 0.0), std::nextafter(1.0, 2.0), 1e-17, 1e17}) {
    for (const double sy : {1.0, -1.0}) {
      for (const double sx : {1.0, -1.0}) {
        for (const double swap : {0.0, 1.0}) {
          const double y = sy * (swap > 0.0 ? 1.0 : r), x = sx * (swap > 0.0 ? r : 1.0);
          const long double exact =
              std::atan2(static_cast<long double>(y), static_cast<long double>(x));
          EXPECT_LE(ulps(virtmech::detail::atan2_by_fit(y, x), exact), 2.0) << y << " " << x;
        }
      }
    }
  }
}

TEST(Arctangent, SpecialValuesAreTheLibrarys) {
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double tiny = std::numeric_limits<double>::denorm_min();
  const double big = std::numeric_limits<double>::max();
  const double v[] = {0.0, -0.0, 1.0, -1.0, inf, -inf, tiny, -tiny, big, -big, 1e-301, 2e300};
  for (const double y : v) {
    for (const double x : v) {
      const double a = virtmech::detail::atan2_by_fit(y, x), b = std::atan2(y, x);
      EXPECT_EQ(std::signbit(a), std::signbit(b)) << y << " " << x;
      EXPECT_LE(std::abs(a - b), 4.5e-16 * std::abs(b)) << y << " " << x;
    }
    EXPECT_TRUE(std::isnan(virtmech::detail::atan2_by_fit(y, nan)));
    EXPECT_TRUE(std::isnan(virtmech::detail::atan2_by_fit(nan, y)));
  }
  // the signs of zero: +-0 toward +x, +-pi toward -x
  EXPECT_TRUE(std::signbit(virtmech::detail::atan2_by_fit(-0.0, 1.0)));
  EXPECT_FALSE(std::signbit(virtmech::detail::atan2_by_fit(0.0, 1.0)));
  EXPECT_EQ(virtmech::detail::atan2_by_fit(-0.0, -1.0), -M_PI);
  EXPECT_EQ(virtmech::detail::atan2_by_fit(0.0, -1.0), M_PI);
}

namespace {

// the larger error of sin x and cos x in ulps (an exact zero must be given exactly)
double sincos_ulps(double x) {
  double s, c;
  virtmech::detail::sincos_by_fit(x, s, c);
  const long double xl = x;
  const long double es = std::sin(xl), ec = std::cos(xl);
  const double us = es == 0.0L ? (s == 0.0 ? 0.0 : 1e9) : ulps(s, es);
  return std::max(us, ulps(c, ec));
}

struct Worst {
  double ulps = 0.0, x = 0.0;
  void see(double at) {
    const double u = sincos_ulps(at);
    if (u > ulps) {
      ulps = u;
      x = at;
    }
  }
};

}  // namespace

TEST(SineCosine, AreWithinTwoUlpsOfTheExactValues) {
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> joint(-10.0, 10.0), wide(-2000.0, 2000.0),
      decades(-300.0, 0.0);
  Worst worst;
  for (long i = 0; i < 1000000; ++i) {
    worst.see(joint(rng));  // joint angles
    worst.see(wide(rng));   // the reduction's whole range and beyond
    worst.see(joint(rng) * std::pow(10.0, decades(rng)));  // tiny ones
  }
  EXPECT_LE(worst.ulps, 2.0) << "at x = " << worst.x;
  EXPECT_GT(worst.ulps, 0.5);  // (the test reaches the approximation's error)
}

TEST(SineCosine, AreWithinTwoUlpsAtTheQuadrantsSeams) {
  // near k pi/4 and k pi/2 (where the reduction switches and where sin or cos vanishes),
  // a few ulps either side, for k up to the reduction's end
  Worst worst;
  for (int k = -1300; k <= 1300; ++k) {
    for (const double base : {k * M_PI / 4.0, k * M_PI / 2.0}) {
      double x = base;
      for (int i = 0; i < 4; ++i) x = std::nextafter(x, -1e9);
      for (int i = 0; i < 9; ++i, x = std::nextafter(x, 1e9)) worst.see(x);
    }
  }
  EXPECT_LE(worst.ulps, 2.0) << "at x = " << worst.x;
}

TEST(SineCosine, SpecialValuesAreTheLibrarys) {
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const double x : {0.0, -0.0, inf, -inf, nan, 1e300, -1e300, 1e3, -1e3, 1e3 + 1e-9}) {
    double s, c;
    virtmech::detail::sincos_by_fit(x, s, c);
    const double es = std::sin(x), ec = std::cos(x);
    EXPECT_EQ(std::isnan(s), std::isnan(es)) << x;
    EXPECT_EQ(std::isnan(c), std::isnan(ec)) << x;
    if (!std::isnan(es)) {
      EXPECT_EQ(std::signbit(s), std::signbit(es)) << x;
      EXPECT_LE(std::abs(s - es), 4.5e-16) << x;
      EXPECT_LE(std::abs(c - ec), 4.5e-16) << x;
    }
  }
}

TEST(CycleTrigonometry, IsTheOwnOrInACoreOnCmathTheLibrarys) {
  // the cycle's sincos and atan2 forward to one implementation, bit for bit
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> wide(-20.0, 20.0);
  for (int i = 0; i < 10000; ++i) {
    const double x = wide(rng), y = wide(rng);
    double s, c, s_expected, c_expected;
    virtmech::detail::sincos(x, s, c);
    if (virtmech::detail::kStdMath) {
      s_expected = std::sin(x);
      c_expected = std::cos(x);
    } else {
      virtmech::detail::sincos_by_fit(x, s_expected, c_expected);
    }
    ASSERT_EQ(s, s_expected) << x;
    ASSERT_EQ(c, c_expected) << x;
    ASSERT_EQ(virtmech::detail::atan2(y, x), virtmech::detail::kStdMath
                                                 ? std::atan2(y, x)
                                                 : virtmech::detail::atan2_by_fit(y, x))
        << y << " " << x;
  }
}
