// The paper's range-space and null-space filters (eqs. 5 and 9), weighted.
#pragma once

#include "virtmech/types.hpp"

namespace virtmech {

/// Relative threshold below which an eigenvalue of J^T W J counts as zero in the
/// pseudo-inverse (relative to the largest eigenvalue).
constexpr double kPinvTolerance = 1e-10;

/// Moore-Penrose pseudo-inverse of a symmetric positive semi-definite matrix A (n x n):
/// eigenvalues below kPinvTolerance * max eigenvalue count as 0. Computed by Cholesky when
/// A is provably conditioned well enough that no eigenvalue is cut (then A^+ = A^-1), else
/// by eigen-decomposition. Allocation-free.
void symmetric_pinv(const JointMatrix& A, JointMatrix& A_pinv) noexcept;

/// Range-space filter P(W) = W J (J^T W J)^+ J^T (eq. 5), W diagonal (a 6-vector).
Matrix6 range_filter(const Jacobian& J, const Vector6& W) noexcept;
/// Range-space filter with a full symmetric positive semi-definite weight matrix.
Matrix6 range_filter(const Jacobian& J, const Matrix6& W) noexcept;

/// Null-space filter N(W) = I - P(W) (eq. 9).
Matrix6 null_filter(const Jacobian& J, const Vector6& W) noexcept;
Matrix6 null_filter(const Jacobian& J, const Matrix6& W) noexcept;

}  // namespace virtmech
