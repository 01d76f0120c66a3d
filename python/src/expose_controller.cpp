// The controller and the mechanism set (include/virtmech/controller.hpp,
// mechanism_set.hpp) with their outputs.
#include <nanobind/stl/optional.h>

#include "expose.hpp"

namespace vmpy {

using namespace nb::literals;

namespace {

Eigen::Matrix<bool, Eigen::Dynamic, 1> joint_mask(std::uint32_t bits, Eigen::Index n) {
  Eigen::Matrix<bool, Eigen::Dynamic, 1> a(n);
  for (Eigen::Index i = 0; i < n; ++i) a[i] = ((bits >> i) & 1u) != 0;
  return a;
}

// `settings` (or the defaults) with the keywords set, each through its property (so that a
// mistake names the setting); TypeError for a keyword that is no setting
template <class S>
S settings_from(nb::handle settings, const nb::kwargs& kwargs, const char* what) {
  S s = settings.is_none() ? S() : nb::cast<S>(settings);
  nb::object target = nb::cast(&s, nb::rv_policy::reference);
  for (auto [key, value] : kwargs) {
    if (!nb::hasattr(target, key)) {
      throw nb::type_error((std::string(what) + "() got an unexpected keyword argument " +
                            nb::cast<std::string>(nb::repr(key)) + "; expected a setting (" +
                            (std::is_same_v<S, ControllerSettings> ? "CONTROLLER" : "SET") +
                            "_SETTINGS)").c_str());
    }
    nb::setattr(target, key, value);
  }
  return s;
}

// q and dq of the renderer's device, an output to fill (or a new one), the torque's array
template <class Renderer, class Out>
nb::object step(Renderer& self, nb::handle q, nb::handle dq, double t, nb::handle out,
                const char* out_name) {
  const int n = self.device().dof();
  const JointVector qv = joints_arg("q", q, n), dqv = joints_arg("dq", dq, n);
  nb::object result = out.is_none() ? nb::cast(Out()) : nb::borrow(out);
  if (!nb::isinstance<Out>(result)) {
    throw nb::type_error(("out: expected a virtmech." + std::string(out_name) + " to fill, got " +
                          nb::cast<std::string>(nb::repr(out))).c_str());
  }
  self.step(qv.data(), dqv.data(), *nb::inst_ptr<Out>(result), t);
  return result;
}

// one property per row of VM_CYCLE_OUTPUT (include/virtmech/output_table.h)
void expose_cycle_output(nb::module_& m) {
  nb::class_<CycleOutput> cls(m, "CycleOutput", "Everything one controller cycle reports.");
  cls.def(nb::init<>(), "An empty output, to be filled by Controller.step(..., out=...).");
#define VM_PY_FIELD(name, doc) cls.def_ro(#name, &CycleOutput::name, nb::rv_policy::copy, doc);
#define VM_PY_REAL(name, value, doc) VM_PY_FIELD(name, doc)
#define VM_PY_POSE(name, doc) \
  cls.def_prop_ro(#name, [](const CycleOutput& o) { return Eigen::Matrix4d(o.name.matrix()); }, doc);
#define VM_PY_LOCKS(name, of, doc) \
  cls.def_prop_ro(#name, [](const CycleOutput& o) { return joint_mask(o.name, o.of.size()); }, doc);
  VM_CYCLE_OUTPUT(VM_PY_FIELD, VM_PY_FIELD, VM_PY_POSE, VM_PY_LOCKS, VM_PY_FIELD, VM_PY_REAL,
                  VM_PY_FIELD)
#undef VM_PY_FIELD
#undef VM_PY_REAL
#undef VM_PY_POSE
#undef VM_PY_LOCKS
  cls.def_prop_ro("status_names", [](const CycleOutput& o) { return status_names(o.status); },
                  "The names of the status bits set, e.g. ['ramping'] while the force ramps in.")
      .def_prop_ro("fault", [](const CycleOutput& o) { return (o.status & status::kFaultMask) != 0; },
                   "True when a fault bit is set (status & 0xFF00): the torque is zero.");
}

void expose_controller_class(nb::module_& m) {
  const SettingsDoc cdoc = settings_doc(
      controller_setting_infos(),
      "self, device: DeviceBase, mechanism: Mechanism, settings: ControllerSettings | None = None",
      "Controller(device, mechanism, settings=None, **settings): validated and allocated here, "
      "once; then step() once per servo cycle. Its settings: a ControllerSettings and/or its "
      "properties as keywords (CONTROLLER_SETTINGS: defaults and ranges). Gains and weights "
      "are 6-vectors [x y z rx ry rz]; unset ones take the defaults of docs/theory.md "
      "(derived from the device's actuation and the length scale L).\n\nThreads: one "
      "controller belongs to one thread at a time (step() and the rest are not for concurrent "
      "calls); its device and mechanism are immutable and may be shared by controllers on "
      "other threads.");
  nb::class_<Controller>(m, "Controller", "The virtual-mechanism controller: one step() per servo cycle.")
      .def("__init__", [](Controller* self, std::shared_ptr<Device> device,
                          std::shared_ptr<Mechanism> mechanism, nb::handle settings, nb::kwargs kw) {
            new (self) Controller(std::move(device), std::move(mechanism),
                                  settings_from<ControllerSettings>(settings, kw, "Controller"));
          }, "device"_a, "mechanism"_a, "settings"_a = nb::none(), "kwargs"_a,
          nb::sig(cdoc.signature), cdoc.doc)
      .def("step", [](Controller& self, nb::handle q, nb::handle dq, double t, nb::handle out,
                      nb::handle torque) {
            const int n = self.device().dof();
            std::optional<OutArray> tau;
            if (!torque.is_none()) tau.emplace("torque", torque, n);
            nb::object result = step<Controller, CycleOutput>(self, q, dq, t, out, "CycleOutput");
            if (tau) Eigen::Map<Eigen::VectorXd>(tau->data(), n) = nb::inst_ptr<CycleOutput>(result)->torque;
            return result;
          }, "q"_a, "dq"_a, "t"_a = std::numeric_limits<double>::quiet_NaN(), nb::kw_only(),
          "out"_a = nb::none(), "torque"_a = nb::none(),
          "One servo cycle: device joint positions q (n,) and velocities dq (n,) in; returns a "
          "CycleOutput. t: the cycle's time stamp [s] for the watchdog (optional). out: a "
          "CycleOutput to fill in place (returned); torque: a float64 array (n,) to receive the "
          "joint torques. With both, and q, dq float64 arrays, a Python servo loop creates no "
          "object per cycle. Non-finite or implausible inputs give zero torque and a fault "
          "status, never an exception.")
      .def("reset", &Controller::reset, "Restart: placements from home, ramp-in from zero.")
      .def_prop_ro("device", [](const Controller& c) { return std::const_pointer_cast<Device>(c.device_ptr()); })
      .def_prop_ro("mechanism", [](const Controller& c) { return std::const_pointer_cast<Mechanism>(c.mechanism_ptr()); })
      .def_prop_ro("model", [](const Controller& c) { return to_python(describe(c.model()), false); },
                   "The resolved settings (every default filled in).")
      .def_prop_ro("last", [](const Controller& c) { return c.last(); }, "The last cycle's output.");
}

void expose_set_output(nb::module_& m) {
  nb::class_<MechanismSetOutput>(m, "MechanismSetOutput", "Everything one cycle of a MechanismSet reports.")
      .def(nb::init<>())
      .def_ro("cycle", &MechanismSetOutput::cycle,
              "The rendered member's CycleOutput, torque and wrench the set's output (member 0's "
              "with zero force when none is engaged).")
      .def_ro("active", &MechanismSetOutput::active, "The member rendered, -1 for none.")
      .def_ro("switching", &MechanismSetOutput::switching,
              "The output is moving from one member's force to another's at the set rates.")
      .def_prop_ro("distance", [](const MechanismSetOutput& o) {
            return Eigen::VectorXd(Eigen::Map<const Eigen::VectorXd>(o.distance.data(), o.size));
          }, "Each member's engagement distance from the handle [m] (MechanismSetOutput::distance).")
      .def_prop_ro("contact", [](const MechanismSetOutput& o) {
            std::vector<bool> c;
            for (int i = 0; i < o.size; ++i) c.push_back(((o.contact >> i) & 1u) != 0);
            return c;
          },
                   "Per member: unilateral and in contact.")
      .def_prop_ro("torque", [](const MechanismSetOutput& o) { return Eigen::VectorXd(o.cycle.torque); },
                   "The set's joint torques (n,) [N·m or N] (cycle.torque).")
      .def_prop_ro("wrench", [](const MechanismSetOutput& o) { return o.cycle.wrench; },
                   "The set's wrench at the handle (6,) [N; N·m] (cycle.wrench).")
      .def_prop_ro("status", [](const MechanismSetOutput& o) { return o.cycle.status; },
                   "Status bits of the rendered member's cycle (virtmech.status).")
      .def_prop_ro("status_names", [](const MechanismSetOutput& o) { return status_names(o.cycle.status); },
                   "The names of the status bits set (virtmech.status).");
}

void expose_mechanism_set(nb::module_& m) {
  const SettingsDoc sdoc = settings_doc(
      set_setting_infos(),
      "self, device: DeviceBase, capacity: int = 4, settings: MechanismSetSettings | None = None",
      "MechanismSet(device, capacity=4, settings=None, **settings): a MechanismSetSettings "
      "and/or its properties as keywords (SET_SETTINGS: defaults and ranges).");
  nb::class_<MechanismSet>(
      m, "MechanismSet",
      "Several mechanisms on one device, at most one rendered per cycle: a member engages within "
      "snap_distance [m] and lets go beyond release_distance (hysteresis; a unilateral member's "
      "distance is its tip's height, 0 in contact); switching moves the force at most "
      "force_rate [N/s] and moment_rate [N m/s]. One set belongs to one thread at a time; its "
      "members' devices and mechanisms may be shared across threads.")
      .def("__init__", [](MechanismSet* self, std::shared_ptr<Device> device, int capacity,
                          nb::handle settings, nb::kwargs kw) {
            new (self) MechanismSet(std::move(device), capacity,
                                    settings_from<MechanismSetSettings>(settings, kw, "MechanismSet"));
          }, "device"_a, "capacity"_a = 4, "settings"_a = nb::none(), "kwargs"_a,
          nb::sig(sdoc.signature), sdoc.doc)
      .def("add", [](MechanismSet& self, const Controller& member) { return self.add(member); },
           "member"_a,
           "Adds a member: a copy of a Controller of the set's device and the member's mechanism "
           "(its settings as Controller's). Returns its index.")
      .def("step", [](MechanismSet& self, nb::handle q, nb::handle dq, double t, nb::handle out) {
            return step<MechanismSet, MechanismSetOutput>(self, q, dq, t, out, "MechanismSetOutput");
          }, "q"_a, "dq"_a, "t"_a = std::numeric_limits<double>::quiet_NaN(), nb::kw_only(),
          "out"_a = nb::none(), "One servo cycle of every member; returns a MechanismSetOutput.")
      .def("reset", &MechanismSet::reset)
      .def_prop_ro("size", &MechanismSet::size)
      .def_prop_ro("capacity", &MechanismSet::capacity)
      .def_prop_ro("active", &MechanismSet::active)
      .def_prop_ro("last", [](const MechanismSet& s) { return s.last(); }, "The last cycle's MechanismSetOutput.")
      .def_prop_ro("device", [](const MechanismSet& s) { return std::const_pointer_cast<Device>(s.device_ptr()); })
      .def("member", [](const MechanismSet& s, int i) {
            if (i < 0 || i >= s.size()) {
              throw nb::index_error(("i: expected 0 <= i < " + std::to_string(s.size()) + ", got " +
                                     std::to_string(i)).c_str());
            }
            return std::const_pointer_cast<Mechanism>(s.member(i).mechanism_ptr());
          }, "i"_a, "The i-th member's mechanism.");
}

}  // namespace

void expose_controller(nb::module_& m) {
  expose_cycle_output(m);
  expose_controller_class(m);
  expose_set_output(m);
  expose_mechanism_set(m);
}

}  // namespace vmpy
