// Curves and surfaces (include/virtmech/geometry.hpp). NURBS: Piegl & Tiller, The NURBS
// Book, 2nd ed., 1997, algorithms A2.1, A2.3, A3.2, A3.6, A4.2, A4.4.
#include "virtmech/geometry.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include "newton_stop.hpp"
#include "trig.hpp"
#include "virtmech/validate.hpp"

namespace virtmech {

namespace {

constexpr int kP = kMaxNurbsDegree + 1;  // work-array size
constexpr int kD = kMaxDerivativeOrder + 1;
constexpr double kPi = 3.14159265358979323846;

// binomial coefficients up to kMaxDerivativeOrder
struct Binomial {
  double c[kD][kD] = {};
  constexpr Binomial() {
    for (int n = 0; n < kD; ++n) {
      c[n][0] = 1.0;
      for (int k = 1; k <= n; ++k) c[n][k] = c[n - 1][k - 1] + (k < n ? c[n - 1][k] : 0.0);
    }
  }
};
constexpr Binomial kBin{};

// falling factorials n! / (n - k)! for n, k <= kMaxDerivativeOrder (0 where k > n)
struct Falling {
  double f[kD][kD] = {};
  constexpr Falling() {
    for (int n = 0; n < kD; ++n) {
      double v = 1.0;
      for (int k = 0; k <= n; ++k) {
        f[n][k] = v;
        v *= static_cast<double>(n - k);
      }
    }
  }
};
constexpr Falling kFall{};

// ---- knot vectors --------------------------------------------------------------------

// Checks a knot vector for n control points of degree p; returns the domain [U_p, U_n].
void check_knots(const char* name, const Eigen::VectorXd& U, int n, int p) {
  const Eigen::Index expected = n + p + 1;
  if (U.size() != expected) {
    std::ostringstream os;
    os << name << ": expected n + degree + 1 = " << expected << " values (n = " << n
       << " control points, degree " << p << "), got " << U.size();
    throw std::invalid_argument(os.str());
  }
  require_finite(name, U);
  int multiplicity = 1;
  for (Eigen::Index i = 1; i < U.size(); ++i) {
    if (U[i] < U[i - 1]) {
      std::ostringstream os;
      os << name << ": expected non-decreasing values, got " << U[i] << " after " << U[i - 1]
         << " at index " << i << " of " << format_vector(U);
      throw std::invalid_argument(os.str());
    }
    multiplicity = U[i] == U[i - 1] ? multiplicity + 1 : 1;
    if (multiplicity > p + 1) {
      std::ostringstream os;
      os << name << ": expected every knot's multiplicity at most degree + 1 = " << p + 1
         << ", got " << U[i] << " " << multiplicity << " times in " << format_vector(U);
      throw std::invalid_argument(os.str());
    }
  }
  if (!(U[p] < U[n])) {
    std::ostringstream os;
    os << name << ": expected a non-empty domain [knots[degree], knots[n]] = [" << U[p] << ", "
       << U[n] << "], got " << format_vector(U);
    throw std::invalid_argument(os.str());
  }
}

void check_degree(const char* name, int p) {
  if (p < 1 || p > kMaxNurbsDegree) {
    throw std::invalid_argument(std::string(name) + ": expected 1 to " +
                                std::to_string(kMaxNurbsDegree) + ", got " + std::to_string(p));
  }
}

// A2.1: the span index i with U_i <= u < U_(i+1), p <= i <= n - 1 (n control points);
// u within [U_p, U_n].
int find_span(const double* U, int n, int p, double u) noexcept {
  if (u >= U[n]) {
    int i = n - 1;
    while (i > p && U[i] == U[i + 1]) --i;
    return i;
  }
  if (u <= U[p]) {
    int i = p;
    while (i < n - 1 && U[i] == U[i + 1]) ++i;
    return i;
  }
  int lo = p, hi = n;
  int mid = (lo + hi) / 2;
  while (u < U[mid] || u >= U[mid + 1]) {
    if (u < U[mid]) {
      hi = mid;
    } else {
      lo = mid;
    }
    mid = (lo + hi) / 2;
  }
  return mid;
}

// A2.3: ders[k][j] = k-th derivative of N_(i-p+j),p at u, k <= nd (nd <= p: higher are 0).
void basis_derivatives(const double* U, int i, int p, double u, int nd,
                       double (&ders)[kD][kP]) noexcept {
  double ndu[kP][kP];
  double left[kP], right[kP];
  double a[2][kP];
  ndu[0][0] = 1.0;
  for (int j = 1; j <= p; ++j) {
    left[j] = u - U[i + 1 - j];
    right[j] = U[i + j] - u;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      ndu[j][r] = right[r + 1] + left[j - r];
      const double temp = ndu[r][j - 1] / ndu[j][r];
      ndu[r][j] = saved + right[r + 1] * temp;
      saved = left[j - r] * temp;
    }
    ndu[j][j] = saved;
  }
  for (int j = 0; j <= p; ++j) ders[0][j] = ndu[j][p];
  const int n = std::min(nd, p);
  for (int r = 0; r <= p; ++r) {
    int s1 = 0, s2 = 1;
    a[0][0] = 1.0;
    for (int k = 1; k <= n; ++k) {
      double d = 0.0;
      const int rk = r - k, pk = p - k;
      if (r >= k) {
        a[s2][0] = a[s1][0] / ndu[pk + 1][rk];
        d = a[s2][0] * ndu[rk][pk];
      }
      const int j1 = rk >= -1 ? 1 : -rk;
      const int j2 = (r - 1 <= pk) ? k - 1 : p - r;
      for (int j = j1; j <= j2; ++j) {
        a[s2][j] = (a[s1][j] - a[s1][j - 1]) / ndu[pk + 1][rk + j];
        d += a[s2][j] * ndu[rk + j][pk];
      }
      if (r <= pk) {
        a[s2][k] = -a[s1][k - 1] / ndu[pk + 1][r];
        d += a[s2][k] * ndu[r][pk];
      }
      ders[k][r] = d;
      std::swap(s1, s2);
    }
  }
  double f = p;
  for (int k = 1; k <= n; ++k) {
    for (int j = 0; j <= p; ++j) ders[k][j] *= f;
    f *= (p - k);
  }
  for (int k = n + 1; k <= nd; ++k)
    for (int j = 0; j <= p; ++j) ders[k][j] = 0.0;
}

double clamp(double x, double lo, double hi) noexcept { return std::min(std::max(x, lo), hi); }

int clamp_order(int order) noexcept { return std::min(std::max(order, 0), kMaxDerivativeOrder); }

// the samples' parameters: `per_span` intervals in every non-empty knot span
std::vector<double> sample_parameters(const Eigen::VectorXd& U, int n, int p, int per_span) {
  std::vector<double> s;
  for (int i = p; i < n; ++i) {
    if (U[i] == U[i + 1]) continue;
    for (int k = 0; k < per_span; ++k) s.push_back(U[i] + (U[i + 1] - U[i]) * k / per_span);
  }
  s.push_back(U[n]);
  return s;
}

int samples_per_span(int p) { return std::max(8, 2 * p); }

// The largest multiplicity of a knot strictly inside the domain [U[p], U[n]] (0: none).
int interior_multiplicity(const Eigen::VectorXd& U, int n, int p) noexcept {
  int most = 0;
  for (int i = p + 1; i < n; ++i) {
    if (!(U[i] > U[p] && U[i] < U[n])) continue;
    int k = 1;
    while (i + k < n && U[i + k] == U[i]) ++k;
    most = std::max(most, k);
    i += k - 1;
  }
  return most;
}

// ---- a curve span's and a surface span pair's derivatives ----------------------------

// GCC (8 and later for the pragma) and Clang: unroll the loops over degrees and orders, and
// inline every call within the function (Eigen's small-vector expressions) so that they
// unroll with it
#if defined(__clang__) || (defined(__GNUC__) && __GNUC__ >= 8)
#define VIRTMECH_UNROLL _Pragma("GCC unroll 8")
#else
#define VIRTMECH_UNROLL
#endif
#if defined(__GNUC__)
#define VIRTMECH_FLATTEN __attribute__((flatten))
#else
#define VIRTMECH_FLATTEN
#endif

using SpanKernel = void (*)(const Eigen::Vector4d*, double, int, int, CurveDerivatives&) noexcept;

// The derivatives (k <= nd) of a rational curve of degree p over one span at the offset x
// from its middle, from the homogeneous curve's Taylor coefficients C there:
// d^k Cw / du^k = sum_{a>=k} C_a a!/(a-k)! x^(a-k), by Horner; then the quotient rule (The
// NURBS Book, A4.2). P, ND >= 0 make p, nd constants (as span_pair_arithmetic below).
template <int P, int ND>
VIRTMECH_FLATTEN void span_arithmetic(const Eigen::Vector4d* C, double x, int p_given,
                                      int nd_given, CurveDerivatives& out) noexcept {
  constexpr int kN = ND >= 0 ? ND + 1 : kD;  // orders held
  const int p = P >= 0 ? P : std::min(p_given, kMaxNurbsDegree);
  const int nd = ND >= 0 ? ND : std::min(nd_given, kN - 1);
  Eigen::Vector4d Cw[kN];
  VIRTMECH_UNROLL for (int k = 0; k <= nd; ++k) {
    if (k > p) {
      Cw[k].setZero();
      continue;
    }
    Eigen::Vector4d acc = kFall.f[p][k] * C[p];
    VIRTMECH_UNROLL for (int a = p - 1; a >= k; --a) acc = acc * x + kFall.f[a][k] * C[a];
    Cw[k] = acc;
  }
  VIRTMECH_UNROLL for (int k = 0; k <= nd; ++k) {
    Eigen::Vector3d v = Cw[k].template head<3>();
    VIRTMECH_UNROLL for (int i = 1; i <= k; ++i) v -= kBin.c[k][i] * Cw[i][3] * out.col(k - i);
    out.col(k) = v / Cw[0][3];
  }
}

template <int P>
void span_derivatives(const Eigen::Vector4d* C, double x, int p, int nd,
                      CurveDerivatives& out) noexcept {
  switch (nd) {
    case 0: return span_arithmetic<P, 0>(C, x, p, 0, out);
    case 1: return span_arithmetic<P, 1>(C, x, p, 1, out);
    case 2: return span_arithmetic<P, 2>(C, x, p, 2, out);
    default: return span_arithmetic<P, -1>(C, x, p, nd, out);
  }
}

// the instance for degree p: a constant up to 5, else as given
SpanKernel span_kernel(int p) noexcept {
  static constexpr SpanKernel kTable[5] = {&span_derivatives<1>, &span_derivatives<2>,
                                           &span_derivatives<3>, &span_derivatives<4>,
                                           &span_derivatives<5>};
  return p <= 5 ? kTable[p - 1] : &span_derivatives<-1>;
}

using SpanPairKernel = void (*)(const Eigen::Vector4d*, double, double, int, int, int,
                                SurfaceDerivatives&) noexcept;

// The derivatives (k, l <= nd) of a rational surface of degrees (p, q) over one span pair
// at the offsets (x, y) from its middle, from the homogeneous surface's Taylor coefficients
// C there (index a * (q + 1) + b): d^(k+l) Sw / du^k dv^l = sum_{a>=k, b>=l} C_ab
// a!/(a-k)! b!/(b-l)! x^(a-k) y^(b-l), Horner in y for each a, then in x; then the quotient
// rule (The NURBS Book, A4.4), every (k, l) with k, l <= nd (as geomdl).
// P, Q, ND >= 0 make p, q, nd constants, so that the loops unroll (and flatten inlines
// Eigen's small vector operations into them): NurbsSurface picks the instance for its
// degrees at construction, the usual degrees and orders as constants; -1: as given.
template <int P, int Q, int ND>
VIRTMECH_FLATTEN void span_pair_arithmetic(const Eigen::Vector4d* C, double x, double y,
                                           int p_given, int q_given, int nd_given,
                                           SurfaceDerivatives& out) noexcept {
  constexpr int kTu = (P >= 0 ? P : kMaxNurbsDegree) + 1;
  constexpr int kTv = (Q >= 0 ? Q : kMaxNurbsDegree) + 1;
  constexpr int kN = ND >= 0 ? ND + 1 : kD;  // orders held
  // (given values kept within the arrays for the compiler, which cannot see that they are)
  const int p = P >= 0 ? P : std::min(p_given, kTu - 1);
  const int q = Q >= 0 ? Q : std::min(q_given, kTv - 1);
  const int nd = ND >= 0 ? ND : std::min(nd_given, kN - 1);
  const int du = std::min(nd, p), dv = std::min(nd, q);
  Eigen::Vector4d T[kTu][kTv];  // T[a][l]: d^l/dv^l of sum_b C_ab y^b (l <= dv)
  VIRTMECH_UNROLL for (int a = 0; a <= p; ++a) {
    const Eigen::Vector4d* row = C + a * (q + 1);
    VIRTMECH_UNROLL for (int l = 0; l <= dv; ++l) {
      Eigen::Vector4d acc = kFall.f[q][l] * row[q];
      VIRTMECH_UNROLL for (int b = q - 1; b >= l; --b) acc = acc * y + kFall.f[b][l] * row[b];
      T[a][l] = acc;
    }
  }
  Eigen::Vector4d Sw[kN][kN];
  VIRTMECH_UNROLL for (int k = 0; k <= nd; ++k) {
    VIRTMECH_UNROLL for (int l = 0; l <= nd; ++l) {
      if (k > du || l > dv) {
        Sw[k][l].setZero();
        continue;
      }
      Eigen::Vector4d acc = kFall.f[p][k] * T[p][l];
      VIRTMECH_UNROLL for (int a = p - 1; a >= k; --a) acc = acc * x + kFall.f[a][k] * T[a][l];
      Sw[k][l] = acc;
    }
  }
  VIRTMECH_UNROLL for (int k = 0; k <= nd; ++k) {
    VIRTMECH_UNROLL for (int l = 0; l <= nd; ++l) {
      Eigen::Vector3d w = Sw[k][l].template head<3>();
      VIRTMECH_UNROLL for (int j = 1; j <= l; ++j) w -= kBin.c[l][j] * Sw[0][j][3] * out(k, l - j);
      VIRTMECH_UNROLL for (int i = 1; i <= k; ++i) {
        w -= kBin.c[k][i] * Sw[i][0][3] * out(k - i, l);
        Eigen::Vector3d w2 = Eigen::Vector3d::Zero();
        VIRTMECH_UNROLL for (int j = 1; j <= l; ++j) {
          w2 += kBin.c[l][j] * Sw[i][j][3] * out(k - i, l - j);
        }
        w -= kBin.c[k][i] * w2;
      }
      out(k, l) = w / Sw[0][0][3];
    }
  }
}

// degrees P, Q as constants, and the orders the closest point and the mechanisms use
template <int P, int Q>
void span_pair_derivatives(const Eigen::Vector4d* C, double x, double y, int p, int q, int nd,
                           SurfaceDerivatives& out) noexcept {
  switch (nd) {
    case 0: return span_pair_arithmetic<P, Q, 0>(C, x, y, p, q, 0, out);
    case 1: return span_pair_arithmetic<P, Q, 1>(C, x, y, p, q, 1, out);
    case 2: return span_pair_arithmetic<P, Q, 2>(C, x, y, p, q, 2, out);
    default: return span_pair_arithmetic<P, Q, -1>(C, x, y, p, q, nd, out);
  }
}

// the instance for degrees (p, q): constants up to 3 (the usual degrees), else as given
SpanPairKernel span_pair_kernel(int p, int q) noexcept {
  if (p > 3 || q > 3) return &span_pair_derivatives<-1, -1>;
  static constexpr SpanPairKernel kTable[3][3] = {
      {&span_pair_derivatives<1, 1>, &span_pair_derivatives<1, 2>, &span_pair_derivatives<1, 3>},
      {&span_pair_derivatives<2, 1>, &span_pair_derivatives<2, 2>, &span_pair_derivatives<2, 3>},
      {&span_pair_derivatives<3, 1>, &span_pair_derivatives<3, 2>, &span_pair_derivatives<3, 3>}};
  return kTable[p - 1][q - 1];
}

// ---- closest point: projected Newton with Levenberg-Marquardt safeguard ----------------

// Minimises f(x) = |S(x) - p|^2 / 2 over the box [lo, hi] from x (refined in place);
// returns f. `eval(x, S, g, H)`: the point, the gradient and the Hessian of f at x.
template <int N, typename Eval>
double refine(Eigen::Matrix<double, N, 1>& x, const Eigen::Matrix<double, N, 1>& lo,
              const Eigen::Matrix<double, N, 1>& hi, const Eval& eval) noexcept {
  static_assert(N == 1 || N == 2, "refine: one or two parameters");
  using Vec = Eigen::Matrix<double, N, 1>;
  using Mat = Eigen::Matrix<double, N, N>;
  Vec g;
  Mat H;
  double f = eval(x, g, H);
  Vec scale;
  for (int i = 0; i < N; ++i) {
    const double w = hi[i] - lo[i];
    scale[i] = std::isfinite(w) ? w : 1.0;
  }
  double last = 0.0;  // the last full Newton step (scaled), 0 if the last was not one
  for (int it = 0; it < 100; ++it) {
    // active set: at a bound with the gradient pointing out of the box
    bool free[N];
    int nfree = 0;
    for (int i = 0; i < N; ++i) {
      free[i] = !((x[i] <= lo[i] && g[i] > 0.0) || (x[i] >= hi[i] && g[i] < 0.0));
      nfree += free[i];
    }
    if (nfree == 0) break;
    Mat Hf = Mat::Identity();
    Vec gf = Vec::Zero();
    for (int i = 0; i < N; ++i) {
      if (!free[i]) continue;
      gf[i] = g[i];
      for (int j = 0; j < N; ++j)
        if (free[j]) Hf(i, j) = H(i, j);
    }
    if (gf.isZero(0.0)) break;
    // regularise where not positive definite (N <= 2: eigenvalues in closed form)
    double lmin, lmax;
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
    double mu = 0.0;
    if (!(lmin > 1e-10 * lmax)) mu = -lmin + 1e-3 * lmax;
    const Mat A = Hf + mu * Mat::Identity();
    Vec d;
    if (N == 1) {
      d[0] = -gf[0] / A(0, 0);
    } else {
      const double det = A(0, 0) * A(N - 1, N - 1) - A(0, N - 1) * A(N - 1, 0);
      d[0] = -(A(N - 1, N - 1) * gf[0] - A(0, N - 1) * gf[N - 1]) / det;
      d[N - 1] = -(A(0, 0) * gf[N - 1] - A(N - 1, 0) * gf[0]) / det;
    }
    for (int i = 0; i < N; ++i)
      if (!free[i]) d[i] = 0.0;
    if (!d.allFinite()) break;
    const bool small = (d.cwiseAbs().array() <= 1e-7 * scale.array()).all() && mu == 0.0;
    Vec xn;
    Vec gn;
    Mat Hn;
    double fn = 0.0;
    // backtracking (Armijo) along the projected direction dir
    auto search = [&](const Vec& dir, bool full_ok) {
      double t = 1.0;
      for (int ls = 0; ls < 60; ++ls) {
        xn = (x + t * dir).cwiseMax(lo).cwiseMin(hi);
        if (xn == x) return false;  // the step vanished: no progress along dir
        fn = eval(xn, gn, Hn);
        if (fn <= f + 1e-4 * g.dot(xn - x) || (full_ok && t == 1.0)) return true;
        t *= 0.5;
      }
      return false;
    };
    bool accepted = search(d, small);
    // across a crease (a knot of full multiplicity) the one-sided Hessian misleads the
    // coupled step: one coordinate at a time
    for (int i = 0; i < N && !accepted && N > 1; ++i) {
      if (!free[i] || g[i] == 0.0) continue;
      Vec di = Vec::Zero();
      di[i] = -g[i] / std::max(H(i, i), 1e-3 * lmax);
      accepted = search(di, false);
    }
    if (!accepted) break;
    double a = 0.0;  // the step, scaled (a coordinate held, lo = hi, has none)
    for (int i = 0; i < N; ++i) {
      if (scale[i] > 0.0) a = std::max(a, std::abs(xn[i] - x[i]) / scale[i]);
    }
    const bool newton = mu == 0.0 && xn == Vec((x + d).cwiseMax(lo).cwiseMin(hi));
    x = xn;
    f = fn;
    g = gn;
    H = Hn;
    if (a <= 1e-15) break;
    // after two full Newton steps, a next one at rounding level is not taken
    if (newton && detail::next_newton_step_below(a, last, 1e-15)) break;
    last = newton ? a : 0.0;
  }
  return f;
}

// a small fixed-capacity list of the best candidates (smallest distance first)
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

// NurbsSurface::closest_point keeps the samples' distances on the stack up to this many
// samples (8 KiB)
constexpr int kKeptSamples = 1024;

// a bounding sphere's radius over the largest sampled distance from its centre (a curve's
// sample interval, a surface's cell: the shape departs from its samples by far less)
constexpr double kSphereMargin = 1.5;

// f(x) = |S(x) - p|^2 / 2 with its gradient and Hessian, for refine<2>
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

Eigen::Vector3d safe_normalized(const Eigen::Vector3d& v, const char* name) {
  const double n = v.norm();
  if (!(std::isfinite(n) && n > 0.0)) {
    throw std::invalid_argument(std::string(name) + ": expected a finite, non-zero vector, got " +
                                format_vector(v));
  }
  return v / n;
}

}  // namespace

