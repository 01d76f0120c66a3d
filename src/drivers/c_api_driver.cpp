// The driver C API (virtmech_driver.h) over virtmech::drivers::DriverServo.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <limits>
#include <memory>
#include <new>
#include <string>

#include "../c_api_handles.hpp"
#include "virtmech/drivers/driver_servo.hpp"
#include "virtmech_driver.h"

using namespace virtmech;
using namespace virtmech::drivers;

// the C record and flags are the C++ ones
static_assert(sizeof(vm_driver_record) == sizeof(TickRecord));
static_assert(offsetof(vm_driver_record, q) == offsetof(TickRecord, q));
static_assert(offsetof(vm_driver_record, command) == offsetof(TickRecord, command));
static_assert(offsetof(vm_driver_record, handle_p) == offsetof(TickRecord, handle_p));
static_assert(offsetof(vm_driver_record, wrench_range) == offsetof(TickRecord, wrench_range));
static_assert(VM_DRIVER_LATE == driver_flag::kLate);
static_assert(VM_DRIVER_WATCHDOG == driver_flag::kWatchdog);
static_assert(VM_DRIVER_DEVICE_ERROR == driver_flag::kDeviceError);
static_assert(VM_DRIVER_FAULT_HELD == driver_flag::kFaultHeld);
static_assert(VM_DRIVER_STOPPING == driver_flag::kStopping);
static_assert(VM_DRIVER_BAD_READING == driver_flag::kBadReading);
static_assert(VM_DRIVER_STOP_REQUESTED == static_cast<int>(StopReason::kRequested));
static_assert(VM_DRIVER_STOP_DEVICE_ERROR == static_cast<int>(StopReason::kDeviceError));
static_assert(VM_DRIVER_STOP_FAULT_HELD == static_cast<int>(StopReason::kFaultHeld));

struct vm_driver {
  DriverServo servo;
  template <typename Renderer>
  vm_driver(Renderer& r, const ServoSettings& s) : servo(r, s) {}
};

namespace {

ServoSettings servo_settings(const vm_driver_settings* s) {
  ServoSettings out;
  if (s != nullptr) {
    out.period_s = s->period_s;
    out.velocity_cutoff_hz = s->velocity_cutoff_hz;
    out.late_s = s->late_s;
    out.fault_limit_s = s->fault_limit_s;
    out.record_capacity = s->record_capacity;
  }
  return out;
}

void put_error(char* error, size_t size, const char* message) {
  if (error != nullptr && size > 0) std::snprintf(error, size, "%s", message);
}

template <typename Renderer>
int create(Renderer* renderer, const char* what, const vm_driver_settings* settings,
           vm_driver** out, char* error, size_t error_size) {
  if (out == nullptr) {
    put_error(error, error_size, "out: expected a place for the driver, got NULL");
    return VM_ERROR_ARGUMENT;
  }
  *out = nullptr;
  if (renderer == nullptr) {
    put_error(error, error_size, (std::string(what) + ": expected one, got NULL").c_str());
    return VM_ERROR_ARGUMENT;
  }
  try {
    *out = new vm_driver(*renderer, servo_settings(settings));
    return VM_OK;
  } catch (const std::invalid_argument& e) {
    put_error(error, error_size, e.what());
    return VM_ERROR_ARGUMENT;
  } catch (const std::exception& e) {
    put_error(error, error_size, e.what());
    return VM_ERROR_INTERNAL;
  }
}

}  // namespace

extern "C" {

void vm_driver_settings_init(vm_driver_settings* settings) {
  if (settings == nullptr) return;
  const ServoSettings d;
  settings->period_s = d.period_s;
  settings->velocity_cutoff_hz = d.velocity_cutoff_hz;
  settings->late_s = d.late_s;
  settings->fault_limit_s = d.fault_limit_s;
  settings->record_capacity = d.record_capacity;
}

int vm_driver_create(vm_controller* controller, const vm_driver_settings* settings,
                     vm_driver** out, char* error, size_t error_size) {
  Controller* c = controller ? &detail::controller_of(controller) : nullptr;
  return create(c, "controller", settings, out, error, error_size);
}

int vm_driver_create_for_set(vm_mechanism_set* set, const vm_driver_settings* settings,
                             vm_driver** out, char* error, size_t error_size) {
  MechanismSet* s = set ? &detail::set_of(set) : nullptr;
  return create(s, "set", settings, out, error, error_size);
}

void vm_driver_destroy(vm_driver* driver) { delete driver; }

void vm_driver_reset(vm_driver* driver) {
  if (driver != nullptr) driver->servo.reset();
}

uint32_t vm_driver_tick(vm_driver* driver, const double* q, int n, double t_s, double* tau) {
  if (driver == nullptr || q == nullptr || tau == nullptr || n != driver->servo.dof()) {
    for (int i = 0; tau != nullptr && i < n; ++i) tau[i] = 0.0;
    return VM_DRIVER_BAD_READING;
  }
  const uint32_t flags = driver->servo.tick(q, t_s, tau);
  driver->servo.end_tick(0, std::numeric_limits<double>::quiet_NaN());
  return flags;
}

void vm_driver_device_error(vm_driver* driver, uint32_t code) {
  if (driver != nullptr) driver->servo.device_error(code);
}

void vm_driver_request_stop(vm_driver* driver) {
  if (driver != nullptr) driver->servo.request_stop();
}

size_t vm_driver_read_records(vm_driver* driver, vm_driver_record* out, size_t max) {
  if (driver == nullptr || out == nullptr) return 0;
  return driver->servo.read_records(reinterpret_cast<TickRecord*>(out), max);
}

void vm_driver_statistics(const vm_driver* driver, vm_driver_stats* out) {
  if (out == nullptr) return;
  *out = vm_driver_stats{};
  if (driver == nullptr) return;
  const ServoStats s = driver->servo.stats();
#define VM_STATS_COPY(name, doc) out->name = s.name;
#define VM_STATS_STOP(name, doc) out->name = static_cast<int>(s.name);
  VM_SERVO_STATS(VM_STATS_COPY, VM_STATS_COPY, VM_STATS_COPY, VM_STATS_STOP)
#undef VM_STATS_COPY
#undef VM_STATS_STOP
}

}  // extern "C"
