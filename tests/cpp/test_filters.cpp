// WeightedProjector: the filters (eqs. 5, 9) and the weighted fit from an orthogonal
// factorisation of sqrt(W) J. Properties on random and near-singular cases, edge cases, and
// no heap use. Norms are spectral (2-norms).
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "heap_counter.hpp"
#include "virtmech/filters.hpp"

using namespace virtmech;

namespace {

constexpr double kTol = 1e-12;  // rounding, relative (the factorisation never squares kappa)

const void* volatile g_sink = nullptr;  // keeps the control allocation from being elided

using Dyn = Eigen::MatrixXd;

double norm2(const Dyn& M) {
  if (M.size() == 0) return 0.0;
  return Eigen::JacobiSVD<Dyn>(M).singularValues()(0);
}

// Rank with singular values below kPinvTolerance of the largest counted as 0; -1 when one lies
// within a factor 1e3 of that cut (pivots and singular values may then decide differently).
int svd_rank(const Dyn& M) {
  if (M.size() == 0) return 0;
  const Eigen::VectorXd s = Eigen::JacobiSVD<Dyn>(M).singularValues();
  if (!(s(0) > 0.0)) return 0;
  int r = 0;
  for (Eigen::Index i = 0; i < s.size(); ++i) {
    const double rel = s(i) / s(0);
    if (rel > kPinvTolerance * 1e-3 && rel < kPinvTolerance * 1e3) return -1;
    r += rel > kPinvTolerance;
  }
  return r;
}

Matrix6 range_matrix(const WeightedProjector& p) {
  Matrix6 P;
  for (int k = 0; k < 6; ++k) P.col(k) = p.range(Vector6::Unit(k));
  return P;
}

// W J (J^T W J)^+ J^T = S (A^+)^T J^T, A = S J, by an SVD of A with rank r: an independent
// algorithm (the test may allocate).
Dyn svd_reference(const Dyn& S, const Dyn& J, int r) {
  if (r == 0) return Dyn::Zero(6, 6);
  const Dyn A = S * J;
  Eigen::JacobiSVD<Dyn> svd(A, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Dyn U = svd.matrixU().leftCols(r), V = svd.matrixV().leftCols(r);
  const Eigen::VectorXd s = svd.singularValues().head(r);
  return S * U * s.cwiseInverse().asDiagonal() * V.transpose() * J.transpose();
}

// N_phi x = x - S (A_phi^+)^T J^T x, A = S J, A_phi^+ = V diag(phi_i / sigma_i) U^T with the
// soft rank's factors phi_i = smoothstep((sigma_i / |A|_F - 1e-5) / (1e-3 - 1e-5)), by an SVD
// of A: an independent algorithm. `smallest`: the least sigma_i / |A|_F of the rank's.
Vector6 soft_null_reference(const Dyn& S, const Dyn& J, const Vector6& x, double& smallest) {
  smallest = 1.0;
  const Dyn A = S * J;
  const double frob = A.norm();
  if (A.cols() == 0 || !(frob > 0.0)) return x;
  Eigen::JacobiSVD<Dyn> svd(A, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::VectorXd s = svd.singularValues();
  Eigen::VectorXd f = Eigen::VectorXd::Zero(s.size());
  for (Eigen::Index i = 0; i < s.size(); ++i) {
    const double t = std::clamp((s(i) / frob - 1e-5) / (1e-3 - 1e-5), 0.0, 1.0);
    const double phi = t * t * (3.0 - 2.0 * t);
    f(i) = phi > 0.0 ? phi / s(i) : 0.0;
    if (s(i) > kPinvTolerance * s(0)) smallest = std::min(smallest, s(i) / frob);
  }
  const Vector6 p = S * svd.matrixU() * f.asDiagonal() * svd.matrixV().transpose() *
                    J.transpose() * x;
  return x - p;
}

// null(x) against the reference: x - range(x) exactly where every singular value is well
// above the soft rank's band, else to rounding relative to the filtered projection's size.
void check_null(const WeightedProjector& p, const Dyn& S, const Dyn& J, const Vector6& x,
                const std::string& what) {
  double smallest = 1.0;
  const Vector6 ref = soft_null_reference(S, J, x, smallest);
  if (smallest >= 1e-2) {
    EXPECT_EQ(p.null(x), x - p.range(x)) << what;
  } else {
    EXPECT_LE((p.null(x) - ref).norm(), 1e-7 * (x.norm() + (x - ref).norm())) << what;
  }
}

struct Case {
  Jacobian J;
  Vector6 w;
};

// Like the Python strategy: entries 0 or +-1e-3 .. 10 (log-uniform), 0 .. 8 columns, sometimes
// a repeated, scaled-copy or zero column, or planar rows zeroed; weights 0 or 0.01 .. 10.
Case random_case(std::mt19937& rng, int trial) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const int m = trial % (kMaxDof + 1);
  Case c{Jacobian(6, m), Vector6()};
  for (int j = 0; j < m; ++j) {
    for (int i = 0; i < 6; ++i) {
      const double x = u(rng);
      c.J(i, j) = x < 0.15 ? 0.0 : (x < 0.575 ? -1.0 : 1.0) * std::pow(10.0, -3.0 + 4.0 * u(rng));
    }
  }
  const int kind = (trial / (kMaxDof + 1)) % 5;
  if (kind == 1 && m > 1) c.J.col(m - 1) = c.J.col(0);
  if (kind == 2 && m > 1) c.J.col(m - 1) = c.J.col(0) * (4.0 * u(rng) - 2.0);
  if (kind == 3 && m > 0) c.J.col(trial % m).setZero();
  if (kind == 4) c.J.row(2).setZero(), c.J.row(3).setZero(), c.J.row(4).setZero();
  for (int i = 0; i < 6; ++i) c.w[i] = u(rng) < 0.3 ? 0.0 : std::pow(10.0, -2.0 + 3.0 * u(rng));
  return c;
}

Dyn random_orthogonal(std::mt19937& rng, int n) {
  std::normal_distribution<double> g(0.0, 1.0);
  Dyn G(n, n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) G(i, j) = g(rng);
  return Eigen::HouseholderQR<Dyn>(G).householderQ() * Dyn::Identity(n, n);
}

// The properties of P(W), N(W) for one case (W = S^2, S symmetric); returns the rank of
// sqrt(W) J by SVD (-1: ambiguous).
int check_properties(const WeightedProjector& p, const Jacobian& J, const Matrix6& W,
                     const Matrix6& S, const std::string& what) {
  const Matrix6 P = range_matrix(p);
  const Matrix6 N = Matrix6::Identity() - P;
  EXPECT_TRUE(P.allFinite()) << what;
  const double nP = norm2(P);
  EXPECT_LE(norm2(P * P - P), kTol * std::max(1.0, nP) * std::max(1.0, nP)) << what;
  const Dyn WJ = W * J;
  EXPECT_LE(norm2(N * WJ), kTol * norm2(WJ)) << what;
  for (int i = 0; i < 6; ++i) {
    if (W.row(i).isZero(0.0)) EXPECT_EQ(P.row(i).cwiseAbs().maxCoeff(), 0.0) << what << i;
  }
  const Vector6 x = Vector6::LinSpaced(6, -1.0, 1.5);
  check_null(p, S, J, x, what);
  const int r = svd_rank(S * J);
  if (r >= 0) {
    EXPECT_EQ(p.rank(), r) << what;
    if (r == svd_rank(J) && J.cols() > 0) {
      // the product J^T N itself rounds to eps |J| |N| (|N| > 1 for an oblique N)
      EXPECT_LE(norm2(J.transpose() * N), kTol * norm2(J) * std::max(1.0, norm2(N))) << what;
    }
    const Dyn R = svd_reference(S, J, r);
    EXPECT_LE(norm2(P - R), 1e-8 * std::max(1.0, norm2(R))) << what;
  }
  return r;
}

}  // namespace

TEST(FilterProjector, PropertiesOnRandomCases) {
  std::mt19937 rng(2024);
  int ambiguous = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Case c = random_case(rng, trial);
    WeightedProjector p;
    p.compute(c.J, c.w);
    const Matrix6 W = c.w.asDiagonal();
    const Matrix6 S = c.w.cwiseSqrt().asDiagonal();
    ambiguous += check_properties(p, c.J, W, S, "trial " + std::to_string(trial)) < 0;
    // the free functions are this code
    EXPECT_EQ(range_filter(c.J, c.w), range_matrix(p));
    Matrix6 N;
    for (int k = 0; k < 6; ++k) N.col(k) = p.null(Vector6::Unit(k));
    EXPECT_EQ(null_filter(c.J, c.w), N);
    EXPECT_EQ(range_filter(c.J, W), range_matrix(p));
  }
  EXPECT_LT(ambiguous, 20);
}

