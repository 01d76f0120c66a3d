#include "virtmech/velocity_filter.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "virtmech/validate.hpp"

namespace virtmech {

VelocityFilter::VelocityFilter(int n, double period_s, double alpha)
    : period_s_(period_s), alpha_(alpha) {
  if (n < 1 || n > kMaxDof) {
    throw std::invalid_argument("n: expected 1 to " + std::to_string(kMaxDof) +
                                " joints, got " + std::to_string(n));
  }
  require_positive("period_s", period_s);
  if (!(alpha > 0.0 && alpha <= 1.0)) {
    throw std::invalid_argument("alpha: expected a number in (0, 1], got " +
                                std::to_string(alpha));
  }
  prev_.setZero(n);
  dq_.setZero(n);
}

double VelocityFilter::alpha_for_cutoff(double period_s, double cutoff_hz) noexcept {
  constexpr double kPi = 3.14159265358979323846;
  return cutoff_hz > 0.0 ? period_s / (period_s + 1.0 / (2.0 * kPi * cutoff_hz)) : 1.0;
}

const JointVector& VelocityFilter::update(const double* q) noexcept {
  const Eigen::Map<const Eigen::VectorXd> sample(q, dq_.size());
  if (primed_) dq_ += alpha_ * ((sample - prev_) / period_s_ - dq_);
  prev_ = sample;
  primed_ = true;
  return dq_;
}

void VelocityFilter::reset() noexcept {
  dq_.setZero();
  primed_ = false;
}

}  // namespace virtmech
