// The closed-loop simulation's inner loop, compiled (virtmech.sim, engine="compiled").
//
// One call runs a stretch of control cycles with everything the Python loop of
// virtmech/sim/loop.py does per cycle and per physics step: the sensor model, the controller,
// gravity compensation through the motors, zero-order hold, the hand's impedance wrench every
// physics step, MuJoCo's step, and the log row. The hand's plan (anchor, gains, push force),
// the sensor noise and the dropouts are computed in Python beforehand, one array per stretch.
//
// MuJoCo is reached through what the mujoco package already loaded in this process: the
// addresses of mjModel, mjData and of mj_step1, mj_step2 and mj_jacBodyCom, and NumPy views of
// the mjData arrays the loop reads and writes. The extension neither includes nor links MuJoCo,
// so virtmech builds and imports without it.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/vector.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "virtmech/virtmech.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace {

using virtmech::Controller;
using virtmech::CycleOutput;
using virtmech::Jacobian;
using virtmech::JointVector;
using virtmech::Pose;
using virtmech::Vector6;

using MjStepFn = void (*)(const void* m, void* d);
using MjJacBodyComFn = void (*)(const void* m, const void* d, double* jacp, double* jacr,
                                int body);

using F64 = nb::ndarray<double, nb::c_contig, nb::device::cpu>;
using CF64 = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;

// plan columns, one row per control cycle (see virtmech/sim/human.py, Intent.plan)
constexpr int kPlanP = 0, kPlanR = 3, kPlanV = 12, kPlanW = 15, kPlanGains = 18, kPlanForce = 22,
              kPlanForceInHandle = 25, kPlanSegment = 26, kPlanColumns = 27;

void require(bool ok, const std::string& what) {
  if (!ok) throw nb::value_error(what.c_str());
}