TEST(FilterProjector, NearSingularStaysFullRankAndAccurate) {
  // sqrt(W) J with singular values 1 .. 1e-6 (a Probe 1e-5 rad from its singular pose), on
  // weighted rows only or with zero-weighted rows that J still moves
  std::mt19937 rng(7);
  for (int trial = 0; trial < 200; ++trial) {
    const int m = 1 + trial % 5;
    const int k = std::min(m, 3);  // rank of the weighted rows' block
    Vector6 w = Vector6::Zero();
    w.head(3) << 1.0, 2.0, 0.5;
    if (trial % 2) w.tail(3).setConstant(0.01);
    Dyn Jd = Dyn::Zero(6, m);
    Eigen::VectorXd s = Eigen::VectorXd::LinSpaced(k, 0.0, -6.0);
    for (int i = 0; i < k; ++i) s(i) = std::pow(10.0, s(i));
    Jd.topRows(3) = random_orthogonal(rng, 3).leftCols(k) * s.asDiagonal() *
                    random_orthogonal(rng, m).topRows(k);
    std::normal_distribution<double> g(0.0, 1.0);
    for (int j = 0; j < m; ++j)
      for (int i = 3; i < 6; ++i) Jd(i, j) = g(rng);
    const Jacobian J = Jd;
    WeightedProjector p;
    p.compute(J, w);
    const int r = check_properties(p, J, Matrix6(w.asDiagonal()),
                                   Matrix6(w.cwiseSqrt().asDiagonal()),
                                   "trial " + std::to_string(trial));
    EXPECT_EQ(r, trial % 2 ? m : k) << trial;
  }
}

