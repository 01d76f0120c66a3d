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
/// QR, then an RZ step only when rank < m). Non-finite J or W give NaN results. One column
/// (m = 1, a one-joint mechanism) needs no factorisation: with j = J and A = S j of rank 1
/// (A != 0), P(W) x = W j (j^T x) / (j^T W j) and the fit is (j^T W v) / (j^T W j), both in
/// closed form.
///
/// Where the Gram matrix of A's weighted rows certifies that A has full row rank on them
/// with every singular value at least 1e-3 of |A|_F (rank = the number of weights
/// > 0), compute() leaves the factorisation to the first query that needs it: rank() is
/// known, and P(W) x for x on the weighted axes only is x itself (see range()). Results are
/// the same either way. One projector is not for concurrent use (const queries may
/// factorise).
///
/// Continuity of the null-space filter: where some singular value of A lies below 1e-3
/// |A|_F (a pose near a singular one), null() is x - P_phi x with the filtered
/// pseudo-inverse A_phi^+ = V diag(phi_i / sigma_i) U^T (from the eigen-decomposition of
/// A A^T), phi_i = smoothstep((sigma_i / |A|_F - 1e-5) / (1e-3 - 1e-5)): it changes
/// continuously with J (and W) where the rank would change, instead of stepping. A
/// placement singular up to its solver's accuracy (singular values ~1e-13..1e-6 of the
/// largest) lies below the band: the null-space force along the direction it cannot follow
/// is kept on every cycle. range(), fit() and residual() keep the factorisation's rank
/// (kPinvTolerance), as rank() reports it.
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
  /// N(W) x = x - P_phi(W) x (eq. 9), P_phi with the soft rank (see the class comment):
  /// where every singular value of A lies above the soft rank's band, x - range(x).
  Vector6 null(const Vector6& x) const noexcept;
  /// P_phi(W) x = x - null(x), the range with the soft rank: where every singular value of A
  /// lies above the soft rank's band, range(x) exactly. A force split as null(x) plus
  /// soft_range(x) renders each direction once, however near a singular pose.
  Vector6 soft_range(const Vector6& x) const noexcept;
  /// The weighted minimum-norm least-squares fit (J^T W J)^+ J^T W v (m entries), e.g. the
  /// placement's joint rate for a handle twist v.
  void fit(const Vector6& v, JointVector& theta_dot) const noexcept;
  /// J theta_dot - v for theta_dot = fit(v): the part of the twist v the columns do not
  /// follow. With every weight > 0 it is 0 at rank 6, and at rank 5 -W^-1 n (n^T v) /
  /// (n^T W^-1 n), n = S q J's left null vector (q Q's last column: one dot product, no
  /// fit) where the weights spread less than sqrt(W) J is ill-conditioned (16 kappa(T)),
  /// so that it is as accurate as the fit; otherwise J fit(v) - v.
  Vector6 residual(const Vector6& v) const noexcept;
  /// Numerical rank of sqrt(W) J.
  int rank() const noexcept { return rank_; }
  /// sum_i phi(sigma_i), phi(sigma) = smoothstep((sigma / |A|_F - 1e-5) / (1e-3 - 1e-5)):
  /// rank() where every singular value lies outside that band (singular values below 1e-5
  /// |A|_F count as 0, above 1e-3 |A|_F as 1), and continuous in J and W. A placement that
  /// is singular up to its solver's accuracy (~1e-9..1e-6) stays below the band.
  double soft_rank() const noexcept {
    check_soft();
    return filtered_ ? soft_rank_ : static_cast<double>(rank_);
  }

  /// One compute(J, w) of several.
  struct Job {
    WeightedProjector* projector;
    const Jacobian* J;
    const Vector6* w;
  };
  /// jobs[i].projector->compute(*jobs[i].J, *jobs[i].w) for i < count, the factorisations
  /// advanced step by step together (up to four at a time): each is a chain of dependent
  /// square roots and divisions, and interleaved the processor overlaps them. Same results.
  static void compute_all(const Job* jobs, int count) noexcept;

 private:
  void set(const Jacobian& J, const Vector6& w) noexcept;
  bool full_row_rank_certified() const noexcept;
  void factorise() const noexcept;  // a deferred factorisation, now
  int start_factorisation() const noexcept;
  bool pivot_step(int k) const noexcept;
  void finish_factorisation() const noexcept;
  void set_column() noexcept;  // m = 1: the closed form's W j and 1 / (j^T W j)
  bool well_conditioned() const noexcept;  // the factorisation's sigma_min >= kSoftRankHigh |A|_F
  void filter() const noexcept;            // the filtered pseudo-inverse's U, sigma^2, phi
  Vector6 filtered_range(const Vector6& x) const noexcept;  // (frame V^T)
  void check_soft() const noexcept;  // the soft rank's filter, once per factorisation

  // A = diag(s_) J_ Pi factorised: R (then T) on and above the diagonal of the first m_
  // columns of a_, zeros below it; Q's reflectors at full length in the columns of q_
  // (column k: k zeros, 1, then the reflector's tail), so applying one is a fixed-size
  // (vectorised) 6-vector operation; Z's reflectors in rows 0..r-1 of a_, right of column r
  // (mutable: the factors of a deferred factorisation are computed by the first query)
  using Columns = Eigen::Matrix<double, 6, kMaxDof>;
  mutable Columns a_;
  mutable Matrix6 q_;
  mutable Vector6 tau_, ztau_;  // Q's and Z's reflector coefficients
  mutable int perm_[kMaxDof];   // column k of A Pi is column perm_[k] of A
  int m_ = 0;             // columns of J
  Columns J_;             // J, or V^T J for a full W (first m_ columns)
  Vector6 w_;             // the diagonal weights s_, s_inv_, free_ were derived from
  Vector6 s_, s_inv_;     // sqrt of the (eigen)weights and its pseudo-inverse
  Vector6 free_;          // 1 where the weight is 0, else 0
  double s_min_ = kInf, s_max_ = 0.0;  // the least and largest of s_ > 0: kappa(S)
  int support_ = 0;       // weights > 0: the rank sqrt(W) J can have at most
  // every weight > 0 and rank 5: Q's last column (A^T q_null_ = 0)
  mutable Vector6 q_null_ = Vector6::Zero();
  mutable bool null_ready_ = false;  // q_null_ is residual()'s
  Matrix6 V_;             // eigenvectors of a full W (rotated_ only)
  mutable double n2_[kMaxDof] = {};  // while factorising: squared norms of rows k..5
  mutable double cut_ = 0.0;         // while factorising: (kPinvTolerance |R_00|)^2
  mutable double frob2_ = 0.0;       // |A|_F^2 of the factorisation
  mutable int rank_ = 0;
  bool w_finite_ = true;            // w_ finite
  mutable bool finite_ = true;      // J and W finite
  bool rotated_ = false;            // full W: everything is in the frame V^T
  mutable bool split_ = true;       // see compute_all()
  mutable bool deferred_ = false;   // rank_ certified, the factorisation not yet done
  bool column_ = false;             // m = 1: the closed form, no factorisation
  Vector6 wj_ = Vector6::Zero();    // m = 1: W j
  double inv_jwj_ = 0.0;            // m = 1: 1 / (j^T W j), 0 at rank 0
  // near a singular pose: A A^T = U diag(sigma^2) U^T and the factors phi (filtered_)
  mutable bool filtered_ = false;
  mutable bool soft_checked_ = false;   // filtered_ decided for this factorisation
  mutable bool certified_soft_ = false; // the certification shows sigma_k >= 1e-3 |A|_F
  mutable Matrix6 u_ = Matrix6::Identity();
  mutable Vector6 phi_ = Vector6::Zero();
  mutable Vector6 phi_sigma2_ = Vector6::Zero();  // phi_i / sigma_i^2 (0 where phi_i = 0)
  mutable double soft_rank_ = 0.0;
};

/// Range-space filter P(W) = W J (J^T W J)^+ J^T (eq. 5), W diagonal (a 6-vector).
Matrix6 range_filter(const Jacobian& J, const Vector6& W) noexcept;
/// Range-space filter with a full symmetric positive semi-definite weight matrix.
Matrix6 range_filter(const Jacobian& J, const Matrix6& W) noexcept;

/// Null-space filter N(W) = I - P(W) (eq. 9), with the soft rank (WeightedProjector::null).
Matrix6 null_filter(const Jacobian& J, const Vector6& W) noexcept;
Matrix6 null_filter(const Jacobian& J, const Matrix6& W) noexcept;

}  // namespace virtmech
