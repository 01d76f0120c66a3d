// A probe's stylus whose tip is held to a curve or a surface (closed_form.hpp:
// curve_stylus_newton, surface_stylus_newton): Newton's method on the shape's parameters and
// the sphere of stylus directions, with exact second derivatives.
#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "../closed_form.hpp"
#include "angle_solve.hpp"

namespace virtmech::detail {

namespace {

// Newton's method for a probe's stylus whose tip is held to a shape of N parameters (a
// curve, N = 1, or a surface, N = 2): x the parameters in [lo, hi], u the tip-to-handle
// direction on S^2, minimising w_p |P(x) + L u - p_R|^2 + w_r angle(u, u_R)^2.
// `shape(x, order, P, D1, D2)`: the point, its first derivatives (columns) and, for order
// 2, its second (column i * N + j the derivative in x_i and x_j).
template <int N, typename Shape>
class StylusNewton {
 public:
  static constexpr int M = N + 2;
  using VecN = Eigen::Matrix<double, N, 1>;
  using VecM = Eigen::Matrix<double, M, 1>;
  using MatM = Eigen::Matrix<double, M, M>;
  using D1 = Eigen::Matrix<double, 3, N>;
  using D2 = Eigen::Matrix<double, 3, N * N>;
  using Basis = Eigen::Matrix<double, 3, 2>;

  StylusNewton(const Shape& shape, const VecN& lo, const VecN& hi,
               const StylusObjective& objective) noexcept
      : shape_(shape), lo_(lo), hi_(hi), o_(objective), L_(objective.length),
        // the position term stiff against the turn's (the rotation weighing at most a
        // hundredth at the stylus's length): where the valley below is narrow; on a curve
        // (N = 1) there is none (see second_order_correction)
        stiff_(N == 2 && objective.w_r <= 1e-2 * objective.w_p * L_ * L_) {}

  // The local minimum from (x, u), written there; false where it declines (see
  // curve_stylus_newton).
  bool solve(VecN& x, Eigen::Vector3d& u) noexcept {
    if (!inside(x) || !(o_.w_p > 0.0)) return false;
    u.normalize();
    x_uncorrected_ = x;
    u_uncorrected_ = u;
    for (int it = 0; it < 30; ++it) {
      Here e;
      evaluate(x, u, e);
      if (corrected_) {  // the correction kept only where it lowered the cost
        corrected_ = false;
        if (e.f > f_uncorrected_) {
          x = x_uncorrected_;
          u = u_uncorrected_;
          --it;
          continue;
        }
      }
      const Basis E = tangent_basis(u);  // (u's, for both uses below)
      if (second_order_correction(e, E, x, u)) {
        --it;
        continue;
      }
      f_before_ = kInf;
      const Outcome outcome = newton_step(e, E, x, u);
      if (outcome != Outcome::kGoOn) return outcome == Outcome::kConverged;
    }
    return false;
  }

 private:
  enum class Outcome { kGoOn, kConverged, kDeclined };

  // the shape and the cost's terms at (x, u): the handle's position error r, the angle
  // from u_R with acos_squared_terms' h and dh, and the cost f
  struct Here {
    Eigen::Vector3d P, r;
    D1 d1;
    D2 d2;
    double ang, h, dh, f;
  };

  bool inside(const VecN& y) const noexcept {
    return (y.array() >= lo_.array()).all() && (y.array() <= hi_.array()).all();
  }

  void evaluate(const VecN& x, const Eigen::Vector3d& u, Here& e) const noexcept {
    shape_(x, 2, e.P, e.d1, e.d2);
    e.r = e.P + L_ * u - o_.p_R;  // the handle's position error
    acos_squared_terms(u.dot(o_.u_R), u.cross(o_.u_R).norm(), e.ang, e.h, e.dh);
    e.f = o_.w_p * e.r.squaredNorm() + o_.w_r * e.ang * e.ang;
  }

  double cost(const VecN& y, const Eigen::Vector3d& u_) const noexcept {
    Eigen::Vector3d P;
    D1 d1;
    D2 d2;
    shape_(y, 0, P, d1, d2);
    const Eigen::Vector3d r = P + L_ * u_ - o_.p_R;
    const double ang = detail::atan2(u_.cross(o_.u_R).norm(), u_.dot(o_.u_R));
    return o_.w_p * r.squaredNorm() + o_.w_r * ang * ang;
  }