TEST(FilterProjector, FitMatchesCompleteOrthogonalDecomposition) {
  std::mt19937 rng(11);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int trial = 0; trial < 1000; ++trial) {
    const Case c = random_case(rng, trial);
    Vector6 v;
    for (int i = 0; i < 6; ++i) v[i] = g(rng);
    WeightedProjector p;
    p.compute(c.J, c.w);
    JointVector theta_dot;
    p.fit(v, theta_dot);
    ASSERT_EQ(theta_dot.size(), c.J.cols());
    const Dyn S = c.w.cwiseSqrt().asDiagonal();
    const Dyn A = S * Dyn(c.J);
    if (A.cols() == 0) continue;
    Eigen::CompleteOrthogonalDecomposition<Dyn> cod(A.rows(), A.cols());
    cod.setThreshold(kPinvTolerance);
    cod.compute(A);
    const Eigen::VectorXd ref = cod.solve(S * v);
    EXPECT_EQ(p.rank(), cod.rank()) << trial;
    if (cod.rank() == 0) {
      EXPECT_TRUE(theta_dot.isZero(0.0)) << trial;
      continue;
    }
    // two backward-stable least-squares solutions differ by eps (kappa |x| + kappa^2 |res| /
    // s_1), kappa = s_1 / s_r (the two pivot orders may differ)
    const Eigen::VectorXd sv = Eigen::JacobiSVD<Dyn>(A).singularValues();
    const double kappa = sv(0) / sv(cod.rank() - 1);
    const double res = (A * ref - S * v).norm();
    EXPECT_LE((theta_dot - ref).norm(), 1e-14 * (kappa * ref.norm() + kappa * kappa * res / sv(0)))
        << trial;
  }
}

