// make_controller_model: the settings resolved against a device and a mechanism, stage by
// stage. Every range is its row's in include/virtmech/settings_table.h (check_settings);
// what is checked here is what depends on the device or the mechanism.
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "virtmech/controller.hpp"
#include "virtmech/registry.hpp"

namespace virtmech {

namespace {

constexpr double kEpsilon = std::numeric_limits<double>::epsilon();

// [1 1 1 L^2 L^2 L^2]
Vector6 scaled_ones(double L) {
  Vector6 w;
  w << 1.0, 1.0, 1.0, L * L, L * L, L * L;
  return w;
}

// task axes along which the passive joints never move (checked at the device's home)
void resolve_renderable(const Device& device, ControllerModel& m) {
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
}

// W_A and W_e on the axes the device renders, W_e* on the rest (eq. 25); gains on the axes
// it cannot render are zero, so the null-space filter does not turn unrenderable moments
// into forces along the mechanism's motion (docs/theory.md, section 5)
void resolve_weights_and_gains(const Device& device, const ControllerSettings& s,
                               ControllerModel& m) {
  const Vector6 unit = scaled_ones(m.length_scale);
  Vector6 mask;
  for (int k = 0; k < 6; ++k) mask[k] = m.renderable[static_cast<size_t>(k)] ? 1.0 : 0.0;
  const Vector6 powered = mask.cwiseProduct(unit);
  const Vector6 unpowered = (Vector6::Ones() - mask).cwiseProduct(unit);
  m.w_a = s.w_a.value_or(powered);
  m.w_e = s.w_e.value_or(powered);
  m.w_e_star = s.w_e_star.value_or(unpowered);
  if (m.w_e.isZero(0.0)) {
    throw std::invalid_argument("w_e: expected at least one weight > 0, got all zero");
  }
  if (m.w_a.isZero(0.0)) {
    throw std::invalid_argument("w_a: expected at least one weight > 0, got all zero");
  }
  m.w_a_support = static_cast<int>((m.w_a.array() > 0.0).count());
  m.w_e_effective = m.w_e + s.secondary_weight * unit;
  m.w_e_star_effective = m.w_e_star + s.secondary_weight * unit;
  const auto inverse = [](const Vector6& w) {
    return (w.array() > 0.0).all() ? Vector6(w.cwiseInverse()) : Vector6(Vector6::Zero());
  };
  m.w_e_inverse = inverse(m.w_e_effective);
  m.w_e_star_inverse = inverse(m.w_e_star_effective);
  m.kp = s.kp.value_or(Vector6(device.stiffness() * powered));
  m.kv = s.kv.value_or(Vector6(device.damping() * powered));
}

// whether eq. 26's range term is evaluated, and whether W_A shares the nearest placement's
// rate: W_A = c (W_e + secondary_weight U), every ratio within a few rounding errors of c
void resolve_law(const Device& device, const ControllerSettings& s, ControllerModel& m) {
  m.law = s.law;
  m.error_velocity = s.error_velocity;
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
  }
  double c = 0.0;
  bool proportional = true;
  for (int i = 0; i < 6; ++i) {
    const double a = m.w_a[i], e = m.w_e_effective[i];
    if (a == 0.0 || e == 0.0) {
      proportional = proportional && a == e;
    } else if (c == 0.0) {
      c = a / e;
    } else {
      proportional = proportional && std::abs(a - c * e) <= 8.0 * kEpsilon * a;
    }
  }
  m.w_a_shares_rate = proportional && m.error_velocity == ErrorVelocity::kRelative;
}

// timing, limits, the placements' iteration caps, passivity
void resolve_cycle(const Device& device, const ControllerSettings& s, ControllerModel& m) {
  m.period_s = s.period_s;
  // (the table bounds ramp_time_s to 60 s and period_s from below: the count is exact)
  m.ramp_cycles = std::max(1L, static_cast<long>(std::llround(s.ramp_time_s / s.period_s)));
  // however short ramp_time_s, the force ramps back over kMinimumFaultRampS after a fault
  m.fault_ramp_cycles = std::max(
      m.ramp_cycles, static_cast<long>(std::ceil(kMinimumFaultRampS / s.period_s - 1e-9)));
  m.watchdog_s = s.watchdog_s;
  m.max_force = s.max_force > 0.0 ? std::min(s.max_force, device.max_force()) : device.max_force();
  m.max_torque =
      s.max_torque > 0.0 ? std::min(s.max_torque, device.max_torque()) : device.max_torque();
  m.track.max_iterations = s.max_iterations;
  m.track_initial.max_iterations = s.max_iterations_initial;
  m.passivity = s.passivity;
  m.passivity_max_energy = s.passivity_max_energy_j;
  m.passivity_start_energy = s.passivity_start_energy_j;
  m.passivity_fade = s.passivity_fade_j;
  m.passivity_budget = s.passivity_budget_j;
  m.passivity_fade_step = std::min(1.0, s.period_s / s.passivity_fade_time_s);
}

// the plausible q and dq: the device's range and fastest speeds widened by the margins; the
// passivity observer's play, one encoder count
void resolve_range(const Device& device, const ControllerSettings& s, ControllerModel& m) {
  const int n = device.dof();
  m.q_min.resize(n);
  m.q_max.resize(n);
  m.dq_max.resize(n);
  m.passivity_play.resize(n);
  for (int i = 0; i < n; ++i) {
    const bool revolute = device.joint_type(i) == JointType::kRevolute;
    const double margin = revolute ? s.range_margin_rad : s.range_margin_m;
    m.q_min[i] = device.lower()[i] - margin;
    m.q_max[i] = device.upper()[i] + margin;
    m.dq_max[i] =
        device.max_velocity()[i] + (revolute ? s.velocity_margin_rad_s : s.velocity_margin_m_s);
    // half a count: the observer's displacement can sit between two counts a joint flips
    // between, within the play of both (docs/theory.md, 8)
    m.passivity_play[i] = 0.5 * (revolute ? s.passivity_resolution_rad : s.passivity_resolution_m);
  }
}

}  // namespace

