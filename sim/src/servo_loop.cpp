// The servo-rate loop of virtmech.sim (see servo_loop.hpp).
#include "virtmech/sim/servo_loop.hpp"


#include <algorithm>
#include <chrono>
#include <cmath>
#include <mutex>
#include <stdexcept>
#include <string>

namespace virtmech::sim {

namespace {

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}

// a field of `width` entries at column `col` of a row of `columns`
void check_field(const char* table, const char* name, int col, int width, int columns,
                 bool optional) {
  if (col == -1 && optional) return;
  require(col >= 0 && col + width <= columns,
          std::string(table) + "." + name + ": column " + std::to_string(col) + " (" +
              std::to_string(width) + " entries) is not within a row of " +
              std::to_string(columns) + " columns");
}

std::mutex timer_mutex;
int timer_depth = 0;
mjfTime timer_saved = nullptr;

// The model's joints and bodies, and the loop's settings, checked against a device of `dof`
// joints.
void check_model_and_settings(const mjModel* model, const LoopSettings& settings, int dof) {
  const std::string n = std::to_string(dof);
  require(model->nq == dof && model->nv == dof,
          "model: expected one MuJoCo hinge or slide joint per device joint (nq = nv = " + n +
              "), got nq = " + std::to_string(model->nq) + ", nv = " + std::to_string(model->nv));
  require(model->nu == int(settings.actuated.size()),
          "actuated: expected one device joint per MuJoCo actuator (" + std::to_string(model->nu) +
              "), got " + std::to_string(settings.actuated.size()));
  for (int a : settings.actuated) {
    require(a >= 0 && a < dof, "actuated: index " + std::to_string(a) + " is not a joint of the " +
                                  n + "-joint device");
  }
  require(settings.coupling_inv.rows() == dof && settings.coupling_inv.cols() == dof,
          "coupling_inv: expected shape (" + n + ", " + n + ")");
  require(settings.coupling_offset.size() == dof, "coupling_offset: expected shape (" + n + ",)");
  require(settings.substeps >= 1, "substeps: expected >= 1, got " + std::to_string(settings.substeps));
  require(settings.period_s > 0.0 && std::isfinite(settings.period_s),
          "period_s: expected a positive number, got " + std::to_string(settings.period_s));
  require(settings.comp_bodies.size() == settings.comp_masses.size(),
          "comp_masses: expected one mass per body in comp_bodies");
  for (int b : settings.comp_bodies) {
    require(b >= 0 && b < model->nbody, "comp_bodies: " + std::to_string(b) + " is not a body");
  }
  require(settings.delay_cycles >= 0, "delay_cycles: expected >= 0");
  require(settings.quantum >= 0.0, "quantum: expected >= 0");
  require(settings.velocity_alpha > 0.0 && settings.velocity_alpha <= 1.0,
          "velocity_alpha: expected a number in (0, 1], got " +
              std::to_string(settings.velocity_alpha));
  require(settings.hand_body == -1 || (settings.hand_body > 0 && settings.hand_body < model->nbody),
          "hand_body: " + std::to_string(settings.hand_body) + " is not a body (nor -1: none)");
}

}  // namespace

TimerOff::TimerOff() {
  std::lock_guard<std::mutex> lock(timer_mutex);
  if (timer_depth++ == 0) {
    timer_saved = mjcb_time;
    mjcb_time = nullptr;
  }
}

TimerOff::~TimerOff() {
  std::lock_guard<std::mutex> lock(timer_mutex);
  if (--timer_depth == 0) {
    mjcb_time = timer_saved;
    timer_saved = nullptr;
  }
}

ServoLoop::ServoLoop(Controller& controller, mjModel* model, mjData* data,
                     LoopSettings settings, const PlanLayout& plan, const LogLayout& log)
    : ctrl_(&controller),
      device_(&controller.device()),
      m_(model),
      d_(data),
      s_(std::move(settings)),
      plan_(plan),
      log_(log) {
  mdof_ = controller.mechanism().dof();
  init();
}

ServoLoop::ServoLoop(MechanismSet& set, mjModel* model, mjData* data, LoopSettings settings,
                     const PlanLayout& plan, const LogLayout& log)
    : set_(&set), device_(&set.device()), m_(model), d_(data), s_(std::move(settings)),
      plan_(plan), log_(log) {
  require(set.size() > 0, "set: expected a mechanism set with at least one member");
  for (int i = 0; i < set.size(); ++i) mdof_ = std::max(mdof_, set.member(i).mechanism().dof());
  init();
}