  // A full Newton step that raised the cost, or whose position error is off its linear
  // model by more than 1e-3 of it, has left the valley of the position term, the stiff
  // one: on a surface with w_r << w_p L^2 (a nearest placement, the rotation weighted 1e-6)
  // and the handle pressed in, the tip may sit anywhere on the circle where the stylus
  // reaches the surface, a narrow, curved valley, where the quadratic model's error along a
  // long step (w_p times the surface's and the sphere's curvature) outweighs the angle
  // term's gain: the Maratos effect. The second-order correction brings the position error
  // back to what the step's linear model predicted, by the least change of the parameters
  // and the stylus: (dx, du) = -A^T (A A^T)^-1 (r - r_model), A = [d1, L E]; it is kept
  // where it lowers the cost (at most 12 of them, each costing one or two evaluations
  // more), and the convergence test then starts afresh. On a curve (N = 1) A is square: the
  // position term's minimum is a point, there is no valley, and no correction is made; nor
  // where the turn's weight is not small (`stiff`), where the corrections were kept on half
  // the tries or fewer. True where (x, u) moved by a correction.
  bool second_order_correction(const Here& e, const Basis& E, VecN& x,
                               Eigen::Vector3d& u) noexcept {
    const double off_model = (e.r - r_model_).norm();
    if (!(stiff_ && f_before_ < kInf && corrections_ < 12 &&
          (e.f > f_before_ || (off_model > 1e-3 * e.r.norm() && off_model > 1e-12 * L_)))) {
      return false;
    }
    ++corrections_;
    Eigen::Matrix<double, 3, M> A;
    A.template leftCols<N>() = e.d1;
    A.template rightCols<2>() = L_ * E;
    const Eigen::Matrix3d AAt = A * A.transpose();
    const Eigen::LLT<Eigen::Matrix3d> llt(AAt);
    if (llt.info() != Eigen::Success) return false;
    const VecM c = -A.transpose() * llt.solve(Eigen::Vector3d(e.r - r_model_));
    const VecN x_c = x + c.template head<N>();
    if (!(c.allFinite() && inside(x_c))) return false;
    x_uncorrected_ = x;
    u_uncorrected_ = u;
    f_uncorrected_ = e.f;
    corrected_ = true;
    last_ = 0.0;  // the next full step is not the one before's successor
    x = x_c;
    const Eigen::Vector3d w = E * c.template tail<2>();
    u = (u + w).normalized();
    f_before_ = kInf;
    return true;
  }

  // the cost's gradient g and Hessian H in (x, the tangent plane at u: basis E)
  void gradient_hessian(const Here& e, const Eigen::Vector3d& u, const Basis& E, VecM& g,
                        MatM& H) const noexcept {
    const double w_p = o_.w_p, w_r = o_.w_r, L = L_;
    // the gradient and Hessian in u as a function on R^3, then on the sphere
    const Eigen::Vector3d g_u = 2.0 * w_p * L * e.r - 2.0 * w_r * e.h * o_.u_R;
    g.template head<N>() = 2.0 * w_p * (e.d1.transpose() * e.r);
    g.template tail<2>() = E.transpose() * g_u;
    for (int i = 0; i < N; ++i)
      for (int j = 0; j < N; ++j)
        H(i, j) = 2.0 * w_p * (e.d1.col(i).dot(e.d1.col(j)) + e.d2.col(i * N + j).dot(e.r));
    const Eigen::Matrix<double, 2, N> H_ux = 2.0 * w_p * L * (E.transpose() * e.d1);
    H.template bottomLeftCorner<2, N>() = H_ux;
    H.template topRightCorner<N, 2>() = H_ux.transpose();
    const Eigen::Vector2d Ru = E.transpose() * o_.u_R;
    Eigen::Matrix2d H_uu = (2.0 * w_p * L * L - u.dot(g_u)) * Eigen::Matrix2d::Identity();
    H_uu -= 2.0 * w_r * e.dh * Ru * Ru.transpose();
    H.template bottomRightCorner<2, 2>() = H_uu;
  }

  // Newton's step where H is positive definite (`newton`); else the saddle-free step (each
  // eigendirection's Newton step with |lambda|: descending along negative curvature, as
  // where the stylus stands square to the shape and the position cost is flat to second
  // order along it)
  VecM newton_or_saddle_free(const MatM& H, const VecM& g, bool& newton) const noexcept {
    const Eigen::LLT<MatM> llt(H);
    newton = llt.info() == Eigen::Success;
    if (newton) return -llt.solve(g);
    Eigen::SelfAdjointEigenSolver<MatM> eig;
    if constexpr (M == 3) {
      eig.computeDirect(H);
    } else {
      eig.compute(H);
    }
    const VecM lam = eig.eigenvalues().cwiseAbs();
    const double floor = 1e-9 * std::max(lam.maxCoeff(), o_.w_p * L_ * L_);
    const VecM gv = eig.eigenvectors().transpose() * g;
    return -eig.eigenvectors() * gv.cwiseQuotient(lam.cwiseMax(floor));
  }

