// virtmech._sim: the simulation's servo-rate loop (sim/include/virtmech/sim/servo_loop.hpp)
// for virtmech.sim, and the log's table of columns (log_table.hpp). Linked with MuJoCo's C
// library from the mujoco wheel; mjModel and mjData come from the mujoco package's MjModel
// and MjData (their `_address`).
#include <mujoco/mujoco.h>
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <cstdint>
#include <memory>
#include <string>

#include "virtmech/sim/servo_loop.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using virtmech::Device;
using namespace virtmech::sim;

namespace {

using F64 = nb::ndarray<double, nb::c_contig, nb::device::cpu>;
using CF64 = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;

// a layout from {field: column}, each field set through its property (an unknown one named)
template <class Layout>
Layout layout_from(const char* what, const nb::dict& d) {
  Layout out;
  nb::object target = nb::cast(&out, nb::rv_policy::reference);
  for (auto [key, value] : d) {
    if (!nb::hasattr(target, key)) {
      throw nb::value_error((std::string(what) + ": unknown field " + nb::cast<std::string>(key)).c_str());
    }
    nb::setattr(target, key, value);
  }
  return out;
}

void require_rows(const char* name, size_t ndim, size_t rows, size_t got_rows, size_t cols, size_t got_cols) {
  if (ndim != (cols ? 2u : 1u) || got_rows != rows || (cols && got_cols != cols)) {
    throw nb::value_error((std::string(name) + ": expected shape (" + std::to_string(rows) +
                           (cols ? ", " + std::to_string(cols) + ")" : ",)")).c_str());
  }
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
              const LoopSettings& settings, const nb::dict& plan, const nb::dict& log)
      : loop(renderer, reinterpret_cast<mjModel*>(model), reinterpret_cast<mjData*>(data),
             settings, layout_from<PlanLayout>("plan_layout", plan),
             layout_from<LogLayout>("log_layout", log)) {}

  PyServoLoop(HeldTorque& held, std::uintptr_t model, std::uintptr_t data,
              const LoopSettings& settings, const nb::dict& plan, const nb::dict& log)
      : loop(held.device(), held, reinterpret_cast<mjModel*>(model),
             reinterpret_cast<mjData*>(data), settings,
             layout_from<PlanLayout>("plan_layout", plan),
             layout_from<LogLayout>("log_layout", log)) {}

  void run(long k0, CF64 plan, CF64 noise, CF64 dropout, F64 log) {
    const size_t rows = plan.ndim() == 2 ? plan.shape(0) : 0;
    require_rows("plan", plan.ndim(), rows, rows, size_t(loop.plan_layout().columns),
                 plan.ndim() == 2 ? plan.shape(1) : 0);
    require_rows("noise", noise.ndim(), rows, noise.shape(0), size_t(loop.dof()),
                 noise.ndim() == 2 ? noise.shape(1) : 0);
    require_rows("dropout", dropout.ndim(), rows, dropout.shape(0), 0, 0);
    require_rows("log", log.ndim(), rows, log.shape(0), size_t(loop.log_layout().columns),
                 log.ndim() == 2 ? log.shape(1) : 0);
    nb::gil_scoped_release release;
    loop.run(k0, rows, plan.data(), noise.data(), dropout.data(), log.data());
  }

  ServoLoop loop;
};

// the log's columns and the layouts of a hand-plan row and a log row
void expose_layouts(nb::module_& m) {
  nb::list table;  // the log's columns (log_table.hpp)
  for (const LogField& f : log_fields()) {
    nb::dict row;
    row["field"] = f.field;
    row["first"] = log_names(f, 1, 1).front();
    row["derived"] = f.derived;
    row["units"] = log_units(f);
    table.append(row);
  }
  m.attr("LOG_TABLE") = table;
  m.def("log_columns", &log_column_names, "n"_a, "m"_a,
        "The log's column names for a device of n joints and a mechanism of m.");

  nb::class_<PlanLayout> plan(m, "PlanLayout", "Column of each field of a hand-plan row.");
  plan.def(nb::init<>());
  for (auto [name, member] : {std::pair{"columns", &PlanLayout::columns}, {"anchor_p", &PlanLayout::anchor_p},
                              {"anchor_R", &PlanLayout::anchor_R}, {"anchor_v", &PlanLayout::anchor_v},
                              {"anchor_w", &PlanLayout::anchor_w}, {"k_t", &PlanLayout::k_t},
                              {"b_t", &PlanLayout::b_t}, {"k_r", &PlanLayout::k_r}, {"b_r", &PlanLayout::b_r},
                              {"force", &PlanLayout::force}, {"moment", &PlanLayout::moment},
                              {"force_in_handle", &PlanLayout::force_in_handle},
                              {"hand_attached", &PlanLayout::hand_attached}, {"segment", &PlanLayout::segment}}) {
    plan.def_rw(name, member);
  }
  nb::class_<LogLayout> log(m, "LogLayout", "Column of each field of a log row (LOG_TABLE).");
  log.def(nb::init<>()).def_rw("columns", &LogLayout::columns);
#define VM_LOG_MEMBER(field, width, names, units, origin) log.def_rw(#field, &LogLayout::field);
  VM_LOG_TABLE(VM_LOG_MEMBER)
#undef VM_LOG_MEMBER
}