ServoLoop::ServoLoop(const Device& device, ExternalController& controller, mjModel* model,
                     mjData* data, LoopSettings settings, const PlanLayout& plan,
                     const LogLayout& log)
    : external_(&controller), device_(&device), m_(model), d_(data), s_(std::move(settings)),
      plan_(plan), log_(log) {
  init();
  // the controller's columns an external controller leaves: zero in every row
  for (Vector6* v : {&out_.wrench, &out_.wrench_null, &out_.wrench_range, &out_.wrench_unrendered,
                     &out_.error, &out_.error_dot, &out_.error_star, &out_.error_star_dot}) {
    v->setZero();
  }
}

void ServoLoop::init() {
  require(m_ != nullptr && d_ != nullptr, "model, data: expected an mjModel and an mjData");
  n_ = device().dof();
  check_model_and_settings(m_, s_, n_);
  if (s_.hand_body > 0) {
    hand_mass_ = m_->body_mass[s_.hand_body];
    std::copy(m_->body_inertia + 3 * s_.hand_body, m_->body_inertia + 3 * s_.hand_body + 3,
              hand_inertia_);
  }

  const int P = plan_.columns;
  require(P > 0, "plan.columns: expected > 0");
  check_field("plan", "anchor_p", plan_.anchor_p, 3, P, false);
  check_field("plan", "anchor_R", plan_.anchor_R, 9, P, false);
  check_field("plan", "anchor_v", plan_.anchor_v, 3, P, false);
  check_field("plan", "anchor_w", plan_.anchor_w, 3, P, false);
  check_field("plan", "k_t", plan_.k_t, 1, P, false);
  check_field("plan", "b_t", plan_.b_t, 1, P, false);
  check_field("plan", "k_r", plan_.k_r, 1, P, false);
  check_field("plan", "b_r", plan_.b_r, 1, P, false);
  check_field("plan", "force", plan_.force, 3, P, false);
  check_field("plan", "moment", plan_.moment, 3, P, false);
  check_field("plan", "force_in_handle", plan_.force_in_handle, 1, P, false);
  check_field("plan", "hand_attached", plan_.hand_attached, 1, P, false);
  check_field("plan", "segment", plan_.segment, 1, P, false);
  const int L = log_.columns;
  require(L > 0, "log.columns: expected > 0");
  // every field the loop writes (the table's LOOP rows) within a row, where given
#define VM_LOG_MEMBER(field, width, names, units, origin) &LogLayout::field,
  static constexpr int LogLayout::*kColumns[] = {VM_LOG_TABLE(VM_LOG_MEMBER)};
#undef VM_LOG_MEMBER
  const std::vector<LogField>& fields = log_fields();
  for (size_t i = 0; i < fields.size(); ++i) {
    if (!fields[i].derived) {
      check_field("log", fields[i].field, log_.*kColumns[i], log_width(fields[i], n_, mdof_), L,
                  true);
    }
  }


  Cinv_ = s_.coupling_inv;
  CinvT_ = Cinv_.transpose();
  c0_ = s_.coupling_offset;
  // chain-coordinate forces g_s act on the device joints as C^T g_s (s = C q + c0)
  CT_ = Cinv_.inverse().transpose();
  jacp_.assign(3 * size_t(n_), 0.0);
  ring_.assign(size_t(s_.delay_cycles + 1) * size_t(n_), 0.0);
  velocity_ = VelocityFilter(n_, s_.period_s, s_.velocity_alpha);
  for (JointVector* v : {&gs_, &tau_g_, &held_, &q_, &dq_, &qm_, &cmd_,
                         &q_cycle_, &dq_cycle_, &received_, &sv_, &hand_tau_}) {
    v->setZero(n_);
  }
}

ServoLoop::~ServoLoop() {
  if (!attached_) attach_hand(true);
}

// the hand's mass and inertia on (its own) or off (zero), and the model's constants that
// follow from the masses (dof_M0, dof_invweight0, body_subtreemass, ...) recomputed, as a
// model compiled with (without) the hand has them; mj_setConst works on scratch data
void ServoLoop::attach_hand(bool attached) {
  attached_ = attached;
  const int b = s_.hand_body;
  if (b <= 0) return;
  m_->body_mass[b] = attached ? hand_mass_ : 0.0;
  for (int i = 0; i < 3; ++i) m_->body_inertia[3 * b + i] = attached ? hand_inertia_[i] : 0.0;
  if (mjData* scratch = mj_makeData(m_)) {
    mj_setConst(m_, scratch);
    mj_deleteData(scratch);
  }
}

