// The closed-loop simulation's servo-rate loop (virtmech.sim): control cycles with their
// MuJoCo physics steps, driven through MuJoCo's C API.
//
// Per control cycle k (t = k T), for each of the `substeps` physics steps:
//
//     mj_step1                                  (kinematics at the current state)
//     q, dq   <- device coordinates of the true state: q = Cinv (qpos - c0), dq = Cinv qvel
//     first step only:
//         qm, dqm <- sensors (noise, quantisation, dropout, delay, filtered difference)
//         out     <- controller.step(qm, dqm, t)
//         ctrl    <- out.torque - C^T sum_b J_com,b^T m_b g   (on the actuated joints)
//     qfrc_applied <- Cinv^T J^T w_hand(plan row, handle pose and twist)
//     mj_step2                                  (actuation, dynamics, integration)
//
// Before the cycle's first step, where the plan row's hand_attached changes, the hand body's
// mass and inertia are set to zero (released: no hand at all, and no hand wrench) or back to
// the model's, and the model's constants that follow from the masses are recomputed
// (mj_setConst): the physics is then that of a model built without (or with) the hand.
//
// mj_step1 followed by mj_step2 is mj_step, with the inputs set in between. The hand's plan
// (anchor, gains, push), the sensor noise and the dropouts are given, one row per cycle.
//
// Where each quantity sits in a plan row and in a log row is given by the caller (PlanLayout,
// LogLayout): the plan's from virtmech.sim.human.PLAN_COLUMNS, the log's from the one table
// of its columns (log_table.hpp; Python reads the same table).
#pragma once

#include <mujoco/mujoco.h>

#include <cstddef>
#include <vector>

#include "virtmech/sim/log_table.hpp"
#include "virtmech/velocity_filter.hpp"
#include "virtmech/virtmech.hpp"

namespace virtmech::sim {

/// Column of each field of a hand-plan row (the first of its entries; -1: not given, which
/// the loop refuses). Widths: anchor_p 3, anchor_R 9 (row-major), anchor_v 3, anchor_w 3,
/// force 3 and moment 3 (the push: world axes, or handle axes where force_in_handle != 0),
/// hand_attached 1 (0: the hand has let go), the rest 1.
struct PlanLayout {
  int columns = -1;  //!< entries per row
  int anchor_p = -1, anchor_R = -1, anchor_v = -1, anchor_w = -1;
  int k_t = -1, b_t = -1, k_r = -1, b_r = -1;
  int force = -1, moment = -1, force_in_handle = -1, hand_attached = -1, segment = -1;
};

/// Column of each field of a log row (the first of its entries; -1: not written), one
/// member per row of VM_LOG_TABLE (log_table.hpp: widths, names, units); the loop writes the
/// LOOP rows. With a set, theta and theta_star are the rendered member's (NaN past its
/// joints, all NaN with none) and member the member rendered (-1: none).
struct LogLayout {
  int columns = -1;  //!< entries per row
#define VM_LOG_MEMBER(field, width, names, units, origin) int field = -1;
  VM_LOG_TABLE(VM_LOG_MEMBER)
#undef VM_LOG_MEMBER
};

/// How the device sits in the MuJoCo model, and the simulated driver.
struct LoopSettings {
  Eigen::MatrixXd coupling_inv;     //!< Cinv (n x n): device joints q = Cinv (qpos - c0)
  Eigen::VectorXd coupling_offset;  //!< c0 (n)
  std::vector<int> actuated;        //!< device joint of each MuJoCo actuator, in order
  int substeps = 1;                 //!< physics steps per control cycle
  double period_s = 1e-3;           //!< control period T [s]
  std::vector<int> comp_bodies;     //!< bodies whose weight the motors compensate
  std::vector<double> comp_masses;  //!< their masses [kg]
  Eigen::Vector3d gravity = Eigen::Vector3d::Zero();  //!< for the compensation [m/s^2]
  double quantum = 0.0;             //!< encoder step [rad]; 0: none
  int delay_cycles = 0;             //!< sensor delay [cycles]
  double velocity_alpha = 1.0;      //!< the VelocityFilter's gain, in (0, 1]
  int hand_body = -1;  //!< the hand's body (mass zeroed while released); -1: none
};

/// A controller outside the loop, called in the controller's place once per control cycle:
/// a stand-in vendor library serving the simulated device to a real driver (tests/standin).
/// It gets the measured joints (quantised, delayed: what the device's encoders give) and
/// their velocity estimate, and writes the joint torques (the device's joints; the loop
/// applies the actuated joints', with the gravity compensation).
class ExternalController {
 public:
  virtual ~ExternalController() = default;
  virtual void control(double t_s, const double* qm, const double* dqm, double* torque) = 0;
};

/// The loop. Holds the controller, model and data by reference: they must outlive it. The
/// model is changed only where the hand lets go or takes hold again (the hand body's
/// body_mass, body_inertia and the constants mj_setConst computes); the loop restores the
/// hand's mass when it is destroyed.
class ServoLoop {
 public:
  /// Checks the model against the device (one MuJoCo joint per device joint, one actuator
  /// per actuated joint) and the layouts; throws std::invalid_argument naming what is wrong.
  ServoLoop(Controller& controller, mjModel* model, mjData* data, LoopSettings settings,
            const PlanLayout& plan, const LogLayout& log);
  /// The same loop rendering a MechanismSet (its members' controllers; the log's theta
  /// columns as wide as the largest member's joints).
  ServoLoop(MechanismSet& set, mjModel* model, mjData* data, LoopSettings settings,
            const PlanLayout& plan, const LogLayout& log);
  /// The same loop with an external controller on `device` (both must outlive the loop); the
  /// log's controller columns (wrench, theta, e, ...) stay zero.
  ServoLoop(const Device& device, ExternalController& controller, mjModel* model, mjData* data,
            LoopSettings settings, const PlanLayout& plan, const LogLayout& log);
  ~ServoLoop();
  ServoLoop(const ServoLoop&) = delete;
  ServoLoop& operator=(const ServoLoop&) = delete;