// ServoLoop(controller, model, data, settings, plan_layout, log_layout) over a Renderer
template <class Renderer>
void def_init(nb::class_<PyServoLoop>& loop, const char* doc) {
  loop.def(nb::init<Renderer&, std::uintptr_t, std::uintptr_t, const LoopSettings&, const nb::dict&,
                    const nb::dict&>(),
           "controller"_a, "model"_a, "data"_a, "settings"_a, "plan_layout"_a, "log_layout"_a,
           nb::keep_alive<1, 2>(), doc);
}

void expose_loop(nb::module_& m) {
  nb::class_<LoopSettings>(m, "LoopSettings", "How the device sits in the MuJoCo model, and the simulated driver.")
      .def(nb::init<>())
      .def_rw("coupling_inv", &LoopSettings::coupling_inv, "Cinv (n, n): device joints q = Cinv (qpos - c0).")
      .def_rw("coupling_offset", &LoopSettings::coupling_offset, "c0 (n,).")
      .def_rw("actuated", &LoopSettings::actuated, "Device joint of each MuJoCo actuator, in order.")
      .def_rw("substeps", &LoopSettings::substeps, "Physics steps per control cycle.")
      .def_rw("period_s", &LoopSettings::period_s, "Control period T [s].")
      .def_rw("comp_bodies", &LoopSettings::comp_bodies, "Bodies whose weight the motors compensate.")
      .def_rw("comp_masses", &LoopSettings::comp_masses, "Their masses [kg].")
      .def_rw("gravity", &LoopSettings::gravity, "Gravity for the compensation (3,) [m/s^2].")
      .def_rw("quantum", &LoopSettings::quantum, "Encoder step [rad]; 0: none.")
      .def_rw("delay_cycles", &LoopSettings::delay_cycles, "Sensor delay [cycles].")
      .def_rw("velocity_alpha", &LoopSettings::velocity_alpha, "Velocity low-pass: dqf += alpha (diff - dqf).")
      .def_rw("hand_body", &LoopSettings::hand_body, "The hand's body (mass zeroed while released); -1: none.");

  nb::class_<HeldTorque>(m, "HeldTorque",
                         "The joint torques (dof,) [N·m or N] a loop over it applies, as last "
                         "set: a simulated device driven from outside (virtmech ros2-sim).")
      .def(nb::init<std::shared_ptr<Device>>(), "device"_a)
      .def_prop_rw(
          "torque", [](const HeldTorque& h) { return h.torque; },
          [](HeldTorque& h, CF64 tau) {
            require_rows("torque", tau.ndim(), size_t(h.torque.size()), tau.shape(0), 0, 0);
            h.torque = Eigen::Map<const Eigen::VectorXd>(tau.data(), h.torque.size());
          },
          "The held torque (dof,): set it between the loop's runs.");

  nb::class_<PyServoLoop> loop(m, "ServoLoop", "The servo-rate loop (sim/include/virtmech/sim/servo_loop.hpp).");
  def_init<HeldTorque>(loop, "The loop applying a HeldTorque's torque (controller: it).");
  def_init<virtmech::MechanismSet>(loop, "The loop rendering a MechanismSet (controller: the set).");
  def_init<virtmech::Controller>(
      loop, "model, data: the addresses of an mjModel and its mjData (MjModel._address); the "
            "caller keeps them alive. plan_layout, log_layout: {field: column}.");
  loop      .def_prop_ro("log_columns", [](const PyServoLoop& s) { return s.loop.log_layout().columns; })
      .def_prop_ro("hand_attached", [](const PyServoLoop& s) { return s.loop.hand_attached(); })
      .def_prop_ro("control_time_s", [](const PyServoLoop& s) { return s.loop.control_time_s(); },
                   "wall time in the controller's (or set's) step since construction [s]")
      .def("run", &PyServoLoop::run, "k0"_a, "plan"_a, "noise"_a, "dropout"_a, "log"_a.noconvert(),
           "Runs plan.shape[0] control cycles from cycle k0, writing one log row each.");
}

}  // namespace

NB_MODULE(_sim, m) {
  m.doc() = "virtmech's simulation loop (C++, MuJoCo's C API); internal: use virtmech.sim.run.";
  m.attr("MUJOCO_VERSION") = mjVERSION_HEADER;  // the MuJoCo headers it was built with
  m.def("mujoco_library_version", &mj_version, "mj_version() of the MuJoCo library loaded.");
  expose_layouts(m);
  expose_loop(m);
}