  // the factor that caps the step at a tenth of the stylus of tip motion and 0.2 rad of turn
  double step_cap(const D1& d1, const VecM& step) const noexcept {
    const double tip_move = (d1 * step.template head<N>()).norm();
    double scale = 1.0;
    if (tip_move > 0.1 * L_) scale = 0.1 * L_ / tip_move;
    if (step.template tail<2>().norm() * scale > 0.2) scale = 0.2 / step.template tail<2>().norm();
    return scale;
  }

  // (x, u) moved by t times the step (the exponential map on the sphere)
  static void moved_to(const VecN& x, const Eigen::Vector3d& u, const Basis& E,
                       const VecM& step, double t, VecN& x_t, Eigen::Vector3d& u_t) noexcept {
    x_t = x + t * step.template head<N>();
    const double n = t * step.template tail<2>().norm();
    // cos n and sin(n) / n; below 1e-3 by their Taylor polynomials (next terms n^6 / 720
    // and n^6 / 5040 relative, below 1e-20), as on the sphere
    const double n2 = n * n;
    double cn = 1.0 - n2 * (0.5 - n2 * (1.0 / 24.0));
    double sn_n = 1.0 - n2 * (1.0 / 6.0 - n2 * (1.0 / 120.0));
    if (!(n < 1e-3)) {
      cn = std::cos(n);
      sn_n = std::sin(n) / n;
    }
    u_t = n > 0.0
              ? Eigen::Vector3d((cn * u + sn_n * t * (E * step.template tail<2>())).normalized())
              : u;
  }

  // backtracking (Armijo) on the cost from (x, u), of cost f0 and gradient g (the held
  // parameters' zero), along a descent step projected onto the bounds (Bertsekas' projected
  // Armijo rule: the parameters that would leave stop on their bound, the others go on, and
  // the decrease asked is the gradient's along the projected move); false where no step
  // within the bounds descends
  bool line_search(const VecN& x, const Eigen::Vector3d& u, const Basis& E, const VecM& step,
                   double f0, const VecM& g, VecN& x_new, Eigen::Vector3d& u_new) const noexcept {
    double t = 1.0;
    bool accepted = false;
    for (int k = 0; k < 30 && !accepted; ++k, t *= 0.5) {
      moved_to(x, u, E, step, t, x_new, u_new);
      x_new = x_new.cwiseMax(lo_).cwiseMin(hi_);
      const double slope = g.template head<N>().dot(x_new - x) +
                           t * g.template tail<2>().dot(step.template tail<2>());
      accepted = slope < 0.0 && cost(x_new, u_new) <= f0 + 1e-4 * slope;
    }
    return accepted;
  }

  // Projected Newton on the box [lo, hi] (Bertsekas): a parameter at a bound that the
  // descent would push out is held there, its row and column of H replaced by the unit's;
  // the others are free, and a parameter leaves its hold as soon as the descent points
  // inward. Parameter i held, moved by `onto` (onto its bound): the others' step is
  // Newton's with it fixed there (their gradient moved by the coupling), its own `onto`.
  static void hold(int i, double onto, VecM& g, MatM& H) noexcept {
    g += H.col(i) * onto;
    H.row(i).setZero();
    H.col(i).setZero();
    H(i, i) = 1.0;
    g[i] = -onto;
  }

  // Held where the descent pushes out at a bound, or within 1e-3 of the parameter's range
  // of it (Bertsekas' epsilon-active set: an iterate creeping toward a bound along a curved
  // valley is put on it); returns the parameters at a bound left free.
  int hold_at_bounds(const VecN& x, VecM& g, MatM& H) const noexcept {
    int free_at_bound = 0;
    for (int i = 0; i < N; ++i) {
      const double band = std::isfinite(hi_[i] - lo_[i]) ? 1e-3 * (hi_[i] - lo_[i]) : 0.0;
      if (x[i] <= lo_[i] + band && g[i] > 0.0) {
        hold(i, lo_[i] - x[i], g, H);
      } else if (x[i] >= hi_[i] - band && g[i] < 0.0) {
        hold(i, hi_[i] - x[i], g, H);
      } else if (x[i] <= lo_[i] || x[i] >= hi_[i]) {
        free_at_bound |= 1 << i;
      }
    }
    return free_at_bound;
  }

  // the step on the free parameters; one at a bound that the step (through the coupling in
  // H) would move out, where its own gradient points in, is held as well and the step
  // taken again (the reduced step stays a descent)
  VecM free_step(const VecN& x, VecM& g, MatM& H, bool& newton) const noexcept {
    int free_at_bound = hold_at_bounds(x, g, H);
    VecM step = newton_or_saddle_free(H, g, newton);
    for (int i = 0; i < N && free_at_bound; ++i) {
      if (!((free_at_bound >> i) & 1)) continue;
      free_at_bound &= ~(1 << i);
      if ((x[i] <= lo_[i] && step[i] < 0.0) || (x[i] >= hi_[i] && step[i] > 0.0)) {
        hold(i, 0.0, g, H);
        step = newton_or_saddle_free(H, g, newton);
      }
    }
    return step;
  }