// ---- Curve, Surface ----------------------------------------------------------------------

Eigen::Vector3d Curve::tangent(double u) const noexcept {
  CurveDerivatives d;
  derivatives(u, 1, d);
  const double n = d.col(1).norm();
  return n > 0.0 ? Eigen::Vector3d(d.col(1) / n) : Eigen::Vector3d::Zero();
}

double Curve::curvature(double u) const noexcept {
  CurveDerivatives d;
  derivatives(u, 2, d);
  const double n = d.col(1).norm();
  if (!(n > 0.0)) return 0.0;
  return d.col(1).cross(d.col(2)).norm() / (n * n * n);
}

Eigen::Vector3d Surface::normal(double u, double v) const noexcept {
  SurfaceDerivatives d;
  const Eigen::Vector2d lo = lower(), hi = upper();
  u = clamp(u, lo[0], hi[0]);
  v = clamp(v, lo[1], hi[1]);
  derivatives(u, v, 1, d);
  Eigen::Vector3d n = d(1, 0).cross(d(0, 1));
  const double scale = d(1, 0).norm() * d(0, 1).norm();
  if (!(n.norm() > 1e-12 * scale) && std::isfinite(hi[0] - lo[0]) &&
      std::isfinite(hi[1] - lo[1])) {
    // degenerate (a collapsed edge): a little toward the patch's centre
    const Eigen::Vector2d c = 0.5 * (lo + hi);
    const double h = 1e-7;
    derivatives(u + h * (c[0] - u), v + h * (c[1] - v), 1, d);
    n = d(1, 0).cross(d(0, 1));
  }
  const double len = n.norm();
  return len > 0.0 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::UnitZ();
}

