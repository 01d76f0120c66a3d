#include "virtmech/filters.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>


namespace virtmech {

namespace {

// Eigenvalues of a full weight matrix at or below this (relative to the largest) are the
// eigen-solver's rounding of a zero (its backward error is a few eps |W|): they count as 0.
constexpr double kWeightRoundoff = 64.0 * std::numeric_limits<double>::epsilon();

}  // namespace

// Why a complete orthogonal decomposition (column-pivoted Householder QR, plus the RZ step
// only when rank < m) and not an SVD: on 6 x m it is backward stable like the SVD, its
// pivots |R_kk| reveal the rank well enough for a 1e-10 cut (a Probe near its singular pose
// gives ~1e-6, repeated columns ~1e-16), and it costs a fraction of a JacobiSVD. It is
// written out as loops (the algorithm of Eigen's CompleteOrthogonalDecomposition, column
// norms recomputed rather than downdated): Eigen's general code takes ~1.7x as long at
// these sizes, and its Z products take dynamic-size temporaries.

WeightedProjector::WeightedProjector() noexcept
    : qr_(6, 0), tau_(Vector6::Zero()), ztau_(Vector6::Zero()), perm_{}, J_(6, 0),
      s_(Vector6::Zero()), s_inv_(Vector6::Zero()), free_(Vector6::Ones()),
      V_(Matrix6::Identity()) {}

void WeightedProjector::compute(const Jacobian& J, const Vector6& w) noexcept {
  rotated_ = false;
  J_ = J;
  for (int i = 0; i < 6; ++i) {
    const bool on = w[i] > 0.0;  // false for NaN too
    s_[i] = on ? std::sqrt(w[i]) : 0.0;
    s_inv_[i] = on ? 1.0 / s_[i] : 0.0;
    free_[i] = on ? 0.0 : 1.0;
  }
  finite_ = w.allFinite();
  factorise();
}

void WeightedProjector::compute(const Jacobian& J, const Matrix6& W) noexcept {
  bool diagonal = true;
  for (int j = 0; j < 6; ++j)
    for (int i = 0; i < 6; ++i) diagonal = diagonal && (i == j || W(i, j) == 0.0);
  if (diagonal) {
    compute(J, Vector6(W.diagonal()));
    return;
  }
  // P(W) = V P(diag(lambda); V^T J) V^T and the fit likewise: the same code in the frame V^T.
  // Rows (and columns) of W that are exactly 0 stay out of the eigen-problem, so V keeps
  // those axes exactly and they get exactly zero rows of P (the eigenvectors of a rank-
  // deficient W are known only to eps |W| / gap, which would otherwise leak into them).
  int idx[6], k = 0;
  for (int i = 0; i < 6; ++i)
    if (!W.row(i).isZero(0.0)) idx[k++] = i;
  JointMatrix Wk(k, k);
  for (int j = 0; j < k; ++j)
    for (int i = 0; i < k; ++i) Wk(i, j) = W(idx[i], idx[j]);
  Vector6 lambda = Vector6::Zero();
  V_.setIdentity();
  if (k > 0) {
    Eigen::SelfAdjointEigenSolver<JointMatrix> eig(Wk);  // fixed capacity: no heap
    const double cut = kWeightRoundoff * eig.eigenvalues().maxCoeff();
    for (int j = 0; j < k; ++j) {
      const double l = eig.eigenvalues()[j];
      lambda[idx[j]] = (l > cut && l > 0.0) ? l : 0.0;
      for (int i = 0; i < k; ++i) V_(idx[i], idx[j]) = eig.eigenvectors()(i, j);
    }
  }
  compute(V_.transpose() * J, lambda);
  finite_ = finite_ && W.allFinite();
  rotated_ = true;
}

namespace {

// Householder reflector H = I - tau [1; v] [1; v]^T with H [x0; x] = [beta; 0] (Eigen's
// makeHouseholder): x is overwritten with v, x0 with beta.
inline double make_reflector(double& x0, double* x, int stride, int n) noexcept {
  double tail = 0.0;
  for (int i = 0; i < n; ++i) tail += x[i * stride] * x[i * stride];
  if (tail <= std::numeric_limits<double>::min()) {
    for (int i = 0; i < n; ++i) x[i * stride] = 0.0;
    return 0.0;  // H = I
  }
  const double beta = x0 >= 0.0 ? -std::sqrt(x0 * x0 + tail) : std::sqrt(x0 * x0 + tail);
  const double u = beta - x0;
  const double inv = 1.0 / (beta * u);  // one division: v = x / (x0 - beta), tau = u / beta
  const double scale = -beta * inv;
  for (int i = 0; i < n; ++i) x[i * stride] *= scale;
  x0 = beta;
  return u * u * inv;
}

// y0, y (n entries, stride) <- H [y0; y] for the reflector (tau, v).
inline void reflect(double tau, const double* v, int vstride, double& y0, double* y, int ystride,
                    int n) noexcept {
  double d = y0;
  for (int i = 0; i < n; ++i) d += v[i * vstride] * y[i * ystride];
  d *= tau;
  y0 -= d;
  for (int i = 0; i < n; ++i) y[i * ystride] -= d * v[i * vstride];
}

// g <- H_{r-1} ... H_0 g = Q^T g (its first r entries are Q1^T g); a as in factorise().
inline void apply_qt(const double* a, const Vector6& tau, int r, Vector6& g) noexcept {
  for (int k = 0; k < r; ++k)
    reflect(tau[k], a + (k + 1) + 6 * k, 1, g[k], g.data() + k + 1, 1, 5 - k);
}

// g <- H_0 ... H_{r-1} g = Q g.
inline void apply_q(const double* a, const Vector6& tau, int r, Vector6& g) noexcept {
  for (int k = r - 1; k >= 0; --k)
    reflect(tau[k], a + (k + 1) + 6 * k, 1, g[k], g.data() + k + 1, 1, 5 - k);
}

}  // namespace

// The factorisation of A = S J and the choice of formula. With Pi_S = S^+ S (the weighted
// rows) and J^T Pi_S = A^T S^+:
//   P x = S Q1 [Q1^T S^+ x + T^-T (Z^T Pi^T J^T (I - Pi_S) x)_{0:r}]    (split_)
//   P x = S Q1 T^-T (Z^T Pi^T J^T x)_{0:r}                               (direct)
// Both are S (A^+)^T J^T x. The split one keeps the orthogonal part of P (S Q1 Q1^T S^+)
// to rounding times kappa(S) instead of kappa(A); the direct one is better only when the
// weights spread more than sqrt(W) J is ill-conditioned.
void WeightedProjector::factorise() noexcept {
  const int m = static_cast<int>(J_.cols());
  rank_ = 0;
  split_ = true;
  qr_.noalias() = s_.asDiagonal() * J_;
  finite_ = finite_ && qr_.allFinite();
  if (!finite_) return;
  double* a = qr_.data();  // column-major, 6 rows
  for (int j = 0; j < m; ++j) perm_[j] = j;
  // Q: H_{k-1} ... H_0 A Pi = [R11 R12; 0 R22], column pivoting, stopped once the largest
  // remaining column (|R_kk| to come) is at most kPinvTolerance |R_00|: R22 counts as 0
  const int steps = std::min(6, m);
  double cut = 0.0;  // (kPinvTolerance |R_00|)^2
  for (int k = 0; k < steps; ++k) {
    int p = k;
    double best = -1.0;  // the largest squared column norm, |R_kk|^2 to come
    for (int j = k; j < m; ++j) {
      double n2 = 0.0;
      for (int i = k; i < 6; ++i) n2 += a[i + 6 * j] * a[i + 6 * j];
      if (n2 > best) best = n2, p = j;
    }
    if (k == 0) cut = kPinvTolerance * kPinvTolerance * best;
    if (!(best > cut)) break;  // also |R_00| = 0
    if (p != k) {
      for (int i = 0; i < 6; ++i) std::swap(a[i + 6 * k], a[i + 6 * p]);
      std::swap(perm_[k], perm_[p]);
    }
    double* v = a + (k + 1) + 6 * k;
    tau_[k] = make_reflector(a[k + 6 * k], v, 1, 5 - k);
    for (int j = k + 1; j < m; ++j)
      reflect(tau_[k], v, 1, a[k + 6 * j], a + (k + 1) + 6 * j, 1, 5 - k);
    rank_ = k + 1;
  }
  const int r = rank_;
  // Z (only when r < m): [R11 R12] Z_{r-1} ... Z_0 = [T 0], Z_k acting on columns k, r..m-1
  for (int k = r - 1; k >= 0 && r < m; --k) {
    double* z = a + k + 6 * r;  // row k, columns r..m-1 (stride 6)
    ztau_[k] = make_reflector(a[k + 6 * k], z, 6, m - r);
    for (int i = 0; i < k; ++i) reflect(ztau_[k], z, 6, a[i + 6 * k], a + i + 6 * r, 6, m - r);
  }
  if (r == 0) return;
  double tmin = kInf, tmax = 0.0, smin = kInf, smax = 0.0;
  for (int i = 0; i < r; ++i) {
    tmin = std::min(tmin, std::abs(a[i + 6 * i]));
    tmax = std::max(tmax, std::abs(a[i + 6 * i]));
  }
  for (int i = 0; i < 6; ++i) {
    if (s_[i] > 0.0) {
      smin = std::min(smin, s_[i]);
      smax = std::max(smax, s_[i]);
    }
  }
  split_ = smax * tmin <= tmax * smin;  // kappa(S) <= kappa(T)
}

Vector6 WeightedProjector::range(const Vector6& x_in) const noexcept {
  if (!finite_) return Vector6::Constant(std::numeric_limits<double>::quiet_NaN());
  if (rank_ == 0) return Vector6::Zero();
  const Vector6 x = rotated_ ? Vector6(V_.transpose() * x_in) : x_in;
  const int r = rank_, m = static_cast<int>(J_.cols());
  const double* a = qr_.data();
  Vector6 g = Vector6::Zero();
  Vector6 xj = x;  // the part of x that goes through J^T
  if (split_) {
    g = s_inv_.cwiseProduct(x);
    apply_qt(a, tau_, r, g);
    xj = free_.cwiseProduct(x);
  }
  if (!xj.isZero(0.0)) {
    double c[kMaxDof];
    for (int i = 0; i < m; ++i) c[i] = J_.col(perm_[i]).dot(xj);  // Pi^T J^T xj
    for (int k = r - 1; k >= 0 && r < m; --k)  // Z^T c
      reflect(ztau_[k], a + k + 6 * r, 6, c[k], c + r, 1, m - r);
    for (int i = 0; i < r; ++i) {  // T^T t = c_{0:r}, forward substitution
      double t = c[i];
      for (int k = 0; k < i; ++k) t -= a[k + 6 * i] * c[k];
      c[i] = t / a[i + 6 * i];
      g[i] += c[i];
    }
  }
  g.tail(6 - r).setZero();
  apply_q(a, tau_, r, g);
  const Vector6 out = s_.cwiseProduct(g);  // exactly 0 on zero-weight rows
  return rotated_ ? Vector6(V_ * out) : out;
}

Vector6 WeightedProjector::null(const Vector6& x) const noexcept { return x - range(x); }

void WeightedProjector::fit(const Vector6& v, JointVector& theta_dot) const noexcept {
  const int r = rank_, m = static_cast<int>(J_.cols());
  theta_dot.setZero(m);
  if (!finite_) theta_dot.setConstant(std::numeric_limits<double>::quiet_NaN());
  if (!finite_ || r == 0) return;
  // A^+ S v = Pi Z [T^-1 (Q^T S v)_{0:r}; 0]
  const double* a = qr_.data();
  Vector6 g = s_.cwiseProduct(rotated_ ? Vector6(V_.transpose() * v) : v);
  apply_qt(a, tau_, r, g);
  double d[kMaxDof] = {};
  for (int i = r - 1; i >= 0; --i) {  // T d = g_{0:r}, back substitution
    double t = g[i];
    for (int k = i + 1; k < r; ++k) t -= a[i + 6 * k] * d[k];
    d[i] = t / a[i + 6 * i];
  }
  for (int k = 0; k < r && r < m; ++k) reflect(ztau_[k], a + k + 6 * r, 6, d[k], d + r, 1, m - r);
  for (int i = 0; i < m; ++i) theta_dot[perm_[i]] = d[i];
}

namespace {

template <typename Weights>
Matrix6 filter_matrix(const Jacobian& J, const Weights& W, bool range) noexcept {
  WeightedProjector p;
  p.compute(J, W);
  Matrix6 P;
  for (int k = 0; k < 6; ++k) P.col(k) = p.range(Vector6::Unit(k));
  return range ? P : Matrix6(Matrix6::Identity() - P);
}

}  // namespace

Matrix6 range_filter(const Jacobian& J, const Matrix6& W) noexcept {
  return filter_matrix(J, W, true);
}

Matrix6 range_filter(const Jacobian& J, const Vector6& W) noexcept {
  return filter_matrix(J, W, true);
}

Matrix6 null_filter(const Jacobian& J, const Matrix6& W) noexcept {
  return filter_matrix(J, W, false);
}

Matrix6 null_filter(const Jacobian& J, const Vector6& W) noexcept {
  return filter_matrix(J, W, false);
}

}  // namespace virtmech
