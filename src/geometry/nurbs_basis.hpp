// Knot vectors and B-spline basis functions (Piegl & Tiller, The NURBS Book, 2nd ed., 1997,
// algorithms A2.1 and A2.3), and the binomial and falling-factorial tables of the
// derivatives. Internal to the core.
#pragma once

#include <algorithm>
#include <vector>

#include "shape_support.hpp"
#include "virtmech/geometry.hpp"

namespace virtmech::detail {

constexpr int kP = kMaxNurbsDegree + 1;  // work-array size
constexpr int kD = kMaxDerivativeOrder + 1;

// binomial coefficients up to kMaxDerivativeOrder
struct Binomial {
  double c[kD][kD] = {};
  constexpr Binomial() {
    for (int n = 0; n < kD; ++n) {
      c[n][0] = 1.0;
      for (int k = 1; k <= n; ++k) c[n][k] = c[n - 1][k - 1] + (k < n ? c[n - 1][k] : 0.0);
    }
  }
};
inline constexpr Binomial kBin{};

// falling factorials n! / (n - k)! for n, k <= kMaxDerivativeOrder (0 where k > n)
struct Falling {
  double f[kD][kD] = {};
  constexpr Falling() {
    for (int n = 0; n < kD; ++n) {
      double v = 1.0;
      for (int k = 0; k <= n; ++k) {
        f[n][k] = v;
        v *= static_cast<double>(n - k);
      }
    }
  }
};
inline constexpr Falling kFall{};

// Checks a knot vector for n control points of degree p; returns the domain [U_p, U_n].
void check_knots(const char* name, const Eigen::VectorXd& U, int n, int p);

// Checks a degree: 1 to kMaxNurbsDegree.
void check_degree(const char* name, int p);

// A2.1: the span index i with U_i <= u < U_(i+1), p <= i <= n - 1 (n control points);
// u within [U_p, U_n].
inline int find_span(const double* U, int n, int p, double u) noexcept {
  if (u >= U[n]) {
    int i = n - 1;
    while (i > p && U[i] == U[i + 1]) --i;
    return i;
  }
  if (u <= U[p]) {
    int i = p;
    while (i < n - 1 && U[i] == U[i + 1]) ++i;
    return i;
  }
  int lo = p, hi = n;
  int mid = (lo + hi) / 2;
  while (u < U[mid] || u >= U[mid + 1]) {
    if (u < U[mid]) {
      hi = mid;
    } else {
      lo = mid;
    }
    mid = (lo + hi) / 2;
  }
  return mid;
}

// A2.3: ders[k][j] = k-th derivative of N_(i-p+j),p at u, k <= nd (nd <= p: higher are 0).
void basis_derivatives(const double* U, int i, int p, double u, int nd,
                       double (&ders)[kD][kP]) noexcept;

// the samples' parameters: `per_span` intervals in every non-empty knot span
std::vector<double> sample_parameters(const Eigen::VectorXd& U, int n, int p, int per_span);

inline int samples_per_span(int p) { return std::max(8, 2 * p); }

// The largest multiplicity of a knot strictly inside the domain [U[p], U[n]] (0: none).
int interior_multiplicity(const Eigen::VectorXd& U, int n, int p) noexcept;

}  // namespace virtmech::detail