Eigen::Vector2d Surface::closest_point_from(const Eigen::Vector3d& p, const Eigen::Vector2d& start,
                                           const Eigen::Vector2d& lo, const Eigen::Vector2d& hi,
                                           Eigen::Vector3d& point) const noexcept {
  Eigen::Vector2d x = start.cwiseMax(lo).cwiseMin(hi);
  refine<2>(x, lo, hi, DistanceToSurface{*this, p});
  SurfaceDerivatives d;
  derivatives(x[0], x[1], 0, d);
  point = d(0, 0);
  return x;
}

SurfaceCurvature Surface::curvature(double u, double v) const noexcept {
  SurfaceDerivatives d;
  derivatives(u, v, 2, d);
  const Eigen::Vector3d n = normal(u, v);
  const double E = d(1, 0).dot(d(1, 0)), F = d(1, 0).dot(d(0, 1)), G = d(0, 1).dot(d(0, 1));
  const double L = d(2, 0).dot(n), M = d(1, 1).dot(n), N = d(0, 2).dot(n);
  const double det = E * G - F * F;
  SurfaceCurvature c;
  if (det > 0.0) {
    c.mean = (E * N - 2.0 * F * M + G * L) / (2.0 * det);
    c.gaussian = (L * N - M * M) / det;
  }
  return c;
}

