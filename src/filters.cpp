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

// The soft rank's band (WeightedProjector::soft_rank): a singular value sigma of A counts
// with smoothstep((sigma / |A|_F - kSoftRankLow) / (kSoftRankHigh - kSoftRankLow)). Below
// kSoftRankLow lie the singular values of placements singular up to their solver's accuracy
// (a LineGuide beyond its reach: 1e-13..1e-6); above kSoftRankHigh those of every pose 1e-2
// rad or more from a singular one (a Probe pressed 13 um into its plane, stylus square).
constexpr double kSoftRankLow = 1e-5;
constexpr double kSoftRankHigh = 1e-3;

// lambda_min(G) / tr(G) above this certifies every singular value of A at least
// kSoftRankHigh |A|_F (tr(G) = |A|_F^2): the soft rank's factors are all 1
constexpr double kCertifiedSoft = kSoftRankHigh * kSoftRankHigh;

}  // namespace

// Why a complete orthogonal decomposition (column-pivoted Householder QR, plus the RZ step
// only when rank < m) and not an SVD: on 6 x m it is backward stable like the SVD, its
// pivots |R_kk| reveal the rank well enough for a 1e-10 cut (a Probe near its singular pose
// gives ~1e-6, repeated columns ~1e-16), and it costs a fraction of a JacobiSVD. It is
// written out for the fixed height 6 (the algorithm of Eigen's
// CompleteOrthogonalDecomposition, column norms recomputed rather than downdated): Q's
// reflectors are kept at full length with zeros above their pivot row, so every column
// operation is one fixed-size 6-vector operation the compiler unrolls and vectorises (the
// zeros add exact zeros); Eigen's general code takes several times as long at these sizes.

WeightedProjector::WeightedProjector() noexcept
    : a_(Columns::Zero()), q_(Matrix6::Zero()), tau_(Vector6::Zero()), ztau_(Vector6::Zero()),
      perm_{}, J_(Columns::Zero()),
      w_(Vector6::Constant(std::numeric_limits<double>::quiet_NaN())), s_(Vector6::Zero()),
      s_inv_(Vector6::Zero()), free_(Vector6::Ones()), V_(Matrix6::Identity()) {}

void WeightedProjector::compute(const Jacobian& J, const Vector6& w) noexcept {
  const Job job{this, &J, &w};
  compute_all(&job, 1);
}

void WeightedProjector::set(const Jacobian& J, const Vector6& w) noexcept {
  rotated_ = false;
  null_ready_ = false;
  filtered_ = false;
  soft_checked_ = false;
  m_ = static_cast<int>(J.cols());
  for (int j = 0; j < m_; ++j) J_.col(j) = J.col(j);
  // a projector is mostly refactorised with the same weights (the controller keeps one per
  // weighting): their square roots are derived once (NaN weights never compare equal)
  if (!(w.array() == w_.array()).all()) {
    for (int i = 0; i < 6; ++i) {
      const bool on = w[i] > 0.0;  // false for NaN too
      s_[i] = on ? std::sqrt(w[i]) : 0.0;
      s_inv_[i] = on ? 1.0 / s_[i] : 0.0;
      free_[i] = on ? 0.0 : 1.0;
    }
    w_ = w;
    w_finite_ = w.allFinite();
    s_min_ = kInf;
    s_max_ = 0.0;
    support_ = 0;
    for (int i = 0; i < 6; ++i) {
      if (s_[i] > 0.0) {
        ++support_;
        s_min_ = std::min(s_min_, s_[i]);
        s_max_ = std::max(s_max_, s_[i]);
      }
    }
  }
  finite_ = w_finite_;
  column_ = m_ == 1;
  if (column_) set_column();
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

// kFrom[k]: 1 in rows k..5, 0 above; multiplying by it keeps the rows from k on
alignas(16) constexpr double kFrom[7][6] = {{1, 1, 1, 1, 1, 1}, {0, 1, 1, 1, 1, 1},
                                            {0, 0, 1, 1, 1, 1}, {0, 0, 0, 1, 1, 1},
                                            {0, 0, 0, 0, 1, 1}, {0, 0, 0, 0, 0, 1},
                                            {0, 0, 0, 0, 0, 0}};

inline Eigen::Map<const Vector6, Eigen::Aligned16> rows_from(int k) noexcept {
  return Eigen::Map<const Vector6, Eigen::Aligned16>(kFrom[k]);
}

// Householder reflector H = I - tau [1; v] [1; v]^T with H [x0; x] = [beta; 0] (Eigen's
// makeHouseholder), for the short row vectors of the RZ step: x is overwritten with v, x0
// with beta.
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

// g <- H_k g for Q's full-length reflector k
inline void apply_reflector(const Matrix6& q, const Vector6& tau, int k, Vector6& g) noexcept {
  g -= (tau[k] * q.col(k).dot(g)) * q.col(k);
}

// g <- H_{r-1} ... H_0 g = Q^T g (its first r entries are Q1^T g).
inline void apply_qt(const Matrix6& q, const Vector6& tau, int r, Vector6& g) noexcept {
  for (int k = 0; k < r; ++k) apply_reflector(q, tau, k, g);
}

// g <- H_0 ... H_{r-1} g = Q g.
inline void apply_q(const Matrix6& q, const Vector6& tau, int r, Vector6& g) noexcept {
  for (int k = r - 1; k >= 0; --k) apply_reflector(q, tau, k, g);
}

}  // namespace

