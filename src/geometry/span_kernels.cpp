// The span kernels (span_kernels.hpp): The NURBS Book, A4.2 and A4.4, over the
// homogeneous shape's Taylor coefficients.
#include "span_kernels.hpp"

#include <algorithm>

#include "nurbs_basis.hpp"

namespace virtmech::detail {

namespace {

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

}  // namespace

SpanKernel span_kernel(int p) noexcept {
  static constexpr SpanKernel kTable[5] = {&span_derivatives<1>, &span_derivatives<2>,
                                           &span_derivatives<3>, &span_derivatives<4>,
                                           &span_derivatives<5>};
  return p <= 5 ? kTable[p - 1] : &span_derivatives<-1>;
}

SpanPairKernel span_pair_kernel(int p, int q) noexcept {
  if (p > 3 || q > 3) return &span_pair_derivatives<-1, -1>;
  static constexpr SpanPairKernel kTable[3][3] = {
      {&span_pair_derivatives<1, 1>, &span_pair_derivatives<1, 2>, &span_pair_derivatives<1, 3>},
      {&span_pair_derivatives<2, 1>, &span_pair_derivatives<2, 2>, &span_pair_derivatives<2, 3>},
      {&span_pair_derivatives<3, 1>, &span_pair_derivatives<3, 2>, &span_pair_derivatives<3, 3>}};
  return kTable[p - 1][q - 1];
}

}  // namespace virtmech::detail
