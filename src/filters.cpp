#include "virtmech/filters.hpp"

#include <Eigen/Eigenvalues>

#include "small_cholesky.hpp"

namespace virtmech {

namespace {

// A^-1 by Cholesky when that is provably the pseudo-inverse: A positive definite with
// lambda_min / lambda_max > kPinvTolerance, i.e. no eigenvalue the eigen-decomposition would
// cut. lambda_max <= |A|_F and 1 / lambda_min <= |A^-1|_F, so |A|_F |A^-1|_F below (half)
// 1 / kPinvTolerance is a sufficient test, pessimistic by at most the dimension.
bool inverse_if_well_conditioned(const JointMatrix& A, JointMatrix& A_inv) noexcept {
  JointMatrix L = A;
  if (!detail::cholesky_in_place(L)) return false;
  detail::cholesky_inverse(L, A_inv);
  const double kappa = A.norm() * A_inv.norm();  // Frobenius norms
  return kappa < 0.5 / kPinvTolerance;           // false for NaN too
}

}  // namespace

void symmetric_pinv(const JointMatrix& A, JointMatrix& A_pinv) noexcept {
  const Eigen::Index n = A.rows();
  if (n == 1) {
    A_pinv.resize(1, 1);
    A_pinv(0, 0) = A(0, 0) > 0.0 ? 1.0 / A(0, 0) : 0.0;  // the eigen rule for 1 x 1
    return;
  }
  if (n > 1 && inverse_if_well_conditioned(A, A_pinv)) return;
  A_pinv.setZero(n, n);
  if (n == 0) return;
  Eigen::SelfAdjointEigenSolver<JointMatrix> eig(A);  // fixed capacity: no heap
  const auto& lambda = eig.eigenvalues();
  const double lmax = lambda.cwiseAbs().maxCoeff();
  if (!(lmax > 0.0)) return;
  const double cut = kPinvTolerance * lmax;
  const auto& V = eig.eigenvectors();
  for (Eigen::Index k = 0; k < n; ++k) {
    if (lambda[k] > cut) A_pinv.noalias() += (1.0 / lambda[k]) * V.col(k) * V.col(k).transpose();
  }
}

Matrix6 range_filter(const Jacobian& J, const Matrix6& W) noexcept {
  const Jacobian WJ = W * J;
  const JointMatrix H = J.transpose() * WJ;
  JointMatrix Hp;
  symmetric_pinv(H, Hp);
  return WJ * Hp * J.transpose();
}

Matrix6 range_filter(const Jacobian& J, const Vector6& W) noexcept {
  return range_filter(J, Matrix6(W.asDiagonal()));
}

Matrix6 null_filter(const Jacobian& J, const Matrix6& W) noexcept {
  return Matrix6::Identity() - range_filter(J, W);
}

Matrix6 null_filter(const Jacobian& J, const Vector6& W) noexcept {
  return Matrix6::Identity() - range_filter(J, W);
}

}  // namespace virtmech