// ---- NurbsCurve ----------------------------------------------------------------------------

NurbsCurve::NurbsCurve(const Eigen::MatrixX3d& control_points, const Eigen::VectorXd& weights,
                       const Eigen::VectorXd& knots, int degree)
    : n_(static_cast<int>(control_points.rows())), p_(degree), knots_(knots) {
  check_degree("degree", degree);
  if (n_ < degree + 1) {
    throw std::invalid_argument("control_points: expected at least degree + 1 = " +
                                std::to_string(degree + 1) + " points, got " +
                                std::to_string(n_));
  }
  for (int i = 0; i < n_; ++i) require_finite("control_points", Eigen::VectorXd(control_points.row(i).transpose()));
  if (weights.size() != n_) {
    throw std::invalid_argument("weights: expected " + std::to_string(n_) +
                                " values (one per control point), got " +
                                std::to_string(weights.size()));
  }
  if (!weights.allFinite() || !(weights.array() > 0.0).all()) {
    throw std::invalid_argument("weights: expected finite values > 0, got " +
                                format_vector(weights));
  }
  check_knots("knots", knots, n_, p_);
  lower_ = knots[p_];
  upper_ = knots[n_];
  kernel_ = span_kernel(p_);
  pw_.resize(4, n_);
  for (int i = 0; i < n_; ++i) {
    pw_.col(i).head<3>() = weights[i] * control_points.row(i).transpose();
    pw_(3, i) = weights[i];
  }
  // each non-empty span's Taylor coefficients about its middle, C_a = d^a Cw / du^a / a!
  // (a polynomial of degree p there; about the middle the powers stay within half the
  // span), for derivatives_in_span
  taylor_.assign(static_cast<size_t>(n_ - p_) * (p_ + 1), Eigen::Vector4d::Zero());
  for (int span = p_; span < n_; ++span) {
    if (!(knots_[span] < knots_[span + 1])) continue;
    Eigen::Vector4d Cw[kD];
    homogeneous_from_basis(0.5 * (knots_[span] + knots_[span + 1]), span, p_, Cw);
    for (int a = 0; a <= p_; ++a)
      taylor_[static_cast<size_t>(span - p_) * (p_ + 1) + a] = Cw[a] / kFall.f[a][a];
  }
  sample_u_ = sample_parameters(knots_, n_, p_, samples_per_span(p_));
  const size_t ns = sample_u_.size();
  sample_p_.reserve(ns);
  for (double u : sample_u_) sample_p_.push_back(evaluate(u));
  sample_d_start_.resize(ns - 1);
  sample_d_end_.resize(ns - 1);
  CurveDerivatives d;
  for (size_t i = 0; i + 1 < ns; ++i) {
    const int span =
        find_span(knots_.data(), n_, p_, 0.5 * (sample_u_[i] + sample_u_[i + 1]));
    derivatives_in_span(sample_u_[i], span, 1, d);
    sample_d_start_[i] = d.col(1);
    derivatives_in_span(sample_u_[i + 1], span, 1, d);
    sample_d_end_[i] = d.col(1);
    // the interval's bounding sphere: about its middle point, the largest distance over 17
    // points of it, enlarged by half (an interval is an eighth of a knot span or less,
    // where the curve departs from its samples by far less than that)
    const double u0 = sample_u_[i], u1 = sample_u_[i + 1];
    const Eigen::Vector3d c = evaluate(0.5 * (u0 + u1));
    double r = 0.0;
    for (int a = 0; a <= 16; ++a) r = std::max(r, (evaluate(u0 + a * (u1 - u0) / 16.0) - c).norm());
    interval_center_.push_back(c);
    interval_radius_.push_back(kSphereMargin * r);
  }
}

Eigen::MatrixX3d NurbsCurve::control_points() const {
  Eigen::MatrixX3d P(n_, 3);
  for (int i = 0; i < n_; ++i) P.row(i) = (pw_.col(i).head<3>() / pw_(3, i)).transpose();
  return P;
}

Eigen::VectorXd NurbsCurve::weights() const { return pw_.row(3).transpose(); }

Eigen::Vector3d NurbsCurve::evaluate(double u) const noexcept {
  CurveDerivatives d;
  derivatives(u, 0, d);
  return d.col(0);
}

void NurbsCurve::derivatives(double u, int order, CurveDerivatives& out) const noexcept {
  u = clamp(u, lower_, upper_);
  derivatives_in_span(u, find_span(knots_.data(), n_, p_, u), order, out);
}