// The factorisation of A = S J and the choice of formula. With Pi_S = S^+ S (the weighted
// rows) and J^T Pi_S = A^T S^+:
//   P x = S Q1 [Q1^T S^+ x + T^-T (Z^T Pi^T J^T (I - Pi_S) x)_{0:r}]    (split_)
//   P x = S Q1 T^-T (Z^T Pi^T J^T x)_{0:r}                               (direct)
// Both are S (A^+)^T J^T x. The split one keeps the orthogonal part of P (S Q1 Q1^T S^+)
// to rounding times kappa(S) instead of kappa(A); the direct one is better only when the
// weights spread more than sqrt(W) J is ill-conditioned.
void WeightedProjector::compute_all(const Job* jobs, int count) noexcept {
  constexpr int kMaxJobs = 4;  // at a time
  if (count > kMaxJobs) {
    compute_all(jobs + kMaxJobs, count - kMaxJobs);
    count = kMaxJobs;
  }
  int steps[kMaxJobs];
  bool factorising = false;
  for (int i = 0; i < count; ++i) {
    WeightedProjector& p = *jobs[i].projector;
    p.set(*jobs[i].J, *jobs[i].w);
    if (p.column_) {
      steps[i] = 0;
      continue;
    }
    p.deferred_ = p.full_row_rank_certified();
    if (p.deferred_) p.rank_ = p.support_;
    steps[i] = p.deferred_ ? 0 : p.start_factorisation();
    factorising = factorising || !p.deferred_;
  }
  if (!factorising) return;  // (single columns in closed form, certified ranks deferred)
  // step k of every factorisation before step k + 1 of any: the steps of different
  // factorisations are independent, so their latencies overlap
  for (int k = 0; k < 6; ++k) {
    bool any = false;
    for (int i = 0; i < count; ++i) {
      if (k < steps[i] && !jobs[i].projector->pivot_step(k)) steps[i] = k;
      any = any || k + 1 < steps[i];
    }
    if (!any) break;
  }
  for (int i = 0; i < count; ++i) {
    const WeightedProjector& p = *jobs[i].projector;
    if (!p.deferred_ && !p.column_) p.finish_factorisation();
  }
}