void ServoLoop::run(long k0, std::size_t rows, const double* plan, const double* noise,
                    const double* dropout, double* log) {
  TimerOff timer_off;
  const auto P = size_t(plan_.columns), L = size_t(log_.columns), n = size_t(n_);
  for (size_t r = 0; r < rows; ++r) {
    cycle(k0 + long(r), plan + r * P, noise + r * n, dropout[r] != 0.0, log + r * L);
  }
}

void ServoLoop::read_state() {
  const Eigen::Map<const Eigen::VectorXd> qpos(d_->qpos, n_), qvel(d_->qvel, n_);
  sv_ = qpos - c0_;
  q_.noalias() = Cinv_ * sv_;
  dq_.noalias() = Cinv_ * qvel;
}

// sensors.py, Sensors.read, with the noise and dropout of this cycle given
void ServoLoop::sense(const double* noise, bool dropout) {
  const double quantum = s_.quantum;
  for (int i = 0; i < n_; ++i) {
    const double v = q_[i] + noise[i];
    qm_[i] = quantum > 0.0 ? std::nearbyint(v / quantum) * quantum : v;
  }
  if (reads_ > 0 && dropout) qm_ = held_;
  held_ = qm_;
  const long delay = s_.delay_cycles, D = delay + 1;
  std::copy(qm_.data(), qm_.data() + n_, ring_.data() + (reads_ % D) * n_);
  const long oldest = reads_ > delay ? reads_ - delay : 0;
  const Eigen::Map<const Eigen::VectorXd> received(ring_.data() + (oldest % D) * n_, n_);
  velocity_.update(received.data());
  received_ = received;
  ++reads_;
}

// human.py, hand_wrench, at pose T and twist tw, with the push (force; moment) in world axes
Vector6 ServoLoop::hand_wrench(const double* p, const Pose& T, const Vector6& tw,
                               const Vector6& push) const {
  if (!attached_) return Vector6::Zero();  // released: no hand at all
  const Eigen::Map<const Eigen::Vector3d> pa(p + plan_.anchor_p), va(p + plan_.anchor_v),
      wa(p + plan_.anchor_w);
  const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> Ra(p + plan_.anchor_R);
  Vector6 W;
  W.head<3>() = p[plan_.k_t] * (pa - T.translation()) + p[plan_.b_t] * (va - tw.head<3>()) +
                push.head<3>();
  const Eigen::Matrix3d Rerr = Ra * T.linear().transpose();
  W.tail<3>() =
      p[plan_.k_r] * so3_log(Rerr) + p[plan_.b_r] * (wa - tw.tail<3>()) + push.tail<3>();
  return W;
}

void ServoLoop::cycle(long k, const double* plan, const double* noise, bool dropout,
                      double* row) {
  const double t = double(k) * s_.period_s;
  const bool attached = plan[plan_.hand_attached] != 0.0;
  if (attached != attached_) attach_hand(attached);
  Vector6 push = Vector6::Zero();
  Vector6 tw0 = Vector6::Zero(), wrench0 = Vector6::Zero();
  Pose T_h = Pose::Identity();
  for (int s = 0; s < s_.substeps; ++s) {
    mj_step1(m_, d_);
    read_state();
    device().forward_jacobian(q_.data(), pose_, J_);
    if (s == 0) {
      T_h = pose_;
      q_cycle_ = q_;
      dq_cycle_ = dq_;
      control(t, noise, dropout);
      push.head<3>() = Eigen::Map<const Eigen::Vector3d>(plan + plan_.force);
      push.tail<3>() = Eigen::Map<const Eigen::Vector3d>(plan + plan_.moment);
      if (plan[plan_.force_in_handle] != 0.0) {
        push.head<3>() = T_h.linear() * push.head<3>();
        push.tail<3>() = T_h.linear() * push.tail<3>();
      }
    }
    const Vector6 tw = J_ * dq_;
    const Vector6 W = hand_wrench(plan, pose_, tw, push);
    if (s == 0) {
      tw0 = tw;
      wrench0 = W;
    }
    Eigen::Map<Eigen::VectorXd> qfrc(d_->qfrc_applied, n_);
    hand_tau_.noalias() = J_.transpose() * W;  // the hand's wrench on the device's joints
    qfrc.noalias() = CinvT_ * hand_tau_;
    mj_step2(m_, d_);
  }
  write_row(t, T_h, tw0, wrench0, plan, row);
}

