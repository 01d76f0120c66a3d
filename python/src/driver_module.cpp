// virtmech._driver: the device drivers (include/virtmech/drivers/) for virtmech.drive.
// Translation only: a driver's lifecycle (DeviceDriver, shared by the OpenHaptics and the
// Force Dimension drivers), its servo's counters and records (a float64 row of record_width()
// numbers per tick), the driver errors as exceptions.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>

#include <cstdint>
#include <memory>
#include <string>

#include "virtmech/controller.hpp"
#include "virtmech/drivers/force_dimension.hpp"
#include "virtmech/drivers/openhaptics.hpp"
#include "virtmech/mechanism_set.hpp"
#include "virtmech/velocity_filter.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using namespace virtmech;
using namespace virtmech::drivers;

namespace {

// the Python exception of each DriverError kind (module attributes, alive with the module)
PyObject* g_errors[3] = {nullptr, nullptr, nullptr};

ServoSettings servo_settings(double period_s, double velocity_cutoff_hz, double late_s,
                             double fault_limit_s, std::size_t record_capacity) {
  ServoSettings s;
  s.period_s = period_s;
  s.velocity_cutoff_hz = velocity_cutoff_hz;
  s.late_s = late_s;
  s.fault_limit_s = fault_limit_s;
  s.record_capacity = record_capacity;
  return s;
}

nb::dict info_dict(const DeviceInfo& i) {
  nb::dict d;
  d["library"] = i.library;
  d["device_name"] = i.device_name;
  d["vendor"] = i.vendor;
  d["model"] = i.model;
  d["serial"] = i.serial;
  d["driver_version"] = i.driver_version;
  d["sdk_version"] = i.sdk_version;
  d["input_dof"] = i.input_dof;
  d["output_dof"] = i.output_dof;
  d["update_rate_hz"] = i.update_rate_hz;
  d["nominal_max_force_n"] = i.nominal_max_force_n;
  d["nominal_max_continuous_force_n"] = i.nominal_max_continuous_force_n;
  d["nominal_max_stiffness_n_per_m"] = i.nominal_max_stiffness_n_per_m;
  d["nominal_max_damping_n_s_per_m"] = i.nominal_max_damping_n_s_per_m;
  return d;
}

// one entry per row of VM_SERVO_STATS (virtmech/drivers/servo_stats_table.h)
nb::dict stats_dict(const ServoStats& s) {
  nb::dict d;
#define VM_STATS_VALUE(name, doc) d[#name] = s.name;
#define VM_STATS_STOP(name, doc) d[#name] = name_of(s.name);
  VM_SERVO_STATS(VM_STATS_VALUE, VM_STATS_VALUE, VM_STATS_VALUE, VM_STATS_STOP)
#undef VM_STATS_VALUE
#undef VM_STATS_STOP
  return d;
}

template <typename Renderer>
void start(DeviceDriver& d, Renderer& r, double period_s, double velocity_cutoff_hz,
           double late_s, double fault_limit_s, std::size_t record_capacity) {
  d.start(r, servo_settings(period_s, velocity_cutoff_hz, late_s, fault_limit_s, record_capacity));
}

// the driver errors as Python exceptions (RuntimeError's subclasses)
void expose_errors(nb::module_& m) {
  nb::object base = nb::borrow(PyExc_RuntimeError);
  const char* names[3] = {"LibraryError", "DeviceMismatch", "DeviceFault"};
  const char* docs[3] = {
      "The vendor library is missing or is not the vendor's.",
      "The device does not match the scenario's device model (or the controller's limits).",
      "The device failed: opening it, calibrating it, starting its servo."};
  for (int i = 0; i < 3; ++i) {
    g_errors[i] = PyErr_NewExceptionWithDoc(
        (std::string("virtmech._driver.") + names[i]).c_str(), docs[i], base.ptr(), nullptr);
    m.attr(names[i]) = nb::handle(g_errors[i]);
  }
  nb::register_exception_translator([](const std::exception_ptr& p, void*) {
    try {
      std::rethrow_exception(p);
    } catch (const DriverError& e) {
      PyErr_SetString(g_errors[static_cast<int>(e.kind())], e.what());
    }
  });
}

// the velocity filter's gain, the tick record's layout and the driver's flags
void expose_records(nb::module_& m) {
  m.def("velocity_alpha", &VelocityFilter::alpha_for_cutoff, "period_s"_a, "cutoff_hz"_a,
        "The velocity filter's gain: T / (T + 1 / (2 pi f_c)); 1 where cutoff_hz <= 0.");
  m.def("record_width", [] { return kTickRecordWidth; }, "Numbers per tick record.");
  m.def(
      "record_fields",
      [] {
        int count = 0;
        const RecordField* f = record_fields(&count);
        nb::dict d;
        for (int i = 0; i < count; ++i) d[f[i].name] = nb::make_tuple(f[i].offset, f[i].width);
        return d;
      },
      "{field: (first number, width)} of a tick record (arrays at their full width).");
  nb::dict flags;
  for (const auto& [bit, name] : driver_flag::kNames) flags[name] = bit;
  m.attr("FLAGS") = flags;
  m.attr("ZERO_MASK") = driver_flag::kZeroMask;
}

// the servo's settings as keywords with their defaults (ServoSettings)
template <class Renderer>
void def_start(nb::class_<DeviceDriver>& cls, const char* doc) {
  const ServoSettings defaults;
  cls.def("start", &start<Renderer>, "controller"_a, "period_s"_a = defaults.period_s,
          "velocity_cutoff_hz"_a = defaults.velocity_cutoff_hz, "late_s"_a = defaults.late_s,
          "fault_limit_s"_a = defaults.fault_limit_s,
          "record_capacity"_a = defaults.record_capacity, nb::keep_alive<1, 2>(),
          nb::call_guard<nb::gil_scoped_release>(), doc);
}

void expose_device_driver(nb::module_& m) {
  using Unlocked = nb::call_guard<nb::gil_scoped_release>;  // the GIL released while it runs
  nb::class_<DeviceDriver> cls(m, "DeviceDriver",
                               "A device driver (its vendor's SDK loaded at run time).");
  def_start<Controller>(cls, "Starts the servo over a Controller.");
  def_start<MechanismSet>(cls, "Starts the servo over a MechanismSet.");
  cls.def("open", &DeviceDriver::open, "model"_a, nb::keep_alive<1, 2>(), Unlocked(),
          "Opens the device and checks it against the device model.")
      .def("calibrate", [](DeviceDriver& d) { return name_of(d.calibrate()); }, Unlocked(),
           "'ok', 'updated', or 'needs_inkwell' (the stylus must go in the inkwell).")
      .def("stop", &DeviceDriver::stop, Unlocked(),
           "Zero torque, the servo stopped, the device closed (HD: the scheduler stopped, the "
           "callback unscheduled, the device disabled; DHD: the thread joined, dhdStop, dhdClose).")
      .def(
          "request_stop",
          [](DeviceDriver& d) {
            if (d.servo()) d.servo()->request_stop();
          },
          "Zero torque from the next tick on (stop() then ends the run).")
      .def_prop_ro("is_open", &DeviceDriver::is_open)
      .def_prop_ro("running", &DeviceDriver::running)
      .def_prop_ro("info", [](const DeviceDriver& d) { return info_dict(d.info()); })
      .def_prop_ro(
          "stats",
          [](const DeviceDriver& d) {
            return stats_dict(d.servo() ? d.servo()->stats() : ServoStats{});
          },
          "The servo's counters (ticks, late, watchdog, rate_hz, worst_tick_us, ...).")
      .def(
          "read_records",
          [](DeviceDriver& d, std::size_t max) {
            const auto w = static_cast<std::size_t>(kTickRecordWidth);
            auto* buffer = new TickRecord[max > 0 ? max : 1];
            const std::size_t n =
                d.servo() ? d.servo()->read_records(buffer, max) : std::size_t{0};
            nb::capsule owner(buffer, [](void* p) noexcept { delete[] static_cast<TickRecord*>(p); });
            return nb::ndarray<nb::numpy, double, nb::ndim<2>>(
                reinterpret_cast<double*>(buffer), {n, w}, owner);
          },
          "max"_a, "Up to max tick records, oldest first: a (n, record_width()) float64 array.")
      .def("stalled", &DeviceDriver::stalled, "stall_s"_a,
           "True while running when no tick has come for stall_s seconds.")
      .def("describe_error", &DeviceDriver::describe_error, "code"_a,
           "A device error code as the user reads it, e.g. 'HD_COMM_ERROR (0x0302): ...'.");
}

void expose_vendor_drivers(nb::module_& m) {
  nb::class_<OpenHapticsDriver, DeviceDriver>(
      m, "OpenHapticsDriver", "The OpenHaptics HD driver (libHD loaded at run time).")
      .def(
          "__init__",
          [](OpenHapticsDriver* self, const std::string& library, const std::string& device_name) {
            OpenHapticsSettings s;
            s.library = library;
            s.device_name = device_name;
            new (self) OpenHapticsDriver(s);
          },
          "library"_a = "", "device_name"_a = "");

  nb::class_<ForceDimensionDriver, DeviceDriver>(
      m, "ForceDimensionDriver",
      "The Force Dimension DHD driver (libdhd loaded at run time; omega, sigma, Falcon).")
      .def(
          "__init__",
          [](ForceDimensionDriver* self, const std::string& library, int realtime_priority) {
            ForceDimensionSettings s;
            s.library = library;
            s.realtime_priority = realtime_priority;
            new (self) ForceDimensionDriver(s);
          },
          "library"_a = "", "realtime_priority"_a = ForceDimensionSettings().realtime_priority)
      .def_prop_ro("system_type", &ForceDimensionDriver::system_type,
                   "dhdGetSystemType's value of the open device (-1 before).")
      .def_prop_ro("realtime", &ForceDimensionDriver::realtime,
                   "True while the servo thread runs at SCHED_FIFO.")
      .def_prop_ro("priority_note", &ForceDimensionDriver::priority_note,
                   "Why the servo thread does not run at SCHED_FIFO ('' where it does).");
}

}  // namespace

NB_MODULE(_driver, m) {
  m.doc() = "virtmech's device drivers (C++); internal: use virtmech.drive.";
  expose_errors(m);
  expose_records(m);
  expose_device_driver(m);
  expose_vendor_drivers(m);
}
