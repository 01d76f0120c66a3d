// A real device driven by a virtmech renderer: the interface every vendor driver implements
// (one subclass per vendor SDK, the SDK loaded at run time), around the one servo tick
// (DriverServo). The lifecycle runs on a normal thread:
//
//     open(model)   load the vendor library, open the device, identify it, check it against
//                   the device model the renderer uses (refusing a mismatch)
//     calibrate()   bring the device's calibration up to date (or say the stylus must go in
//                   its inkwell)
//     start(r)      the servo ticks r every period from the vendor's scheduler or thread; the
//                   renderer's ramp-in brings the force in
//     stop()        zero torque commanded, the servo stopped, the device closed
//
// and each tick, on the vendor's servo thread: read_joints -> DriverServo::tick (velocity
// estimate, renderer, safety, record) -> write_torques, with no allocation, lock or I/O.
// docs/devices.md, "Running on a real Touch".
#pragma once

#include <atomic>
#include <cstdint>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>

#include "virtmech/drivers/driver_servo.hpp"

namespace virtmech::drivers {

/// What a device reports about itself when opened (NaN, empty: not reported).
struct DeviceInfo {
  std::string library;         //!< the vendor library loaded
  std::string device_name;     //!< the name the device was opened by ("": the default)
  std::string vendor, model, serial, driver_version, sdk_version;
  int input_dof = 0;           //!< joints sensed
  int output_dof = 0;          //!< joints driven
  double update_rate_hz = std::numeric_limits<double>::quiet_NaN();
  double nominal_max_force_n = std::numeric_limits<double>::quiet_NaN();
  double nominal_max_continuous_force_n = std::numeric_limits<double>::quiet_NaN();
  double nominal_max_stiffness_n_per_m = std::numeric_limits<double>::quiet_NaN();
  double nominal_max_damping_n_s_per_m = std::numeric_limits<double>::quiet_NaN();
};

/// What calibrate() found.
enum class Calibration : int {
  kOk = 0,           //!< the calibration was up to date
  kUpdated = 1,      //!< it was brought up to date
  kNeedsInkwell = 2  //!< the user must put the stylus in the inkwell (then call again)
};
}  // namespace virtmech::drivers

/// The calibration's names (name_of, settings.hpp), as DeviceDriver.calibrate() returns them.
template <>
struct virtmech::EnumNames<virtmech::drivers::Calibration> {
  static constexpr EnumName kValues[] = {
      {static_cast<int>(drivers::Calibration::kOk), "ok",
       "the calibration was up to date"},
      {static_cast<int>(drivers::Calibration::kUpdated), "updated",
       "it was brought up to date"},
      {static_cast<int>(drivers::Calibration::kNeedsInkwell), "needs_inkwell",
       "the stylus must go in the inkwell"}};
};

namespace virtmech::drivers {

/// A failure of the lifecycle, with the message the user reads.
class DriverError : public std::runtime_error {
 public:
  enum class Kind : int {
    kLibrary = 0,   //!< the vendor library is missing or is not the vendor's
    kMismatch = 1,  //!< the device does not match the device model (or the renderer's limits)
    kDevice = 2,    //!< the device failed (opening it, calibrating, starting its servo)
  };
  DriverError(Kind kind, const std::string& message, std::uint32_t code = 0)
      : std::runtime_error(message), kind_(kind), code_(code) {}
  Kind kind() const noexcept { return kind_; }
  /// The vendor's error code, 0 where none.
  std::uint32_t code() const noexcept { return code_; }

 private:
  Kind kind_;
  std::uint32_t code_;
};

class DeviceDriver {
 public:
  virtual ~DeviceDriver();
  DeviceDriver(const DeviceDriver&) = delete;
  DeviceDriver& operator=(const DeviceDriver&) = delete;

  /// Opens the device and checks it against `model` (kept by reference: it must outlive the
  /// driver); throws DriverError. The renderer started later must render this device model.
  void open(const Device& model);
  /// Checks the device's calibration and updates it where the device can; kNeedsInkwell
  /// where the user must put the stylus in the inkwell (call again after). Throws
  /// DriverError. After open().
  Calibration calibrate();
  /// Starts the servo over a controller or a set (it must outlive the driver's run): the
  /// renderer is reset and ramps in from the first tick. The renderer must render the device
  /// model of open(), with a force limit within the device's nominal maximum (and a watchdog:
  /// DriverServo). Throws DriverError or std::invalid_argument.
  void start(Controller& controller, const ServoSettings& settings = ServoSettings());
  void start(MechanismSet& set, const ServoSettings& settings = ServoSettings());
  /// Zero torque commanded (waiting at most 100 ms for a tick to send it), the servo
  /// stopped, the device closed. Any state, any number of times.
  void stop() noexcept;

  bool is_open() const noexcept { return open_; }
  bool running() const noexcept { return running_; }
  const DeviceInfo& info() const noexcept { return info_; }
  /// The servo of the last start() (nullptr before): its stats, records and stop state.
  DriverServo* servo() noexcept { return servo_.get(); }
  const DriverServo* servo() const noexcept { return servo_.get(); }
  /// True while running when no tick has come for stall_s [s] (the vendor's servo stopped
  /// calling).
  bool stalled(double stall_s) const noexcept;
  /// A vendor error code as the user reads it: its name, code and the vendor's text, e.g.
  /// "HD_COMM_ERROR (0x0302): communication error".
  virtual std::string describe_error(std::uint32_t code) const = 0;

  /// One servo tick: read the device, DriverServo::tick, write the device. The vendor's servo
  /// calls it once per period while running. noexcept, allocation-free, lock-free.
  void tick() noexcept;

 protected:
  DeviceDriver() = default;
  const Device& model() const noexcept { return *model_; }

  /// Loads the vendor library, opens the device, fills `info` and checks the device against
  /// `model`. Throws DriverError; close_device() is called after a throw.
  virtual void open_device(const Device& model, DeviceInfo& info) = 0;
  virtual Calibration calibrate_device() = 0;
  /// After this, tick() is called once per period until stop_servo(). Throws DriverError.
  virtual void start_servo() = 0;
  /// After this returns, tick() is not called again.
  virtual void stop_servo() noexcept = 0;
  virtual void close_device() noexcept = 0;
  /// The tick's device read: joint readings into q (the model's dof() entries, its joint
  /// coordinates [rad, m]); returns the vendor's error code, 0 for none.
  virtual std::uint32_t read_joints(double* q) noexcept = 0;
  /// The tick's device write: joint torques tau (dof() entries [N·m, N]) to the motors the
  /// device has; returns the vendor's error code, 0 for none.
  virtual std::uint32_t write_torques(const double* tau) noexcept = 0;
  /// The joint velocities the device served with this tick's read_joints (dof() entries
  /// [rad/s, m/s]), used instead of the servo's estimate; nullptr (the default): the device
  /// serves none.
  virtual const double* read_velocities() const noexcept { return nullptr; }

 private:
  template <typename Renderer>
  void start_with(Renderer& renderer, const ServoSettings& settings);

  const Device* model_ = nullptr;
  DeviceInfo info_;
  std::unique_ptr<DriverServo> servo_;
  JointVector q_, tau_;
  std::uint64_t clock0_ = 0;                 // the clock at start()
  std::atomic<std::uint64_t> last_tick_{0};  // the clock at the last tick's start
  bool open_ = false, running_ = false;
};

}  // namespace virtmech::drivers