void ServoLoop::control(double t, const double* noise, bool dropout) {
  sense(noise, dropout);
  const auto t0 = std::chrono::steady_clock::now();
  if (ctrl_) {
    ctrl_->step(received_.data(), velocity_.velocity().data(), out_, t);
  } else if (set_) {
    set_->step(received_.data(), velocity_.velocity().data(), set_out_, t);
  } else {
    out_.torque.setZero(n_);
    external_->control(t, received_.data(), velocity_.velocity().data(), out_.torque.data());
  }
  control_time_s_ +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (set_) out_ = set_out_.cycle;
  cmd_ = out_.torque;
  if (!s_.comp_bodies.empty()) {
    // gravity through the motors: -C^T sum_b J_com,b^T m_b g (kinematics from mj_step1)
    gs_.setZero();
    for (size_t b = 0; b < s_.comp_bodies.size(); ++b) {
      mj_jacBodyCom(m_, d_, jacp_.data(), nullptr, s_.comp_bodies[b]);
      for (int r = 0; r < 3; ++r) {
        const double f = s_.comp_masses[b] * s_.gravity[r];
        for (int j = 0; j < n_; ++j) gs_[j] += jacp_[size_t(r * n_ + j)] * f;
      }
    }
    tau_g_.noalias() = CT_ * gs_;
    for (int a : s_.actuated) cmd_[a] -= tau_g_[a];
  }
  for (size_t i = 0; i < s_.actuated.size(); ++i) d_->ctrl[i] = cmd_[s_.actuated[i]];
}

void ServoLoop::write_row(double t, const Pose& T_h, const Vector6& tw0, const Vector6& wrench0,
                          const double* plan, double* row) const {
  auto put = [row](int col, const auto& v) {
    if (col < 0) return;
    for (Eigen::Index i = 0; i < v.size(); ++i) row[col + i] = v[i];
  };
  auto put1 = [row](int col, double v) {
    if (col >= 0) row[col] = v;
  };
  put1(log_.t, t);
  put(log_.q, q_cycle_);
  put(log_.dq, dq_cycle_);
  put(log_.qm, received_);
  put(log_.dqm, velocity_.velocity());
  put(log_.handle_p, T_h.translation());
  put(log_.stylus, T_h.linear().col(2));
  put(log_.twist, tw0);
  put(log_.wrench, out_.wrench);
  put(log_.tau, out_.torque);
  if (log_.tau_motor >= 0) {  // motor output: zero on passive joints
    double* o = row + log_.tau_motor;
    for (int j = 0; j < n_; ++j) o[j] = 0.0;
    for (size_t i = 0; i < s_.actuated.size(); ++i) o[s_.actuated[i]] = d_->actuator_force[i];
  }
  put1(log_.status, double(out_.status));
  put1(log_.ramp, out_.ramp);
  put1(log_.iterations, double(out_.iterations));
  put1(log_.iterations_star, double(out_.iterations_star));
  if (set_) {  // the rendered member's joints, NaN past them (all NaN with none)
    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (int col : {log_.theta, log_.theta_star}) {
      if (col >= 0) std::fill(row + col, row + col + mdof_, nan);
    }
    put1(log_.member, double(set_out_.active));
    if (set_out_.active >= 0) {
      put(log_.theta, out_.theta);
      put(log_.theta_star, out_.theta_star);
    }
  } else {
    put1(log_.member, 0.0);
    put(log_.theta, out_.theta);
    put(log_.theta_star, out_.theta_star);
  }
  put(log_.e, out_.error);
  put(log_.e_dot, out_.error_dot);
  put(log_.e_star, out_.error_star);
  put(log_.e_star_dot, out_.error_star_dot);
  put(log_.f_null, out_.wrench_null);
  put(log_.f_range, out_.wrench_range);
  put(log_.hand_wrench, wrench0);
  put(log_.anchor, Eigen::Map<const Eigen::Vector3d>(plan + plan_.anchor_p));
  put1(log_.segment, plan[plan_.segment]);
}

}  // namespace virtmech::sim
