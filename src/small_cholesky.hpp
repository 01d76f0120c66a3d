// Cholesky factorisation, solve and inverse for the core's small joint-space matrices
// (n <= kMaxDof), written as plain loops: at these sizes Eigen's general (blocked) paths
// cost more than the arithmetic. Internal to the core.
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

/// (L L^T)^-1, symmetric, from L (cholesky_in_place).
inline void cholesky_inverse(const JointMatrix& L, JointMatrix& A_inv) noexcept {
  const Eigen::Index n = L.rows();
  // M = L^-1 (lower triangular), column by column
  JointMatrix M = JointMatrix::Zero(n, n);
  for (Eigen::Index j = 0; j < n; ++j) {
    M(j, j) = 1.0 / L(j, j);
    for (Eigen::Index i = j + 1; i < n; ++i) {
      double s = 0.0;
      for (Eigen::Index k = j; k < i; ++k) s -= L(i, k) * M(k, j);
      M(i, j) = s / L(i, i);
    }
  }
  // A^-1 = M^T M
  A_inv.resize(n, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j <= i; ++j) {
      double s = 0.0;
      for (Eigen::Index k = i; k < n; ++k) s += M(k, i) * M(k, j);
      A_inv(i, j) = s;
      A_inv(j, i) = s;
    }
  }
}

}  // namespace virtmech::detail
