// Cholesky factorisation and solve for the Gauss-Newton placement's small joint-space
// matrices (n <= kMaxDof), written as plain loops: at these sizes Eigen's LLT costs more
// than the arithmetic (docs/performance.md, "Hand-made routines"). Internal to the core.
#pragma once

#include <cmath>

#include "virtmech/types.hpp"

namespace virtmech::detail {

/// Overwrites the lower triangle of the symmetric A (n x n) with L, A = L L^T. Returns
/// false if A is not (numerically) positive definite; A is then partly overwritten.
inline bool cholesky_in_place(JointMatrix& A) noexcept {
  const Eigen::Index n = A.rows();
  for (Eigen::Index j = 0; j < n; ++j) {
    double d = A(j, j);
    for (Eigen::Index k = 0; k < j; ++k) d -= A(j, k) * A(j, k);
    if (!(d > 0.0)) return false;  // also NaN
    const double ljj = std::sqrt(d);
    A(j, j) = ljj;
    const double inv = 1.0 / ljj;
    for (Eigen::Index i = j + 1; i < n; ++i) {
      double s = A(i, j);
      for (Eigen::Index k = 0; k < j; ++k) s -= A(i, k) * A(j, k);
      A(i, j) = s * inv;
    }
  }
  return true;
}

/// Solves L L^T x = b in place (L from cholesky_in_place).
inline void cholesky_solve_in_place(const JointMatrix& L, JointVector& b) noexcept {
  const Eigen::Index n = L.rows();
  for (Eigen::Index i = 0; i < n; ++i) {
    double s = b[i];
    for (Eigen::Index k = 0; k < i; ++k) s -= L(i, k) * b[k];
    b[i] = s / L(i, i);
  }
  for (Eigen::Index i = n - 1; i >= 0; --i) {
    double s = b[i];
    for (Eigen::Index k = i + 1; k < n; ++k) s -= L(k, i) * b[k];
    b[i] = s / L(i, i);
  }
}

}  // namespace virtmech::detail