TEST(FilterProjector, FullRowRankOnTheWeightedAxesKeepsTheirWrenchesExactly) {
  // W = diag(1, 1, 1, 0, 0, 0) (an under-actuated device's W_A) and sqrt(W) J of rank 3: P(W)
  // is [I G; 0 0], so a wrench on the weighted axes passes exactly and N(W) takes nothing of
  // it; with rank 2 (the rows' span lost a direction) it does not pass whole
  std::mt19937 rng(19);
  std::normal_distribution<double> g(0.0, 1.0);
  const Vector6 w = (Vector6() << 1.0, 1.0, 1.0, 0.0, 0.0, 0.0).finished();
  for (int trial = 0; trial < 500; ++trial) {
    const int m = 3 + trial % 4;
    Jacobian J(6, m);
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < 6; ++i) J(i, j) = g(rng);
    // rank 2 on the weighted rows: exactly, or to 1e-13 (below the rank cut, where no
    // certificate may claim rank 3); 1e-7 is rank 3 again (found by the QR) but below the
    // soft rank's band: the null-space filter keeps the direction (a placement singular to
    // its solver's accuracy renders the pull it cannot follow)
    const int kind = trial % 5;
    const bool deficient = kind < 2, nearly = kind == 2;
    if (kind < 3) {
      const double off = kind == 0 ? 0.0 : kind == 1 ? 1e-13 : 1e-7;
      J.row(2) = 0.5 * J.row(0) - 2.0 * J.row(1);
      for (int j = 0; j < m; ++j) J(2, j) += off * g(rng);
    }
    Vector6 x = Vector6::Zero();
    for (int i = 0; i < 3; ++i) x[i] = g(rng);
    WeightedProjector p;
    p.compute(J, w);
    ASSERT_EQ(p.rank(), deficient ? 2 : 3) << trial;
    if (deficient || nearly) {
      EXPECT_GT(p.null(x).norm(), 1e-6 * x.norm()) << trial;
      if (nearly) EXPECT_EQ(p.range(x), x) << trial;  // (P keeps the factorisation's rank)
    } else {
      EXPECT_EQ(p.range(x), x) << trial;
      EXPECT_EQ(p.null(x), Vector6::Zero()) << trial;
    }
  }
}

TEST(FilterProjector, ARankZeroColumnFollowsNothing) {
  // a zero column (a joint whose motion does not move the handle) fits no twist: the
  // residual is -v, also for a v that is not finite, as for several columns of rank 0
  for (const int m : {1, 3}) {
    const Jacobian J = Jacobian::Zero(6, m);
    WeightedProjector p;
    p.compute(J, Vector6(Vector6::Ones()));
    ASSERT_EQ(p.rank(), 0) << m;
    Vector6 v;
    v << std::numeric_limits<double>::infinity(), 0.0, 1.0, -2.0, 0.0, 3.0;
    const Vector6 r = p.residual(v);
    for (int i = 0; i < 6; ++i) EXPECT_EQ(r[i], -v[i]) << m << " " << i;
  }
}

TEST(FilterProjector, ResidualIsTheWeightedLeastSquaresResidual) {
  // residual(v) = J theta - v, theta the weighted minimum-norm least-squares fit of v,
  // against that fit in long double (Eigen's complete orthogonal decomposition): Jacobians
  // of full column rank 1..6 (rank 5: the one-dot-product formula), weights spread over
  // eight decades (an under-actuated device's 1 and 1e-6 L^2), some of them zero
  using LD = Eigen::Matrix<long double, Eigen::Dynamic, Eigen::Dynamic>;
  using LDv = Eigen::Matrix<long double, Eigen::Dynamic, 1>;
  std::mt19937 rng(17);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int rank5 = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const int m = trial % 3 ? 5 : 1 + trial % 6;
    Jacobian J(6, m);
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < 6; ++i) J(i, j) = g(rng);
    if (trial % 4 == 1)
      for (int j = 0; j < m; ++j) J.col(j) *= std::pow(10.0, -3.0 + 3.0 * u(rng));
    Vector6 w;
    for (int i = 0; i < 6; ++i) w[i] = std::pow(10.0, -8.0 * u(rng));
    if (trial % 2) w << 1.0, 1.0, 1.0, 1e-8, 1e-8, 1e-8;
    if (trial % 7 == 3) w[trial % 6] = 0.0;
    if (trial % 5 == 4) {
      // sqrt(W) J well-conditioned although the weights spread: as many heavy rows as
      // columns, the light rows' motion following from theirs (the residual there is all
      // in the light rows, and small against the heavy rows' part of S v)
      for (int i = 0; i < 6; ++i) w[i] = i < m ? 1.0 : 1e-8;
      J.topRows(m) = random_orthogonal(rng, m);
    }
    Vector6 v;
    for (int i = 0; i < 6; ++i) v[i] = g(rng);
    WeightedProjector p;
    p.compute(J, w);
    const Vector6 r = p.residual(v);
    LDv s(6), vl(6);
    for (int i = 0; i < 6; ++i) s[i] = std::sqrt(static_cast<long double>(w[i]));
    for (int i = 0; i < 6; ++i) vl[i] = v[i];
    const LD Jl = J.cast<long double>();
    const LD A = s.asDiagonal() * Jl;
    Eigen::CompleteOrthogonalDecomposition<LD> cod(A.rows(), A.cols());
    cod.setThreshold(kPinvTolerance);
    cod.compute(A);
    ASSERT_EQ(p.rank(), cod.rank()) << trial;
    ASSERT_GT(p.rank(), 0) << trial;
    const LDv theta = cod.solve(LDv(s.asDiagonal() * vl));
    const Vector6 ref = (Jl * theta - vl).cast<double>();
    rank5 += p.rank() == 5 && w.minCoeff() > 0.0;
    const Vector6 sd = w.cwiseSqrt();
    const Eigen::VectorXd sv = Eigen::JacobiSVD<Dyn>(Dyn(sd.asDiagonal() * J)).singularValues();
    const double kappa = sv(0) / sv(p.rank() - 1);
    // backward stable: errors of eps kappa(sqrt(W) J), in the weighted norm and (the
    // lightly weighted rows carrying it) in the plain one
    EXPECT_LE((r - ref).norm(), 1e-13 * kappa * v.norm()) << trial;
    EXPECT_LE(sd.cwiseProduct(r - ref).norm(), 1e-14 * kappa * sd.cwiseProduct(v).norm()) << trial;
  }
  EXPECT_GT(rank5, 1000);  // the one-dot-product case was exercised
}