void NurbsCurve::homogeneous_from_basis(double u, int span, int nd,
                                        Eigen::Vector4d (&Cw)[kMaxDerivativeOrder + 1])
    const noexcept {
  double ders[kD][kP];
  basis_derivatives(knots_.data(), span, p_, u, nd, ders);
  // A3.2 on the homogeneous points
  for (int k = 0; k <= nd; ++k) {
    Cw[k].setZero();
    if (k > p_) continue;
    for (int j = 0; j <= p_; ++j) Cw[k] += ders[k][j] * pw_.col(span - p_ + j);
  }
}

void NurbsCurve::derivatives_in_span(double u, int span, int order,
                                     CurveDerivatives& out) const noexcept {
  const Eigen::Vector4d* C = taylor_.data() + static_cast<size_t>(span - p_) * (p_ + 1);
  const double x = u - 0.5 * (knots_[span] + knots_[span + 1]);
  kernel_(C, x, p_, clamp_order(order), out);
}

double NurbsCurve::closest_point(const Eigen::Vector3d& p, Eigen::Vector3d& point) const noexcept {
  // Brackets: a sample interval whose f' = C'.(C - p) is < 0 at its start and > 0 at its
  // end (one-sided derivatives, so kinks at knots count) holds a local minimum; so does a
  // sample where f' changes sign across it (a kink), and an end where f' points outward.
  const int ni = static_cast<int>(sample_u_.size()) - 1;  // intervals
  auto d2 = [&](int i) { return (sample_p_[static_cast<size_t>(i)] - p).squaredNorm(); };
  auto g_start = [&](int i) {
    return sample_d_start_[static_cast<size_t>(i)].dot(sample_p_[static_cast<size_t>(i)] - p);
  };
  auto g_end = [&](int i) {
    return sample_d_end_[static_cast<size_t>(i)].dot(sample_p_[static_cast<size_t>(i) + 1] - p);
  };
  // candidate index 4 i + kind: kind 0 the sample i itself (a kink or an end), 1 interval i
  // (a bracket), 2 / 3 interval i from its start / end (a sample that is a discrete local
  // minimum of the distance, refined on its downhill side: a dip between samples whose
  // derivatives agree in sign)
  Best<kCandidates> best;
  for (int i = 0; i <= ni; ++i) {
    const bool left_ok = i == 0 || g_end(i - 1) <= 0.0;
    const bool right_ok = i == ni || g_start(i) >= 0.0;
    const double di = d2(i);
    if (left_ok && right_ok) best.add(4 * i, di);
    if (i < ni && g_start(i) < 0.0 && g_end(i) > 0.0)
      best.add(4 * i + 1, std::min(di, d2(i + 1)));
    if ((i == 0 || d2(i - 1) >= di) && (i == ni || d2(i + 1) >= di)) {
      if (i < ni) best.add(4 * i + 2, di);
      if (i > 0) best.add(4 * (i - 1) + 3, di);
    }
  }
  using V1 = Eigen::Matrix<double, 1, 1>;
  int span = p_;  // the bracket's knot span: one-sided derivatives at its ends
  auto eval = [&](const V1& x, V1& g, Eigen::Matrix<double, 1, 1>& H) {
    CurveDerivatives d;
    derivatives_in_span(x[0], span, 2, d);
    const Eigen::Vector3d r = d.col(0) - p;
    g[0] = d.col(1).dot(r);
    H(0, 0) = d.col(1).squaredNorm() + d.col(2).dot(r);
    return 0.5 * r.squaredNorm();
  };
  double best_f = kInf, best_u = lower_;
  for (int c = 0; c < best.count; ++c) {
    const int k = best.index[c];
    const int i = k / 4, kind = k % 4;
    double u = sample_u_[static_cast<size_t>(i)];
    double f = 0.5 * best.d2[c];
    if (kind != 0) {
      // refined within interval i (the bracket below): skipped where all of the interval is
      // farther than the best so far
      const double lb = (interval_center_[static_cast<size_t>(i)] - p).norm() -
                        interval_radius_[static_cast<size_t>(i)];
      if (lb > 0.0 && 0.5 * lb * lb >= best_f) continue;
      const V1 lo = V1::Constant(sample_u_[static_cast<size_t>(i)]);
      const V1 hi = V1::Constant(sample_u_[static_cast<size_t>(i) + 1]);
      span = find_span(knots_.data(), n_, p_, 0.5 * (lo[0] + hi[0]));
      // a bracket from inside, nearer its closer end (at a knot the derivatives past the
      // bracket's end may differ); else from the sample
      // (a sample whose derivative points away from the interval: from its middle, for a
      // dip the samples straddle)
      double t = kind == 1 ? (d2(i) <= d2(i + 1) ? 0.25 : 0.75) : (kind == 2 ? 0.0 : 1.0);
      if ((kind == 2 && g_start(i) >= 0.0) || (kind == 3 && g_end(i) <= 0.0)) t = 0.5;
      V1 x = V1::Constant(lo[0] + t * (hi[0] - lo[0]));
      f = refine<1>(x, lo, hi, eval);
      u = x[0];
    }
    if (f < best_f) {
      best_f = f;
      best_u = u;
    }
  }
  point = evaluate(best_u);
  return best_u;
}

// ---- NurbsSurface --------------------------------------------------------------------------

