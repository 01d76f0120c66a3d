// What every shape of include/virtmech/geometry.hpp shares: clamps of a parameter and of a
// derivative order, a checked unit vector, and the derivatives of cos and sin. Internal to
// the core.
#pragma once

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "virtmech/geometry.hpp"
#include "virtmech/validate.hpp"

namespace virtmech::detail {

constexpr double kPi = 3.14159265358979323846;

inline double clamp(double x, double lo, double hi) noexcept {
  return std::min(std::max(x, lo), hi);
}

inline int clamp_order(int order) noexcept {
  return std::min(std::max(order, 0), kMaxDerivativeOrder);
}

// v / |v|; std::invalid_argument naming `name` where v is zero or not finite
inline Eigen::Vector3d safe_normalized(const Eigen::Vector3d& v, const char* name) {
  const double n = v.norm();
  if (!(std::isfinite(n) && n > 0.0)) {
    throw std::invalid_argument(std::string(name) + ": expected a finite, non-zero vector, got " +
                                format_vector(v));
  }
  return v / n;
}

// d^k/dt^k of cos t and sin t
inline double dcos(double t, int k) noexcept { return std::cos(t + k * 0.5 * kPi); }
inline double dsin(double t, int k) noexcept { return std::sin(t + k * 0.5 * kPi); }

}  // namespace virtmech::detail
