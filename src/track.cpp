#include "virtmech/track.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <utility>

#include "small_cholesky.hpp"
#include "track_detail.hpp"
#include "virtmech/se3.hpp"

namespace virtmech {

namespace {

// The error's own derivative, -de/dtheta, into D where the rotation weights differ: the
// rotation rows of J (the handle's angular velocity) mapped by J_r^-1(phi), the inverse
// right Jacobian of SO(3) at the error's rotation phi (e = log(R_R R_V^T) moves by
// -J_r^-1(phi) omega). With equal rotation weights J^T W e is the cost's gradient as it is
// (J_r^-T phi = phi), so D is J and eq. 18 stands; with unequal ones J^T W e = 0 (eq. 23)
// would be met away from the cost's minimum, where the cost, the backtracking's merit, no
// longer falls along the steps, and Gauss-Newton crawls or stops short (a Probe on a
// seven-joint arm whose five motors power one moment: 62 steps to its fixed point, or a
// false stop, against 2-4 with the error's own derivative). Returns whether D differs.
bool error_derivative(const Jacobian& J, const Vector6& e, const Vector6& W,
                      Jacobian& D) noexcept {
  if (W[3] == W[4] && W[4] == W[5]) return false;
  const Eigen::Vector3d phi = e.tail<3>();
  const double t = phi.norm();
  if (!(t < M_PI - 1e-6)) return false;  // (also NaN: the log is not differentiable there)
  const Eigen::Matrix3d X = skew(phi);
  const double sin_t = std::sin(t), cos_t = std::cos(t);
  // 1 / t^2 - (1 + cos t) / (2 t sin t), by its series below 1e-4 (next term t^4 / 30240)
  const double k = t < 1e-4 ? 1.0 / 12.0 + t * t / 720.0
                            : 1.0 / (t * t) - (1.0 + cos_t) / (2.0 * t * sin_t);
  const Eigen::Matrix3d Jr_inv = Eigen::Matrix3d::Identity() + 0.5 * X + k * (X * X);
  D = J;
  D.bottomRows<3>() = Jr_inv * J.bottomRows<3>();
  return true;
}

// the mechanism's pose, Jacobian, error and weighted cost at theta, the error's own
// derivative (error_derivative: J itself with equal rotation weights) and g = D^T W e
struct Eval {
  Pose T;
  Jacobian J;
  Jacobian D_mapped;
  bool mapped = false;
  Vector6 e;
  JointVector g;
  double cost = 0.0;
  const Jacobian& D() const noexcept { return mapped ? D_mapped : J; }
};

inline void evaluate(const Mechanism& m, const Pose& target, const JointVector& theta,
                     const Vector6& W, Eval& ev) noexcept {
  m.forward_jacobian(theta.data(), ev.T, ev.J);
  ev.e = pose_error(target, ev.T);
  const Vector6 We = W.cwiseProduct(ev.e);
  ev.cost = ev.e.dot(We);
  ev.mapped = error_derivative(ev.J, ev.e, W, ev.D_mapped);
  // eq. 23's residual; -1/2 of the cost gradient
  ev.g.noalias() = ev.D().transpose() * We;
}

inline double cost_at(const Mechanism& m, const Pose& target, const JointVector& theta,
                      const Vector6& W) noexcept {
  Pose T;
  m.forward(theta.data(), T);
  const Vector6 e = pose_error(target, T);
  return e.dot(W.cwiseProduct(e));
}

// the secant extrapolation applies when the directional derivative kept between these
// fractions of its value over a Gauss-Newton step (a linear convergence rate)
constexpr double kSecantMinRatio = 0.1;
constexpr double kSecantMaxRatio = 0.8;

// halvings of a step before it counts as no descent, and the placement as converged. Where
// the residual is large (a weakly weighted rotation error of radians) the Gauss-Newton step
// can be far too long and this stops short of the minimum; 30 halvings found descent there,
// but in the latency harness turned those placements into slow, capped ones (omni+
// surface_probe's Gauss-Newton steps 1.62 -> 2.09 a cycle) without a scenario gaining.
constexpr int kBacktracks = 10;

inline void clamp_to_limits(const Mechanism& m, JointVector& x) noexcept {
  for (int i = 0; i < m.dof(); ++i) x[i] = std::min(std::max(x[i], m.lower()[i]), m.upper()[i]);
}

// joints on a bound that the cost pushes against: -grad_i = 2 g_i points past the bound;
// `upper` gets those on their upper bound (a joint with lower == upper: by the push's side)
std::uint32_t active_set(const Mechanism& m, const JointVector& theta, const JointVector& g,
                         std::uint32_t& upper) noexcept {
  std::uint32_t active = 0;
  upper = 0;
  for (int i = 0; i < m.dof(); ++i) {
    if (theta[i] >= m.upper()[i] && g[i] > 0.0) {
      active |= 1u << i;
      upper |= 1u << i;
    } else if (theta[i] <= m.lower()[i] && g[i] < 0.0) {
      active |= 1u << i;
    }
  }
  return active;
}

}  // namespace

TrackResult track(const Mechanism& mechanism, const Pose& target, const JointVector& theta0,
                  const Vector6& weights, const TrackOptions& options,
                  JointVector& theta) noexcept {
  Pose pose;
  Jacobian J;
  Vector6 error;
  return detail::track(mechanism, target, options,
                       PlacementIO{&weights, &theta0, &theta, &pose, &J, &error});
}

TrackResult detail::closed_form_result(const Mechanism& mechanism, const Vector6& weights,
                                       const JointVector& theta, const Jacobian& J,
                                       const Vector6& error) noexcept {
  TrackResult result;
  const Vector6 We = weights.cwiseProduct(error);
  result.converged = true;
  result.residual = std::sqrt(std::max(error.dot(We), 0.0));
  // the cost's push on the joints, needed only where one sits on a bound
  bool on_bound = false;
  for (int i = 0; i < mechanism.dof(); ++i) {
    on_bound = on_bound || !(theta[i] < mechanism.upper()[i] && theta[i] > mechanism.lower()[i]);
  }
  if (on_bound) {
    JointVector g;
    Jacobian D;
    g.noalias() = (error_derivative(J, error, weights, D) ? D : J).transpose() * We;
    result.active = active_set(mechanism, theta, g, result.active_upper);
  }
  return result;
}

namespace {

// Projected, damped Gauss-Newton (eqs. 18-20) from a start: its buffers, allocated once per
// placement on the stack (fixed capacity), and its stages.
class GaussNewton {
 public:
  GaussNewton(const Mechanism& mechanism, const Pose& target, const Vector6& weights,
              const TrackOptions& options) noexcept
      : m_(mechanism), target_(target), W_(weights), options_(options), n_(mechanism.dof()),
        step_cap_(n_), H_(n_, n_), L_(n_, n_), delta_(n_), trial_(n_), extrapolated_(n_) {
    for (int i = 0; i < n_; ++i) {
      step_cap_[i] = m_.joint_type(i) == JointType::kRevolute
                         ? options_.max_step
                         : options_.max_step_prismatic * m_.length_scale();
    }
  }

