// The simulated device the stand-in vendor libraries serve in mode mujoco (standin_hd.cpp,
// standin_dhd.cpp): the simulation's own loop (virtmech::sim::ServoLoop) on the MuJoCo model
// `virtmech run` builds, with a scripted hand (the hand's plan rows) and the vendor library's
// side as the loop's controller; the simulated device's state is kept, one row per control
// cycle (the truth), for the tests to compare with.
//
// Its configuration keys (standin_config.hpp):
//   model PATH (.mjb or .xml)  coupling_inv 36  coupling_offset 6  actuated I...  substeps N
//   period_s S  comp_bodies I...  comp_masses KG...  gravity 3  quantum RAD  delay_cycles N
//   velocity_alpha A  hand_body I  qpos0 N  plan_file PATH  plan_rows N
//   plan_layout 14 (PlanLayout's fields in order)
//   truth_file PATH  (float64 rows, truth_layout(n): the simulated device's state)
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "standin_config.hpp"
#include "virtmech/sim/servo_loop.hpp"

namespace standin_sim {

/// The truth's columns for a device of n joints: t, q, dq, handle_p, stylus, twist,
/// tau_motor, hand_wrench, anchor, segment.
inline virtmech::sim::LogLayout truth_layout(int n) {
  virtmech::sim::LogLayout log;
  log.t = 0;
  log.q = 1;
  log.dq = 1 + n;
  log.handle_p = 1 + 2 * n;
  log.stylus = 4 + 2 * n;
  log.twist = 7 + 2 * n;
  log.tau_motor = 13 + 2 * n;
  log.hand_wrench = 13 + 3 * n;
  log.anchor = 19 + 3 * n;
  log.segment = 22 + 3 * n;
  log.columns = 23 + 3 * n;
  return log;
}

/// The simulated device: its model, data and loop, the hand's plan and the truth rows.
class SimulatedDevice {
 public:
  SimulatedDevice() = default;
  SimulatedDevice(const SimulatedDevice&) = delete;
  SimulatedDevice& operator=(const SimulatedDevice&) = delete;
  ~SimulatedDevice() { unload(); }

  /// Loads the model, the loop's settings and the hand's plan that `config` names for
  /// `device`, driven by `controller` (both must outlive the loop), keeping up to
  /// `max_cycles` truth rows. False, with a message naming `who` on stderr, where any is
  /// missing or does not fit the device.
  bool load(const standin_config::Config& config, const virtmech::Device& device,
            virtmech::sim::ExternalController& controller, long max_cycles, const char* who) {
    unload();
    const std::string path = config.text("model", "");
    char error[1000] = "";
    const bool xml = path.size() > 4 && path.substr(path.size() - 4) == ".xml";
    model_ = xml ? mj_loadXML(path.c_str(), nullptr, error, sizeof error)
                 : mj_loadModel(path.c_str(), nullptr);
    if (model_ == nullptr) {
      std::fprintf(stderr, "%s: cannot load the model %s %s\n", who, path.c_str(), error);
      return false;
    }
    data_ = mj_makeData(model_);
    const std::vector<double> qpos0 = config.numbers("qpos0");
    for (int i = 0; i < model_->nq && i < static_cast<int>(qpos0.size()); ++i) {
      data_->qpos[i] = qpos0[static_cast<size_t>(i)];
    }
    mj_forward(model_, data_);
    n_ = device.dof();
    settings_ = settings(config, n_);
    virtmech::sim::PlanLayout plan;
    int* const fields[] = {&plan.columns, &plan.anchor_p, &plan.anchor_R, &plan.anchor_v,
                           &plan.anchor_w, &plan.k_t, &plan.b_t, &plan.k_r, &plan.b_r,
                           &plan.force, &plan.moment, &plan.force_in_handle,
                           &plan.hand_attached, &plan.segment};
    const std::vector<double> layout = config.numbers("plan_layout");
    for (size_t i = 0; i < layout.size() && i < 14; ++i) *fields[i] = static_cast<int>(layout[i]);
    plan_columns_ = plan.columns;
    plan_rows_ = config.integer("plan_rows", 0);
    plan_ = standin_config::read_doubles(config.text("plan_file", ""),
                         static_cast<size_t>(plan_rows_) * static_cast<size_t>(plan_columns_),
                         who);
    if (plan_columns_ <= 0 || plan_rows_ <= 0 ||
        plan_.size() != static_cast<size_t>(plan_rows_ * plan_columns_)) {
      std::fprintf(stderr, "%s: the hand's plan is missing or short\n", who);
      return false;
    }
    const virtmech::sim::LogLayout log = truth_layout(n_);
    truth_columns_ = log.columns;
    max_cycles_ = max_cycles;
    truth_.assign(static_cast<size_t>(max_cycles_) * static_cast<size_t>(truth_columns_), 0.0);
    noise_.assign(static_cast<size_t>(n_), 0.0);
    cycle_ = 0;
    try {
      loop_ = std::make_unique<virtmech::sim::ServoLoop>(device, controller, model_, data_,
                                                         settings_, plan, log);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s: %s\n", who, e.what());
      return false;
    }
    return true;
  }

