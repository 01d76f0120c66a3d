/* virtmech driver C API: the servo tick of a device driver, for a vendor program that owns its
 * loop (an OpenHaptics scheduler callback, a Force Dimension thread): the joint velocities
 * estimated from the readings (the simulation's own filter), the controller's (or set's) step,
 * the safety a real loop needs and one record per tick for a normal thread.
 *
 * Per tick, on the servo thread: read the device's joints -> vm_driver_tick -> write tau to
 * the motors; a device error reported by vm_driver_device_error ends the run (zero torque from
 * then on). On a normal thread: vm_driver_read_records, vm_driver_statistics,
 * vm_driver_request_stop.
 *
 * Allocation: only vm_driver_create and vm_driver_create_for_set allocate (the record ring);
 * vm_driver_destroy frees. Every other call never allocates, never locks and never blocks.
 * Units SI (rad, m, N·m, s): convert from the device's (OpenHaptics: mN·m) at the boundary.
 * docs/devices.md, "Running on a real Touch". */
#ifndef VIRTMECH_DRIVER_H_
#define VIRTMECH_DRIVER_H_

#include <stddef.h>
#include <stdint.h>

#include "virtmech.h"
#include "virtmech/drivers/servo_stats_table.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Driver flags of a tick (vm_driver_tick's return, vm_driver_record.flags). Any of WATCHDOG,
 * DEVICE_ERROR, FAULT_HELD, STOPPING means the tick commanded zero torque. */
#define VM_DRIVER_LATE (1u << 0)         /* the gap since the last tick > period + late_s */
#define VM_DRIVER_WATCHDOG (1u << 1)     /* the controller's watchdog tripped: zero, ramp in */
#define VM_DRIVER_DEVICE_ERROR (1u << 2) /* a device error was reported (now or before) */
#define VM_DRIVER_FAULT_HELD (1u << 3)   /* the controller faulted for fault_limit_s */
#define VM_DRIVER_STOPPING (1u << 4)     /* a stop was requested */
#define VM_DRIVER_BAD_READING (1u << 5)  /* a joint reading was not finite */

/* Why the driver commands zero torque for good (vm_driver_stats.stop). */
#define VM_DRIVER_RUNNING 0
#define VM_DRIVER_STOP_REQUESTED 1
#define VM_DRIVER_STOP_DEVICE_ERROR 2
#define VM_DRIVER_STOP_FAULT_HELD 3

/* Settings; vm_driver_settings_init fills the defaults. */
typedef struct vm_driver_settings {
  double period_s;           /* the servo's nominal period [s] (0.001) */
  double velocity_cutoff_hz; /* the velocity filter's cut-off [Hz] (100); 0: none */
  double late_s;             /* a tick later than period + late_s counts as late [s] (0.0005) */
  double fault_limit_s;      /* controller faults lasting this long end the run [s] (0.25) */
  size_t record_capacity;    /* ticks the record ring holds (16384) */
} vm_driver_settings;

/* One tick as vm_driver_read_records hands it over (the C++ virtmech::drivers::TickRecord). */
typedef struct vm_driver_record {
  double tick;         /* index from the start */
  double t_s;          /* time stamp [s] (the caller's clock) */
  double gap_s;        /* since the last tick [s] (NaN on the first) */
  double tick_us;      /* the tick's own time [µs] */
  double step_us;      /* of which the controller's step [µs] */
  double flags;        /* VM_DRIVER_ bits */
  double status;       /* the controller's VM_STATUS_ bits */
  double device_error; /* the device's error code this tick, 0 for none */
  double member;       /* a set's member rendered (-1: none); 0 for a controller */
  double ramp, iterations, iterations_star;
  double q[VM_MAX_DOF], dq[VM_MAX_DOF]; /* readings [rad, m] and velocity estimate */
  double torque[VM_MAX_DOF];            /* the controller's torque [N·m] */
  double command[VM_MAX_DOF];           /* the torque to send [N·m] (zero where flagged) */
  double theta[VM_MAX_DOF], theta_star[VM_MAX_DOF];
  double handle_p[3], stylus[3], twist[6], wrench[6];
  double error[6], error_dot[6], error_star[6], error_star_dot[6];
  double wrench_null[6], wrench_range[6];
} vm_driver_record;

/* Counters of a driver, readable from a normal thread while it runs: one member per row of
 * VM_SERVO_STATS (virtmech/drivers/servo_stats_table.h: each counter's meaning). */
typedef struct vm_driver_stats {
#define VM_DS_COUNT(name, doc) uint64_t name;
#define VM_DS_REAL(name, doc) double name;
#define VM_DS_BITS(name, doc) uint32_t name;
#define VM_DS_STOP(name, doc) int name;
  VM_SERVO_STATS(VM_DS_COUNT, VM_DS_REAL, VM_DS_BITS, VM_DS_STOP)
#undef VM_DS_COUNT
#undef VM_DS_REAL
#undef VM_DS_BITS
#undef VM_DS_STOP
} vm_driver_stats;

typedef struct vm_driver vm_driver;

/* Fills settings with the defaults. Does not allocate. */
void vm_driver_settings_init(vm_driver_settings* settings);
/* A driver ticking a controller (or a set): it must outlive the driver, and is used by
 * vm_driver_tick alone while the driver runs. The controller needs a watchdog
 * (vm_settings.watchdog_s > 0). settings may be NULL. Allocates; returns VM_OK, or
 * VM_ERROR_ARGUMENT / VM_ERROR_INTERNAL with *out = NULL and a message in error. */
int vm_driver_create(vm_controller* controller, const vm_driver_settings* settings,
                     vm_driver** out, char* error, size_t error_size);
int vm_driver_create_for_set(vm_mechanism_set* set, const vm_driver_settings* settings,
                             vm_driver** out, char* error, size_t error_size);
/* Frees a driver (NULL is allowed). */
void vm_driver_destroy(vm_driver* driver);
/* Before the first tick: the controller restarted (ramp-in from zero), the velocity estimate,
 * the counters, the stop state and unread records cleared. */
void vm_driver_reset(vm_driver* driver);
/* One tick: q the joint readings (n = the controller's dof), t_s its time stamp [s] (the
 * watchdog compares consecutive ones), tau out (n entries) [N·m]. Returns VM_DRIVER_ flags.
 * A wrong n, NULL q or tau: tau gets zeros (where given) and VM_DRIVER_BAD_READING. */
uint32_t vm_driver_tick(vm_driver* driver, const double* q, int n, double t_s, double* tau);
/* The device reported an error (a vendor code, not 0): VM_DRIVER_STOP_DEVICE_ERROR and zero
 * torque from then on. On the servo thread: before vm_driver_tick for a failed read (that
 * tick's torque is zero already), after it for a failed write (zero from the next tick). */
void vm_driver_device_error(vm_driver* driver, uint32_t code);
/* Zero torque from the next tick on (VM_DRIVER_STOP_REQUESTED). Any thread. */
void vm_driver_request_stop(vm_driver* driver);
/* Moves up to max records, oldest first, into out; returns how many. One normal thread. */
size_t vm_driver_read_records(vm_driver* driver, vm_driver_record* out, size_t max);
/* Copies the counters. */
void vm_driver_statistics(const vm_driver* driver, vm_driver_stats* out);

#ifdef __cplusplus
}
#endif

#endif /* VIRTMECH_DRIVER_H_ */