ControllerModel make_controller_model(const Device& device, const Mechanism& mechanism,
                                      const ControllerSettings& s) {
  check_settings(s);
  ControllerModel m;
  m.length_scale = s.length_scale > 0.0 ? s.length_scale : mechanism.length_scale();
  resolve_renderable(device, m);
  resolve_weights_and_gains(device, s, m);
  resolve_law(device, s, m);
  resolve_cycle(device, s, m);
  resolve_range(device, s, m);
  return m;
}

Params describe(const ControllerModel& m) {
  std::vector<bool> renderable(m.renderable.begin(), m.renderable.end());
  return Params()
      .set_vector("kp", m.kp)
      .set_vector("kv", m.kv)
      .set_vector("w_a", m.w_a)
      .set_vector("w_e", m.w_e)
      .set_vector("w_e_star", m.w_e_star)
      .set("length_scale", m.length_scale)
      .set("law", name_of(m.law))
      .set("under_actuated_term", m.under_actuated_term)
      .set("error_velocity", name_of(m.error_velocity))
      .set("period_s", m.period_s)
      .set("ramp_cycles", ParamValue(static_cast<long long>(m.ramp_cycles)))
      .set("watchdog_s", m.watchdog_s)
      .set("max_force", m.max_force)
      .set("max_torque", m.max_torque)
      .set("max_iterations", m.track.max_iterations)
      .set("max_iterations_initial", m.track_initial.max_iterations)
      .set("passivity", name_of(m.passivity))
      .set("passivity_start_energy_j", m.passivity_start_energy)
      .set("passivity_max_energy_j", m.passivity_max_energy)
      .set("passivity_fade_j", m.passivity_fade)
      .set("passivity_budget_j", m.passivity_budget)
      .set("passivity_fade_step", m.passivity_fade_step)
      .set("fault_ramp_cycles", ParamValue(static_cast<long long>(m.fault_ramp_cycles)))
      .set_vector("q_min", m.q_min)
      .set_vector("q_max", m.q_max)
      .set_vector("dq_max", m.dq_max)
      .set_vector("passivity_play", m.passivity_play)
      .set("renderable", renderable);
}

}  // namespace virtmech