// One column j: A = S j has rank 1 unless it is 0 (the QR's cut is relative to |R_00| = |A|,
// so it keeps any A != 0), and P(W) = W j j^T / (j^T W j), the fit (j^T W v) / (j^T W j).
// A squared norm that underflows to 0 or overflows is rank 0, as in the QR.
void WeightedProjector::set_column() noexcept {
  deferred_ = false;
  const Vector6 a = s_.cwiseProduct(J_.col(0));
  finite_ = finite_ && a.allFinite();
  const double jwj = a.squaredNorm();
  rank_ = finite_ && jwj > 0.0 && jwj <= std::numeric_limits<double>::max() ? 1 : 0;
  wj_ = s_.cwiseProduct(a);
  inv_jwj_ = rank_ ? 1.0 / jwj : 0.0;
}

namespace {

// G = A_w A_w^T for the k rows of s > 0 of A = diag(s) J (J's first m columns), its lower
// triangle; returns tr(G)
double weighted_gram(const Eigen::Matrix<double, 6, kMaxDof>& J, const Vector6& s, int m,
                     int k, double (&G)[6][6]) noexcept {
  int rows[6];
  int c = 0;
  for (int i = 0; i < 6; ++i) {
    if (s[i] > 0.0) rows[c++] = i;
  }
  double tr = 0.0;
  for (int a = 0; a < k; ++a) {
    for (int b = 0; b <= a; ++b) {
      double g = 0.0;
      for (int j = 0; j < m; ++j) g += J(rows[a], j) * J(rows[b], j);
      G[a][b] = s[rows[a]] * s[rows[b]] * g;
    }
    tr += G[a][a];
  }
  return tr;
}

// det(G) by cofactors (k <= 3), without the factorisation's chain of divisions: G is a Gram
// matrix (eigenvalues >= -eps tr by rounding), so det(G) > 1e-11 tr^k / (k - 1)^(k - 1)
// >> eps^2 tr^k rules out a pair of negative ones: G is positive definite, as the LDL^T
// of gram_certified_ldl checks, and its determinant has errors of a few eps tr^k
// `soft`: lambda_min(G) / tr(G) shown above kCertifiedSoft as well
bool gram_certified_cofactors(const double (&G)[6][6], int k, double tr, bool& soft) noexcept {
  if (k == 1) {
    soft = true;  // lambda_min = tr
    return true;
  }
  if (k == 2) {
    const double det2 = G[0][0] * G[1][1] - G[1][0] * G[1][0];
    soft = det2 > kCertifiedSoft * tr * tr;
    return det2 > 1e-11 * tr * tr;
  }
  const double det3 = G[0][0] * (G[1][1] * G[2][2] - G[2][1] * G[2][1]) -
                      G[1][0] * (G[1][0] * G[2][2] - G[2][1] * G[2][0]) +
                      G[2][0] * (G[1][0] * G[2][1] - G[1][1] * G[2][0]);
  soft = 4.0 * det3 > kCertifiedSoft * tr * tr * tr;
  return 4.0 * det3 > 1e-11 * tr * tr * tr;
}

// det(G / tr) from an LDL^T of G / tr (false where a pivot is not positive), then
// lambda_min / tr >= det_n (k - 1)^(k - 1) > 1e-11
bool gram_certified_ldl(const double (&G)[6][6], int k, double tr, bool& soft) noexcept {
  double L[6][6], D[6], det = 1.0;
  for (int j = 0; j < k; ++j) {
    double d = G[j][j] / tr;
    for (int p = 0; p < j; ++p) d -= L[j][p] * L[j][p] * D[p];
    if (!(d > 0.0)) return false;
    D[j] = d;
    det *= d;
    for (int i = j + 1; i < k; ++i) {
      double l = G[i][j] / tr;
      for (int p = 0; p < j; ++p) l -= L[i][p] * L[j][p] * D[p];
      L[i][j] = l / d;
    }
  }
  double spread = 1.0;
  for (int i = 1; i < k; ++i) spread *= static_cast<double>(k - 1);
  soft = det * spread > kCertifiedSoft;
  return det * spread > 1e-11;
}

}  // namespace

