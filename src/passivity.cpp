#include "passivity.hpp"

#include <algorithm>
#include <cmath>

#include "wrench_limit.hpp"

namespace virtmech::detail {

double saturated_spring(const Vector6& e, const Vector6& f, double force_limit,
                        double moment_limit) noexcept {
  double energy = 0.0;
  for (int b = 0; b < 2; ++b) {
    const double ef = e.segment<3>(3 * b).dot(f.segment<3>(3 * b));
    const double norm2 = f.segment<3>(3 * b).squaredNorm();
    const double limit = b == 0 ? force_limit : moment_limit;
    // beyond the limit the force is limit e / |e|: e^T f (s - s^2 / 2), s = limit / |f|
    // (the square root only where the force saturates)
    const double s = exceeds(norm2, limit) ? limit / std::sqrt(norm2) : 1.0;
    energy += ef * (s - 0.5 * s * s);
  }
  // (an oblique projection can make e^T f negative: a spring holds no negative energy)
  return std::max(energy, 0.0);
}

void restart_passivity(PassivityState& s, bool springs) noexcept {
  s.cycles = 0;
  s.energy = 0.0;
  s.pending = 0.0;
  // (after a fault the range term's factor stays where it was: the ramp-in brings the force
  // back, and a factor the tank had taken down comes back only as the tank refills)
  if (springs) {
    s.scale = s.factor = s.rendered = 1.0;
    s.following = true;
  }
  s.start_with_springs = springs;
}

namespace {

// The most intervals a joint's booked torque is averaged over: 0.1 s at 1 kHz, several
// counts' time at the slowest motion the observer follows.
constexpr double kTorqueWindow = 100.0;

double median(double a, double b, double c) noexcept {
  return std::max(std::min(a, b), std::min(std::max(a, b), c));
}

// The observer (docs/theory.md, section 8): at cycle k it books, joint by joint, the torque
// held since that joint's displacement p last moved, averaged over those intervals (at most
// kTorqueWindow of them), against p's move p_{k-1} - p_{k-2}, where p is held within the play
// h of q~_{k-1} = median(q_{k-2}, q_{k-1}, q_k) and moves only as far as the play makes it.
// Returns that work [J] (0 until two intervals have passed since the restart).
double observed_work(const ControllerModel& M, int n, PassivityState& s,
                     const double* q) noexcept {
  double work = 0.0, pending = 0.0;
  if (s.cycles == 0) {
    s.q_before.resize(n);
    s.q_last.resize(n);
    s.played.resize(n);
    s.torque_sum.setZero(n);
    s.torque_count.setZero(n);
    for (int i = 0; i < n; ++i) s.q_before[i] = s.q_last[i] = s.played[i] = q[i];
  } else if (s.cycles >= 2) {
    for (int i = 0; i < n; ++i) {
      // the torque held over [k - 2, k - 1] joins the joint's average (a running mean over
      // the last kTorqueWindow intervals where p has stood still longer)
      if (s.torque_count[i] >= kTorqueWindow) {
        s.torque_sum[i] *= (kTorqueWindow - 1.0) / kTorqueWindow;
      } else {
        s.torque_count[i] += 1.0;
      }
      s.torque_sum[i] += s.tau_before[i];
      const double settled = median(s.q_before[i], s.q_last[i], q[i]);
      const double h = M.passivity_play[i];
      const double p = std::clamp(s.played[i], settled - h, settled + h);
      const double mean = s.torque_sum[i] / s.torque_count[i];
      if (p != s.played[i]) {
        work += mean * (p - s.played[i]);
        s.torque_sum[i] = 0.0;
        s.torque_count[i] = 0.0;
      }
      pending += (s.torque_sum[i] + s.tau_last[i]) / (s.torque_count[i] + 1.0) * (settled - p);
      s.played[i] = p;
    }
  }
  if (s.cycles > 0) {
    for (int i = 0; i < n; ++i) {
      s.q_before[i] = s.q_last[i];
      s.q_last[i] = q[i];
    }
  }
  s.pending = std::max(0.0, pending);
  return work;
}

}  // namespace

void passivity(const ControllerModel& M, const Device& dev, PassivityState& s, const double* q,
               const Vector6& twist, CycleOutput& out) noexcept {
  out.wrench_passivity.setZero();
  out.passivity_scale = 1.0;
  if (M.passivity == Passivity::kOff) {
    out.energy = out.stored_energy = 0.0;
    return;
  }
  const int n = dev.dof();
  // what the springs hold: the null term's spring Kp e (e is across the mechanism, where
  // N(W_A) keeps it), and the range term's as the last cycle rendered it, its factor times
  // P(W_A) Kp e*
  double stored = saturated_spring(out.error, M.kp.cwiseProduct(out.error), M.max_force,
                                   M.max_torque);
  if (M.under_actuated_term) {
    stored += s.factor * saturated_spring(out.error_star, s.range_spring, M.max_force,
                                          M.max_torque);
  }
  out.stored_energy = stored;
  const bool restart = s.cycles == 0;
  const double work = observed_work(M, n, s, q);
  // the start hands the rendering what its springs hold, at most passivity_start_energy_j; a
  // restart
  // after a fault or a watchdog trip (or of a set's member as it engages) starts empty: the
  // spring was stretched meanwhile (by a stylus falling past its joint range, by 20 N);
  // afterwards the level loses the motors' work and holds at most the springs' energy and
  // the reserve (passivity_max_energy_j, default 0): energy absorbed long ago (by damping,
  // say) beyond it does not later power motion the user did not ask for. No floor: a deficit is paid back before the range term comes back.
  s.energy = restart ? (s.start_with_springs ? std::min(stored, M.passivity_start_energy) : 0.0)
                     : s.energy - work;
  s.energy = std::min(s.energy, stored + M.passivity_max_energy);
  out.energy = s.energy;
  if (!M.under_actuated_term) return;
  // the range term's size as a share of the wrench limits (beyond them, 1: the device
  // renders the limit whatever the factor)
  const double f = std::sqrt(out.wrench_range.head<3>().squaredNorm());
  const double m = std::sqrt(out.wrench_range.tail<3>().squaredNorm());
  const double share = std::max(f > 0.0 ? f / M.max_force : 0.0, m > 0.0 ? m / M.max_torque : 0.0);
  const double limited = std::min(share, 1.0);
  // the factor's aim: 1 down to a level of -budget, 0 below -budget - fade, the level taken
  // as far ahead as the rendered share takes to fall to 0, at the range term's present
  // power (the energy it gives while it fades: a free handle it accelerates is caught early)
  const double step = M.passivity_fade_step;
  const double power = std::max(0.0, s.factor * out.wrench_range.dot(twist));
  const double ahead = power * M.period_s * std::ceil(s.rendered / step);
  const double aim = std::clamp(
      1.0 + (s.energy - s.pending - ahead + M.passivity_budget) / M.passivity_fade, 0.0, 1.0);
  // the rendered share follows the range term's while the aim is 1 and it did; otherwise it
  // moves toward aim times the range term's share by at most one step (of the wrench
  // limits) a cycle: the force the factor takes away or gives back never steps, and a range
  // term that grows while it fades (a falling stylus stretching its spring) is held under a
  // falling envelope
  if (s.following && aim >= 1.0) {
    s.rendered = limited;
  } else {
    s.rendered = std::clamp(s.rendered + std::clamp(aim * limited - s.rendered, -step, step),
                            0.0, limited);
    s.following = aim >= 1.0 && s.rendered >= limited;
  }
  s.factor = share > 0.0 ? s.rendered / share : (aim >= 1.0 ? 1.0 : s.factor);
  const double scale = s.following ? 1.0 : (limited > 0.0 ? s.rendered / limited : 0.0);
  s.scale = scale;
  if (!s.following) out.status |= status::kPassivity;
  out.passivity_scale = scale;
  out.wrench_passivity = (s.factor - 1.0) * out.wrench_range;
}

void hold_torque(const ControllerModel& M, PassivityState& s, const JointVector& torque) noexcept {
  if (M.passivity == Passivity::kOff) return;
  s.tau_before = s.tau_last;
  s.tau_last = torque;
  ++s.cycles;
}

}  // namespace virtmech::detail
