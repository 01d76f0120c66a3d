#include "virtmech/filters.hpp"

#include <Eigen/Eigenvalues>

namespace virtmech {

void symmetric_pinv(const JointMatrix& A, JointMatrix& A_pinv) noexcept {
  const Eigen::Index n = A.rows();
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
