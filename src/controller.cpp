#include "virtmech/controller.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "cycle_clock.hpp"
#include "flush_denormals.hpp"
#include "passivity.hpp"
#include "track_detail.hpp"
#include "virtmech/filters.hpp"
#include "virtmech/se3.hpp"
#include "virtmech/validate.hpp"
#include "wrench_limit.hpp"

namespace virtmech {

namespace {

// largest change per cycle, as a fraction of the placement's step cap, that the warm start
// extrapolates
constexpr double kWarmStartFraction = 0.1;

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

// --- the cycle's stages, in the order step() runs them ---------------------------------

namespace {

// Zero torque and a fault bit; the next good cycle starts placements afresh and ramps in.
void fault(const ControllerModel& M, const Device& dev, ControllerData& d, std::uint32_t bits,
           CycleOutput& out) noexcept {
  out.status |= bits;
  out.torque.setZero(dev.dof());
  detail::restart_passivity(d.passivity, false);  // the tank starts afresh with the ramp-in
  out.wrench.setZero();
  out.ramp = 0.0;
  out.limit_scale = 1.0;
  d.ramp_count = 0;
  d.ramp_cycles = M.fault_ramp_cycles;  // however short ramp_time_s, the force never steps back
  d.first = true;
}

// q and dq finite, q inside the device's range widened by the margin, dq within the
// device's fastest plausible speeds plus the margin (docs/theory.md, 9).
std::uint32_t check_input(const ControllerModel& M, const Device& dev, const double* q,
                          const double* dq) noexcept {
  const int n = dev.dof();
  const Eigen::Map<const JointVector> qv(q, n), dqv(dq, n);
  if (!qv.allFinite() || !dqv.allFinite()) return status::kFaultNonFiniteInput;
  std::uint32_t bad = status::kOk;
  for (int i = 0; i < n; ++i) {
    if (q[i] < M.q_min[i] || q[i] > M.q_max[i]) bad |= status::kFaultOutOfRange;
    if (std::abs(dq[i]) > M.dq_max[i]) bad |= status::kFaultImplausibleVelocity;
  }
  return bad;
}

// A gap longer than watchdog_s, or time running backwards, restarts the ramp-in.
void watchdog(const ControllerModel& M, ControllerData& d, double t_s, CycleOutput& out) noexcept {
  if (!(M.watchdog_s > 0.0) || !std::isfinite(t_s)) return;
  if (std::isfinite(d.last_t) && (t_s - d.last_t > M.watchdog_s || t_s < d.last_t)) {
    out.status |= status::kWatchdog;
    d.ramp_count = 0;
    d.ramp_cycles = M.fault_ramp_cycles;
    // the torque the motors held over the gap is unknown (an amplifier may have dropped it):
    // the energy tank starts afresh, as after a fault
    detail::restart_passivity(d.passivity, false);
  }
  d.last_t = t_s;
}

// X_R = Phi_R(q), J_R(q) (eqs. 13, 15), or the caller's (at_q), and the handle twist.
void device_kinematics(const Device& dev, ControllerData& d, const double* q, const double* dq,
                       const DeviceKinematics* at_q) noexcept {
  if (at_q) {
    d.handle_pose = at_q->pose;
    d.J_R = at_q->J;
  } else {
    dev.forward_jacobian(q, d.handle_pose, d.J_R);
  }
  d.v_R.noalias() = d.J_R * Eigen::Map<const JointVector>(dq, d.J_R.cols());
}

// J without the columns of the joints in `active`.
void free_columns(const Jacobian& J, std::uint32_t active, Jacobian& J_free) noexcept {
  const int m = static_cast<int>(J.cols());
  int k = 0;
  for (int i = 0; i < m; ++i) k += (active >> i) & 1u ? 0 : 1;
  J_free.resize(6, k);
  k = 0;
  for (int i = 0; i < m; ++i) {
    if (!((active >> i) & 1u)) J_free.col(k++) = J.col(i);
  }
}

// The placement's start: the last placement moved on by its last change (placements follow
// the handle smoothly, so this starts second-order close), when that change is between two
// converged placements; the first cycle after a start, reset or fault starts where it is.
JointVector placement_start(const ControllerModel& M, const Mechanism& mech, const Pose& target,
                            const Vector6& W, bool first, const Placement& p) noexcept {
  const TrackOptions& opts = first ? M.track_initial : M.track;
  JointVector theta0 =
      !first && p.extrapolate ? warm_start(mech, opts, p.theta, p.theta_prev) : p.theta;
  if (first) {
    // a mechanism with several local optima starts near the global one
    mech.seed(target, W, theta0);
    theta0 = theta0.cwiseMax(mech.lower()).cwiseMin(mech.upper());
  }
  return theta0;
}

void placed(const Mechanism& mech, const Vector6& W, bool first, const JointVector& theta,
            Placement& p) noexcept;

// Places the mechanism for the handle pose with weights W (eqs. 18-20), warm-started (or
// from `seeded`, a first cycle's seed), and records the active set: joints held at a limit
// are locked (their columns leave J_free).
void place(const ControllerModel& M, const Mechanism& mech, const Pose& target,
           const Vector6& W, bool first, Placement& p,
           const JointVector* seeded = nullptr) noexcept {
  const TrackOptions& opts = first ? M.track_initial : M.track;
  const JointVector theta0 =
      seeded ? JointVector(seeded->cwiseMax(mech.lower()).cwiseMin(mech.upper()))
             : placement_start(M, mech, target, W, first, p);
  JointVector theta;
  p.result = detail::track(mech, target, opts, PlacementIO{&W, &theta0, &theta, &p.pose, &p.J,
                                                            &p.error});
  placed(mech, W, first, theta, p);
}

// Both placements of a first cycle: seeded together where the mechanism shares their cost
// (Mechanism::seed_pair), else each by seed(), the un-powered one's from the nearest's
// converged placement.
void place_first_pair(const ControllerModel& M, const Mechanism& mech,
                      ControllerData& d) noexcept {
  JointVector a = d.nearest.theta, b = d.nearest.theta;
  const bool both = mech.seed_pair(d.handle_pose, M.w_e_effective, M.w_e_star_effective, a, b);
  virtmech::place(M, mech, d.handle_pose, M.w_e_effective, true, d.nearest, both ? &a : nullptr);
  if (!both) d.unpowered.theta = d.nearest.theta;
  virtmech::place(M, mech, d.handle_pose, M.w_e_star_effective, true, d.unpowered,
                  both ? &b : nullptr);
}

// Both placements of a cycle after its first in one closed form (Mechanism::place_pair),
// which shares what depends on the handle pose alone; false where the mechanism has none.
bool place_pair(const ControllerModel& M, const Mechanism& mech, const Pose& target,
                Placement& a, Placement& b) noexcept {
  if (!M.track.closed_form) return false;
  const JointVector start_a = placement_start(M, mech, target, M.w_e_effective, false, a);
  const JointVector start_b = placement_start(M, mech, target, M.w_e_star_effective, false, b);
  JointVector theta_a, theta_b;
  const PlacementIO io_a{&M.w_e_effective, &start_a, &theta_a, &a.pose, &a.J, &a.error};
  const PlacementIO io_b{&M.w_e_star_effective, &start_b, &theta_b, &b.pose, &b.J, &b.error};
  if (!mech.place_pair(target, io_a, io_b)) return false;
  a.result = detail::closed_form_result(mech, M.w_e_effective, theta_a, a.J, a.error);
  b.result = detail::closed_form_result(mech, M.w_e_star_effective, theta_b, b.J, b.error);
  placed(mech, M.w_e_effective, false, theta_a, a);
  placed(mech, M.w_e_star_effective, false, theta_b, b);
  return true;
}

// A placement's bookkeeping once theta, its pose, Jacobian, error and result are in: the warm
// start's history, the active set, its lock weights and J_free, the constraint wrench.
void placed(const Mechanism& mech, const Vector6& W, bool first, const JointVector& theta,
            Placement& p) noexcept {
  p.extrapolate = !first && p.result.converged && p.converged;
  p.converged = p.result.converged;
  p.theta_prev = first ? theta : p.theta;
  p.theta = theta;
  p.active = p.result.active;
  // how far the cost presses each active joint past its bound, as a depth: the step the
  // weighted error asks of the joint alone, |J_i^T W e| / (J_i^T W J_i), times its column's
  // length-scaled norm |J_i|_U (for a lift-off joint, the tip's depth)
  p.partial = 0;
  p.partial_lock = 1.0;
  if (p.active) {
    const Vector6 We = W.cwiseProduct(p.error);
    const double L2 = mech.length_scale() * mech.length_scale();
    for (int i = 0; i < mech.dof(); ++i) {
      if (!((p.active >> i) & 1u)) continue;
      const auto Ji = p.J.col(i);
      const double g = std::abs(Ji.dot(We)), norm2 = Ji.dot(W.cwiseProduct(Ji));
      const double length =
          std::sqrt(Ji.head<3>().squaredNorm() + L2 * Ji.tail<3>().squaredNorm());
      // depth = g length / norm2 < kLockDepthM: partly locked
      const double lock =
          g * length < kLockDepthM * norm2 ? g * length / (norm2 * kLockDepthM) : 1.0;
      p.lock[static_cast<size_t>(i)] = lock;
      if (lock < 1.0) {
        p.partial |= 1u << i;
        p.partial_lock = std::min(p.partial_lock, lock);
      }
    }
  }
  free_columns(p.J, p.active, p.J_free);
  p.has_wrench = mech.constraint_wrench(p.theta.data(), p.pose, p.J, p.active, p.wrench);
}

// The placement's rate follows from the mechanism's constraint wrench n (J_free^T n = 0,
// rank 5) and needs no factorisation, where the weights are invertible (W_inv != 0).
bool rate_by_wrench(const Placement& p, const Vector6& W_inv) noexcept {
  return p.has_wrench && W_inv[0] > 0.0;
}

// e_dot: the part of the handle's twist the placement does not follow, through the locked
// Jacobian (docs/theory.md, 3); or the paper's eq. 10. `proj` holds sqrt(W) J_free when
// `factorised`, else is factorised here (not needed by the rate from a constraint wrench).
void error_rate(const ControllerModel& M, const Placement& p, const Vector6& W,
                const Vector6& W_inv, const Vector6& v_R, bool factorised,
                WeightedProjector& proj, Vector6& e_dot) noexcept {
  if (M.error_velocity == ErrorVelocity::kHandle) {
    e_dot = -v_R;  // eq. 10
    return;
  }
  if (rate_by_wrench(p, W_inv)) {
    // J theta_dot - v_R with theta_dot the weighted fit: W (J theta_dot - v_R) is normal to
    // every column, so along n, and J theta_dot = v_R + e_dot is normal to n:
    // e_dot = -W^-1 n (n^T v_R) / (n^T W^-1 n)
    const Vector6 Wn = W_inv.cwiseProduct(p.wrench);
    e_dot = (-p.wrench.dot(v_R) / p.wrench.dot(Wn)) * Wn;
    return;
  }
  if (!factorised) proj.compute(p.J_free, W);
  e_dot = proj.residual(v_R);  // J (J^T W J)^+ J^T W v_R - v_R
}

// e_dot with the partly locked joints (docs/theory.md, 6): error_rate()'s, every active
// joint locked, blended toward the rate with the partly locked ones free by their least lock
// weight, so that a contact's damping builds up with its depth. `scratch` factorises the
// second rate where the mechanism has no constraint wrench for it.
void locked_rate(const ControllerModel& M, const Mechanism& mech, const Placement& p,
                 const Vector6& W, const Vector6& W_inv, const Vector6& v_R, bool factorised,
                 WeightedProjector& proj, WeightedProjector& scratch, Vector6& e_dot) noexcept {
  error_rate(M, p, W, W_inv, v_R, factorised, proj, e_dot);
  if (!p.partial || M.error_velocity == ErrorVelocity::kHandle) return;
  const std::uint32_t held = p.active & ~p.partial;
  Vector6 n = Vector6::Zero(), free_rate;
  if (W_inv[0] > 0.0 && mech.constraint_wrench(p.theta.data(), p.pose, p.J, held, n)) {
    const Vector6 Wn = W_inv.cwiseProduct(n);
    free_rate = (-n.dot(v_R) / n.dot(Wn)) * Wn;
  } else {
    Jacobian J;
    free_columns(p.J, held, J);
    scratch.compute(J, W);
    free_rate = scratch.residual(v_R);
  }
  e_dot = free_rate + p.partial_lock * (e_dot - free_rate);
}

// The factorisations the terms' first pass needs, all at once (WeightedProjector::
// compute_all overlaps them): the nearest placement's rate and P(W_A) there, the un-powered
// placement's rate.
void factorise_first_pass(const ControllerModel& M, ControllerData& d) noexcept {
  WeightedProjector::Job jobs[3];
  int n = 0;
  const bool rates = M.error_velocity == ErrorVelocity::kRelative;
  if (M.w_a_shares_rate) {
    // with W_A a multiple of W_e the rate's factorisation is P(W_A)'s
    jobs[n++] = {&d.projector_a, &d.nearest.J_free, &M.w_e_effective};
  } else {
    if (rates && !rate_by_wrench(d.nearest, M.w_e_inverse)) {
      jobs[n++] = {&d.rate, &d.nearest.J_free, &M.w_e_effective};
    }
    jobs[n++] = {&d.projector_a, &d.nearest.J_free, &M.w_a};
  }
  if (rates && M.under_actuated_term && !rate_by_wrench(d.unpowered, M.w_e_star_inverse)) {
    jobs[n++] = {&d.rate_star, &d.unpowered.J_free, &M.w_e_star_effective};
  }
  WeightedProjector::compute_all(jobs, n);
}

// A limit pushes and never pulls: for each joint of the placement held at a limit whose
// motion the wrench f drives back past its bound (the sticking pull of damping as the handle
// leaves a surface), f loses that drive, W_A J_i (J_i^T f) / (J_i^T W_A J_i) times the
// joint's lock weight (a clamp: continuous in f, nothing removed where nothing pulls).
// Returns the joints that pulled.
std::uint32_t let_go(const Mechanism& mech, const Placement& p, const Vector6& W_A,
                     Vector6& f) noexcept {
  std::uint32_t pulled = 0;
  for (int i = 0; i < mech.dof(); ++i) {
    if (!((p.active >> i) & 1u)) continue;
    const double power = p.J.col(i).dot(f);  // > 0: f drives theta_i up
    const bool at_upper = (p.result.active_upper >> i) & 1u;
    if (!(at_upper ? power > 0.0 : power < 0.0)) continue;
    const Vector6 WJ_i = W_A.cwiseProduct(p.J.col(i));
    const double norm = p.J.col(i).dot(WJ_i);
    if (norm > 0.0) f -= (p.lock[static_cast<size_t>(i)] * power / norm) * WJ_i;
    pulled |= 1u << i;
  }
  return pulled;
}

// Null-space term N(W_A)(Kp e + Kv e_dot) (eqs. 7, 9, 11) at the nearest placement, locked
// joints kept in the constraint; a limit only pushes. Returns the joints that pulled.
std::uint32_t null_space_term(const ControllerModel& M, const Mechanism& mech,
                              ControllerData& d, CycleOutput& out) noexcept {
  Placement& p = d.nearest;  // (out.error = -p.error: Controller::place wrote it)
  WeightedProjector& rate = M.w_a_shares_rate ? d.projector_a : d.rate;
  locked_rate(M, mech, p, M.w_e_effective, M.w_e_inverse, d.v_R, true, rate, d.rate_partial,
              out.error_dot);
  const Vector6 F = M.kp.cwiseProduct(out.error) + M.kv.cwiseProduct(out.error_dot);
  out.wrench_null = d.projector_a.null(F);
  if (M.under_actuated_term) d.null_soft_excess = out.wrench_null - (F - d.projector_a.range(F));
  return let_go(mech, p, M.w_a, out.wrench_null);
}

// Range-space term P(W_A)(Kp e* + Kv e*_dot) of eq. 26 with the un-powered placement's
// error (eq. 25). P is taken at the nearest placement, as in the paper, with every column:
// F* points to X_V*, a pose within the limits, so no direction toward it is removed. Where
// the nearest placement is singular, i.e. has lost a direction of motion the mechanism has
// at the un-powered placement (a probe's stylus exactly along the normal, the handle at the
// end of its reach), P is taken at the un-powered placement (docs/theory.md, 6).
std::uint32_t range_space_term(const ControllerModel& M, const Mechanism& mech,
                               ControllerData& d, CycleOutput& out) noexcept {
  Placement& p = d.unpowered;  // (out.error_star = -p.error: Controller::place wrote it)
  // P(W_A) at the nearest placement, every column: the null term's when none is locked.
  // Neither it nor the un-powered placement's J (every column) changes between the passes.
  if (d.nearest.active) d.projector_a.compute(d.nearest.J, M.w_a);
  const WeightedProjector* P = &d.projector_a;
  if (P->rank() < std::min(M.w_a_support, mech.dof())) {
    d.projector.compute(p.J, M.w_a);
    if (d.projector.rank() > P->rank()) P = &d.projector;
  }
  locked_rate(M, mech, p, M.w_e_star_effective, M.w_e_star_inverse, d.v_R, true, d.rate_star,
              d.rate_partial, out.error_star_dot);
  const Vector6 F = M.kp.cwiseProduct(out.error_star) + M.kv.cwiseProduct(out.error_star_dot);
  // (near a singular pose the null-space term's soft rank renders a share of the directions
  // its hard cut would leave to this term: that share is not rendered here again, so that
  // the two terms together are eq. 26 with the hard cut)
  out.wrench_range = P->range(F) - d.null_soft_excess;
  if (M.passivity != Passivity::kOff) {
    d.passivity.range_spring = P->range(M.kp.cwiseProduct(out.error_star));
  }
  return let_go(mech, p, M.w_a, out.wrench_range);
}

// Removes the part of f that would load the passive joints, by the smallest change in the
// length-scaled wrench norm: f <- f - P(D; J_passive) f, D = diag(1, 1, 1, L^2, L^2, L^2)
// (docs/theory.md, 6). Afterwards J_passive^T f = 0.
void keep_renderable(const ControllerModel& M, const Device& dev, ControllerData& d, Vector6& f,
                     CycleOutput& out) noexcept {
  if (dev.fully_actuated()) return;
  const int n = dev.dof();
  Jacobian J_p(6, n - dev.num_actuated());
  int c = 0;
  for (int i = 0; i < n; ++i) {
    if (!dev.actuated(i)) J_p.col(c++) = d.J_R.col(i);
  }
  if (c == 3 && J_p.topRows<3>().isZero(0.0)) {
    // three passive axes through the handle origin (the Omni's gimbal): P(D; J_p) f is
    // [0; A A^+ m] = [0; m] while the axes span space, A the 3 x 3 of their directions
    const Eigen::Matrix3d A = J_p.bottomRows<3>();
    // |det A| > 1e-10 |a_1| |a_2| |a_3|, squared (no square roots)
    const double det = A.determinant();
    if (det * det > 1e-20 * A.colwise().squaredNorm().prod()) {
      out.wrench_unrendered << 0.0, 0.0, 0.0, f.tail<3>();
      f.tail<3>().setZero();
      return;
    }
  }
  const double L2 = M.length_scale * M.length_scale;
  Vector6 D;
  D << 1.0, 1.0, 1.0, L2, L2, L2;
  d.projector.compute(J_p, D);
  out.wrench_unrendered = d.projector.range(f);
  f -= out.wrench_unrendered;
}

// The ramp-in's factor this cycle (out.ramp), one cycle further on.
void advance_ramp(ControllerData& d, CycleOutput& out) noexcept {
  out.ramp = std::min(1.0, static_cast<double>(d.ramp_count + 1) /
                               static_cast<double>(d.ramp_cycles));
  if (d.ramp_count < d.ramp_cycles) ++d.ramp_count;
  if (out.ramp < 1.0) out.status |= status::kRamping;
}

// Force and moment limits keeping direction, ramp-in, tau = J_R^T f with passive joints at
// exactly 0 (eq. 8), joint torque limits.
void safety(const ControllerModel& M, const Device& dev, ControllerData& d, Vector6& f,
            CycleOutput& out) noexcept {
  const int n = dev.dof();
  double scale = 1.0;
  // (the square roots only where a limit acts)
  const double fn2 = f.head<3>().squaredNorm(), mn2 = f.tail<3>().squaredNorm();
  if (detail::exceeds(fn2, M.max_force)) scale = std::min(scale, M.max_force / std::sqrt(fn2));
  if (detail::exceeds(mn2, M.max_torque)) scale = std::min(scale, M.max_torque / std::sqrt(mn2));
  if (scale < 1.0) out.status |= status::kForceClamped;
  advance_ramp(d, out);
  f *= scale * out.ramp;

  out.torque.noalias() = d.J_R.transpose() * f;  // eq. 8
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
}

// The force outputs cleared: a cycle without a wrench (also what begin() clears of them).
void clear_force(int n, CycleOutput& out) noexcept {
  out.torque.setZero(n);
  out.wrench.setZero();
  out.wrench_null.setZero();
  out.wrench_range.setZero();
  out.wrench_unrendered.setZero();
  out.wrench_passivity.setZero();
  out.error_dot.setZero();
  out.error_star_dot.setZero();
  out.limit_scale = 1.0;
  out.energy = 0.0;
  out.stored_energy = 0.0;
  out.passivity_scale = 1.0;
}

// Every output of the cycle cleared, so that a faulted cycle reports nothing of the last
// one (poses identity, errors zero): the caller may reuse one CycleOutput. (A good cycle
// writes them itself.)
void begin(int n, CycleOutput& out) noexcept {
  out.status = status::kOk;
  clear_force(n, out);
  out.error.setZero();
  out.error_star.setZero();
  out.handle_pose.setIdentity();
  out.mechanism_pose.setIdentity();
  out.mechanism_pose_star.setIdentity();
  out.iterations = out.iterations_star = 0;
  out.residual = out.residual_star = 0.0;
  out.active = out.active_star = 0;
  out.ramp = 0.0;
  out.computation_time_us = 0.0;
}

}  // namespace

Controller::Controller(std::shared_ptr<const Device> device,
                       std::shared_ptr<const Mechanism> mechanism,
                       const ControllerSettings& settings)
    : device_(std::move(device)), mechanism_(std::move(mechanism)) {
  if (!device_) throw std::invalid_argument("device: expected a device, got null");
  if (!mechanism_) throw std::invalid_argument("mechanism: expected a mechanism, got null");
  model_ = make_controller_model(*device_, *mechanism_, settings);
  detail::CycleClock::calibrate();  // (once per process, not in a cycle)
  reset();
  data_.last.torque = JointVector::Zero(device_->dof());
  data_.last.theta = data_.nearest.theta;
  data_.last.theta_star = data_.unpowered.theta;
}

void Controller::reset() noexcept {
  data_.nearest.theta = mechanism_->home();
  data_.unpowered.theta = mechanism_->home();
  data_.first = true;
  data_.ramp_count = 0;
  data_.ramp_cycles = model_.ramp_cycles;
  detail::restart_passivity(data_.passivity, true);
  data_.last_t = std::numeric_limits<double>::quiet_NaN();
}

void Controller::restart_energy() noexcept { detail::restart_passivity(data_.passivity, false); }

void Controller::applied(const double* tau) noexcept {
  // (nothing to book with passivity off or before the tank's first cycle)
  if (model_.passivity == Passivity::kOff || data_.passivity.cycles == 0) return;
  data_.passivity.tau_last = Eigen::Map<const JointVector>(tau, device_->dof());
}

namespace {

// The placements' outputs (the joints at a limit before the terms release any).
void placement_outputs(const ControllerModel& M, ControllerData& d, CycleOutput& out) noexcept {
  const Placement& pn = d.nearest;
  const Placement& pu = M.under_actuated_term ? d.unpowered : d.nearest;
  out.theta = pn.theta;
  out.theta_star = pu.theta;
  out.mechanism_pose = pn.pose;
  out.mechanism_pose_star = pu.pose;
  out.iterations = pn.result.iterations;
  out.residual = pn.result.residual;
  out.active = pn.active;
  out.iterations_star = M.under_actuated_term ? pu.result.iterations : 0;
  out.residual_star = M.under_actuated_term ? pu.result.residual : 0.0;
  out.active_star = M.under_actuated_term ? pu.active : 0u;
  if (!pn.result.converged || (M.under_actuated_term && !pu.result.converged)) {
    out.status |= status::kNotConverged;
  }
  if (!M.under_actuated_term) d.unpowered.theta = pn.theta;
}

}  // namespace

std::uint32_t Controller::step(const Eigen::Ref<const Eigen::VectorXd>& q,
                               const Eigen::Ref<const Eigen::VectorXd>& dq, CycleOutput& out,
                               double t_s) noexcept {
  if (q.size() != device_->dof() || dq.size() != device_->dof()) {
    begin(device_->dof(), out);
    fault(model_, *device_, data_, status::kFaultBadSize, out);
    out.theta = data_.nearest.theta;
    out.theta_star = data_.unpowered.theta;
    data_.last = out;
    return out.status;
  }
  return step(q.data(), dq.data(), out, t_s);
}

std::uint32_t Controller::step(const double* q, const double* dq, CycleOutput& out,
                               double t_s) noexcept {
  const detail::FlushDenormals flush;
  const std::uint32_t placed = place_cycle(q, dq, nullptr, out, t_s);
  if (placed & status::kFaultMask) return placed;
  return render_cycle(out);
}

std::uint32_t Controller::place(const double* q, const double* dq, CycleOutput& out,
                                double t_s) noexcept {
  const detail::FlushDenormals flush;
  return place_cycle(q, dq, nullptr, out, t_s);
}

std::uint32_t Controller::place(const double* q, const double* dq, const DeviceKinematics& at_q,
                                CycleOutput& out, double t_s) noexcept {
  const detail::FlushDenormals flush;
  return place_cycle(q, dq, &at_q, out, t_s);
}

std::uint32_t Controller::render(CycleOutput& out) noexcept {
  const detail::FlushDenormals flush;
  return render_cycle(out);
}

std::uint32_t Controller::place_cycle(const double* q, const double* dq,
                                      const DeviceKinematics* at_q, CycleOutput& out,
                                      double t_s) noexcept {
  ControllerData& d = data_;
  d.cycle_start = detail::CycleClock::now();
  const Device& dev = *device_;
  const Mechanism& mech = *mechanism_;
  const ControllerModel& M = model_;
  out.status = status::kOk;

  if (const std::uint32_t bad = check_input(M, dev, q, dq)) {
    begin(dev.dof(), out);
    fault(M, dev, d, bad, out);
    out.theta = d.nearest.theta;
    out.theta_star = d.unpowered.theta;
    out.computation_time_us = 0.0;
    d.last = out;
    return out.status;
  }
  // a good cycle writes every output but these (a faulted one clears them all with begin()),
  // so that none reports anything of the last cycle
  if (!M.under_actuated_term) {
    out.wrench_range.setZero();
    out.error_star.setZero();
    out.error_star_dot.setZero();
  }
  if (dev.fully_actuated()) out.wrench_unrendered.setZero();
  watchdog(M, d, t_s, out);
  device_kinematics(dev, d, q, dq, at_q);
  d.q_cycle = Eigen::Map<const JointVector>(q, dev.dof());
  d.dq_cycle = Eigen::Map<const JointVector>(dq, dev.dof());
  out.handle_pose = d.handle_pose;

  // the two placements (eqs. 18-20, 25): in one closed form where the mechanism has it (the
  // first cycle's un-powered placement starts from the nearest, so that one in turn)
  if (M.under_actuated_term && d.first) {
    place_first_pair(M, mech, d);
  } else if (!(M.under_actuated_term &&
               virtmech::place_pair(M, mech, d.handle_pose, d.nearest, d.unpowered))) {
    virtmech::place(M, mech, d.handle_pose, M.w_e_effective, d.first, d.nearest);
    if (M.under_actuated_term) {
      virtmech::place(M, mech, d.handle_pose, M.w_e_star_effective, d.first, d.unpowered);
    }
  }
  d.first = false;
  placement_outputs(M, d, out);
  out.error = -d.nearest.error;  // e = X_V - X_R (eq. 22)
  if (M.under_actuated_term) out.error_star = -d.unpowered.error;
  return out.status;
}

std::uint32_t Controller::render_cycle(CycleOutput& out) noexcept {
  const Device& dev = *device_;
  const Mechanism& mech = *mechanism_;
  const ControllerModel& M = model_;
  ControllerData& d = data_;
  const double* q = d.q_cycle.data();

  // eq. 26 (eq. 11 without the range term)
  factorise_first_pass(M, d);
  const std::uint32_t let_go_null = null_space_term(M, mech, d, out);
  const std::uint32_t let_go_range = M.under_actuated_term ? range_space_term(M, mech, d, out) : 0u;
  Vector6 f = out.wrench_null + out.wrench_range;

  detail::passivity(M, dev, d.passivity, q, d.v_R, out);
  f += out.wrench_passivity;
  keep_renderable(M, dev, d, f, out);
  safety(M, dev, d, f, out);
  detail::hold_torque(M, d.passivity, out.torque);
  // the joints at a limit, less those the terms let go (their force pulled away from it)
  out.active = d.nearest.active & ~let_go_null;
  out.active_star = M.under_actuated_term ? d.unpowered.active & ~let_go_range : 0u;

  if (!out.torque.allFinite() || !f.allFinite()) {  // belt and braces: zero, start afresh
    d.nearest.theta = mech.home();
    d.unpowered.theta = mech.home();
    const std::uint32_t informative = out.status;
    begin(dev.dof(), out);
    out.status = informative;
    out.theta = d.nearest.theta;
    out.theta_star = d.unpowered.theta;
    fault(M, dev, d, status::kFaultNonFiniteOutput, out);
  }
  return finish(out);
}

std::uint32_t Controller::unrendered(CycleOutput& out) noexcept {
  clear_force(device_->dof(), out);
  advance_ramp(data_, out);  // as safety() advances it
  return finish(out);
}

std::uint32_t Controller::finish(CycleOutput& out) noexcept {
  out.computation_time_us =
      detail::CycleClock::microseconds(data_.cycle_start, detail::CycleClock::now());
  data_.last = out;
  return out.status;
}

}  // namespace virtmech
