// The servo tick of a device driver, between its device read and its device write: the
// joint velocities estimated (VelocityFilter, the simulation's own filter), the renderer's
// step (a Controller or a MechanismSet), the safety a real loop needs (a late tick's force
// zeroed and ramped back, a device error or a fault that persists ending in zero torque for
// good) and one record per tick handed to a normal thread through a lock-free ring. The tick
// allocates nothing, takes no lock, does no I/O and throws nothing.
//
// A vendor driver (DeviceDriver) calls it from its servo; a program that owns its loop calls
// it directly (the C API's vm_driver_tick). docs/devices.md, "Running on a real Touch".
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <limits>

#include "virtmech/controller.hpp"
#include "virtmech/drivers/servo_stats_table.h"
#include "virtmech/drivers/spsc_ring.hpp"
#include "virtmech/mechanism_set.hpp"
#include "virtmech/velocity_filter.hpp"

namespace virtmech::drivers {

/// Bits of a tick's driver flags (TickRecord::flags). Any of kWatchdog, kDeviceError,
/// kFaultHeld, kStopping means the tick commanded zero torque.
namespace driver_flag {
constexpr std::uint32_t kLate = 1u << 0;         //!< the gap since the last tick > period + late_s
constexpr std::uint32_t kWatchdog = 1u << 1;     //!< the renderer's watchdog tripped: zero, ramp in
constexpr std::uint32_t kDeviceError = 1u << 2;  //!< the device reported an error (now or before)
constexpr std::uint32_t kFaultHeld = 1u << 3;    //!< the renderer faulted for fault_limit_s
constexpr std::uint32_t kStopping = 1u << 4;     //!< a stop was requested
constexpr std::uint32_t kBadReading = 1u << 5;   //!< a joint reading was not finite
constexpr std::uint32_t kZeroMask = kWatchdog | kDeviceError | kFaultHeld | kStopping;
/// Each flag's name, as Python's virtmech._driver.FLAGS spells it.
inline constexpr BitName kNames[] = {{kLate, "late"},           {kWatchdog, "watchdog"},
                                     {kDeviceError, "device_error"}, {kFaultHeld, "fault_held"},
                                     {kStopping, "stopping"},   {kBadReading, "bad_reading"}};
}  // namespace driver_flag

/// Why the servo commands zero torque for good (the first cause wins).
enum class StopReason : int {
  kNone = 0,         //!< running
  kRequested = 1,    //!< request_stop(): Ctrl-C, a signal, the end of the run
  kDeviceError = 2,  //!< the device reported an error (device_error())
  kFaultHeld = 3,    //!< the renderer's faults (implausible readings) lasted fault_limit_s
};
}  // namespace virtmech::drivers

/// The reasons' names (name_of, settings.hpp): what Python's stats and run.json write.
template <>
struct virtmech::EnumNames<virtmech::drivers::StopReason> {
  static constexpr EnumName kValues[] = {
      {static_cast<int>(drivers::StopReason::kNone), "running",
       "the servo runs"},
      {static_cast<int>(drivers::StopReason::kRequested), "requested",
       "request_stop(): Ctrl-C, a signal, the end of the run"},
      {static_cast<int>(drivers::StopReason::kDeviceError), "device_error",
       "the device reported an error"},
      {static_cast<int>(drivers::StopReason::kFaultHeld), "fault_held",
       "the renderer's faults lasted fault_limit_s"}};
};

