// The velocity filter a servo loop estimates joint velocities with, against its closed forms.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "virtmech/velocity_filter.hpp"

using namespace virtmech;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kT = 1e-3;

TEST(VelocityFilter, AlphaIsTheFirstOrderLowPassGain) {
  for (double fc : {1.0, 30.0, 100.0, 400.0}) {
    const long double tau = 1.0L / (2.0L * 3.141592653589793238462643L * fc);
    const long double alpha = 1e-3L / (1e-3L + tau);
    EXPECT_NEAR(VelocityFilter::alpha_for_cutoff(1e-3, fc), static_cast<double>(alpha), 1e-16);
  }
  EXPECT_EQ(VelocityFilter::alpha_for_cutoff(1e-3, 0.0), 1.0);
  EXPECT_EQ(VelocityFilter::alpha_for_cutoff(1e-3, -5.0), 1.0);
}

TEST(VelocityFilter, RampConvergesAsTheClosedForm) {
  // q = v t: every difference is v, so dq_k = v (1 - (1 - alpha)^k) after the first sample
  const double alpha = VelocityFilter::alpha_for_cutoff(kT, 100.0), v = 0.37;
  VelocityFilter f(2, kT, alpha);
  for (int k = 0; k < 200; ++k) {
    const double q[2] = {v * k * kT, -v * k * kT};
    const JointVector& dq = f.update(q);
    const double expected = v * (1.0 - std::pow(1.0 - alpha, k));
    EXPECT_NEAR(dq[0], expected, 1e-12 * v) << k;
    EXPECT_NEAR(dq[1], -expected, 1e-12 * v) << k;
  }
}

TEST(VelocityFilter, DelaysASlowSineByTheDocumentedDelay) {
  // a 2 Hz sine: the estimate lags the true velocity by 1 / (2 pi f_c) + T / 2 (low-pass and
  // backward difference), with unit gain
  const double fc = 100.0, f = 2.0, w = 2 * kPi * f;
  VelocityFilter filter(1, kT, VelocityFilter::alpha_for_cutoff(kT, fc));
  double sc = 0, cc = 0, ss = 0, ys = 0, yc = 0;
  for (int k = 0; k < 4000; ++k) {
    const double t = k * kT, q = std::sin(w * t);
    const double dq = filter.update(&q)[0];
    if (k >= 2000) {  // steady state: fit dq = a cos(w t) + b sin(w t)
      const double c = std::cos(w * t), s = std::sin(w * t);
      cc += c * c;
      ss += s * s;
      sc += s * c;
      yc += dq * c;
      ys += dq * s;
    }
  }
  // dq = w cos(w (t - delay)): a = w cos(w delay), b = w sin(w delay)
  const double det = cc * ss - sc * sc;
  const double a = (yc * ss - ys * sc) / det, b = (ys * cc - yc * sc) / det;
  const double gain = std::hypot(a, b) / w, delay = std::atan2(b, a) / w;
  EXPECT_NEAR(gain, 1.0, 0.01);
  EXPECT_NEAR(delay, 1.0 / (2 * kPi * fc) + kT / 2, 0.02 * (1.0 / (2 * kPi * fc) + kT / 2));
}

TEST(VelocityFilter, ResetStartsAfresh) {
  VelocityFilter f(1, kT, 0.5);
  const double a = 0.0, b = 1.0, c = 5.0;
  f.update(&a);
  EXPECT_GT(f.update(&b)[0], 0.0);
  f.reset();
  EXPECT_EQ(f.velocity()[0], 0.0);
  EXPECT_EQ(f.update(&c)[0], 0.0);  // the first sample after reset: no difference yet
  EXPECT_EQ(f.update(&c)[0], 0.0);
}

TEST(VelocityFilter, RefusesBadSettings) {
  EXPECT_THROW(VelocityFilter(0, kT, 0.5), std::invalid_argument);
  EXPECT_THROW(VelocityFilter(kMaxDof + 1, kT, 0.5), std::invalid_argument);
  EXPECT_THROW(VelocityFilter(3, 0.0, 0.5), std::invalid_argument);
  EXPECT_THROW(VelocityFilter(3, kT, 0.0), std::invalid_argument);
  EXPECT_THROW(VelocityFilter(3, kT, 1.5), std::invalid_argument);
}

}  // namespace
