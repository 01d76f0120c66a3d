// The OpenHaptics HD driver (3D Systems Touch, Touch X; SensAble PHANTOM Omni): libHD loaded at
// run time (virtmech/drivers/hd_api.h), so nothing of the SDK is needed to build.
//
// open:      hdInitDevice(name) -> identification (HD_DEVICE_MODEL_TYPE, vendor, serial,
//            HD_INPUT_DOF / HD_OUTPUT_DOF, the nominal force limits) checked against the
//            device model: a model of another kind, other joint counts, or motors the device
//            lacks are refused
// calibrate: hdStartScheduler, then hdCheckCalibration in a frame (a synchronous callback);
//            hdUpdateCalibration with the style the device supports (automatic, inkwell,
//            encoder reset), or kNeedsInkwell when it needs the stylus in the inkwell
// start:     hdEnable(HD_FORCE_OUTPUT), the tick scheduled at HD_MAX_SCHEDULER_PRIORITY
// tick:      hdBeginFrame -> HD_CURRENT_JOINT_ANGLES, HD_CURRENT_GIMBAL_ANGLES (the model's
//            joints 0-2 and 3-5: the PhantomOmni convention) -> hdGetError -> DriverServo
//            -> HD_CURRENT_JOINT_TORQUE = 1000 tau[0..2] [mN·m] (and HD_CURRENT_GIMBAL_TORQUE
//            = 1000 tau[3..5] where the model drives the gimbal and the device has its
//            motors; never on an Omni or Touch) -> hdEndFrame -> hdGetError
// stop:      zero torque (a tick sends it), hdStopScheduler, hdUnschedule, hdDisableDevice
#pragma once

#include <string>

#include "virtmech/drivers/device_driver.hpp"
#include "virtmech/drivers/hd_api.h"

namespace virtmech::drivers {

struct OpenHapticsSettings {
  /// The HD library's file; empty: "libHD.so" on the loader's search path, then the
  /// OpenHaptics install folders (vm_hd_load).
  std::string library;
  /// The device's name as configured with the Touch setup tool (e.g. "Default Device");
  /// empty: HD_DEFAULT_DEVICE.
  std::string device_name;
};

class OpenHapticsDriver final : public DeviceDriver {
 public:
  explicit OpenHapticsDriver(OpenHapticsSettings settings = OpenHapticsSettings());
  ~OpenHapticsDriver() override;

  /// "HD_COMM_ERROR (0x0302): " followed by hdGetErrorString's text.
  std::string describe_error(std::uint32_t code) const override;
  const OpenHapticsSettings& settings() const noexcept { return settings_; }
  /// The callback the HD scheduler runs each tick (user data: the driver).
  static HDCallbackCode tick_callback(void* driver);

 protected:
  void open_device(const Device& model, DeviceInfo& info) override;
  Calibration calibrate_device() override;
  void start_servo() override;
  void stop_servo() noexcept override;
  void close_device() noexcept override;
  std::uint32_t read_joints(double* q) noexcept override;
  std::uint32_t write_torques(const double* tau) noexcept override;

 private:
  void start_scheduler();
  /// The next error on HD's stack as a DriverError of `kind` naming `call`, if there is one.
  void throw_on_error(const char* call, DriverError::Kind kind);
  // the stages of open_device(), in order
  void init_device(DeviceInfo& info);
  void identify(DeviceInfo& info);
  void check_against(const Device& model, const DeviceInfo& info);

  OpenHapticsSettings settings_;
  vm_hd_api hd_{};
  HHD device_ = HD_INVALID_HANDLE;
  HDSchedulerHandle schedule_ = 0;
  bool scheduled_ = false, scheduler_started_ = false;
  bool gimbal_torque_ = false;  // the model drives the gimbal and the device has its motors
  HDdouble joint_torque_[3] = {0, 0, 0}, gimbal_torque_mnm_[3] = {0, 0, 0};  // [mN·m]
};

}  // namespace virtmech::drivers