namespace virtmech::drivers {

/// Settings of the servo tick.
struct ServoSettings {
  double period_s = 1e-3;             //!< the servo's nominal period T [s]
  double velocity_cutoff_hz = 100.0;  //!< the velocity filter's cut-off [Hz]; 0: none
  /// A tick whose gap since the last one exceeds period_s + late_s counts as late [s].
  double late_s = 0.5e-3;
  /// Renderer faults (joint readings out of range or not finite) lasting this long end the
  /// run: zero torque for good and StopReason::kFaultHeld [s].
  double fault_limit_s = 0.25;
  std::size_t record_capacity = 16384;  //!< ticks the record ring holds (power of two above)
};

/// One tick, as the ring carries it to a normal thread: doubles only (integers exact), so
/// that a reader can take it as a row of kTickRecordWidth numbers (record_fields()).
struct TickRecord {
  double tick;             //!< index of the tick from the start
  double t_s;              //!< time stamp [s] since the start, the driver's clock
  double gap_s;            //!< time since the last tick [s] (NaN on the first)
  double tick_us;          //!< the whole tick, device read to device write [µs] (end_tick)
  double step_us;          //!< of which the renderer's step [µs]
  double flags;            //!< driver_flag bits
  double status;           //!< the renderer's status bits (virtmech::status)
  double device_error;     //!< the device's error code this tick, 0 for none
  double member;           //!< a set's member rendered (-1: none); 0 for a controller
  double ramp;             //!< ramp-in factor [0, 1]
  double iterations, iterations_star;
  double q[kMaxDof];        //!< joint readings [rad or m]
  double dq[kMaxDof];       //!< velocity estimate [rad/s or m/s]
  double torque[kMaxDof];   //!< the renderer's torque [N·m or N]
  double command[kMaxDof];  //!< the torque sent to the device [N·m or N] (zero where flagged)
  double theta[kMaxDof], theta_star[kMaxDof];  //!< the placements
  double handle_p[3];       //!< handle position [m]
  double stylus[3];         //!< handle z axis
  double twist[6];          //!< handle twist J_R dq [m/s; rad/s]
  double wrench[6];         //!< the renderer's wrench at the handle [N; N·m]
  double error[6], error_dot[6], error_star[6], error_star_dot[6];
  double wrench_null[6], wrench_range[6];
};

/// Numbers per record.
constexpr int kTickRecordWidth = static_cast<int>(sizeof(TickRecord) / sizeof(double));
static_assert(sizeof(TickRecord) % sizeof(double) == 0, "TickRecord holds doubles only");

/// One field of TickRecord: its first number and how many.
struct RecordField {
  const char* name;
  int offset, width;
};
/// Every field of TickRecord in order (arrays at their full kMaxDof width).
const RecordField* record_fields(int* count) noexcept;

/// Counters of the servo, readable from any thread while it runs.
struct ServoStats {
#define VM_STATS_COUNT(name, doc) std::uint64_t name = 0;
#define VM_STATS_REAL(name, doc) double name = 0.0;
#define VM_STATS_BITS(name, doc) std::uint32_t name = 0;
#define VM_STATS_STOP(name, doc) StopReason name = StopReason::kNone;
  VM_SERVO_STATS(VM_STATS_COUNT, VM_STATS_REAL, VM_STATS_BITS, VM_STATS_STOP)
#undef VM_STATS_COUNT
#undef VM_STATS_REAL
#undef VM_STATS_BITS
#undef VM_STATS_STOP
};

class DriverServo {
 public:
  /// The servo over a controller, or over a mechanism set (at least one member); the
  /// renderer must outlive the servo and is used by the tick alone while it runs. Each of
  /// its controllers needs a watchdog (ControllerSettings::watchdog_s > 0): a tick that comes
  /// later than it commands zero torque and the force ramps in again. Throws
  /// std::invalid_argument naming a bad setting. Allocates the record ring.
  DriverServo(Controller& controller, const ServoSettings& settings = ServoSettings());
  DriverServo(MechanismSet& set, const ServoSettings& settings = ServoSettings());
  DriverServo(const DriverServo&) = delete;
  DriverServo& operator=(const DriverServo&) = delete;

  /// Before the first tick (a normal thread, the servo not ticking): the renderer reset
  /// (placements from home, the ramp-in from zero), the velocity estimate, the counters and
  /// the stop state cleared; records not read are dropped.
  void reset() noexcept;