TEST(FilterProjector, ResidualWithAFullWeightMatrix) {
  // W = M M^T (rank 6, 4 or 2): residual(v) = J theta - v, theta the weighted minimum-norm
  // fit, against that fit from W's symmetric square root and a complete orthogonal
  // decomposition (Eigen's)
  std::mt19937 rng(29);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int trial = 0; trial < 300; ++trial) {
    const int m = 1 + trial % 6, rank_w = 6 - 2 * (trial % 3);
    Jacobian J(6, m);
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < 6; ++i) J(i, j) = g(rng);
    Dyn M(6, rank_w);
    for (int j = 0; j < rank_w; ++j)
      for (int i = 0; i < 6; ++i) M(i, j) = g(rng);
    const Matrix6 W = M * M.transpose();
    Vector6 v;
    for (int i = 0; i < 6; ++i) v[i] = g(rng);
    WeightedProjector p;
    p.compute(J, W);
    const Vector6 r = p.residual(v);
    Eigen::SelfAdjointEigenSolver<Matrix6> eig(W);
    // (eigenvalues at rounding level are W's zeros, as the projector reads them)
    Vector6 lambda = eig.eigenvalues();
    const double cut = 64.0 * std::numeric_limits<double>::epsilon() * lambda.maxCoeff();
    for (int i = 0; i < 6; ++i) lambda[i] = lambda[i] > cut ? lambda[i] : 0.0;
    const Matrix6 S = eig.eigenvectors() * lambda.cwiseSqrt().asDiagonal() *
                      eig.eigenvectors().transpose();
    const Dyn A = S * J;
    Eigen::CompleteOrthogonalDecomposition<Dyn> cod(A.rows(), A.cols());
    cod.setThreshold(1e-9);
    cod.compute(A);
    const Eigen::VectorXd theta = cod.solve(Eigen::VectorXd(S * v));
    const Vector6 ref = J * theta - v;
    EXPECT_LE((r - ref).norm(), 1e-9 * v.norm()) << trial;
  }
}

TEST(FilterProjector, NonFiniteJacobianOnAZeroWeightRowGivesNaN) {
  // the rows a weight excludes are still J's: a NaN there is a bad input, reported as NaN
  // (not hidden by the weights, nor by a deferred factorisation)
  Jacobian J(6, 3);
  J.setRandom();
  J(5, 1) = std::nan("");
  const Vector6 w = (Vector6() << 1.0, 1.0, 1.0, 0.0, 0.0, 0.0).finished();
  WeightedProjector p;
  p.compute(J, w);
  EXPECT_EQ(p.rank(), 0);
  const Vector6 x = (Vector6() << 1.0, 2.0, 3.0, 0.0, 0.0, 0.0).finished();
  EXPECT_TRUE(p.range(x).array().isNaN().all());
  JointVector theta_dot;
  p.fit(x, theta_dot);
  EXPECT_TRUE(theta_dot.array().isNaN().all());
  EXPECT_TRUE(p.residual(x).array().isNaN().all());
}

