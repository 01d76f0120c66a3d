// virtmech._sim: the simulation's servo-rate loop (sim/include/virtmech/sim/servo_loop.hpp)
// for virtmech.sim. Linked with MuJoCo's C library from the mujoco wheel; mjModel and mjData
// come from the mujoco package's MjModel and MjData (their `_address`).
#include <mujoco/mujoco.h>
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "virtmech/sim/servo_loop.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using virtmech::Controller;
using virtmech::Device;
using virtmech::MechanismSet;
using namespace virtmech::sim;

namespace {

using F64 = nb::ndarray<double, nb::c_contig, nb::device::cpu>;
using CF64 = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;

std::string shape(const CF64& a) {
  std::string s = "(";
  for (size_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

void require_shape(const char* name, const CF64& a, size_t rows, size_t cols) {
  const bool ok = cols == 0 ? (a.ndim() == 1 && a.shape(0) == rows)
                            : (a.ndim() == 2 && a.shape(0) == rows && a.shape(1) == cols);
  if (!ok) {
    throw nb::value_error((std::string(name) + ": expected shape (" + std::to_string(rows) +
                           (cols == 0 ? ",)" : ", " + std::to_string(cols) + ")") + ", got " +
                           shape(a))
                              .c_str());
  }
}

// A layout from {field: column}: the fields are the struct's members (by name), the columns
// the caller's table's (virtmech.sim.inner)
template <class Layout>
Layout layout(const char* what, const nb::dict& d,
              const std::vector<std::pair<const char*, int Layout::*>>& members) {
  Layout out;
  for (auto [key, value] : d) {
    const std::string k = nb::cast<std::string>(key);
    bool known = false;
    for (const auto& [name, member] : members) {
      if (k == name) {
        out.*member = nb::cast<int>(value);
        known = true;
      }
    }
    if (!known) throw nb::value_error((std::string(what) + ": unknown field " + k).c_str());
  }
  return out;
}

PlanLayout plan_layout(const nb::dict& d) {
  using L = PlanLayout;
  return layout<L>("plan_layout", d,
                   {{"columns", &L::columns}, {"anchor_p", &L::anchor_p},
                    {"anchor_R", &L::anchor_R}, {"anchor_v", &L::anchor_v},
                    {"anchor_w", &L::anchor_w}, {"k_t", &L::k_t}, {"b_t", &L::b_t},
                    {"k_r", &L::k_r}, {"b_r", &L::b_r}, {"force", &L::force},
                    {"moment", &L::moment}, {"force_in_handle", &L::force_in_handle},
                    {"hand_attached", &L::hand_attached}, {"segment", &L::segment}});
}

LogLayout log_layout(const nb::dict& d) {
  using L = LogLayout;
  return layout<L>(
      "log_layout", d,
      {{"columns", &L::columns}, {"t", &L::t}, {"q", &L::q}, {"dq", &L::dq}, {"qm", &L::qm},
       {"dqm", &L::dqm}, {"handle_p", &L::handle_p}, {"stylus", &L::stylus},
       {"twist", &L::twist}, {"wrench", &L::wrench}, {"tau", &L::tau},
       {"tau_motor", &L::tau_motor}, {"status", &L::status}, {"ramp", &L::ramp},
       {"iterations", &L::iterations}, {"iterations_star", &L::iterations_star},
       {"theta", &L::theta}, {"theta_star", &L::theta_star}, {"e", &L::e}, {"e_dot", &L::e_dot},
       {"e_star", &L::e_star}, {"e_star_dot", &L::e_star_dot}, {"f_null", &L::f_null},
       {"f_range", &L::f_range}, {"hand_wrench", &L::hand_wrench}, {"anchor", &L::anchor},
       {"segment", &L::segment}, {"member", &L::member}});
}

// A simulated device driven from outside the simulation (virtmech ros2-sim): the loop's
// external controller applies the joint torques the caller set last, held.
struct HeldTorque final : ExternalController {
  explicit HeldTorque(std::shared_ptr<Device> d)
      : device_ptr(std::move(d)), torque(Eigen::VectorXd::Zero(device_ptr->dof())) {}
  void control(double, const double*, const double*, double* tau) override {
    for (Eigen::Index i = 0; i < torque.size(); ++i) tau[i] = torque[i];
  }
  const Device& device() const { return *device_ptr; }
  std::shared_ptr<Device> device_ptr;
  Eigen::VectorXd torque;
};

struct PyServoLoop {
  template <typename Renderer>  // a Controller or a MechanismSet
  PyServoLoop(Renderer& renderer, std::uintptr_t model, std::uintptr_t data,
              CF64 coupling_inv, CF64 coupling_offset, std::vector<int> actuated, int substeps,
              double period_s, std::vector<int> comp_bodies, std::vector<double> comp_masses,
              CF64 gravity, double quantum, int delay_cycles, double velocity_alpha,
              int hand_body, const nb::dict& plan, const nb::dict& log)
      : loop(renderer, reinterpret_cast<mjModel*>(model), reinterpret_cast<mjData*>(data),
             settings(renderer.device().dof(), coupling_inv, coupling_offset,
                      std::move(actuated), substeps, period_s, std::move(comp_bodies),
                      std::move(comp_masses), gravity, quantum, delay_cycles, velocity_alpha,
                      hand_body),
             plan_layout(plan), log_layout(log)) {}

  PyServoLoop(HeldTorque& held, std::uintptr_t model, std::uintptr_t data, CF64 coupling_inv,
              CF64 coupling_offset, std::vector<int> actuated, int substeps, double period_s,
              std::vector<int> comp_bodies, std::vector<double> comp_masses, CF64 gravity,
              double quantum, int delay_cycles, double velocity_alpha, int hand_body,
              const nb::dict& plan, const nb::dict& log)
      : loop(held.device(), held, reinterpret_cast<mjModel*>(model),
             reinterpret_cast<mjData*>(data),
             settings(held.device().dof(), coupling_inv, coupling_offset, std::move(actuated),
                      substeps, period_s, std::move(comp_bodies), std::move(comp_masses),
                      gravity, quantum, delay_cycles, velocity_alpha, hand_body),
             plan_layout(plan), log_layout(log)) {}

  static LoopSettings settings(int n, const CF64& coupling_inv, const CF64& coupling_offset,
                               std::vector<int> actuated, int substeps, double period_s,
                               std::vector<int> comp_bodies, std::vector<double> comp_masses,
                               const CF64& gravity, double quantum, int delay_cycles,
                               double velocity_alpha, int hand_body) {
    const auto un = static_cast<size_t>(n);
    require_shape("coupling_inv", coupling_inv, un, un);
    require_shape("coupling_offset", coupling_offset, un, 0);
    require_shape("gravity", gravity, 3, 0);
    LoopSettings s;
    s.coupling_inv =
        Eigen::Map<const Eigen::Matrix<double, -1, -1, Eigen::RowMajor>>(coupling_inv.data(), n, n);
    s.coupling_offset = Eigen::Map<const Eigen::VectorXd>(coupling_offset.data(), n);
    s.actuated = std::move(actuated);
    s.substeps = substeps;
    s.period_s = period_s;
    s.comp_bodies = std::move(comp_bodies);
    s.comp_masses = std::move(comp_masses);
    s.gravity = Eigen::Map<const Eigen::Vector3d>(gravity.data());
    s.quantum = quantum;
    s.delay_cycles = delay_cycles;
    s.velocity_alpha = velocity_alpha;
    s.hand_body = hand_body;
    return s;
  }

  void run(long k0, CF64 plan, CF64 noise, CF64 dropout, F64 log) {
    const size_t rows = plan.ndim() == 2 ? plan.shape(0) : 0;
    require_shape("plan", plan, rows, size_t(loop.plan_layout().columns));
    require_shape("noise", noise, rows, size_t(loop.dof()));
    require_shape("dropout", dropout, rows, 0);
    const auto L = size_t(loop.log_layout().columns);
    if (!(log.ndim() == 2 && log.shape(0) == rows && log.shape(1) == L)) {
      throw nb::value_error(("log: expected shape (" + std::to_string(rows) + ", " +
                             std::to_string(L) + ")")
                                .c_str());
    }
    nb::gil_scoped_release release;
    loop.run(k0, rows, plan.data(), noise.data(), dropout.data(), log.data());
  }

  ServoLoop loop;
};

// ServoLoop(renderer, ...) for a Controller or a MechanismSet: the same arguments, the
// renderer kept alive by the loop.
template <typename Renderer>
void def_init(nb::class_<PyServoLoop>& c, const char* doc) {
  c.def(nb::init<Renderer&, std::uintptr_t, std::uintptr_t, CF64, CF64, std::vector<int>, int,
                 double, std::vector<int>, std::vector<double>, CF64, double, int, double, int,
                 const nb::dict&, const nb::dict&>(),
        "controller"_a, "model"_a, "data"_a, "coupling_inv"_a, "coupling_offset"_a,
        "actuated"_a, "substeps"_a, "period_s"_a, "comp_bodies"_a, "comp_masses"_a,
        "gravity"_a, "quantum"_a, "delay_cycles"_a, "velocity_alpha"_a, "hand_body"_a,
        "plan_layout"_a, "log_layout"_a, nb::keep_alive<1, 2>(), doc);
}

}  // namespace

NB_MODULE(_sim, m) {
  m.doc() = "virtmech's simulation loop (C++, MuJoCo's C API); internal: use virtmech.sim.run.";
  m.attr("MUJOCO_VERSION") = mjVERSION_HEADER;  // the MuJoCo headers it was built with
  m.def("mujoco_library_version", &mj_version, "mj_version() of the MuJoCo library loaded.");
  nb::class_<PyServoLoop> loop(m, "ServoLoop",
                               "The servo-rate loop (sim/include/virtmech/sim/servo_loop.hpp).");
  nb::class_<HeldTorque>(m, "HeldTorque",
                         "The joint torques (dof,) [N·m or N] a loop over it applies, as last "
                         "set: a simulated device driven from outside (virtmech ros2-sim).")
      .def(nb::init<std::shared_ptr<Device>>(), "device"_a)
      .def_prop_rw(
          "torque", [](const HeldTorque& h) { return h.torque; },
          [](HeldTorque& h, CF64 tau) {
            require_shape("torque", tau, size_t(h.torque.size()), 0);
            h.torque = Eigen::Map<const Eigen::VectorXd>(tau.data(), h.torque.size());
          },
          "The held torque (dof,): set it between the loop's runs.");
  def_init<HeldTorque>(loop, "The loop applying a HeldTorque's torque (controller: it).");
  def_init<MechanismSet>(loop, "The loop rendering a MechanismSet (controller: the set).");
  def_init<Controller>(
      loop,
      "model, data: the addresses of an mjModel and its mjData (MjModel._address); the "
      "caller keeps them alive. hand_body: the hand's body id (-1: none), whose mass the "
      "loop zeroes while the plan's hand_attached is 0. plan_layout, log_layout: "
      "{field: column}.");
  loop
      .def_prop_ro("log_columns", [](const PyServoLoop& s) { return s.loop.log_layout().columns; })
      .def_prop_ro("hand_attached", [](const PyServoLoop& s) { return s.loop.hand_attached(); })
      .def_prop_ro("control_time_s",
                   [](const PyServoLoop& s) { return s.loop.control_time_s(); },
                   "wall time in the controller's (or set's) step since construction [s]")
      .def("run", &PyServoLoop::run, "k0"_a, "plan"_a, "noise"_a, "dropout"_a,
           "log"_a.noconvert(),
           "Runs plan.shape[0] control cycles from cycle k0, writing one log row each.");
}
