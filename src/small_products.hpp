// J x and J^T y for the cycle's 6 x n Jacobians (n <= kMaxDof), written as column loops: with
// a run-time column count Eigen takes its general matrix-vector kernel, whose set-up costs
// more than the arithmetic at these sizes. Internal to the core.
#pragma once

#include "virtmech/types.hpp"

namespace virtmech::detail {

/// J x, x with J.cols() entries.
inline Vector6 jacobian_times(const Jacobian& J, const double* x) noexcept {
  Vector6 y = Vector6::Zero();
  for (Eigen::Index i = 0; i < J.cols(); ++i) y += x[i] * J.col(i);
  return y;
}

/// J^T y into out (resized to J.cols()).
inline void jacobian_transpose_times(const Jacobian& J, const Vector6& y,
                                     JointVector& out) noexcept {
  out.resize(J.cols());
  for (Eigen::Index i = 0; i < J.cols(); ++i) out[i] = J.col(i).dot(y);
}

}  // namespace virtmech::detail