  // x + step within the bounds
  bool within_bounds(const VecN& x, const VecM& step) const noexcept {
    return inside(x + step.template head<N>());
  }

  // One step from (x, u): the full Newton step where H is positive definite and the step
  // within its caps and the bounds, else a capped step with a line search projected onto
  // the bounds
  Outcome newton_step(const Here& e, const Basis& E, VecN& x, Eigen::Vector3d& u) noexcept {
    VecM g;
    MatM H;
    gradient_hessian(e, u, E, g, H);
    const VecM gradient = g;
    bool newton;
    VecM step = free_step(x, g, H, newton);
    if (!step.allFinite()) return Outcome::kDeclined;
    const double scale = step_cap(e.d1, step);
    step *= scale;
    const bool within = within_bounds(x, step);
    VecN x_new;
    Eigen::Vector3d u_new;
    const bool full = newton && scale == 1.0 && within;
    if (full) {
      moved_to(x, u, E, step, 1.0, x_new, u_new);
      x_new = x_new.cwiseMax(lo_).cwiseMin(hi_);  // (onto a bound exactly where held onto it)
      f_before_ = o_.w_p * e.r.squaredNorm() + o_.w_r * e.ang * e.ang;
      r_model_ = e.r + e.d1 * step.template head<N>() + L_ * (E * step.template tail<2>());
    } else {
      const double f0 = o_.w_p * e.r.squaredNorm() + o_.w_r * e.ang * e.ang;
      if (!line_search(x, u, E, step, f0, gradient, x_new, u_new)) return Outcome::kDeclined;
    }
    const double moved = (e.d1 * (x_new - x)).norm(), n = (u_new - u).norm();
    x = x_new;
    u = u_new;
    // converged: a full Newton step that moved the tip and the stylus by rounding noise (the
    // next would be its square); or, after two full Newton steps, one whose successor would
    const double a = std::max(moved / L_, n);
    if (full && a <= 1e-12) return Outcome::kConverged;
    if (full && next_newton_step_below(a, last_, 1e-12)) return Outcome::kConverged;
    last_ = full ? a : 0.0;
    return Outcome::kGoOn;
  }

  const Shape& shape_;
  const VecN lo_, hi_;
  const StylusObjective o_;
  const double L_;
  const bool stiff_;
  double last_ = 0.0;  // the last full Newton step (scaled), 0 if the last was not one
  // after a full Newton step: the cost before it and the position error its linear model
  // predicted (for the second-order correction); after a correction, the point it
  // corrected and its cost
  double f_before_ = kInf;
  Eigen::Vector3d r_model_ = Eigen::Vector3d::Zero();
  int corrections_ = 0;
  bool corrected_ = false;
  VecN x_uncorrected_;
  Eigen::Vector3d u_uncorrected_;
  double f_uncorrected_ = 0.0;
};

}  // namespace

bool curve_stylus_newton(const Curve& curve, const StylusObjective& objective, double& s,
                         Eigen::Vector3d& u) noexcept {
  using V1 = Eigen::Matrix<double, 1, 1>;
  const auto shape = [&](const V1& x, int order, Eigen::Vector3d& P,
                         Eigen::Matrix<double, 3, 1>& d1, Eigen::Matrix<double, 3, 1>& d2) {
    CurveDerivatives d;
    curve.derivatives(x[0], order, d);
    P = d.col(0);
    if (order >= 1) d1 = d.col(1);
    if (order >= 2) d2 = d.col(2);
  };
  V1 x = V1::Constant(s);
  StylusNewton<1, decltype(shape)> newton(shape, V1::Constant(curve.lower()),
                                          V1::Constant(curve.upper()), objective);
  const bool ok = newton.solve(x, u);
  s = x[0];
  return ok;
}

bool surface_stylus_newton(const Surface& surface, const StylusObjective& objective,
                           const Eigen::Vector2d& lo, const Eigen::Vector2d& hi,
                           Eigen::Vector2d& uv, Eigen::Vector3d& u) noexcept {
  const auto shape = [&](const Eigen::Vector2d& x, int order, Eigen::Vector3d& P,
                         Eigen::Matrix<double, 3, 2>& d1, Eigen::Matrix<double, 3, 4>& d2) {
    SurfaceDerivatives d;
    surface.derivatives(x[0], x[1], order, d);
    P = d(0, 0);
    if (order >= 1) d1 << d(1, 0), d(0, 1);
    if (order >= 2) d2 << d(2, 0), d(1, 1), d(1, 1), d(0, 2);
  };
  StylusNewton<2, decltype(shape)> newton(shape, lo, hi, objective);
  return newton.solve(uv, u);
}

}  // namespace virtmech::detail