NurbsSurface::NurbsSurface(const Eigen::MatrixX3d& control_points, const Eigen::MatrixXd& weights,
                           const Eigen::VectorXd& knots_u, const Eigen::VectorXd& knots_v,
                           int degree_u, int degree_v)
    : nu_(static_cast<int>(weights.rows())),
      nv_(static_cast<int>(weights.cols())),
      p_(degree_u),
      q_(degree_v),
      knots_u_(knots_u),
      knots_v_(knots_v) {
  check_degree("degree_u", degree_u);
  check_degree("degree_v", degree_v);
  if (control_points.rows() != static_cast<Eigen::Index>(nu_) * nv_) {
    throw std::invalid_argument("control_points: expected nu * nv = " + std::to_string(nu_) +
                                " * " + std::to_string(nv_) + " points (the weights' shape), got " +
                                std::to_string(control_points.rows()));
  }
  if (nu_ < degree_u + 1 || nv_ < degree_v + 1) {
    throw std::invalid_argument("control_points: expected at least (degree_u + 1, degree_v + 1) = (" +
                                std::to_string(degree_u + 1) + ", " + std::to_string(degree_v + 1) +
                                ") points, got (" + std::to_string(nu_) + ", " +
                                std::to_string(nv_) + ")");
  }
  if (!control_points.allFinite()) {
    throw std::invalid_argument("control_points: expected finite values");
  }
  if (!weights.allFinite() || !(weights.array() > 0.0).all()) {
    throw std::invalid_argument("weights: expected finite values > 0, got min " +
                                std::to_string(weights.minCoeff()));
  }
  check_knots("knots_u", knots_u, nu_, p_);
  check_knots("knots_v", knots_v, nv_, q_);
  lower_ = {knots_u[p_], knots_v[q_]};
  upper_ = {knots_u[nu_], knots_v[nv_]};
  kernel_ = span_pair_kernel(p_, q_);
  pw_.resize(4, nu_ * nv_);
  for (int i = 0; i < nu_; ++i) {
    for (int j = 0; j < nv_; ++j) {
      const int c = i * nv_ + j;
      pw_.col(c).head<3>() = weights(i, j) * control_points.row(c).transpose();
      pw_(3, c) = weights(i, j);
    }
  }
  // each non-empty span pair's Taylor coefficients about its middle, C_ab =
  // d^(a+b) Sw / du^a dv^b / (a! b!) from the basis functions (a polynomial of degree p, q
  // there: its Taylor series is exact), for derivatives_in_spans
  const size_t block = static_cast<size_t>(p_ + 1) * (q_ + 1);
  taylor_.assign(static_cast<size_t>(nu_ - p_) * (nv_ - q_) * block, Eigen::Vector4d::Zero());
  for (int su = p_; su < nu_; ++su) {
    if (!(knots_u_[su] < knots_u_[su + 1])) continue;
    for (int sv = q_; sv < nv_; ++sv) {
      if (!(knots_v_[sv] < knots_v_[sv + 1])) continue;
      Eigen::Vector4d Sw[kD][kD];
      homogeneous_from_basis(0.5 * (knots_u_[su] + knots_u_[su + 1]),
                             0.5 * (knots_v_[sv] + knots_v_[sv + 1]), su, sv,
                             std::max(p_, q_), Sw);
      Eigen::Vector4d* C =
          taylor_.data() + static_cast<size_t>((su - p_) * (nv_ - q_) + (sv - q_)) * block;
      for (int a = 0; a <= p_; ++a)
        for (int b = 0; b <= q_; ++b)
          C[a * (q_ + 1) + b] = Sw[a][b] / (kFall.f[a][a] * kFall.f[b][b]);
    }
  }
  // C^2 across a knot of multiplicity k needs degree - k >= 2
  const int mu = interior_multiplicity(knots_u_, nu_, p_);
  const int mv = interior_multiplicity(knots_v_, nv_, q_);
  kinked_ = (mu > 0 && mu > p_ - 2) || (mv > 0 && mv > q_ - 2);
  creased_ = (mu > 0 && mu >= p_) || (mv > 0 && mv >= q_);
  sample_u_ = sample_parameters(knots_u_, nu_, p_, samples_per_span(p_));
  sample_v_ = sample_parameters(knots_v_, nv_, q_, samples_per_span(q_));
  sample_p_.reserve(sample_u_.size() * sample_v_.size());
  sample_su_.reserve(sample_p_.capacity());
  sample_sv_.reserve(sample_p_.capacity());
  sample_su_left_.reserve(sample_p_.capacity());
  sample_sv_below_.reserve(sample_p_.capacity());
  SurfaceDerivatives d;
  for (size_t i = 0; i < sample_u_.size(); ++i) {
    const double u = sample_u_[i];
    const int su = find_span(knots_u_.data(), nu_, p_, u);
    // the span to the left of u (a sample is a knot or between two)
    const int su_left =
        i == 0 ? su : find_span(knots_u_.data(), nu_, p_, 0.5 * (sample_u_[i - 1] + u));
    for (size_t j = 0; j < sample_v_.size(); ++j) {
      const double v = sample_v_[j];
      const int sv = find_span(knots_v_.data(), nv_, q_, v);
      const int sv_below =
          j == 0 ? sv : find_span(knots_v_.data(), nv_, q_, 0.5 * (sample_v_[j - 1] + v));
      derivatives_in_spans(u, v, su, sv, 1, d);
      sample_p_.push_back(d(0, 0));
      sample_su_.push_back(d(1, 0));
      sample_sv_.push_back(d(0, 1));
      derivatives_in_spans(u, v, su_left, sv, 1, d);
      sample_su_left_.push_back(d(1, 0));
      derivatives_in_spans(u, v, su, sv_below, 1, d);
      sample_sv_below_.push_back(d(0, 1));
    }
  }
  // each cell's bounding sphere, as the curve's intervals': about its middle point, the
  // largest distance over 9 x 9 points of it, enlarged by half
  const size_t su = sample_u_.size(), sv = sample_v_.size();
  cell_center_.reserve((su - 1) * (sv - 1));
  cell_radius_.reserve((su - 1) * (sv - 1));
  for (size_t i = 0; i + 1 < su; ++i) {
    for (size_t j = 0; j + 1 < sv; ++j) {
      const double u0 = sample_u_[i], u1 = sample_u_[i + 1];
      const double v0 = sample_v_[j], v1 = sample_v_[j + 1];
      const Eigen::Vector3d c = evaluate(0.5 * (u0 + u1), 0.5 * (v0 + v1));
      double r = 0.0;
      for (int a = 0; a <= 8; ++a)
        for (int b = 0; b <= 8; ++b)
          r = std::max(r, (evaluate(u0 + a * (u1 - u0) / 8.0, v0 + b * (v1 - v0) / 8.0) - c).norm());
      cell_center_.push_back(c);
      cell_radius_.push_back(kSphereMargin * r);
    }
  }
}

Eigen::MatrixX3d NurbsSurface::control_points() const {
  Eigen::MatrixX3d P(nu_ * nv_, 3);
  for (int c = 0; c < nu_ * nv_; ++c) P.row(c) = (pw_.col(c).head<3>() / pw_(3, c)).transpose();
  return P;
}

Eigen::MatrixXd NurbsSurface::weights() const {
  Eigen::MatrixXd W(nu_, nv_);
  for (int i = 0; i < nu_; ++i)
    for (int j = 0; j < nv_; ++j) W(i, j) = pw_(3, i * nv_ + j);
  return W;
}

Eigen::Vector3d NurbsSurface::evaluate(double u, double v) const noexcept {
  SurfaceDerivatives d;
  derivatives(u, v, 0, d);
  return d(0, 0);
}

void NurbsSurface::derivatives(double u, double v, int order,
                               SurfaceDerivatives& out) const noexcept {
  u = clamp(u, lower_[0], upper_[0]);
  v = clamp(v, lower_[1], upper_[1]);
  derivatives_in_spans(u, v, find_span(knots_u_.data(), nu_, p_, u),
                       find_span(knots_v_.data(), nv_, q_, v), order, out);
}

void NurbsSurface::homogeneous_from_basis(double u, double v, int su, int sv, int nd,
                                          Eigen::Vector4d (&Sw)[kMaxDerivativeOrder + 1]
                                                               [kMaxDerivativeOrder + 1])
    const noexcept {
  double Nu[kD][kP], Nv[kD][kP];
  basis_derivatives(knots_u_.data(), su, p_, u, nd, Nu);
  basis_derivatives(knots_v_.data(), sv, q_, v, nd, Nv);
  // A3.6 on the homogeneous points
  const int du = std::min(nd, p_), dv = std::min(nd, q_);
  for (int k = 0; k <= nd; ++k)
    for (int l = 0; l <= nd; ++l) Sw[k][l].setZero();
  Eigen::Vector4d temp[kP];
  for (int k = 0; k <= du; ++k) {
    for (int s = 0; s <= q_; ++s) {
      temp[s].setZero();
      for (int r = 0; r <= p_; ++r) temp[s] += Nu[k][r] * pw_.col((su - p_ + r) * nv_ + sv - q_ + s);
    }
    for (int l = 0; l <= dv; ++l) {
      for (int s = 0; s <= q_; ++s) Sw[k][l] += Nv[l][s] * temp[s];
    }
  }
}

void NurbsSurface::derivatives_in_spans(double u, double v, int su, int sv, int order,
                                        SurfaceDerivatives& out) const noexcept {
  const Eigen::Vector4d* C =
      taylor_.data() + static_cast<size_t>((su - p_) * (nv_ - q_) + (sv - q_)) * (p_ + 1) * (q_ + 1);
  const double x = u - 0.5 * (knots_u_[su] + knots_u_[su + 1]);
  const double y = v - 0.5 * (knots_v_[sv] + knots_v_[sv + 1]);
  kernel_(C, x, y, p_, q_, clamp_order(order), out);
}

