#include "virtmech/controller.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "track_detail.hpp"
#include "virtmech/filters.hpp"
#include "virtmech/se3.hpp"
#include "virtmech/validate.hpp"

namespace virtmech {

namespace {

Vector6 scaled_ones(double L) {
  Vector6 w;
  w << 1.0, 1.0, 1.0, L * L, L * L, L * L;
  return w;
}

Vector6 checked_weights(const std::string& name, const Vector6& w) {
  require_non_negative(name, w);
  return w;
}

// largest change per cycle, as a fraction of the placement's step cap, that the warm start
// extrapolates
constexpr double kWarmStartFraction = 0.1;

// The range-space filter P(W) = W J (J^T W J)^+ J^T (eq. 5) applied to wrenches, W diagonal.
// With S = W^1/2 J, S (S^T S)^+ = (S S^T)^+ S, so equally P(W) x = W^1/2 G^+ W^1/2 J J^T x
// with G = S S^T restricted to the k task axes of non-zero weight. J^T W J (m x m) and G
// (k x k) have the same non-zero eigenvalues, hence the same pseudo-inverse cut: the smaller
// one is factored (for the Omni, k = 3 forces against a 5-joint probe).
class RangeFilter {
 public:
  RangeFilter(const Jacobian& J, const Vector6& w) noexcept : J_(J) {
    const int m = static_cast<int>(J.cols());
    for (int i = 0; i < 6; ++i) {
      if (w[i] > 0.0) {
        axes_[k_] = i;
        sqrt_w_[k_] = std::sqrt(w[i]);
        ++k_;
      }
    }
    dual_ = k_ < m;
    if (dual_) {
      S_.resize(k_, m);
      for (int r = 0; r < k_; ++r) S_.row(r) = sqrt_w_[r] * J.row(axes_[r]);
      JointMatrix G(k_, k_);
      G.noalias() = S_ * S_.transpose();
      symmetric_pinv(G, Gp_);
    } else {
      WJ_.noalias() = w.asDiagonal() * J;
      JointMatrix H(m, m);
      H.noalias() = J.transpose() * WJ_;
      symmetric_pinv(H, Gp_);
    }
  }

  /// P(W) x.
  Vector6 apply(const Vector6& x) const noexcept {
    JointVector u(J_.cols());
    u.noalias() = J_.transpose() * x;
    Vector6 out;
    if (dual_) {
      JointVector v(k_), y(k_);
      v.noalias() = S_ * u;
      y.noalias() = Gp_ * v;
      out.setZero();
      for (int r = 0; r < k_; ++r) out[axes_[r]] = sqrt_w_[r] * y[r];
    } else {
      JointVector y(J_.cols());
      y.noalias() = Gp_ * u;
      out.noalias() = WJ_ * y;
    }
    return out;
  }

