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

const char* stop_name(StopReason r) {
  switch (r) {
    case StopReason::kRequested:
      return "requested";
    case StopReason::kDeviceError:
      return "device_error";
    case StopReason::kFaultHeld:
      return "fault_held";
    default:
      return "running";
  }
}

const char* calibration_name(Calibration c) {
  switch (c) {
    case Calibration::kOk:
      return "ok";
    case Calibration::kUpdated:
      return "updated";
    default:
      return "needs_inkwell";
  }
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

nb::dict stats_dict(const ServoStats& s) {
  nb::dict d;
  d["ticks"] = s.ticks;
  d["late"] = s.late;
  d["watchdog"] = s.watchdog;
  d["zero_ticks"] = s.zero_ticks;
  d["dropped"] = s.dropped;
  d["elapsed_s"] = s.elapsed_s;
  d["rate_hz"] = s.rate_hz;
  d["worst_tick_us"] = s.worst_tick_us;
  d["worst_gap_s"] = s.worst_gap_s;
  d["force_n"] = s.force_n;
  d["status"] = s.status;
  d["flags"] = s.flags;
  d["stop"] = stop_name(s.reason);
  d["device_error"] = s.device_error;
  d["fault_status"] = s.fault_status;
  return d;
}

template <typename Renderer>
void start(DeviceDriver& d, Renderer& r, double period_s, double velocity_cutoff_hz,
           double late_s, double fault_limit_s, std::size_t record_capacity) {
  const ServoSettings s =
      servo_settings(period_s, velocity_cutoff_hz, late_s, fault_limit_s, record_capacity);
  nb::gil_scoped_release release;
  d.start(r, s);
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
  flags["late"] = driver_flag::kLate;
  flags["watchdog"] = driver_flag::kWatchdog;
  flags["device_error"] = driver_flag::kDeviceError;
  flags["fault_held"] = driver_flag::kFaultHeld;
  flags["stopping"] = driver_flag::kStopping;
  flags["bad_reading"] = driver_flag::kBadReading;
  m.attr("FLAGS") = flags;
  m.attr("ZERO_MASK") = driver_flag::kZeroMask;
}

void expose_device_driver(nb::module_& m) {
  const ServoSettings defaults;
  nb::class_<DeviceDriver>(m, "DeviceDriver",
                           "A device driver (its vendor's SDK loaded at run time).")
      .def(
          "open",
          [](DeviceDriver& d, const Device& model) {
            nb::gil_scoped_release release;
            d.open(model);
          },
          "model"_a, nb::keep_alive<1, 2>(),
          "Opens the device and checks it against the device model.")
      .def(
          "calibrate",
          [](DeviceDriver& d) {
            Calibration c;
            {
              nb::gil_scoped_release release;
              c = d.calibrate();
            }
            return calibration_name(c);
          },
          "'ok', 'updated', or 'needs_inkwell' (the stylus must go in the inkwell).")
      .def("start", &start<Controller>, "controller"_a, "period_s"_a = defaults.period_s,
           "velocity_cutoff_hz"_a = defaults.velocity_cutoff_hz, "late_s"_a = defaults.late_s,
           "fault_limit_s"_a = defaults.fault_limit_s,
           "record_capacity"_a = defaults.record_capacity, nb::keep_alive<1, 2>(),
           "Starts the servo over a Controller.")
      .def("start", &start<MechanismSet>, "controller"_a, "period_s"_a = defaults.period_s,
           "velocity_cutoff_hz"_a = defaults.velocity_cutoff_hz, "late_s"_a = defaults.late_s,
           "fault_limit_s"_a = defaults.fault_limit_s,
           "record_capacity"_a = defaults.record_capacity, nb::keep_alive<1, 2>(),
           "Starts the servo over a MechanismSet.")
      .def(
          "stop",
          [](DeviceDriver& d) {
            nb::gil_scoped_release release;
            d.stop();
          },
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
