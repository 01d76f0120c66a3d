#include "virtmech/track.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "virtmech/se3.hpp"

namespace virtmech {

namespace {

struct Eval {
  Pose T;
  Jacobian J;
  Vector6 e;
  double cost;
};

inline void evaluate(const Mechanism& m, const Pose& target, const JointVector& theta,
                     const Vector6& W, Eval& ev) noexcept {
  m.forward_jacobian(theta.data(), ev.T, ev.J);
  ev.e = pose_error(target, ev.T);
  ev.cost = ev.e.dot(W.cwiseProduct(ev.e));
}

inline double cost_at(const Mechanism& m, const Pose& target, const JointVector& theta,
                      const Vector6& W) noexcept {
  Pose T;
  m.forward(theta.data(), T);
  const Vector6 e = pose_error(target, T);
  return e.dot(W.cwiseProduct(e));
}

}  // namespace

TrackResult track(const Mechanism& mechanism, const Pose& target, const JointVector& theta0,
                  const Vector6& weights, const TrackOptions& options,
                  JointVector& theta) noexcept {
  const int n = mechanism.dof();
  const KinematicChain& chain = mechanism.chain();
  TrackResult result;
  theta = theta0;
  for (int i = 0; i < n; ++i) {
    theta[i] = std::min(std::max(theta[i], chain.joint(i).lower), chain.joint(i).upper);
  }
  // the largest step per joint
  JointVector step_cap(n);
  for (int i = 0; i < n; ++i) {
    step_cap[i] = chain.joint(i).type == JointType::kRevolute
                      ? options.max_step
                      : options.max_step_prismatic * mechanism.length_scale();
  }

  Eval ev;
  evaluate(mechanism, target, theta, weights, ev);
  JointMatrix H(n, n);
  JointVector g(n), delta(n), trial(n);
  Eigen::LLT<JointMatrix> llt(n);

  for (int it = 0; it < options.max_iterations; ++it) {
    const Jacobian WJ = weights.asDiagonal() * ev.J;
    H.noalias() = ev.J.transpose() * WJ;
    g.noalias() = WJ.transpose() * ev.e;  // J^T W e: eq. 23's residual
    if (g.cwiseAbs().maxCoeff() <= options.gradient_tolerance) {
      result.converged = true;
      break;
    }
    const double mu = options.damping * (H.trace() / n) + 1e-300;
    H.diagonal().array() += mu;
    llt.compute(H);
    delta = llt.solve(g);  // eq. 18: (J^T W J)^-1 J^T W (X_R - X_V)
    // limit the step, keeping its direction
    double scale = 1.0;
    for (int i = 0; i < n; ++i) {
      const double a = std::abs(delta[i]);
      if (a > step_cap[i]) scale = std::min(scale, step_cap[i] / a);
    }
    delta *= scale;
    // backtrack while the cost rises (the linearisation of eq. 16 is only local)
    double alpha = 1.0;
    bool accepted = false;
    for (int k = 0; k < 8; ++k) {
      trial = theta + alpha * delta;
      for (int i = 0; i < n; ++i) {
        trial[i] = std::min(std::max(trial[i], chain.joint(i).lower), chain.joint(i).upper);
      }
      if (cost_at(mechanism, target, trial, weights) <= ev.cost * (1.0 + 1e-12) + 1e-300) {
        accepted = true;
        break;
      }
      alpha *= 0.5;
    }
    result.iterations = it + 1;
    if (!accepted) {  // no descent left at this resolution: a (constrained) minimum
      result.converged = true;
      break;
    }
    const double moved = (trial - theta).cwiseAbs().maxCoeff();
    theta = trial;  // eq. 20
    evaluate(mechanism, target, theta, weights, ev);
    if (moved <= options.step_tolerance) {
      result.converged = true;
      break;
    }
  }
  result.residual = std::sqrt(std::max(ev.cost, 0.0));
  return result;
}

}  // namespace virtmech