Eigen::Vector2d NurbsSurface::closest_point(const Eigen::Vector3d& p,
                                            Eigen::Vector3d& point) const noexcept {
  const int mu = static_cast<int>(sample_u_.size()), mv = static_cast<int>(sample_v_.size());
  // the samples' squared distances from p, kept on the stack where they fit (each is read
  // by up to four cells' tests and nine samples' local-minimum tests)
  double kept[kKeptSamples];
  const bool keep = mu * mv <= kKeptSamples;
  auto d2 = [&](int i, int j) {
    const size_t k = static_cast<size_t>(i) * mv + j;
    return keep ? kept[k] : (sample_p_[k] - p).squaredNorm();
  };
  // the gradient's parts at sample (i, j): from the right in u / from above in v, or (a
  // cell's far corner, an edge interval's end) from the left / from below
  auto gu = [&](int i, int j, bool left = false) {
    const size_t k = static_cast<size_t>(i) * mv + j;
    return (left ? sample_su_left_ : sample_su_)[k].dot(sample_p_[k] - p);
  };
  auto gv = [&](int i, int j, bool below = false) {
    const size_t k = static_cast<size_t>(i) * mv + j;
    return (below ? sample_sv_below_ : sample_sv_)[k].dot(sample_p_[k] - p);
  };
  // the distance from p of cell (i, j) at least (where that is > 0)
  auto cell_bound = [&](int i, int j) {
    const size_t cell = static_cast<size_t>(i) * (mv - 1) + j;
    return (cell_center_[cell] - p).norm() - cell_radius_[cell];
  };
  // the distance from p of the cells about sample (i, j) at least: a start's minimum lies
  // in one of them
  auto cells_bound = [&](int i, int j) {
    double lb = kInf;
    for (int a = std::max(i - 1, 0); a <= std::min(i, mu - 2); ++a)
      for (int b = std::max(j - 1, 0); b <= std::min(j, mv - 2); ++b)
        lb = std::min(lb, cell_bound(a, b));
    return lb;
  };
  // The nearest sample bounds the least distance from above (the refinement from it, the
  // first, descends), so a cell farther than it holds no minimum that counts: only the
  // cells within it are searched.
  double least[4] = {kInf, kInf, kInf, kInf};  // (four chains of minima overlap)
  for (size_t k = 0; k < sample_p_.size(); ++k) {
    const double e = (sample_p_[k] - p).squaredNorm();
    if (keep) kept[k] = e;
    least[k % 4] = std::min(least[k % 4], e);
  }
  const double near2 = std::min(std::min(least[0], least[1]), std::min(least[2], least[3]));
  const double near = std::sqrt(near2);
  // Candidates (index i * mv + j, the start), in those cells: (1) samples that are discrete
  // local minima of the distance; (2) cells whose corners' gradients change sign in u and
  // in v (a minimum inside), started at the nearest corner; (3) along the four edges,
  // sample intervals whose tangential gradient changes sign (a minimum on or near the edge).
  Best<kCandidates> best;
  auto local_min = [&](int i, int j) {
    const double dij = d2(i, j);
    for (int a = std::max(i - 1, 0); a <= std::min(i + 1, mu - 1); ++a)
      for (int b = std::max(j - 1, 0); b <= std::min(j + 1, mv - 1); ++b)
        if ((a != i || b != j) && d2(a, b) < dij) return;
    best.add(i * mv + j, dij);
  };
  auto edge_v = [&](int i, int j) {  // the interval (i, j)-(i, j + 1) of an edge u = const
    if (gv(i, j) <= 0.0 && gv(i, j + 1, true) >= 0.0) {
      const bool first = d2(i, j) <= d2(i, j + 1);
      best.add(i * mv + (first ? j : j + 1), std::min(d2(i, j), d2(i, j + 1)));
    }
  };
  auto edge_u = [&](int i, int j) {  // the interval (i, j)-(i + 1, j) of an edge v = const
    if (gu(i, j) <= 0.0 && gu(i + 1, j, true) >= 0.0) {
      const bool first = d2(i, j) <= d2(i + 1, j);
      best.add((first ? i : i + 1) * mv + j, std::min(d2(i, j), d2(i + 1, j)));
    }
  };
  for (int i = 0; i + 1 < mu; ++i) {
    for (int j = 0; j + 1 < mv; ++j) {
      // the cell's sphere farther than the nearest sample: |c - p| - radius > near
      const size_t cell = static_cast<size_t>(i) * (mv - 1) + j;
      const double reach = cell_radius_[cell] + near;
      if ((cell_center_[cell] - p).squaredNorm() > reach * reach) continue;
      for (int a = i; a <= i + 1; ++a)
        for (int b = j; b <= j + 1; ++b) local_min(a, b);
      double umin = kInf, umax = -kInf, vmin = kInf, vmax = -kInf, dmin = kInf;
      int start = 0;
      for (int a = i; a <= i + 1; ++a) {
        for (int b = j; b <= j + 1; ++b) {
          const double x = gu(a, b, a > i), y = gv(a, b, b > j), dd = d2(a, b);
          umin = std::min(umin, x), umax = std::max(umax, x);
          vmin = std::min(vmin, y), vmax = std::max(vmax, y);
          if (dd < dmin) dmin = dd, start = a * mv + b;
        }
      }
      // on a creased surface also from inside the cell (a corner on a crease may descend
      // to the other side's minimum, and one beside it to this side's): index samples +
      // cell
      if (umin <= 0.0 && umax >= 0.0 && vmin <= 0.0 && vmax >= 0.0) {
        best.add(start, dmin);
        if (creased_) best.add(mu * mv + i * (mv - 1) + j, dmin);
      }
      if (i == 0) edge_v(0, j);
      if (i + 2 == mu) edge_v(mu - 1, j);
      if (j == 0) edge_u(i, 0);
      if (j + 2 == mv) edge_u(i, mv - 1);
    }
  }
  const DistanceToSurface eval{*this, p};
  double best_f = kInf;
  Eigen::Vector2d best_x = lower_;
  for (int c = 0; c < best.count; ++c) {
    const int k = best.index[c];
    const bool in_cell = k >= mu * mv;
    const int i = in_cell ? (k - mu * mv) / (mv - 1) : k / mv;
    const int j = in_cell ? (k - mu * mv) % (mv - 1) : k % mv;
    if (best_f < kInf) {
      const double lb = in_cell ? cell_bound(i, j) : cells_bound(i, j);
      if (lb > 0.0 && 0.5 * lb * lb >= best_f) continue;
    }
    Eigen::Vector2d x(sample_u_[static_cast<size_t>(i)], sample_v_[static_cast<size_t>(j)]);
    if (in_cell) {  // a quarter of the way in from its nearest corner
      const Eigen::Vector2d far(sample_u_[static_cast<size_t>(i) + 1],
                                sample_v_[static_cast<size_t>(j) + 1]);
      const Eigen::Vector2d mid = 0.5 * (x + far);
      int a = 0, b = 0;
      for (int s = 0; s < 4; ++s)
        if (d2(i + s / 2, j + s % 2) < d2(i + a, j + b)) a = s / 2, b = s % 2;
      const Eigen::Vector2d corner(a ? far[0] : x[0], b ? far[1] : x[1]);
      x = 0.5 * (corner + mid);
    }
    const double f = refine<2>(x, lower_, upper_, eval);
    if (f < best_f) {
      best_f = f;
      best_x = x;
    }
  }
  // polish: along a crease (a knot of full multiplicity), or a knot where the Hessian jumps,
  // the coupled steps zigzag; the 1-D problems with u, then v held, then both free again
  // settle them (a C^2 surface has no such line)
  for (int round = 0; round < 3 && best.count > 0 && kinked_; ++round) {
    const double f0 = best_f;
    for (int fixed = 0; fixed < 3; ++fixed) {
      Eigen::Vector2d lo = lower_, hi = upper_, x = best_x;
      if (fixed < 2) lo[fixed] = hi[fixed] = x[fixed];
      const double f = refine<2>(x, lo, hi, eval);
      if (f < best_f) {
        best_f = f;
        best_x = x;
      }
    }
    if (!(best_f < f0)) break;
  }
  point = evaluate(best_x[0], best_x[1]);
  return best_x;
}