 private:
  const Jacobian& J_;
  std::array<int, 6> axes_{};
  std::array<double, 6> sqrt_w_{};
  int k_ = 0;
  bool dual_ = false;
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor, 6, kMaxDof> S_;
  Jacobian WJ_;
  JointMatrix Gp_;
};

// The warm start of a placement: theta moved on by its last change, when that change is
// the smooth motion of one cycle (within a tenth of the solver's step cap per joint); after
// a jump (a branch switch, a glitch) extrapolating would start far off, so theta itself.
JointVector warm_start(const Mechanism& mech, const TrackOptions& opts, const JointVector& theta,
                       const JointVector& theta_prev) noexcept {
  JointVector start = theta;
  const JointVector change = theta - theta_prev;
  for (int i = 0; i < mech.dof(); ++i) {
    const double cap = mech.joint_type(i) == JointType::kRevolute
                           ? opts.max_step
                           : opts.max_step_prismatic * mech.length_scale();
    if (!(std::abs(change[i]) <= kWarmStartFraction * cap)) return start;
  }
  start += change;
  return start;
}

}  // namespace

ControllerModel make_controller_model(const Device& device, const Mechanism& mechanism,
                                      const ControllerSettings& s) {
  ControllerModel m;
  require_non_negative("length_scale", s.length_scale);
  m.length_scale = s.length_scale > 0.0 ? s.length_scale : mechanism.length_scale();
  const double L = m.length_scale;
  const Vector6 unit = scaled_ones(L);

  // task axes along which the passive joints never move (checked at the device's home)
  Pose T;
  Jacobian J;
  device.forward_jacobian(device.home().data(), T, J);
  for (int k = 0; k < 6; ++k) {
    bool moved = false;
    for (int i = 0; i < device.dof(); ++i) {
      if (!device.actuated(i) && std::abs(J(k, i)) > 1e-9) moved = true;
    }
    m.renderable[static_cast<size_t>(k)] = !moved;
  }
  Vector6 mask;
  for (int k = 0; k < 6; ++k) mask[k] = m.renderable[static_cast<size_t>(k)] ? 1.0 : 0.0;

  // W_A and W_e on the axes the device renders, W_e* on the rest (eq. 25); gains on the
  // axes it cannot render are zero, so the null-space filter does not turn unrenderable
  // moments into forces along the mechanism's motion (docs/theory.md, section 5)
  const Vector6 powered = mask.cwiseProduct(unit);
  const Vector6 unpowered = (Vector6::Ones() - mask).cwiseProduct(unit);
  m.w_a = s.w_a ? checked_weights("w_a", *s.w_a) : powered;
  m.w_e = s.w_e ? checked_weights("w_e", *s.w_e) : powered;
  m.w_e_star = s.w_e_star ? checked_weights("w_e_star", *s.w_e_star) : unpowered;
  if (m.w_e.isZero(0.0)) throw std::invalid_argument("w_e: expected at least one weight > 0, got all zero");
  if (m.w_a.isZero(0.0)) throw std::invalid_argument("w_a: expected at least one weight > 0, got all zero");
  require_non_negative("secondary_weight", s.secondary_weight);
  m.w_e_effective = m.w_e + s.secondary_weight * unit;
  m.w_e_star_effective = m.w_e_star + s.secondary_weight * unit;

  const double k = device.stiffness(), b = device.damping();
  m.kp = s.kp ? checked_weights("kp", *s.kp) : Vector6(k * powered);
  m.kv = s.kv ? checked_weights("kv", *s.kv) : Vector6(b * powered);

  m.law = s.law;
  switch (s.law) {
    case ControlLaw::kAuto:
      m.under_actuated_term = !device.fully_actuated() && !m.w_e_star.isZero(0.0);
      break;
    case ControlLaw::kNullSpace:
      m.under_actuated_term = false;
      break;
    case ControlLaw::kUnderActuated:
      if (m.w_e_star.isZero(0.0)) {
        throw std::invalid_argument(
            "w_e_star: law 'under_actuated' needs at least one weight > 0, got all zero (the "
            "device " + device.name() + " has no un-powered task axis by default)");
      }
      m.under_actuated_term = true;
      break;
    default:
      throw std::invalid_argument("law: expected auto, null_space or under_actuated");
  }
  if (s.error_velocity != ErrorVelocity::kRelative && s.error_velocity != ErrorVelocity::kHandle) {
    throw std::invalid_argument("error_velocity: expected relative or handle");
  }
  m.error_velocity = s.error_velocity;

  require_positive("period_s", s.period_s);
  require_non_negative("ramp_time_s", s.ramp_time_s);
  require_non_negative("watchdog_s", s.watchdog_s);
  m.period_s = s.period_s;
  m.ramp_cycles = std::max(1L, static_cast<long>(std::llround(s.ramp_time_s / s.period_s)));
  m.watchdog_s = s.watchdog_s;

  require_non_negative("max_force", s.max_force);
  require_non_negative("max_torque", s.max_torque);
  m.max_force = s.max_force > 0.0 ? std::min(s.max_force, device.max_force()) : device.max_force();
  m.max_torque =
      s.max_torque > 0.0 ? std::min(s.max_torque, device.max_torque()) : device.max_torque();

  if (s.max_iterations < 1 || s.max_iterations_initial < 1) {
    std::ostringstream os;
    os << "max_iterations: expected >= 1, got " << s.max_iterations << " (initial "
       << s.max_iterations_initial << ")";
    throw std::invalid_argument(os.str());
  }
  m.track.max_iterations = s.max_iterations;
  m.track_initial.max_iterations = s.max_iterations_initial;
  return m;
}

Controller::Controller(std::shared_ptr<const Device> device,
                       std::shared_ptr<const Mechanism> mechanism,
                       const ControllerSettings& settings)
    : device_(std::move(device)), mechanism_(std::move(mechanism)) {
  if (!device_) throw std::invalid_argument("device: expected a device, got null");
  if (!mechanism_) throw std::invalid_argument("mechanism: expected a mechanism, got null");
  model_ = make_controller_model(*device_, *mechanism_, settings);
  reset();
  last_.torque = JointVector::Zero(device_->dof());
  last_.theta = theta_;
  last_.theta_star = theta_star_;
}

void Controller::reset() noexcept {
  theta_ = mechanism_->home();
  theta_star_ = mechanism_->home();
  first_ = true;
  ramp_count_ = 0;
  last_t_ = std::numeric_limits<double>::quiet_NaN();
}

void Controller::fault(std::uint32_t bits, CycleOutput& out) noexcept {
  out.status |= bits;
  out.torque.setZero(device_->dof());
  out.wrench.setZero();
  out.ramp = 0.0;
  out.limit_scale = 1.0;
  ramp_count_ = 0;  // ramp in again once the fault clears
  first_ = true;
}

void Controller::placement_rate(const Jacobian& J_V, const Vector6& W, const Vector6& v_R,
                                Vector6& e_dot) const noexcept {
  if (model_.error_velocity == ErrorVelocity::kHandle) {
    e_dot = -v_R;  // eq. 10
    return;
  }
  // theta_dot = (J^T W J)^+ J^T W v_R: the rate of the weighted placement, first order
  const int m = static_cast<int>(J_V.cols());
  const Jacobian WJ = W.asDiagonal() * J_V;
  JointMatrix H(m, m);
  H.noalias() = J_V.transpose() * WJ;
  JointMatrix Hp;
  symmetric_pinv(H, Hp);
  JointVector rhs(m);
  rhs.noalias() = WJ.transpose() * v_R;
  JointVector theta_dot(m);
  theta_dot.noalias() = Hp * rhs;
  e_dot.noalias() = J_V * theta_dot;
  e_dot -= v_R;
}

std::uint32_t Controller::step(const Eigen::Ref<const Eigen::VectorXd>& q,
                               const Eigen::Ref<const Eigen::VectorXd>& dq, CycleOutput& out,
                               double t_s) noexcept {
  if (q.size() != device_->dof() || dq.size() != device_->dof()) {
    out.status = status::kOk;
    fault(status::kFaultBadSize, out);
    last_ = out;
    return out.status;
  }
  return step(q.data(), dq.data(), out, t_s);
}

std::uint32_t Controller::step(const double* q, const double* dq, CycleOutput& out,
                               double t_s) noexcept {
  const auto t_start = std::chrono::steady_clock::now();
  const Device& dev = *device_;
  const Mechanism& mech = *mechanism_;
  const ControllerModel& M = model_;
  const int n = dev.dof();
  out.status = status::kOk;
  out.torque.setZero(n);
  out.wrench_null.setZero();
  out.wrench_range.setZero();
  out.wrench_unrendered.setZero();
  out.error_star.setZero();
  out.error_star_dot.setZero();

  const Eigen::Map<const JointVector> qv(q, n), dqv(dq, n);
  if (!qv.allFinite() || !dqv.allFinite()) {
    fault(status::kFaultNonFiniteInput, out);
    out.theta = theta_;
    out.theta_star = theta_star_;
    out.computation_time_us = 0.0;
    last_ = out;
    return out.status;
  }
  if (M.watchdog_s > 0.0 && std::isfinite(t_s)) {
    if (std::isfinite(last_t_) && (t_s - last_t_ > M.watchdog_s || t_s < last_t_)) {
      out.status |= status::kWatchdog;
      ramp_count_ = 0;
    }
    last_t_ = t_s;
  }

  // device kinematics (eqs. 13, 15)
  Jacobian J_R;
  dev.forward_jacobian(q, out.handle_pose, J_R);
  Vector6 v_R;
  v_R.noalias() = J_R * dqv;

  // nearest placement, W_e (eqs. 18-20)
  // warm start: the last placement moved on by its last change (placements follow the
  // handle smoothly, so this starts second-order close to the answer), when that change is
  // between two converged placements: an unconverged one (a handle beyond the mechanism's
  // reach) wanders, and extrapolating the wandering would throw the start off. The first
  // cycle after a start, reset or fault starts from where it is.
  const TrackOptions& opts = first_ ? M.track_initial : M.track;
  JointVector theta0 =
      !first_ && extrapolate_ ? warm_start(mech, opts, theta_, theta_prev_) : theta_;
  JointVector theta_new;
  Jacobian J_V;
  const TrackResult r = detail::track(mech, out.handle_pose, theta0, M.w_e_effective, opts,
                                      theta_new, out.mechanism_pose, J_V);
  extrapolate_ = !first_ && r.converged && converged_;
  converged_ = r.converged;
  theta_prev_ = first_ ? theta_new : theta_;
  theta_ = theta_new;
  out.theta = theta_;
  out.iterations = r.iterations;
  out.residual = r.residual;
  if (!r.converged) out.status |= status::kNotConverged;
  out.error = pose_error(out.mechanism_pose, out.handle_pose);  // e = X_V - X_R (eq. 22)
  placement_rate(J_V, M.w_e_effective, v_R, out.error_dot);
  Vector6 F = M.kp.cwiseProduct(out.error) + M.kv.cwiseProduct(out.error_dot);  // eq. 7

  // the filters share W_A: P F = W_A J_V (J_V^T W_A J_V)^+ J_V^T F
  const RangeFilter P_A(J_V, M.w_a);
  out.wrench_null = F - P_A.apply(F);  // N(W_A) F (eqs. 9, 11)

  // un-powered placement, W_e* (eq. 25), and the range-space term of eq. 26
  if (M.under_actuated_term) {
    if (first_) theta_star_ = theta_;
    theta0 = !first_ && extrapolate_star_
                 ? warm_start(mech, opts, theta_star_, theta_star_prev_)
                 : theta_star_;
    Jacobian J_Vs;
    const TrackResult rs = detail::track(mech, out.handle_pose, theta0, M.w_e_star_effective,
                                         opts, theta_new, out.mechanism_pose_star, J_Vs);
    extrapolate_star_ = !first_ && rs.converged && converged_star_;
    converged_star_ = rs.converged;
    theta_star_prev_ = first_ ? theta_new : theta_star_;
    theta_star_ = theta_new;
    out.iterations_star = rs.iterations;
    out.residual_star = rs.residual;
    if (!rs.converged) out.status |= status::kNotConverged;
    out.error_star = pose_error(out.mechanism_pose_star, out.handle_pose);
    placement_rate(J_Vs, M.w_e_star_effective, v_R, out.error_star_dot);
    const Vector6 Fs = M.kp.cwiseProduct(out.error_star) + M.kv.cwiseProduct(out.error_star_dot);
    out.wrench_range = P_A.apply(Fs);  // P(W_A) F*
  } else {
    theta_star_ = theta_;
    out.iterations_star = 0;
    out.residual_star = 0.0;
    out.mechanism_pose_star = out.mechanism_pose;
  }
  out.theta_star = theta_star_;
  first_ = false;

  // eq. 26 (eq. 11 without the range term)
  Vector6 f = out.wrench_null + out.wrench_range;

  // keep only what the device can render: remove, in the length-scaled metric, the part
  // of f that would load the passive joints (J_pas^T f = 0 afterwards)
  if (!dev.fully_actuated()) {
    const double L = M.length_scale;
    Eigen::Matrix<double, 6, Eigen::Dynamic, Eigen::ColMajor, 6, kMaxDof> Jp(6, n - dev.num_actuated());
    int c = 0;
    for (int i = 0; i < n; ++i) {
      if (dev.actuated(i)) continue;
      Jp.col(c).head<3>() = J_R.col(i).head<3>();
      Jp.col(c).tail<3>() = L * J_R.col(i).tail<3>();
      ++c;
    }
    JointMatrix G(c, c);
    G.noalias() = Jp.transpose() * Jp;
    JointMatrix Gp;
    symmetric_pinv(G, Gp);
    JointVector tau_p(c);
    c = 0;
    for (int i = 0; i < n; ++i) {
      if (!dev.actuated(i)) tau_p[c++] = J_R.col(i).dot(f);
    }
    JointVector y(c);
    y.noalias() = Gp * tau_p;
    Vector6 delta;
    delta.noalias() = Jp * y;
    delta.tail<3>() *= L;
    out.wrench_unrendered = delta;
    f -= delta;
  }

  // safety: force / moment limits preserving direction, ramp-in, joint torque limits
  double scale = 1.0;
  const double fn = f.head<3>().norm(), mn = f.tail<3>().norm();
  if (fn > M.max_force) scale = std::min(scale, M.max_force / fn);
  if (mn > M.max_torque) scale = std::min(scale, M.max_torque / mn);
  if (scale < 1.0) out.status |= status::kForceClamped;
  out.ramp = std::min(1.0, static_cast<double>(ramp_count_ + 1) / static_cast<double>(M.ramp_cycles));
  if (ramp_count_ < M.ramp_cycles) ++ramp_count_;
  if (out.ramp < 1.0) out.status |= status::kRamping;
  f *= scale * out.ramp;

  out.torque.noalias() = J_R.transpose() * f;  // eq. 8
  double tscale = 1.0;
  for (int i = 0; i < n; ++i) {
    if (!dev.actuated(i)) {
      out.torque[i] = 0.0;  // un-powered joints receive exactly zero
      continue;
    }
    const double a = std::abs(out.torque[i]);
    if (a > dev.torque_limit()[i]) tscale = std::min(tscale, dev.torque_limit()[i] / a);
  }
  if (tscale < 1.0) {
    out.status |= status::kTorqueClamped;
    out.torque *= tscale;
    f *= tscale;
  }
  out.limit_scale = scale * tscale;
  out.wrench = f;

  if (!out.torque.allFinite() || !f.allFinite()) {
    theta_ = mech.home();
    theta_star_ = mech.home();
    fault(status::kFaultNonFiniteOutput, out);
  }
  const auto t_end = std::chrono::steady_clock::now();
  out.computation_time_us = std::chrono::duration<double, std::micro>(t_end - t_start).count();
  last_ = out;
  return out.status;
}

}  // namespace virtmech