  // Iterates from theta (clamped to the limits) to the placement, written to theta; the
  // last evaluation (at theta) in `last`.
  TrackResult run(JointVector& theta, const Eval*& last) noexcept {
    TrackResult result;
    clamp_to_limits(m_, theta);
    evaluate(m_, target_, theta, W_, *ev_);
    for (int it = 0; it < options_.max_iterations; ++it) {
      // joints on a bound the cost pushes against stay there (projected Gauss-Newton: their
      // gradient entries and columns leave the step, so the others' step is the
      // constrained problem's, not an unconstrained one clipped)
      std::uint32_t upper;
      const std::uint32_t locked = active_set(m_, theta, ev_->g, upper);
      JointVector& g_free = trial_;  // scratch until the step is taken
      g_free = ev_->g;
      for (int i = 0; i < n_; ++i) {
        if (locked & (1u << i)) g_free[i] = 0.0;
      }
      if (g_free.cwiseAbs().maxCoeff() <= options_.gradient_tolerance) {
        result.converged = true;
        break;
      }
      const double scale = gauss_newton_step(locked, g_free);
      result.iterations = it + 1;
      const double slope0 = g_free.dot(delta_);  // > 0: delta descends the weighted cost
      if (scale == 1.0 && delta_.cwiseQuotient(step_cap_).cwiseAbs().maxCoeff() < 1e-4) {
        step_and_secant(theta, slope0);
      } else if (!backtracked(theta)) {  // no descent along delta: a (constrained) minimum
        result.converged = true;
        break;
      }
      const double moved = (trial_ - theta).cwiseAbs().maxCoeff();
      theta = trial_;  // eq. 20
      std::swap(ev_, trial_ev_);
      if (moved <= options_.step_tolerance) {
        result.converged = true;
        break;
      }
    }
    finish(theta, result);
    last = ev_;
    return result;
  }