TEST(FilterProjector, FitIsTheWeightedMinimumNormSolution) {
  // J^T W (J theta_dot - v) = 0 and theta_dot in the row space of sqrt(W) J, with a full W
  std::mt19937 rng(13);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const int m = 1 + trial % kMaxDof;
    Jacobian J(6, m);
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < 6; ++i) J(i, j) = g(rng);
    if (trial % 3 == 0 && m > 1) J.col(m - 1) = J.col(0);
    const Dyn Q = random_orthogonal(rng, 6);
    Vector6 lambda;
    for (int i = 0; i < 6; ++i) lambda[i] = i < trial % 4 ? 0.0 : 0.1 + std::abs(g(rng));
    const Matrix6 W = Q * lambda.asDiagonal() * Q.transpose();
    const Matrix6 S = Q * lambda.cwiseSqrt().asDiagonal() * Q.transpose();
    Vector6 v;
    for (int i = 0; i < 6; ++i) v[i] = g(rng);
    WeightedProjector p;
    p.compute(J, W);
    JointVector theta_dot;
    p.fit(v, theta_dot);
    const Dyn A = S * J;
    const double nA = norm2(A);
    const Dyn normal = A.transpose() * (A * theta_dot - S * v);  // the normal equations
    EXPECT_LE(normal.norm(), 1e-12 * nA * nA * v.norm()) << trial;
    const Dyn pinv = A.completeOrthogonalDecomposition().pseudoInverse();
    EXPECT_LE((pinv * A * theta_dot - theta_dot).norm(), 1e-10 * std::max(1.0, theta_dot.norm()))
        << trial;
    check_properties(p, J, W, S, "full W trial " + std::to_string(trial));
  }
}

TEST(FilterProjector, NoColumns) {
  const Jacobian J(6, 0);
  const Vector6 ones = Vector6::Ones();
  WeightedProjector p;
  p.compute(J, ones);
  EXPECT_EQ(p.rank(), 0);
  const Vector6 x = Vector6::LinSpaced(6, 1.0, 6.0);
  EXPECT_EQ(p.range(x), Vector6::Zero());
  EXPECT_EQ(p.null(x), x);
  JointVector theta_dot(3);
  p.fit(x, theta_dot);
  EXPECT_EQ(theta_dot.size(), 0);
  EXPECT_EQ(range_filter(J, ones), Matrix6::Zero());
  EXPECT_EQ(null_filter(J, Matrix6(Matrix6::Identity())), Matrix6::Identity());
}

TEST(FilterProjector, ZeroWeightsOrZeroJacobian) {
  Jacobian J(6, 4);
  J.setRandom();
  const Vector6 x = Vector6::LinSpaced(6, 1.0, 6.0);
  for (const Jacobian& Jc : {J, Jacobian(Jacobian::Zero(6, 4))}) {
    for (const Vector6& w : {Vector6(Vector6::Zero()), Vector6(Vector6::Ones())}) {
      if (w.isOnes() && !Jc.isZero()) continue;
      WeightedProjector p;
      p.compute(Jc, w);
      EXPECT_EQ(p.rank(), 0);
      EXPECT_EQ(p.range(x), Vector6::Zero());
      EXPECT_EQ(p.null(x), x);
      JointVector theta_dot;
      p.fit(x, theta_dot);
      EXPECT_EQ(theta_dot, JointVector::Zero(4));
      EXPECT_EQ(range_filter(Jc, w), Matrix6::Zero());
      EXPECT_EQ(null_filter(Jc, Matrix6(w.asDiagonal())), Matrix6::Identity());
    }
  }
}

TEST(FilterProjector, NonFiniteInputsGiveNaN) {
  Jacobian J = Jacobian::Identity(6, 3);
  Vector6 w = Vector6::Ones();
  const Vector6 x = Vector6::Ones();
  JointVector theta_dot;
  WeightedProjector p;
  J(4, 1) = std::nan("");
  p.compute(J, w);
  EXPECT_TRUE(p.range(x).array().isNaN().all());
  p.fit(x, theta_dot);
  EXPECT_TRUE(theta_dot.array().isNaN().all());
  J(4, 1) = 0.0;
  w[2] = std::nan("");
  p.compute(J, w);
  EXPECT_TRUE(p.null(x).array().isNaN().all());
  Matrix6 W = Matrix6::Identity();
  W(0, 1) = W(1, 0) = kInf;
  p.compute(J, W);
  EXPECT_TRUE(p.range(x).array().isNaN().all());
  p.compute(J, Vector6(Vector6::Ones()));  // and back
  EXPECT_TRUE(p.range(x).allFinite());
}

