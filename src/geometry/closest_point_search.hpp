// What the closest-point searches of the shapes share: the refinement of a start by
// projected Newton with a Levenberg-Marquardt safeguard inside a parameter box, a small list
// of the best starts, and the distance's derivatives on a surface. Internal to the core.
#pragma once

#include <algorithm>
#include <cmath>

#include "../newton_stop.hpp"
#include "virtmech/geometry.hpp"

namespace virtmech::detail {

template <int N>
using Param = Eigen::Matrix<double, N, 1>;
template <int N>
using ParamMatrix = Eigen::Matrix<double, N, N>;

/// A point of refine()'s search: the parameters, and f, its gradient and Hessian there.
template <int N>
struct SearchPoint {
  Param<N> x, g;
  ParamMatrix<N> H;
  double f = 0.0;
};

/// The coordinates free to move at x (`free`), and their count: not at a bound with the
/// gradient pointing out of the box [lo, hi] (the active set).
template <int N>
int free_coordinates(const SearchPoint<N>& at, const Param<N>& lo, const Param<N>& hi,
                     bool (&free)[N]) noexcept {
  int nfree = 0;
  for (int i = 0; i < N; ++i) {
    free[i] = !((at.x[i] <= lo[i] && at.g[i] > 0.0) || (at.x[i] >= hi[i] && at.g[i] < 0.0));
    nfree += free[i];
  }
  return nfree;
}

/// Newton's step d over the free coordinates, with H regularised by mu I where it is not
/// positive definite (N <= 2: its eigenvalues in closed form); lmax the largest |eigenvalue|
/// (at least 1e-300). False where the free gradient vanishes or the step is not finite.
template <int N>
bool regularised_newton_step(const SearchPoint<N>& at, const bool (&free)[N], Param<N>& d,
                             double& mu, double& lmax) noexcept {
  using Vec = Param<N>;
  using Mat = ParamMatrix<N>;
  Mat Hf = Mat::Identity();
  Vec gf = Vec::Zero();
  for (int i = 0; i < N; ++i) {
    if (!free[i]) continue;
    gf[i] = at.g[i];
    for (int j = 0; j < N; ++j)
      if (free[j]) Hf(i, j) = at.H(i, j);
  }
  if (gf.isZero(0.0)) return false;
  double lmin;
  if (N == 1) {
    lmin = lmax = Hf(0, 0);
  } else {
    const double m = 0.5 * (Hf(0, 0) + Hf(N - 1, N - 1));
    // (a plain square root: the entries are far from overflow and underflow)
    const double h = 0.5 * (Hf(0, 0) - Hf(N - 1, N - 1));
    const double q = std::sqrt(h * h + Hf(0, N - 1) * Hf(0, N - 1));
    lmin = m - q;
    lmax = m + q;
  }
  lmax = std::max(std::max(std::abs(lmin), std::abs(lmax)), 1e-300);
  mu = 0.0;
  if (!(lmin > 1e-10 * lmax)) mu = -lmin + 1e-3 * lmax;
  const Mat A = Hf + mu * Mat::Identity();
  if (N == 1) {
    d[0] = -gf[0] / A(0, 0);
  } else {
    const double det = A(0, 0) * A(N - 1, N - 1) - A(0, N - 1) * A(N - 1, 0);
    d[0] = -(A(N - 1, N - 1) * gf[0] - A(0, N - 1) * gf[N - 1]) / det;
    d[N - 1] = -(A(0, 0) * gf[N - 1] - A(N - 1, 0) * gf[0]) / det;
  }
  for (int i = 0; i < N; ++i)
    if (!free[i]) d[i] = 0.0;
  return d.allFinite();
}

/// Backtracking (Armijo) from `at` along the direction dir projected onto the box: the
/// point accepted into `next`; `full_ok`: the full step is taken whatever the cost. False
/// where no step descends (or the step vanishes).
template <int N, typename Eval>
bool backtrack(const SearchPoint<N>& at, const Param<N>& dir, bool full_ok, const Param<N>& lo,
               const Param<N>& hi, const Eval& eval, SearchPoint<N>& next) noexcept {
  double t = 1.0;
  for (int ls = 0; ls < 60; ++ls) {
    next.x = (at.x + t * dir).cwiseMax(lo).cwiseMin(hi);
    if (next.x == at.x) return false;  // the step vanished: no progress along dir
    next.f = eval(next.x, next.g, next.H);
    if (next.f <= at.f + 1e-4 * at.g.dot(next.x - at.x) || (full_ok && t == 1.0)) return true;
    t *= 0.5;
  }
  return false;
}

/// Across a crease (a knot of full multiplicity) the one-sided Hessian misleads the coupled
/// step: a step along one free coordinate at a time (lmax: the Hessian's largest
/// |eigenvalue|), the first that descends into `next`. False where none does (or N = 1).
template <int N, typename Eval>
bool coordinate_step(const SearchPoint<N>& at, const bool (&free)[N], double lmax,
                     const Param<N>& lo, const Param<N>& hi, const Eval& eval,
                     SearchPoint<N>& next) noexcept {
  for (int i = 0; i < N && N > 1; ++i) {
    if (!free[i] || at.g[i] == 0.0) continue;
    Param<N> di = Param<N>::Zero();
    di[i] = -at.g[i] / std::max(at.H(i, i), 1e-3 * lmax);
    if (backtrack(at, di, false, lo, hi, eval, next)) return true;
  }
  return false;
}

/// The largest change of a coordinate from x to y, relative to the box's width `scale` (a
/// coordinate held, lo = hi, has none).
template <int N>
double scaled_step(const Param<N>& x, const Param<N>& y, const Param<N>& scale) noexcept {
  double a = 0.0;
  for (int i = 0; i < N; ++i) {
    if (scale[i] > 0.0) a = std::max(a, std::abs(y[i] - x[i]) / scale[i]);
  }
  return a;
}

/// Minimises f(x) = |S(x) - p|^2 / 2 over the box [lo, hi] from x (refined in place);
/// returns f. `eval(x, g, H)`: f, its gradient and its Hessian at x.
template <int N, typename Eval>
double refine(Param<N>& x, const Param<N>& lo, const Param<N>& hi, const Eval& eval) noexcept {
  static_assert(N == 1 || N == 2, "refine: one or two parameters");
  using Vec = Param<N>;
  SearchPoint<N> at, next;
  at.x = x;
  at.f = eval(at.x, at.g, at.H);
  Vec scale;
  for (int i = 0; i < N; ++i) {
    const double w = hi[i] - lo[i];
    scale[i] = std::isfinite(w) ? w : 1.0;
  }
  double last = 0.0;  // the last full Newton step (scaled), 0 if the last was not one
  for (int it = 0; it < 100; ++it) {
    bool free[N];
    if (free_coordinates(at, lo, hi, free) == 0) break;
    Vec d;
    double mu, lmax;
    if (!regularised_newton_step(at, free, d, mu, lmax)) break;
    const bool small = (d.cwiseAbs().array() <= 1e-7 * scale.array()).all() && mu == 0.0;
    if (!backtrack(at, d, small, lo, hi, eval, next) &&
        !coordinate_step(at, free, lmax, lo, hi, eval, next)) {
      break;
    }
    const double a = scaled_step(at.x, next.x, scale);
    const bool newton = mu == 0.0 && next.x == Vec((at.x + d).cwiseMax(lo).cwiseMin(hi));
    at = next;
    if (a <= 1e-15) break;
    // after two full Newton steps, a next one at rounding level is not taken
    if (newton && next_newton_step_below(a, last, 1e-15)) break;
    last = newton ? a : 0.0;
  }
  x = at.x;
  return at.f;
}

/// A small fixed-capacity list of the best candidates (smallest distance first).
template <int K>
struct Best {
  int index[K];
  double d2[K];
  int count = 0;
  void add(int i, double d) noexcept {
    for (int j = 0; j < count; ++j)
      if (index[j] == i) return;  // the same start twice
    int pos = count < K ? count : K;
    while (pos > 0 && d2[pos - 1] > d) --pos;
    if (pos >= K) return;
    for (int j = std::min(count, K - 1); j > pos; --j) {
      index[j] = index[j - 1];
      d2[j] = d2[j - 1];
    }
    index[pos] = i;
    d2[pos] = d;
    count = std::min(count + 1, K);
  }
};

constexpr int kCandidates = 24;

/// A bounding sphere's radius over the largest sampled distance from its centre (a curve's
/// sample interval, a surface's cell: the shape departs from its samples by far less).
constexpr double kSphereMargin = 1.5;

/// f(x) = |S(x) - p|^2 / 2 with its gradient and Hessian, for refine<2>.
struct DistanceToSurface {
  const Surface& s;
  const Eigen::Vector3d& p;
  double operator()(const Eigen::Vector2d& x, Eigen::Vector2d& g, Eigen::Matrix2d& H) const noexcept {
    SurfaceDerivatives d;
    s.derivatives(x[0], x[1], 2, d);
    const Eigen::Vector3d r = d(0, 0) - p;
    g << d(1, 0).dot(r), d(0, 1).dot(r);
    H(0, 0) = d(1, 0).squaredNorm() + d(2, 0).dot(r);
    H(1, 1) = d(0, 1).squaredNorm() + d(0, 2).dot(r);
    H(0, 1) = H(1, 0) = d(1, 0).dot(d(0, 1)) + d(1, 1).dot(r);
    return 0.5 * r.squaredNorm();
  }
};

}  // namespace virtmech::detail