  void unload() {
    loop_.reset();
    if (data_) mj_deleteData(data_);
    if (model_) mj_deleteModel(model_);
    data_ = nullptr;
    model_ = nullptr;
  }

  bool loaded() const { return loop_ != nullptr; }
  long cycles() const { return cycle_; }

  /// What the encoders read of the present state, as the loop senses it (coupling,
  /// quantisation; no noise, no delay): the reading the next cycle's controller gets.
  void sensed(double* q) const {
    for (int i = 0; i < n_; ++i) {
      double v = 0.0;
      for (int j = 0; j < n_; ++j) {
        v += settings_.coupling_inv(i, j) * (data_->qpos[j] - settings_.coupling_offset[j]);
      }
      q[i] = settings_.quantum > 0.0 ? std::nearbyint(v / settings_.quantum) * settings_.quantum
                                     : v;
    }
  }

  /// The joints' true rates of the present state (the coupling applied, no estimate).
  void rates(double* dq) const {
    for (int i = 0; i < n_; ++i) {
      double v = 0.0;
      for (int j = 0; j < n_; ++j) v += settings_.coupling_inv(i, j) * data_->qvel[j];
      dq[i] = v;
    }
  }

  /// One control cycle (the controller called once), its truth row kept.
  void cycle() {
    const long c = cycle_++;
    const long r = std::min(c, plan_rows_ - 1);
    const double dropout = 0.0;
    double* truth = c < max_cycles_ ? &truth_[static_cast<size_t>(c * truth_columns_)]
                                    : &truth_[0];  // past the trace: overwritten
    loop_->run(c, 1, &plan_[static_cast<size_t>(r * plan_columns_)], noise_.data(), &dropout,
               truth);
  }

  /// The truth rows of the cycles run into `path` (nothing where it is empty).
  void write_truth(const std::string& path) const {
    if (!loop_ || path.empty()) return;
    if (std::FILE* t = std::fopen(path.c_str(), "wb")) {
      const long cycles = std::min(cycle_, max_cycles_);
      std::fwrite(truth_.data(), sizeof(double),
                  static_cast<size_t>(cycles) * static_cast<size_t>(truth_columns_), t);
      std::fclose(t);
    }
  }

 private:
  static virtmech::sim::LoopSettings settings(const standin_config::Config& config, int n) {
    virtmech::sim::LoopSettings s;
    const std::vector<double> cinv = config.numbers("coupling_inv"),
                              c0 = config.numbers("coupling_offset");
    s.coupling_inv = Eigen::MatrixXd::Identity(n, n);
    s.coupling_offset = Eigen::VectorXd::Zero(n);
    const size_t nn = static_cast<size_t>(n);
    for (size_t i = 0; i < cinv.size() && i < nn * nn; ++i) {
      s.coupling_inv(static_cast<long>(i / nn), static_cast<long>(i % nn)) = cinv[i];
    }
    for (size_t i = 0; i < c0.size() && i < nn; ++i) s.coupling_offset[static_cast<long>(i)] = c0[i];
    for (double a : config.numbers("actuated")) s.actuated.push_back(static_cast<int>(a));
    s.substeps = static_cast<int>(config.integer("substeps", 1));
    s.period_s = config.number("period_s", 1e-3);
    for (double b : config.numbers("comp_bodies")) s.comp_bodies.push_back(static_cast<int>(b));
    s.comp_masses = config.numbers("comp_masses");
    const std::vector<double> g = config.numbers("gravity");
    for (size_t i = 0; i < g.size() && i < 3; ++i) s.gravity[static_cast<long>(i)] = g[i];
    s.quantum = config.number("quantum", 0.0);
    s.delay_cycles = static_cast<int>(config.integer("delay_cycles", 0));
    s.velocity_alpha = config.number("velocity_alpha", 1.0);
    s.hand_body = static_cast<int>(config.integer("hand_body", -1));
    return s;
  }

  mjModel* model_ = nullptr;
  mjData* data_ = nullptr;
  int n_ = 0;
  virtmech::sim::LoopSettings settings_;
  std::unique_ptr<virtmech::sim::ServoLoop> loop_;
  std::vector<double> plan_, truth_, noise_;
  int plan_columns_ = 0, truth_columns_ = 0;
  long plan_rows_ = 0, max_cycles_ = 0;
  long cycle_ = 0;  // the simulation's control cycles run
};

}  // namespace standin_sim