std::string shape(const CF64& a) {
  std::string s = "(";
  for (size_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

void require_shape(const char* name, const CF64& a, size_t rows, size_t cols) {
  const bool ok = cols == 0 ? (a.ndim() == 1 && a.shape(0) == rows)
                            : (a.ndim() == 2 && a.shape(0) == rows && a.shape(1) == cols);
  require(ok, std::string(name) + ": expected shape (" + std::to_string(rows) +
                  (cols == 0 ? ",)" : ", " + std::to_string(cols) + ")") + ", got " + shape(a));
}

class SimKernel {
 public:
  SimKernel(Controller& controller, std::uintptr_t model, std::uintptr_t data,
            std::uintptr_t mj_step1, std::uintptr_t mj_step2, std::uintptr_t mj_jac_body_com,
            F64 qpos, F64 qvel, F64 ctrl, F64 qfrc_applied, F64 actuator_force, CF64 coupling_inv,
            CF64 coupling_offset, std::vector<int> actuated, int substeps, double period_s,
            std::vector<int> comp_bodies, std::vector<double> comp_masses, CF64 gravity,
            double quantum, int delay_cycles, double velocity_alpha)
      : ctrl_(controller),
        m_(reinterpret_cast<const void*>(model)),
        d_(reinterpret_cast<void*>(data)),
        step1_(reinterpret_cast<MjStepFn>(mj_step1)),
        step2_(reinterpret_cast<MjStepFn>(mj_step2)),
        jac_body_com_(reinterpret_cast<MjJacBodyComFn>(mj_jac_body_com)),
        qpos_(qpos), qvel_(qvel), ctrl_arr_(ctrl), qfrc_(qfrc_applied), act_force_(actuator_force),
        act_(std::move(actuated)), nsub_(substeps), T_(period_s),
        comp_bodies_(std::move(comp_bodies)), comp_masses_(std::move(comp_masses)),
        quantum_(quantum), delay_(delay_cycles), alpha_(velocity_alpha) {
    n_ = ctrl_.device().dof();
    mdof_ = ctrl_.mechanism().dof();
    const auto un = static_cast<size_t>(n_);
    require(model != 0 && data != 0, "model, data: expected the addresses of mjModel and mjData");
    require(mj_step1 != 0 && mj_step2 != 0 && mj_jac_body_com != 0,
            "mj_step1, mj_step2, mj_jac_body_com: expected function addresses, got 0");
    require(qpos.ndim() == 1 && qpos.shape(0) == un,
            "qpos: expected shape (" + std::to_string(n_) + ",) (one MuJoCo joint per chain joint)");
    require(qvel.ndim() == 1 && qvel.shape(0) == un,
            "qvel: expected shape (" + std::to_string(n_) + ",)");
    require(qfrc_applied.ndim() == 1 && qfrc_applied.shape(0) == un,
            "qfrc_applied: expected shape (" + std::to_string(n_) + ",)");
    require(ctrl.ndim() == 1 && ctrl.shape(0) == act_.size(),
            "ctrl: expected one entry per actuated joint (" + std::to_string(act_.size()) + ")");
    require(actuator_force.ndim() == 1 && actuator_force.shape(0) == act_.size(),
            "actuator_force: expected one entry per actuated joint (" +
                std::to_string(act_.size()) + ")");
    for (int a : act_) {
      require(a >= 0 && a < n_, "actuated: index " + std::to_string(a) + " is not a joint of the " +
                                    std::to_string(n_) + "-joint device");
    }
    require(n_ <= virtmech::kMaxDof && mdof_ <= virtmech::kMaxDof, "controller: too many joints");
    require_shape("coupling_inv", coupling_inv, un, un);
    require_shape("coupling_offset", coupling_offset, un, 0);
    require_shape("gravity", gravity, 3, 0);
    require(substeps >= 1, "substeps: expected >= 1, got " + std::to_string(substeps));
    require(period_s > 0.0 && std::isfinite(period_s),
            "period_s: expected a positive number, got " + std::to_string(period_s));
    require(comp_bodies_.size() == comp_masses_.size(),
            "comp_masses: expected one mass per body in comp_bodies");
    require(delay_cycles >= 0, "delay_cycles: expected >= 0, got " + std::to_string(delay_cycles));
    require(quantum >= 0.0, "quantum: expected >= 0");
    Cinv_ = Eigen::Map<const Eigen::Matrix<double, -1, -1, Eigen::RowMajor>>(coupling_inv.data(),
                                                                              n_, n_);
    CinvT_ = Cinv_.transpose();
    c0_ = Eigen::Map<const Eigen::VectorXd>(coupling_offset.data(), n_);
    g_ = Eigen::Map<const Eigen::Vector3d>(gravity.data());
    // chain-coordinate forces g_s act on the device joints as C^T g_s (s = C q + c0)
    CT_ = Cinv_.inverse().transpose();
    jacp_.resize(3 * un);
    gs_.resize(n_);
    ring_.assign(static_cast<size_t>(delay_ + 1) * un, 0.0);
    held_.setZero(n_);
    prev_.setZero(n_);
    dqf_.setZero(n_);
    q_.setZero(n_);
    s_.setZero(n_);
    dq_.setZero(n_);
    q_cycle_.setZero(n_);
    received_.setZero(n_);
    dq_cycle_.setZero(n_);
    qm_.setZero(n_);
    cmd_.setZero(n_);
  }

  //! Log columns one cycle writes (virtmech.sim.loop.kernel_columns).
  int columns() const { return 1 + 4 * n_ + 12 + 6 + 2 * n_ + 4 + 2 * mdof_ + 24 + 12 + 6 + 3 + 1; }

  //! Runs cycles k0 .. k0 + rows - 1 (rows = plan.shape[0]) and writes their log rows.
  void run(long k0, CF64 plan, CF64 noise, CF64 dropout, F64 log) {
    const size_t rows = plan.ndim() == 2 ? plan.shape(0) : 0;
    require_shape("plan", plan, rows, kPlanColumns);
    require_shape("noise", noise, rows, static_cast<size_t>(n_));
    require_shape("dropout", dropout, rows, 0);
    require(log.ndim() == 2 && log.shape(0) == rows && log.shape(1) == size_t(columns()),
            "log: expected shape (" + std::to_string(rows) + ", " + std::to_string(columns()) +
                ")");
    nb::gil_scoped_release release;
    for (size_t r = 0; r < rows; ++r) {
      cycle(k0 + long(r), plan.data() + r * kPlanColumns, noise.data() + r * size_t(n_),
            dropout.data()[r] != 0.0, log.data() + r * size_t(columns()));
    }
  }

 private:
  void read_state() {
    const Eigen::Map<const Eigen::VectorXd> qpos(qpos_.data(), n_), qvel(qvel_.data(), n_);
    s_ = qpos - c0_;
    q_.noalias() = Cinv_ * s_;
    dq_.noalias() = Cinv_ * qvel;
  }

  // sensors.py, Sensors.read, with the noise and dropout of this cycle given
  void sense(const double* noise, bool dropout) {
    for (int i = 0; i < n_; ++i) {
      const double v = q_[i] + noise[i];
      qm_[i] = quantum_ > 0.0 ? std::nearbyint(v / quantum_) * quantum_ : v;
    }
    if (reads_ > 0 && dropout) qm_ = held_;
    held_ = qm_;
    const long D = delay_ + 1;
    std::copy(qm_.data(), qm_.data() + n_, ring_.data() + (reads_ % D) * n_);
    const long oldest = reads_ > delay_ ? reads_ - delay_ : 0;
    const Eigen::Map<const Eigen::VectorXd> received(ring_.data() + (oldest % D) * n_, n_);
    if (reads_ > 0) dqf_ += alpha_ * ((received - prev_) / T_ - dqf_);
    prev_ = received;
    received_ = received;
    ++reads_;
  }

  // human.py, hand_wrench, at pose T and twist tw
  static Vector6 hand_wrench(const double* p, const Pose& T, const Vector6& tw,
                             const Eigen::Vector3d& force) {
    const Eigen::Map<const Eigen::Vector3d> pa(p + kPlanP), va(p + kPlanV), wa(p + kPlanW);
    const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> Ra(p + kPlanR);
    const double kt = p[kPlanGains], bt = p[kPlanGains + 1], kr = p[kPlanGains + 2],
                 br = p[kPlanGains + 3];
    Vector6 W;
    W.head<3>() = kt * (pa - T.translation()) + bt * (va - tw.head<3>()) + force;
    const Eigen::Matrix3d Rerr = Ra * T.linear().transpose();
    W.tail<3>() = kr * virtmech::so3_log(Rerr) + br * (wa - tw.tail<3>());
    return W;
  }

  void cycle(long k, const double* plan, const double* noise, bool dropout, double* row) {
    const double t = double(k) * T_;
    Eigen::Vector3d force = Eigen::Vector3d::Zero();
    Vector6 tw0 = Vector6::Zero(), wrench0 = Vector6::Zero();
    Pose T_h = Pose::Identity();
    for (int s = 0; s < nsub_; ++s) {
      step1_(m_, d_);
      read_state();
      ctrl_.device().forward_jacobian(q_.data(), pose_, J_);
      if (s == 0) {
        T_h = pose_;
        q_cycle_ = q_;
        dq_cycle_ = dq_;
        control(t, noise, dropout);
        force = Eigen::Map<const Eigen::Vector3d>(plan + kPlanForce);
        if (plan[kPlanForceInHandle] != 0.0) force = T_h.linear() * force;
      }
      const Vector6 tw = J_ * dq_;
      const Vector6 W = hand_wrench(plan, pose_, tw, force);
      if (s == 0) {
        tw0 = tw;
        wrench0 = W;
      }
      Eigen::Map<Eigen::VectorXd> qfrc(qfrc_.data(), n_);
      qfrc.noalias() = CinvT_ * (J_.transpose() * W);
      step2_(m_, d_);
    }
    write_row(t, T_h, tw0, wrench0, plan, row);
  }

  void control(double t, const double* noise, bool dropout) {
    sense(noise, dropout);
    ctrl_.step(received_.data(), dqf_.data(), out_, t);
    cmd_ = out_.torque;
    if (!comp_bodies_.empty()) {
      // gravity through the motors: -C^T sum_b J_com,b^T m_b g (kinematics from mj_step1)
      gs_.setZero();
      for (size_t b = 0; b < comp_bodies_.size(); ++b) {
        jac_body_com_(m_, d_, jacp_.data(), nullptr, comp_bodies_[b]);
        for (int r = 0; r < 3; ++r) {
          const double f = comp_masses_[b] * g_[r];
          for (int j = 0; j < n_; ++j) gs_[j] += jacp_[size_t(r * n_ + j)] * f;
        }
      }
      tau_g_.noalias() = CT_ * gs_;
      for (int a : act_) cmd_[a] -= tau_g_[a];
    }
    for (size_t i = 0; i < act_.size(); ++i) ctrl_arr_.data()[i] = cmd_[act_[i]];
  }

  void write_row(double t, const Pose& T_h, const Vector6& tw0, const Vector6& wrench0,
                 const double* plan, double* row) const {
    double* o = row;
    auto put = [&o](const auto& v) {
      for (Eigen::Index i = 0; i < v.size(); ++i) *o++ = v[i];
    };
    *o++ = t;
    put(q_cycle_);
    put(dq_cycle_);
    put(received_);
    put(dqf_);
    put(T_h.translation());
    put(T_h.linear().col(2));
    put(tw0);
    put(out_.wrench);
    put(out_.torque);
    for (int j = 0; j < n_; ++j) o[j] = 0.0;  // motor output: zero on passive joints
    for (size_t i = 0; i < act_.size(); ++i) o[act_[i]] = act_force_.data()[i];
    o += n_;
    *o++ = double(out_.status);
    *o++ = out_.ramp;
    *o++ = double(out_.iterations);
    *o++ = double(out_.iterations_star);
    put(out_.theta);
    put(out_.theta_star);
    put(out_.error);
    put(out_.error_dot);
    put(out_.error_star);
    put(out_.error_star_dot);
    put(out_.wrench_null);
    put(out_.wrench_range);
    put(wrench0);
    for (int i = 0; i < 3; ++i) *o++ = plan[kPlanP + i];
    *o++ = plan[kPlanSegment];
  }

  Controller& ctrl_;
  const void* m_;
  void* d_;
  MjStepFn step1_, step2_;
  MjJacBodyComFn jac_body_com_;
  F64 qpos_, qvel_, ctrl_arr_, qfrc_, act_force_;
  std::vector<int> act_;
  int nsub_;
  double T_;
  std::vector<int> comp_bodies_;
  std::vector<double> comp_masses_;
  double quantum_;
  long delay_;
  double alpha_;
  int n_ = 0, mdof_ = 0;
  virtmech::JointMatrix Cinv_, CinvT_, CT_;
  JointVector c0_;
  Eigen::Vector3d g_;
  std::vector<double> jacp_, ring_;
  JointVector gs_, tau_g_, held_, prev_, dqf_, q_, dq_, qm_, cmd_, q_cycle_, dq_cycle_, received_;
  JointVector s_;
  long reads_ = 0;
  Pose pose_ = Pose::Identity();
  Jacobian J_;
  CycleOutput out_;
};

}  // namespace

void bind_sim_kernel(nb::module_& m) {
  nb::class_<SimKernel>(m, "_SimKernel",
                        "The compiled inner loop of virtmech.sim (internal: use virtmech.sim.run).")
      .def(nb::init<Controller&, std::uintptr_t, std::uintptr_t, std::uintptr_t, std::uintptr_t,
                    std::uintptr_t, F64, F64, F64, F64, F64, CF64, CF64, std::vector<int>, int,
                    double, std::vector<int>, std::vector<double>, CF64, double, int, double>(),
           "controller"_a, "model"_a, "data"_a, "mj_step1"_a, "mj_step2"_a, "mj_jac_body_com"_a,
           // arrays the loop writes into must be the arrays themselves, never converted copies
           "qpos"_a.noconvert(), "qvel"_a.noconvert(), "ctrl"_a.noconvert(),
           "qfrc_applied"_a.noconvert(), "actuator_force"_a.noconvert(), "coupling_inv"_a,
           "coupling_offset"_a, "actuated"_a, "substeps"_a, "period_s"_a, "comp_bodies"_a,
           "comp_masses"_a, "gravity"_a, "quantum"_a, "delay_cycles"_a, "velocity_alpha"_a,
           nb::keep_alive<1, 2>())
      .def_prop_ro("columns", &SimKernel::columns, "Log columns one cycle writes.")
      .def("run", &SimKernel::run, "k0"_a, "plan"_a, "noise"_a, "dropout"_a, "log"_a.noconvert(),
           "Runs plan.shape[0] control cycles from cycle k0, writing one log row each.");
}
