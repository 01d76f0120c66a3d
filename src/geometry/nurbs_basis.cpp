// Knot vectors and B-spline basis functions (nurbs_basis.hpp).
#include "nurbs_basis.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include "virtmech/validate.hpp"

namespace virtmech::detail {

void check_knots(const char* name, const Eigen::VectorXd& U, int n, int p) {
  const Eigen::Index expected = n + p + 1;
  if (U.size() != expected) {
    std::ostringstream os;
    os << name << ": expected n + degree + 1 = " << expected << " values (n = " << n
       << " control points, degree " << p << "), got " << U.size();
    throw std::invalid_argument(os.str());
  }
  require_finite(name, U);
  int multiplicity = 1;
  for (Eigen::Index i = 1; i < U.size(); ++i) {
    if (U[i] < U[i - 1]) {
      std::ostringstream os;
      os << name << ": expected non-decreasing values, got " << U[i] << " after " << U[i - 1]
         << " at index " << i << " of " << format_vector(U);
      throw std::invalid_argument(os.str());
    }
    multiplicity = U[i] == U[i - 1] ? multiplicity + 1 : 1;
    if (multiplicity > p + 1) {
      std::ostringstream os;
      os << name << ": expected every knot's multiplicity at most degree + 1 = " << p + 1
         << ", got " << U[i] << " " << multiplicity << " times in " << format_vector(U);
      throw std::invalid_argument(os.str());
    }
  }
  if (!(U[p] < U[n])) {
    std::ostringstream os;
    os << name << ": expected a non-empty domain [knots[degree], knots[n]] = [" << U[p] << ", "
       << U[n] << "], got " << format_vector(U);
    throw std::invalid_argument(os.str());
  }
}

void check_degree(const char* name, int p) {
  if (p < 1 || p > kMaxNurbsDegree) {
    throw std::invalid_argument(std::string(name) + ": expected 1 to " +
                                std::to_string(kMaxNurbsDegree) + ", got " + std::to_string(p));
  }
}

void basis_derivatives(const double* U, int i, int p, double u, int nd,
                       double (&ders)[kD][kP]) noexcept {
  double ndu[kP][kP];
  double left[kP], right[kP];
  double a[2][kP];
  ndu[0][0] = 1.0;
  for (int j = 1; j <= p; ++j) {
    left[j] = u - U[i + 1 - j];
    right[j] = U[i + j] - u;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      ndu[j][r] = right[r + 1] + left[j - r];
      const double temp = ndu[r][j - 1] / ndu[j][r];
      ndu[r][j] = saved + right[r + 1] * temp;
      saved = left[j - r] * temp;
    }
    ndu[j][j] = saved;
  }
  for (int j = 0; j <= p; ++j) ders[0][j] = ndu[j][p];
  const int n = std::min(nd, p);
  for (int r = 0; r <= p; ++r) {
    int s1 = 0, s2 = 1;
    a[0][0] = 1.0;
    for (int k = 1; k <= n; ++k) {
      double d = 0.0;
      const int rk = r - k, pk = p - k;
      if (r >= k) {
        a[s2][0] = a[s1][0] / ndu[pk + 1][rk];
        d = a[s2][0] * ndu[rk][pk];
      }
      const int j1 = rk >= -1 ? 1 : -rk;
      const int j2 = (r - 1 <= pk) ? k - 1 : p - r;
      for (int j = j1; j <= j2; ++j) {
        a[s2][j] = (a[s1][j] - a[s1][j - 1]) / ndu[pk + 1][rk + j];
        d += a[s2][j] * ndu[rk + j][pk];
      }
      if (r <= pk) {
        a[s2][k] = -a[s1][k - 1] / ndu[pk + 1][r];
        d += a[s2][k] * ndu[r][pk];
      }
      ders[k][r] = d;
      std::swap(s1, s2);
    }
  }
  double f = p;
  for (int k = 1; k <= n; ++k) {
    for (int j = 0; j <= p; ++j) ders[k][j] *= f;
    f *= (p - k);
  }
  for (int k = n + 1; k <= nd; ++k)
    for (int j = 0; j <= p; ++j) ders[k][j] = 0.0;
}

std::vector<double> sample_parameters(const Eigen::VectorXd& U, int n, int p, int per_span) {
  std::vector<double> s;
  for (int i = p; i < n; ++i) {
    if (U[i] == U[i + 1]) continue;
    for (int k = 0; k < per_span; ++k) s.push_back(U[i] + (U[i + 1] - U[i]) * k / per_span);
  }
  s.push_back(U[n]);
  return s;
}

int interior_multiplicity(const Eigen::VectorXd& U, int n, int p) noexcept {
  int most = 0;
  for (int i = p + 1; i < n; ++i) {
    if (!(U[i] > U[p] && U[i] < U[n])) continue;
    int k = 1;
    while (i + k < n && U[i + k] == U[i]) ++k;
    most = std::max(most, k);
    i += k - 1;
  }
  return most;
}

}  // namespace virtmech::detail