// True when the Gram matrix G = A_w A_w^T of A's k weighted rows shows them of full row rank
// with a margin: lambda_min(G) >= det(G) / (tr(G) / (k - 1))^(k - 1) (the other k - 1
// eigenvalues' product is at most that, by AM-GM) above 1e-11 tr(G), i.e. sigma_k(A) >
// 3e-6 |A|_F, where the QR's cut is 1e-10 |R_00| <= 1e-10 |A|_F: the QR would find rank k
// (after j < k steps the remaining columns' norms reach sigma_k / sqrt(m)). det(G) from
// an LDL^T of G / tr(G) (relative errors ~ k eps kappa(G) <= 1e-4 here). Above
// kCertifiedSoft tr(G) (certified_soft_) no singular value lies in the soft rank's band.
bool WeightedProjector::full_row_rank_certified() const noexcept {
  const int k = support_, m = m_;
  certified_soft_ = false;
  if (!finite_ || k == 0 || k > m) return false;
  // every entry finite, the zero-weighted rows' too (a factorisation would find 0 * NaN and
  // give NaN results, as documented)
  if (!J_.leftCols(m).allFinite()) return false;
  double G[6][6];
  const double tr = weighted_gram(J_, s_, m, k, G);
  if (!(tr > 0.0) || !std::isfinite(tr)) return false;  // also NaN
  return k <= 3 ? gram_certified_cofactors(G, k, tr, certified_soft_)
                : gram_certified_ldl(G, k, tr, certified_soft_);
}

void WeightedProjector::factorise() const noexcept {
  if (!deferred_) return;
  deferred_ = false;
  const int steps = start_factorisation();
  for (int k = 0; k < steps; ++k) {
    if (!pivot_step(k)) break;
  }
  finish_factorisation();
}

// A = S J, its column norms; the number of pivot steps to try (0 if not finite)
int WeightedProjector::start_factorisation() const noexcept {
  const int m = m_;
  rank_ = 0;
  split_ = true;
  // n2_[j]: squared norm of column j's rows k..5, recomputed as each step updates the column
  Vector6 nonfinite = Vector6::Zero();  // sum of x - x: 0, or NaN if any x is not finite
  for (int j = 0; j < m; ++j) {
    const Vector6 col = s_.cwiseProduct(J_.col(j));
    a_.col(j) = col;
    nonfinite += col - col;
    n2_[j] = col.squaredNorm();
    perm_[j] = j;
  }
  frob2_ = 0.0;
  for (int j = 0; j < m; ++j) frob2_ += n2_[j];
  finite_ = finite_ && (nonfinite.array() == 0.0).all();
  if (!finite_) return 0;
  cut_ = 0.0;
  return std::min(6, m);
}

// Q: H_{k-1} ... H_0 A Pi = [R11 R12; 0 R22], column pivoting, stopped once the largest
// remaining column (|R_kk| to come) is at most kPinvTolerance |R_00|: R22 counts as 0.
// Step k; false when it stops.
[[gnu::always_inline]] inline bool WeightedProjector::pivot_step(int k) const noexcept {
  const int m = m_;
  double* n2 = n2_;
  int p = k;
  double best = n2[k];  // the largest squared column norm, |R_kk|^2 to come
  for (int j = k + 1; j < m; ++j) {
    if (n2[j] > best) best = n2[j], p = j;
  }
  if (k == 0) cut_ = kPinvTolerance * kPinvTolerance * best;  // (kPinvTolerance |R_00|)^2
  if (!(best > cut_)) return false;  // also |R_00| = 0
  if (p != k) {
    a_.col(k).swap(a_.col(p));
    std::swap(perm_[k], perm_[p]);
    n2[p] = n2[k];
  }
  // H_k [x0; x] = [beta; 0] for column k's rows k..5 (Eigen's makeHouseholder), with
  // x0^2 + |x|^2 = best. H_k = I - tau [1; v] [1; v]^T, v = scale x: the products x^T y of
  // the columns y it updates do not wait for the square root and the division
  const auto below_k = rows_from(k + 1);
  const Vector6 x = a_.col(k).cwiseProduct(below_k);
  double xy[kMaxDof];
  for (int j = k + 1; j < m; ++j) xy[j] = x.dot(a_.col(j));
  const double x0 = a_(k, k), tail = x.squaredNorm();
  double scale = 0.0;
  if (tail <= std::numeric_limits<double>::min()) {
    tau_[k] = 0.0;  // H = I
  } else {
    const double beta = x0 >= 0.0 ? -std::sqrt(best) : std::sqrt(best);
    const double u = beta - x0;
    const double inv = 1.0 / (beta * u);  // one division: v = x / (x0 - beta), tau = u / beta
    scale = -beta * inv;
    tau_[k] = u * u * inv;
    a_(k, k) = beta;
  }
  auto v = q_.col(k);
  v = scale * x;
  v[k] = 1.0;
  a_.col(k) -= x;  // zeros below the diagonal
  for (int j = k + 1; j < m; ++j) {
    auto col = a_.col(j);
    col -= (tau_[k] * (col[k] + scale * xy[j])) * v;  // H_k y, v^T y = y_k + scale x^T y
    n2[j] = col.cwiseProduct(below_k).squaredNorm();
  }
  rank_ = k + 1;
  return true;
}

