// The paper's range-space and null-space filters (eqs. 5 and 9), weighted.
#pragma once

#include "virtmech/types.hpp"

namespace virtmech {

/// The one relative rank tolerance of the filters: a pivot |R_ii| of the column-pivoted QR
/// of sqrt(W) J at or below kPinvTolerance * |R_00| counts as 0, i.e. singular values of
/// sqrt(W) J below ~1e-10 of the largest (rounding-level ones, from repeated or zero columns,
/// are ~1e-16; a Probe 1e-5 rad from its singular pose has ~1e-6, and stays full rank).
constexpr double kPinvTolerance = 1e-10;

/// P(W) and N(W) for one Jacobian and diagonal weights, factorised once and applied many
/// times. Fixed capacity (J has at most kMaxDof columns); noexcept; never allocates.
///
/// With S = W^(1/2) and A = S J: W J (J^T W J)^+ = S (A^+)^T, so P(W) x = S (A^+)^T J^T x
/// without forming J^T W J (which squares the condition number). A is factorised by a
/// complete orthogonal decomposition, A Pi = Q [T 0; 0 0] Z^T (column-pivoted Householder
/// QR, then an RZ step only when rank < m). Non-finite J or W give NaN results.
class WeightedProjector {
 public:
  WeightedProjector() noexcept;

  /// Factorises sqrt(W) J. J: 6 x m (0 <= m <= kMaxDof); w: diagonal weights >= 0 (negative
  /// ones count as 0).
  void compute(const Jacobian& J, const Vector6& w) noexcept;
  /// Full symmetric positive semi-definite W (6 x 6): W = V diag(lambda) V^T, then the
  /// diagonal weights lambda on V^T J (same factorisation, same rank as sqrt(W) J);
  /// eigenvalues at rounding level (64 eps of the largest) count as 0. A diagonal W takes
  /// compute(J, W.diagonal()) exactly.
  void compute(const Jacobian& J, const Matrix6& W) noexcept;

  /// P(W) x (eq. 5 applied to a wrench x).
  Vector6 range(const Vector6& x) const noexcept;
  /// N(W) x = x - P(W) x (eq. 9).
  Vector6 null(const Vector6& x) const noexcept;
  /// The weighted minimum-norm least-squares fit (J^T W J)^+ J^T W v (m entries), e.g. the
  /// placement's joint rate for a handle twist v.
  void fit(const Vector6& v, JointVector& theta_dot) const noexcept;
  /// Numerical rank of sqrt(W) J.
  int rank() const noexcept { return rank_; }

 private:
  void factorise() noexcept;

  // A = diag(s_) J_ factorised in place: Q's reflectors below the diagonal, T on and above
  // it (r x r), Z's reflectors in rows 0..r-1 right of column r
  Jacobian qr_;
  Vector6 tau_, ztau_;    // Q's and Z's reflector coefficients
  int perm_[kMaxDof];     // column k of A Pi is column perm_[k] of A
  Jacobian J_;            // J, or V^T J for a full W
  Vector6 s_, s_inv_;     // sqrt of the (eigen)weights and its pseudo-inverse
  Vector6 free_;          // 1 where the weight is 0, else 0
  Matrix6 V_;             // eigenvectors of a full W (rotated_ only)
  int rank_ = 0;
  bool finite_ = true;    // J and W finite
  bool rotated_ = false;  // full W: everything is in the frame V^T
  bool split_ = true;     // see factorise()
};

/// Range-space filter P(W) = W J (J^T W J)^+ J^T (eq. 5), W diagonal (a 6-vector).
Matrix6 range_filter(const Jacobian& J, const Vector6& W) noexcept;
/// Range-space filter with a full symmetric positive semi-definite weight matrix.
Matrix6 range_filter(const Jacobian& J, const Matrix6& W) noexcept;

/// Null-space filter N(W) = I - P(W) (eq. 9).
Matrix6 null_filter(const Jacobian& J, const Vector6& W) noexcept;
Matrix6 null_filter(const Jacobian& J, const Matrix6& W) noexcept;

}  // namespace virtmech