  /// Runs cycles k0 .. k0 + rows - 1: plan (rows x plan.columns), noise (rows x n),
  /// dropout (rows; != 0: the sample is lost), log (rows x log.columns) written.
  /// MuJoCo's timer callback is off meanwhile (TimerOff) and restored on return or throw.
  void run(long k0, std::size_t rows, const double* plan, const double* noise,
           const double* dropout, double* log);

  int dof() const noexcept { return n_; }
  /// Wall time spent in the controller's (or the set's) step since construction [s]: the
  /// part of the loop's time that is the rendering itself, not the simulation around it.
  double control_time_s() const noexcept { return control_time_s_; }
  bool hand_attached() const noexcept { return attached_; }
  const PlanLayout& plan_layout() const noexcept { return plan_; }
  const LogLayout& log_layout() const noexcept { return log_; }

 private:
  void init();
  const Device& device() const noexcept { return *device_; }
  void read_state();
  void sense(const double* noise, bool dropout);
  void control(double t, const double* noise, bool dropout);
  Vector6 hand_wrench(const double* p, const Pose& T, const Vector6& tw,
                      const Vector6& push) const;
  void attach_hand(bool attached);
  void cycle(long k, const double* plan, const double* noise, bool dropout, double* row);
  void write_row(double t, const Pose& T_h, const Vector6& tw0, const Vector6& wrench0,
                 const double* plan, double* row) const;

  Controller* ctrl_ = nullptr;  // one of the three
  MechanismSet* set_ = nullptr;
  ExternalController* external_ = nullptr;
  const Device* device_ = nullptr;
  MechanismSetOutput set_out_;
  mjModel* m_;
  mjData* d_;
  LoopSettings s_;
  PlanLayout plan_;
  LogLayout log_;
  int n_ = 0, mdof_ = 0;
  JointMatrix Cinv_, CinvT_, CT_;
  JointVector c0_;
  std::vector<double> jacp_, ring_;
  JointVector gs_, tau_g_, held_, q_, dq_, qm_, cmd_, q_cycle_, dq_cycle_, received_, sv_,
      hand_tau_;
  VelocityFilter velocity_;  // the estimate from the received positions (dqm)
  long reads_ = 0;
  double control_time_s_ = 0.0;
  bool attached_ = true;
  double hand_mass_ = 0.0, hand_inertia_[3] = {0.0, 0.0, 0.0};
  Pose pose_ = Pose::Identity();
  Jacobian J_;
  CycleOutput out_;
};

/// MuJoCo's global timer callback mjcb_time switched off for a scope and restored when the
/// last such scope in the process ends, on return or throw. The mujoco Python package
/// installs a timer that reads the clock about twenty times per physics step (10 % of a
/// run); while off, mjData.timer is not updated (in any thread).
class TimerOff {
 public:
  TimerOff();
  ~TimerOff();
  TimerOff(const TimerOff&) = delete;
  TimerOff& operator=(const TimerOff&) = delete;
};

}  // namespace virtmech::sim