// ---- analytic shapes -------------------------------------------------------------------

namespace {
// d^k/dt^k of cos t and sin t
double dcos(double t, int k) noexcept { return std::cos(t + k * 0.5 * kPi); }
double dsin(double t, int k) noexcept { return std::sin(t + k * 0.5 * kPi); }
}  // namespace

Sphere::Sphere(const Eigen::Vector3d& center, double radius, const Eigen::Vector3d& axis)
    : c_(center), r_(radius) {
  require_finite("center", Eigen::VectorXd(center));
  require_positive("radius", radius);
  const Eigen::Vector3d a = safe_normalized(axis, "axis");
  Eigen::Vector3d e1 = Eigen::Vector3d::UnitX() - a.x() * a;
  if (e1.norm() < 1e-6) e1 = Eigen::Vector3d::UnitY() - a.y() * a;
  e1.normalize();
  A_ << e1, a.cross(e1), a;
}

Eigen::Vector2d Sphere::lower() const noexcept { return {-kPi, -0.5 * kPi}; }
Eigen::Vector2d Sphere::upper() const noexcept { return {kPi, 0.5 * kPi}; }

Eigen::Vector3d Sphere::evaluate(double u, double v) const noexcept {
  v = clamp(v, -0.5 * kPi, 0.5 * kPi);
  double su, cu, sv, cv;
  detail::sincos(u, su, cu);
  detail::sincos(v, sv, cv);
  return c_ + r_ * (A_ * Eigen::Vector3d(cu * cv, su * cv, sv));
}

void Sphere::derivatives(double u, double v, int order, SurfaceDerivatives& d) const noexcept {
  const int nd = clamp_order(order);
  v = clamp(v, -0.5 * kPi, 0.5 * kPi);
  for (int k = 0; k <= nd; ++k) {
    for (int l = 0; l <= nd; ++l) {
      const Eigen::Vector3d e(dcos(u, k) * dcos(v, l), dsin(u, k) * dcos(v, l),
                              k == 0 ? dsin(v, l) : 0.0);
      d(k, l) = r_ * (A_ * e);
    }
  }
  d(0, 0) += c_;
}

Eigen::Vector3d Sphere::normal(double u, double v) const noexcept {
  return (evaluate(u, v) - c_) / r_;
}

Eigen::Vector2d Sphere::closest_point(const Eigen::Vector3d& p,
                                      Eigen::Vector3d& point) const noexcept {
  const Eigen::Vector3d q = A_.transpose() * (p - c_);
  const double n = q.norm();
  if (!(n > 0.0)) {
    point = evaluate(0.0, 0.0);
    return {0.0, 0.0};
  }
  point = c_ + (r_ / n) * (p - c_);
  return {detail::atan2(q[1], q[0]), detail::atan2(q[2], std::hypot(q[0], q[1]))};
}

Cylinder::Cylinder(const Eigen::Vector3d& point, const Eigen::Vector3d& direction, double radius)
    : a_(point), r_(radius) {
  require_finite("point", Eigen::VectorXd(point));
  d_ = safe_normalized(direction, "direction");
  require_positive("radius", radius);
  e1_ = d_.unitOrthogonal();
  e2_ = d_.cross(e1_);
}

Eigen::Vector2d Cylinder::lower() const noexcept { return {-kPi, -kInf}; }
Eigen::Vector2d Cylinder::upper() const noexcept { return {kPi, kInf}; }

Eigen::Vector3d Cylinder::evaluate(double u, double v) const noexcept {
  double s, c;
  detail::sincos(u, s, c);
  return a_ + r_ * (c * e1_ + s * e2_) + v * d_;
}

void Cylinder::derivatives(double u, double v, int order, SurfaceDerivatives& d) const noexcept {
  const int nd = clamp_order(order);
  for (int k = 0; k <= nd; ++k)
    for (int l = 0; l <= nd; ++l) d(k, l).setZero();
  for (int k = 0; k <= nd; ++k) d(k, 0) = r_ * (dcos(u, k) * e1_ + dsin(u, k) * e2_);
  d(0, 0) += a_ + v * d_;
  if (nd >= 1) d(0, 1) = d_;
}

Eigen::Vector3d Cylinder::normal(double u, double) const noexcept {
  double s, c;
  detail::sincos(u, s, c);
  return c * e1_ + s * e2_;
}

Eigen::Vector2d Cylinder::closest_point(const Eigen::Vector3d& p,
                                        Eigen::Vector3d& point) const noexcept {
  const Eigen::Vector3d q = p - a_;
  const double v = q.dot(d_);
  const double x = q.dot(e1_), y = q.dot(e2_);
  const double u = (x == 0.0 && y == 0.0) ? 0.0 : detail::atan2(y, x);
  point = evaluate(u, v);
  return {u, v};
}

Plane::Plane(const Eigen::Vector3d& point, const Eigen::Vector3d& normal) : o_(point) {
  require_finite("point", Eigen::VectorXd(point));
  n_ = safe_normalized(normal, "normal");
  e1_ = n_.unitOrthogonal();
  e2_ = n_.cross(e1_);
}

Eigen::Vector2d Plane::lower() const noexcept { return {-kInf, -kInf}; }
Eigen::Vector2d Plane::upper() const noexcept { return {kInf, kInf}; }

Eigen::Vector3d Plane::evaluate(double u, double v) const noexcept {
  return o_ + u * e1_ + v * e2_;
}

void Plane::derivatives(double u, double v, int order, SurfaceDerivatives& d) const noexcept {
  const int nd = clamp_order(order);
  for (int k = 0; k <= nd; ++k)
    for (int l = 0; l <= nd; ++l) d(k, l).setZero();
  d(0, 0) = evaluate(u, v);
  if (nd >= 1) {
    d(1, 0) = e1_;
    d(0, 1) = e2_;
  }
}

Eigen::Vector3d Plane::normal(double, double) const noexcept { return n_; }

Eigen::Vector2d Plane::closest_point(const Eigen::Vector3d& p,
                                     Eigen::Vector3d& point) const noexcept {
  const Eigen::Vector3d q = p - o_;
  const Eigen::Vector2d uv(q.dot(e1_), q.dot(e2_));
  point = evaluate(uv[0], uv[1]);
  return uv;
}

}  // namespace virtmech
