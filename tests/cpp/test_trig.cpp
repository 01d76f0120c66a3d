// The cycle's own atan2 (src/trig.hpp) against long double and the library's.
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

TEST(CycleTrigonometry, IsTheOwnOrInACoreOnCmathTheLibrarys) {
  // the cycle's atan2 forwards to one implementation, bit for bit
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> wide(-20.0, 20.0);
  for (int i = 0; i < 10000; ++i) {
    const double x = wide(rng), y = wide(rng);
    ASSERT_EQ(virtmech::detail::atan2(y, x), virtmech::detail::kStdMath
                                                 ? std::atan2(y, x)
                                                 : virtmech::detail::atan2_by_fit(y, x))
        << y << " " << x;
  }
}