TEST(FilterProjector, FullWeightMatrix) {
  std::mt19937 rng(17);
  std::uniform_int_distribution<int> small(-3, 3);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const int m = 1 + trial % kMaxDof;
    Jacobian J(6, m);
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < 6; ++i) J(i, j) = g(rng);
    // a diagonal matrix is the vector path, bit for bit
    Vector6 w;
    for (int i = 0; i < 6; ++i) w[i] = i == trial % 6 ? 0.0 : 0.5 + std::abs(g(rng));
    WeightedProjector pv, pm;
    pv.compute(J, w);
    pm.compute(J, Matrix6(w.asDiagonal()));
    EXPECT_EQ(range_matrix(pv), range_matrix(pm));
    // W = B B^T with small integer B (exact, rank 6 - trial % 4), some rows and columns 0
    Dyn B(6, 6 - trial % 4);
    for (Eigen::Index j = 0; j < B.cols(); ++j)
      for (int i = 0; i < 6; ++i) B(i, j) = small(rng);
    if (trial % 2) B.row(1).setZero(), B.row(4).setZero();
    const Matrix6 W = B * B.transpose();
    Eigen::SelfAdjointEigenSolver<Matrix6> eig(W);
    Vector6 lambda = eig.eigenvalues();
    for (int i = 0; i < 6; ++i) lambda[i] = lambda[i] > 1e-12 * lambda.maxCoeff() ? lambda[i] : 0.0;
    const Matrix6 S =
        eig.eigenvectors() * lambda.cwiseSqrt().asDiagonal() * eig.eigenvectors().transpose();
    WeightedProjector p;
    p.compute(J, W);
    check_properties(p, J, W, S, "trial " + std::to_string(trial));
    EXPECT_EQ(range_filter(J, W), range_matrix(p));
  }
}

TEST(FilterProjector, ReuseLeavesNoState) {
  std::mt19937 rng(19);
  WeightedProjector reused;
  const Vector6 x = Vector6::LinSpaced(6, -2.0, 3.0);
  for (int trial = 0; trial < 300; ++trial) {
    const Case c = random_case(rng, (trial * 7) % 45);
    WeightedProjector fresh;
    if (trial % 3 == 0) {
      const Matrix6 W = Matrix6(c.w.asDiagonal()) + 0.1 * Matrix6::Ones();
      reused.compute(c.J, W);
      fresh.compute(c.J, W);
    } else {
      reused.compute(c.J, c.w);
      fresh.compute(c.J, c.w);
    }
    EXPECT_EQ(reused.rank(), fresh.rank());
    EXPECT_EQ(reused.range(x), fresh.range(x));
    JointVector a, b;
    reused.fit(x, a);
    fresh.fit(x, b);
    EXPECT_EQ(a, b);
  }
}

TEST(FilterProjector, NeverAllocates) {
  // Eigen allocates with std::malloc, which the executable's heap counter sees on glibc
  if (!vmtest::heap_counter_sees_malloc()) GTEST_SKIP() << "malloc is counted on glibc only";
  const vmtest::HeapCount control = vmtest::heap_count_of([] {
    Eigen::MatrixXd M(7, 7);  // dynamic size: heap
    g_sink = M.data();
  });
  ASSERT_GT(control.allocations, 0);

  std::mt19937 rng(23);
  std::vector<Case> cases;
  for (int trial = 0; trial < 90; ++trial) cases.push_back(random_case(rng, trial));
  const Vector6 x = Vector6::LinSpaced(6, -1.0, 1.0);
  double sum = 0.0;
  WeightedProjector p;
  JointVector theta_dot;
  const vmtest::HeapCount n = vmtest::heap_count_of([&] {
    for (const Case& c : cases) {
      p.compute(c.J, c.w);
      sum += p.range(x).sum() + p.null(x).sum() + p.rank();
      p.fit(x, theta_dot);
      sum += theta_dot.sum();
      const Matrix6 W = Matrix6(c.w.asDiagonal()) + 0.1 * Matrix6::Ones();  // full W
      p.compute(c.J, W);
      sum += p.range(x).sum();
      p.fit(x, theta_dot);
      sum += theta_dot.sum();
      sum += range_filter(c.J, c.w).sum() + null_filter(c.J, W).sum();
    }
  });
  EXPECT_EQ(n.allocations, 0);
  EXPECT_EQ(n.frees, 0);
  EXPECT_TRUE(std::isfinite(sum));
}