// Z (only when r < m): [R11 R12] Z_{r-1} ... Z_0 = [T 0], Z_k acting on columns k, r..m-1;
// then the choice of formula
void WeightedProjector::finish_factorisation() const noexcept {
  if (!finite_) return;
  const int m = m_;
  const int r = rank_;
  double* a = a_.data();  // column-major, 6 rows
  for (int k = r - 1; k >= 0 && r < m; --k) {
    double* z = a + k + 6 * r;  // row k, columns r..m-1 (stride 6)
    ztau_[k] = make_reflector(a[k + 6 * k], z, 6, m - r);
    for (int i = 0; i < k; ++i) reflect(ztau_[k], z, 6, a[i + 6 * k], a + i + 6 * r, 6, m - r);
  }
  null_ready_ = false;
  if (r == 5 && support_ == 6) {  // the left null space of A, for residual()
    q_null_ = Vector6::Unit(5);
    apply_q(q_, tau_, 5, q_null_);
  }
  if (r == 0) return;
  double tmin = kInf, tmax = 0.0;
  for (int i = 0; i < r; ++i) {
    tmin = std::min(tmin, std::abs(a_(i, i)));
    tmax = std::max(tmax, std::abs(a_(i, i)));
  }
  split_ = s_max_ * tmin <= tmax * s_min_;  // kappa(S) <= kappa(T)
  // residual()'s -S^-1 q (q^T S v) errs by eps kappa(S) |v| (q^T S v is small, its terms are
  // not, and S^-1 scales it back): within 16 times the fit's eps kappa(A) where kappa(S) <=
  // 16 kappa(T) (kappa(T) = |R_00| / |R_44| <= kappa(A))
  null_ready_ = r == 5 && support_ == 6 && s_max_ * tmin <= 16.0 * tmax * s_min_;
}

// True where every singular value the factorisation kept is at least kSoftRankHigh |A|_F
// (those it cut are below kSoftRankLow |A|_F): the soft rank's factors are 0 or 1 and the
// factorisation's formulas are the filtered ones. sigma_min(T) >= 1 / |T^-1|_F.
bool WeightedProjector::well_conditioned() const noexcept {
  const int r = rank_;
  if (!finite_ || r == 0) return true;
  // T^-1 column by column (back substitution), its squared Frobenius norm
  double inv[6][6];  // inv[j][i]: row i of column j
  double norm2 = 0.0;
  for (int j = 0; j < r; ++j) {
    for (int i = r - 1; i >= 0; --i) {
      double t = i == j ? 1.0 : 0.0;
      for (int k = i + 1; k <= j; ++k) t -= a_(i, k) * inv[j][k];
      inv[j][i] = i > j ? 0.0 : t / a_(i, i);
      norm2 += inv[j][i] * inv[j][i];
    }
  }
  return norm2 * kCertifiedSoft * frob2_ <= 1.0;
}

