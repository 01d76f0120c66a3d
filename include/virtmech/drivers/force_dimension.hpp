// The Force Dimension DHD driver (omega.3, omega.6, omega.7, sigma.7; the Novint Falcon through
// the same SDK): libdhd loaded at run time (virtmech/drivers/dhd_api.h), so nothing of the SDK
// is needed to build. The device model is a CartesianDevice.
//
// open:      dhdOpen -> dhdGetSystemType chooses the model (a type virtmech does not model is
//            refused) -> checked against the device model: another model is refused
// calibrate: nothing to do (the device is ready once open)
// start:     dhdEnableForce(on), then the driver's own loop thread at the servo's period
//            (ServoSettings::period_s)
//            (SCHED_FIFO where the system permits it; else normal priority, said by
//            priority_note(), and the gaps the servo measures say the jitter)
// tick:      dhdGetPositionAndOrientationFrame, dhdGetLinearVelocity and
//            dhdGetAngularVelocityRad -> coordinates and their rates (CartesianDevice) ->
//            DriverServo -> the handle wrench of the coordinate torques ->
//            dhdSetForceAndTorque (dhdSetForceAndTorqueAndGripperForce with a zero gripper
//            force where the model has a gripper); a negative return is a device error: zero
//            force from then on, and the SDK's text (dhdErrorGetLastStr) kept for the message
// stop:      zero force (a tick sends it), the thread joined, dhdStop, dhdClose
#pragma once

#include <atomic>
#include <string>
#include <thread>

#include "virtmech/cartesian_device.hpp"
#include "virtmech/drivers/device_driver.hpp"
#include "virtmech/drivers/dhd_api.h"

namespace virtmech::drivers {

struct ForceDimensionSettings {
  /// The DHD library's file; empty: "libdhd.so" on the loader's search path.
  std::string library;
  /// Ask for SCHED_FIFO at this priority (1..99); 0: normal priority.
  int realtime_priority = 80;
};

/// The error codes a tick reports (DriverServo's device error): which call failed.
namespace dhd_error {
constexpr std::uint32_t kReadPose = 1;      //!< dhdGetPositionAndOrientationFrame
constexpr std::uint32_t kReadVelocity = 2;  //!< dhdGetLinearVelocity / dhdGetAngularVelocityRad
constexpr std::uint32_t kWriteForce = 3;    //!< dhdSetForceAndTorque(AndGripperForce)
}  // namespace dhd_error

class ForceDimensionDriver final : public DeviceDriver {
 public:
  explicit ForceDimensionDriver(ForceDimensionSettings settings = ForceDimensionSettings());
  ~ForceDimensionDriver() override;

  /// "dhdSetForceAndTorque failed: " followed by dhdErrorGetLastStr's text at that tick.
  std::string describe_error(std::uint32_t code) const override;
  const ForceDimensionSettings& settings() const noexcept { return settings_; }
  /// dhdGetSystemType's value of the open device (-1 before).
  int system_type() const noexcept { return system_type_; }
  /// True while the loop thread runs at SCHED_FIFO.
  bool realtime() const noexcept { return realtime_.load(); }
  /// Why the loop thread does not run at SCHED_FIFO ("" where it does, or before start).
  std::string priority_note() const;

 protected:
  void open_device(const Device& model, DeviceInfo& info) override;
  Calibration calibrate_device() override { return Calibration::kOk; }
  void start_servo() override;
  void stop_servo() noexcept override;
  void close_device() noexcept override;
  std::uint32_t read_joints(double* q) noexcept override;
  std::uint32_t write_torques(const double* tau) noexcept override;
  const double* read_velocities() const noexcept override { return dq_; }

 private:
  void loop() noexcept;
  std::uint32_t fail(std::uint32_t code) noexcept;
  [[noreturn]] void throw_sdk(const char* call, DriverError::Kind kind, const std::string& advice);

  ForceDimensionSettings settings_;
  vm_dhd_api dhd_{};
  char id_ = -1;
  int system_type_ = -1;
  bool open_ = false, force_enabled_ = false;
  const CartesianDevice* device_ = nullptr;
  std::thread thread_;
  std::atomic<bool> run_{false}, realtime_{false};
  std::string priority_note_;
  // the tick's state (the loop thread's)
  double q_[6] = {0, 0, 0, 0, 0, 0}, dq_[6] = {0, 0, 0, 0, 0, 0};
  bool have_q_ = false;
  // the first failure's call and SDK text (written once by the loop thread, then read)
  std::atomic<std::uint32_t> failed_{0};
  char failure_[512] = {};
};

}  // namespace virtmech::drivers
