/* A driver servo's counters, one row per field (as virtmech/settings_table.h): the C++
 * struct (virtmech::drivers::ServoStats), its C mirror (vm_driver_stats), the copy between the
 * two and Python's dict (virtmech.drive) are generated from these rows. Plain C (C89
 * preprocessor): the driver's C API includes it.
 *
 * Columns of a row:
 *   COUNT(name, doc)   a count from the start (uint64_t)
 *   REAL(name, doc)    a number
 *   BITS(name, doc)    a word of bits (uint32_t)
 *   STOP(name, doc)    why the servo stopped (C++ StopReason; C int, VM_DRIVER_RUNNING or
 *                      VM_DRIVER_STOP_*; Python its name: 'running', 'requested', ...)
 */
#ifndef VIRTMECH_DRIVERS_SERVO_STATS_TABLE_H_
#define VIRTMECH_DRIVERS_SERVO_STATS_TABLE_H_

#define VM_SERVO_STATS(COUNT, REAL, BITS, STOP)                                      \
  COUNT(ticks, "ticks run")                                                          \
  COUNT(late, "ticks later than period + late_s")                                    \
  COUNT(watchdog, "ticks whose force the watchdog zeroed")                           \
  COUNT(zero_ticks, "ticks that commanded zero torque (any flag)")                   \
  COUNT(dropped, "records dropped (the ring was full)")                              \
  REAL(elapsed_s, "the last tick's time stamp [s]")                                  \
  REAL(rate_hz, "measured: ticks per second between the first and the last [Hz]")    \
  REAL(worst_tick_us, "the longest tick [µs]")                                       \
  REAL(worst_gap_s, "the longest gap between ticks [s]")                             \
  REAL(force_n, "|f| of the last tick [N]")                                          \
  BITS(status, "the last tick's renderer status (virtmech::status, VM_STATUS_*)")    \
  BITS(flags, "the last tick's driver flags (driver_flag, VM_DRIVER_*)")             \
  STOP(stop, "why the servo stopped (the first cause), or running")                  \
  BITS(device_error, "the device error that stopped it (a device_error stop)")       \
  BITS(fault_status, "the renderer's fault bits that stopped it (a fault_held stop)")

#endif /* VIRTMECH_DRIVERS_SERVO_STATS_TABLE_H_ */