// A A^T = U diag(sigma^2) U^T (6 x 6, fixed size: no allocation), phi_i of sigma_i / |A|_F.
void WeightedProjector::filter() const noexcept {
  Matrix6 G = Matrix6::Zero();
  for (int j = 0; j < m_; ++j) {
    const Vector6 a = s_.cwiseProduct(J_.col(j));
    G.noalias() += a * a.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Matrix6> eig(G);
  const double frob2 = G.trace();
  u_ = eig.eigenvectors();
  soft_rank_ = 0.0;
  for (int i = 0; i < 6; ++i) {
    const double lambda = std::max(eig.eigenvalues()[i], 0.0);
    const double rho = frob2 > 0.0 ? std::sqrt(lambda / frob2) : 0.0;
    const double t =
        std::clamp((rho - kSoftRankLow) / (kSoftRankHigh - kSoftRankLow), 0.0, 1.0);
    phi_[i] = t * t * (3.0 - 2.0 * t);  // smoothstep: C1 in sigma
    phi_sigma2_[i] = phi_[i] > 0.0 ? phi_[i] / lambda : 0.0;
    soft_rank_ += phi_[i];
  }
  filtered_ = true;
}

// S (A_phi^+)^T J^T x = S U [diag(phi) U^T S^+ x + diag(phi / sigma^2) U^T A J^T (I - Pi_S) x]
// (A^T S^+ is J^T on the weighted axes; U^T A = diag(sigma) V^T), in the frame V^T.
Vector6 WeightedProjector::filtered_range(const Vector6& x) const noexcept {
  Vector6 g = phi_.cwiseProduct(u_.transpose() * s_inv_.cwiseProduct(x));
  const Vector6 xf = free_.cwiseProduct(x);
  if (!xf.isZero(0.0)) {
    Vector6 ajx = Vector6::Zero();  // A J^T xf = S J (J^T xf)
    for (int j = 0; j < m_; ++j) ajx += J_.col(j).dot(xf) * J_.col(j);
    g += phi_sigma2_.cwiseProduct(u_.transpose() * s_.cwiseProduct(ajx));
  }
  return s_.cwiseProduct(u_ * g);
}

Vector6 WeightedProjector::range(const Vector6& x_in) const noexcept {
  if (!finite_) return Vector6::Constant(std::numeric_limits<double>::quiet_NaN());
  if (rank_ == 0) return Vector6::Zero();
  const Vector6 x = rotated_ ? Vector6(V_.transpose() * x_in) : x_in;
  if (column_) {
    const Vector6 out = (J_.col(0).dot(x) * inv_jwj_) * wj_;
    return rotated_ ? Vector6(V_ * out) : out;
  }
  if (rank_ == support_ && free_.cwiseProduct(x).isZero(0.0)) {
    // x on the weighted axes only, and sqrt(W) J of full row rank on them: Q1 spans those
    // axes, so P x = S Q1 Q1^T S^+ x is x itself (exactly; the zero-weight rows are 0)
    return rotated_ ? Vector6(V_ * x) : x;
  }
  factorise();  // (a certified rank is the factorisation's: rank_ stays)
  const int r = rank_, m = m_;
  const double* a = a_.data();
  Vector6 g = Vector6::Zero();
  Vector6 xj = x;  // the part of x that goes through J^T
  if (split_) {
    g = s_inv_.cwiseProduct(x);
    apply_qt(q_, tau_, r, g);
    xj = free_.cwiseProduct(x);
  }
  g = g.cwiseProduct(Vector6::Ones() - rows_from(r));  // Q1^T: the first r entries
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
  apply_q(q_, tau_, r, g);
  const Vector6 out = s_.cwiseProduct(g);  // exactly 0 on zero-weight rows
  return rotated_ ? Vector6(V_ * out) : out;
}

// The soft rank's filter, decided once per factorisation (on the first query that needs it):
// none where the certification or the factorisation shows every singular value above the
// band, else the eigen-decomposition of A A^T.
void WeightedProjector::check_soft() const noexcept {
  if (soft_checked_) return;
  soft_checked_ = true;
  filtered_ = false;
  if (column_ || (deferred_ && certified_soft_)) return;
  factorise();
  if (!well_conditioned()) filter();
}

Vector6 WeightedProjector::null(const Vector6& x) const noexcept {
  check_soft();
  if (!filtered_ || !finite_) return x - range(x);
  const Vector6 xr = rotated_ ? Vector6(V_.transpose() * x) : x;
  const Vector6 p = filtered_range(xr);
  return x - (rotated_ ? Vector6(V_ * p) : p);
}

Vector6 WeightedProjector::soft_range(const Vector6& x) const noexcept {
  check_soft();
  if (!filtered_ || !finite_) return range(x);
  const Vector6 xr = rotated_ ? Vector6(V_.transpose() * x) : x;
  const Vector6 p = filtered_range(xr);
  return rotated_ ? Vector6(V_ * p) : p;
}

void WeightedProjector::fit(const Vector6& v, JointVector& theta_dot) const noexcept {
  factorise();
  const int r = rank_, m = m_;
  theta_dot.setZero(m);
  if (!finite_) theta_dot.setConstant(std::numeric_limits<double>::quiet_NaN());
  if (!finite_ || r == 0) return;
  if (column_) {
    theta_dot[0] = wj_.dot(rotated_ ? Vector6(V_.transpose() * v) : v) * inv_jwj_;
    return;
  }
  // A^+ S v = Pi Z [T^-1 (Q^T S v)_{0:r}; 0]
  const double* a = a_.data();
  Vector6 g = s_.cwiseProduct(rotated_ ? Vector6(V_.transpose() * v) : v);
  apply_qt(q_, tau_, r, g);
  double d[kMaxDof] = {};
  for (int i = r - 1; i >= 0; --i) {  // T d = g_{0:r}, back substitution
    double t = g[i];
    for (int k = i + 1; k < r; ++k) t -= a[i + 6 * k] * d[k];
    d[i] = t / a[i + 6 * i];
  }
  for (int k = 0; k < r && r < m; ++k) reflect(ztau_[k], a + k + 6 * r, 6, d[k], d + r, 1, m - r);
  for (int i = 0; i < m; ++i) theta_dot[perm_[i]] = d[i];
}

Vector6 WeightedProjector::residual(const Vector6& v_in) const noexcept {
  if (support_ != 6 || rank_ != 6) factorise();
  if (!finite_) return Vector6::Constant(std::numeric_limits<double>::quiet_NaN());
  const Vector6 v = rotated_ ? Vector6(V_.transpose() * v_in) : v_in;
  Vector6 out;
  if (column_) {
    // fit()'s theta_dot, written out (rank 0: none, also for a v that is not finite)
    out = rank_ ? Vector6((wj_.dot(v) * inv_jwj_) * J_.col(0) - v) : Vector6(-v);
  } else if (support_ == 6 && rank_ == 6) {
    out.setZero();  // A of full row rank: every twist followed
  } else if (null_ready_) {
    // S (J theta_dot - v) = -(I - Q1 Q1^T) S v = -Q2 Q2^T S v, Q2 Q's last column
    out = -q_null_.dot(s_.cwiseProduct(v)) * s_inv_.cwiseProduct(q_null_);
  } else {
    JointVector theta_dot;
    fit(v_in, theta_dot);  // (fit rotates v_in itself)
    out = -v;
    for (int j = 0; j < m_; ++j) out += theta_dot[j] * J_.col(j);
  }
  return rotated_ ? Vector6(V_ * out) : out;
}

namespace {

template <typename Weights>
Matrix6 filter_matrix(const Jacobian& J, const Weights& W, bool range) noexcept {
  WeightedProjector p;
  p.compute(J, W);
  Matrix6 F;
  for (int k = 0; k < 6; ++k) F.col(k) = range ? p.range(Vector6::Unit(k)) : p.null(Vector6::Unit(k));
  return F;
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