  /// The tick, first half: q the joint readings (dof() entries), t_s the tick's time stamp
  /// [s] on the caller's clock (the renderer's watchdog compares consecutive ones), tau the
  /// torque to command (dof() entries) [N·m or N]; dq the device's own velocity readings
  /// (dof() entries [rad/s or m/s]) where it serves them, used instead of the filter's
  /// estimate while finite (nullptr: the estimate). Returns the tick's driver flags.
  std::uint32_t tick(const double* q, double t_s, double* tau,
                     const double* dq = nullptr) noexcept;
  /// The tick, second half: the device's error code after its write (0: none; an error ends
  /// the run, zero torque from the next tick on) and the whole tick's time [µs], device read
  /// and write included (NaN: the first half's own, velocity estimate to record). Publishes
  /// the tick's record.
  void end_tick(std::uint32_t device_error, double tick_us) noexcept;
  /// A device error before the command (a failed read): this tick's torque and every later
  /// one zero. Call it before tick().
  void device_error(std::uint32_t code) noexcept;

  /// From a normal thread: zero torque from the next tick on (StopReason::kRequested).
  void request_stop() noexcept;
  StopReason reason() const noexcept {
    return static_cast<StopReason>(reason_.load(std::memory_order_acquire));
  }
  /// From one normal thread: moves up to max records, oldest first, into out.
  std::size_t read_records(TickRecord* out, std::size_t max) noexcept {
    return ring_.pop(out, max);
  }
  ServoStats stats() const noexcept;

  const Device& device() const noexcept { return *device_; }
  int dof() const noexcept { return n_; }
  const ServoSettings& settings() const noexcept { return settings_; }
  const VelocityFilter& velocity() const noexcept { return filter_; }
  /// The renderer's largest force and torque magnitudes [N, N·m] (its model's limits).
  double max_force() const noexcept;

 private:
  void init();
  void stop_for(StopReason reason) noexcept;
  void fill(TickRecord& r, const double* q, const double* dq, double t_s, double gap,
            std::uint32_t flags, double step_us, const double* tau, bool stepped) const noexcept;
  // the stages of tick(), in order
  void claim_record() noexcept;
  std::uint32_t clock_in(double t_s, double& gap) noexcept;
  std::uint32_t render(const double* q, double t_s, const double* dq_device, double* tau,
                       std::uint32_t flags, double& step_us, const double*& dq_served) noexcept;
  std::uint32_t hold_faults(std::uint32_t status, double t_s) noexcept;
  void record(const double* q, const double* dq_served, double t_s, double gap,
              std::uint32_t flags, double step_us, const double* tau, bool stepped,
              std::uint64_t entered) noexcept;

  Controller* ctrl_ = nullptr;  // one of the two
  MechanismSet* set_ = nullptr;
  const Device* device_ = nullptr;
  ServoSettings settings_;
  int n_ = 0;
  VelocityFilter filter_;
  CycleOutput out_;
  MechanismSetOutput set_out_;
  JointVector zero_;
  SpscRing<TickRecord> ring_;
  // the tick thread's own state
  TickRecord* pending_ = nullptr;  // the record of the tick in progress
  double last_t_ = std::numeric_limits<double>::quiet_NaN();
  double first_t_ = std::numeric_limits<double>::quiet_NaN();
  double fault_since_ = std::numeric_limits<double>::quiet_NaN();
  bool device_failed_ = false;  // a device error was seen
  std::uint32_t tick_device_error_ = 0;  // this tick's device error
  // counters, written by the tick, read by stats() (relaxed: each on its own)
  std::atomic<std::uint64_t> ticks_{0}, late_{0}, watchdog_{0}, zero_ticks_{0}, dropped_{0};
  std::atomic<double> elapsed_{0.0}, rate_{0.0}, worst_tick_{0.0}, worst_gap_{0.0},
      force_{0.0};
  std::atomic<std::uint32_t> status_{0}, flags_{0}, device_error_{0}, fault_status_{0};
  std::atomic<int> reason_{0};
};

}  // namespace virtmech::drivers