 private:
  // eq. 18: delta = (J^T W J)^-1 J^T W (X_R - X_V), damped so rank-deficient J^T W J gives
  // the minimum-norm step, the locked joints' rows and columns out; scaled to the step caps
  // (returns the scale)
  double gauss_newton_step(std::uint32_t locked, const JointVector& g_free) noexcept {
    const Jacobian WJ = W_.asDiagonal() * ev_->D();
    H_.noalias() = ev_->D().transpose() * WJ;
    H_.diagonal().array() += options_.damping * (H_.trace() / n_) + 1e-300;
    for (int i = 0; i < n_; ++i) {
      if (!(locked & (1u << i))) continue;
      H_.row(i).setZero();
      H_.col(i).setZero();
      H_(i, i) = 1.0;
    }
    L_ = H_;
    delta_ = g_free;
    if (detail::cholesky_in_place(L_)) {
      detail::cholesky_solve_in_place(L_, delta_);
    } else {
      delta_ = Eigen::LLT<JointMatrix>(H_).solve(g_free);  // not positive definite (NaN, ...)
    }
    double scale = 1.0;
    for (int i = 0; i < n_; ++i) {
      const double a = std::abs(delta_[i]);
      if (a > step_cap_[i]) scale = std::min(scale, step_cap_[i] / a);
    }
    delta_ *= scale;
    return scale;
  }

  // Near the solution cost differences are at rounding level: take the step, then go to
  // the zero of the directional derivative along delta (secant) if it changed sign, or if
  // it kept a good part of its value: Gauss-Newton then converges only linearly (a residual
  // that cannot vanish, as a 5-joint mechanism held to a 6-D pose), and the secant
  // extrapolation removes the slow component. The trial point in trial_ (trial_ev_).
  void step_and_secant(const JointVector& theta, double slope0) noexcept {
    trial_ = theta + delta_;
    clamp_to_limits(m_, trial_);
    evaluate(m_, target_, trial_, W_, *trial_ev_);
    const double slope1 = trial_ev_->g.dot(delta_);
    if (slope0 > 0.0 && slope1 < 0.0) {
      trial_ = theta + (slope0 / (slope0 - slope1)) * delta_;
      clamp_to_limits(m_, trial_);
      evaluate(m_, target_, trial_, W_, *trial_ev_);
    } else if (slope0 > 0.0 && slope1 >= kSecantMinRatio * slope0 &&
               slope1 <= kSecantMaxRatio * slope0) {
      extrapolated_ = theta + (slope0 / (slope0 - slope1)) * delta_;
      clamp_to_limits(m_, extrapolated_);
      evaluate(m_, target_, extrapolated_, W_, *extrapolated_ev_);
      if (std::abs(extrapolated_ev_->g.dot(delta_)) < slope1) {  // kept only if it helped
        trial_ = extrapolated_;
        std::swap(trial_ev_, extrapolated_ev_);
      }
    }
  }

  // Far from it the linearisation of eq. 16 is only local: backtrack on the cost. The
  // trial point in trial_ (trial_ev_); false where no step along delta descends.
  bool backtracked(const JointVector& theta) noexcept {
    double alpha = 1.0;
    for (int k = 0; k < kBacktracks; ++k) {
      trial_ = theta + alpha * delta_;
      clamp_to_limits(m_, trial_);
      if (cost_at(m_, target_, trial_, W_) <= ev_->cost) {
        evaluate(m_, target_, trial_, W_, *trial_ev_);
        return true;
      }
      alpha *= 0.5;
    }
    return false;
  }

  // the active set at theta; where no tolerance was met, converged if the projected
  // gradient meets the gradient tolerance; the residual
  void finish(const JointVector& theta, TrackResult& result) noexcept {
    result.active = active_set(m_, theta, ev_->g, result.active_upper);
    if (!result.converged) {
      trial_ = ev_->g;  // the projected gradient
      for (int i = 0; i < n_; ++i) {
        if (result.active & (1u << i)) trial_[i] = 0.0;
      }
      result.converged = trial_.cwiseAbs().maxCoeff() <= options_.gradient_tolerance;
    }
    result.residual = std::sqrt(std::max(ev_->cost, 0.0));
  }

  const Mechanism& m_;
  const Pose& target_;
  const Vector6& W_;
  const TrackOptions& options_;
  const int n_;
  JointVector step_cap_;
  // three evaluations, swapped rather than copied as a trial is accepted; ev_ is always
  // the evaluation at theta
  Eval evals_[3];
  Eval* ev_ = &evals_[0];
  Eval* trial_ev_ = &evals_[1];
  Eval* extrapolated_ev_ = &evals_[2];
  JointMatrix H_, L_;
  JointVector delta_, trial_, extrapolated_;
};

}  // namespace

TrackResult detail::track(const Mechanism& mechanism, const Pose& target,
                          const TrackOptions& options, const PlacementIO& io) noexcept {
  if (options.closed_form && mechanism.place(target, *io.w, *io.start, *io.theta, *io.T, *io.J,
                                             *io.e)) {
    return closed_form_result(mechanism, *io.w, *io.theta, *io.J, *io.e);
  }
  *io.theta = *io.start;
  GaussNewton solver(mechanism, target, *io.w, options);
  const Eval* last = nullptr;
  const TrackResult result = solver.run(*io.theta, last);
  *io.T = last->T;
  *io.J = last->J;
  *io.e = last->e;
  return result;
}

}  // namespace virtmech
