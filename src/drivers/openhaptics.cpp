#include "virtmech/drivers/openhaptics.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <utility>

namespace virtmech::drivers {

namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::string text(HDstring s) { return s ? std::string(s) : std::string(); }

// the HD model names of the PHANTOM Omni's kinematics: "PHANTOM Omni", "Touch", "Geomagic
// Touch" (not the Touch X, a PHANTOM Desktop)
bool omni_family(const std::string& model) {
  const std::string m = lower(model);
  if (m.find("omni") != std::string::npos) return true;
  return m.find("touch") != std::string::npos && m.find("touch x") == std::string::npos;
}

// hdCheckCalibration inside a frame, as a synchronous scheduler callback
struct CalibrationCall {
  const vm_hd_api* hd;
  HHD device;
  HDenum style;   // 0: check only
  HDenum status;  // hdCheckCalibration's answer
};

HDCallbackCode calibration_callback(void* data) {
  auto* c = static_cast<CalibrationCall*>(data);
  c->hd->hdBeginFrame(c->device);
  if (c->style != 0) c->hd->hdUpdateCalibration(c->style);
  c->status = c->hd->hdCheckCalibration();
  c->hd->hdEndFrame(c->device);
  return HD_CALLBACK_DONE;
}

}  // namespace

OpenHapticsDriver::OpenHapticsDriver(OpenHapticsSettings settings)
    : settings_(std::move(settings)) {}

OpenHapticsDriver::~OpenHapticsDriver() {
  stop();
  vm_hd_unload(&hd_);
}

std::string OpenHapticsDriver::describe_error(std::uint32_t code) const {
  const char* name = vm_hd_error_name(code);
  char head[64];
  std::snprintf(head, sizeof head, "%s (0x%04X)", name ? name : "HD error", code);
  std::string out = head;
  if (hd_.hdGetErrorString != nullptr) {
    const std::string what = text(hd_.hdGetErrorString(code));
    if (!what.empty()) out += ": " + what;
  }
  return out;
}

void OpenHapticsDriver::throw_on_error(const char* call, DriverError::Kind kind) {
  const HDErrorInfo e = hd_.hdGetError();
  if (e.errorCode == HD_SUCCESS) return;
  char internal[32];
  std::snprintf(internal, sizeof internal, "internal error %d", e.internalErrorCode);
  throw DriverError(kind, std::string(call) + ": " + describe_error(e.errorCode) + " (" +
                              internal + ")",
                    e.errorCode);
}

void OpenHapticsDriver::open_device(const Device& model, DeviceInfo& info) {
  init_device(info);
  identify(info);
  check_against(model, info);
  gimbal_torque_ = false;
  for (int i = 3; i < std::min(6, model.dof()); ++i) gimbal_torque_ |= model.actuated(i);
}

// The library loaded (once) and the device initialised and made current.
void OpenHapticsDriver::init_device(DeviceInfo& info) {
  if (hd_.library == nullptr) {
    char error[1024];
    if (vm_hd_load(settings_.library.c_str(), &hd_, error, sizeof error) != 0) {
      throw DriverError(DriverError::Kind::kLibrary, error);
    }
  }
  info.library = hd_.path;
  info.device_name = settings_.device_name;
  const char* name = settings_.device_name.empty() ? HD_DEFAULT_DEVICE
                                                   : settings_.device_name.c_str();
  device_ = hd_.hdInitDevice(name);
  const HDErrorInfo e = hd_.hdGetError();
  if (e.errorCode != HD_SUCCESS || device_ == HD_INVALID_HANDLE) {
    device_ = HD_INVALID_HANDLE;
    const std::string which =
        settings_.device_name.empty() ? "the default device" : "\"" + settings_.device_name + "\"";
    throw DriverError(DriverError::Kind::kDevice,
                      "hdInitDevice(" + which + "): " +
                          describe_error(e.errorCode ? e.errorCode : HD_DEVICE_FAULT) +
                          " (internal error " + std::to_string(e.internalErrorCode) +
                          "); check that the device is connected and powered, that its name "
                          "is the one the Touch setup tool shows, and that you may use its "
                          "port (docs/devices.md, \"Running on a real Touch\")",
                      e.errorCode);
  }
  hd_.hdMakeCurrentDevice(device_);
}

// What the device says it is: model, vendor, versions, joints sensed and driven, servo rate,
// nominal limits.
void OpenHapticsDriver::identify(DeviceInfo& info) {
  info.model = text(hd_.hdGetString(HD_DEVICE_MODEL_TYPE));
  info.vendor = text(hd_.hdGetString(HD_DEVICE_VENDOR));
  info.serial = text(hd_.hdGetString(HD_DEVICE_SERIAL_NUMBER));
  info.driver_version = text(hd_.hdGetString(HD_DEVICE_DRIVER_VERSION));
  info.sdk_version = text(hd_.hdGetString(HD_VERSION));
  HDint dof[1] = {0};
  hd_.hdGetIntegerv(HD_INPUT_DOF, dof);
  info.input_dof = dof[0];
  dof[0] = 0;
  hd_.hdGetIntegerv(HD_OUTPUT_DOF, dof);
  info.output_dof = dof[0];
  HDint rate[1] = {0};
  hd_.hdGetIntegerv(HD_UPDATE_RATE, rate);
  if (rate[0] > 0) info.update_rate_hz = rate[0];
  auto nominal = [&](HDenum what, double scale, double& out) {
    HDdouble v[1] = {0.0};
    hd_.hdGetDoublev(what, v);
    if (v[0] > 0.0) out = v[0] * scale;
  };
  nominal(HD_NOMINAL_MAX_FORCE, 1.0, info.nominal_max_force_n);
  nominal(HD_NOMINAL_MAX_CONTINUOUS_FORCE, 1.0, info.nominal_max_continuous_force_n);
  nominal(HD_NOMINAL_MAX_STIFFNESS, 1e3, info.nominal_max_stiffness_n_per_m);  // N/mm
  nominal(HD_NOMINAL_MAX_DAMPING, 1e3, info.nominal_max_damping_n_s_per_m);    // N s/mm
  throw_on_error("identifying the device", DriverError::Kind::kDevice);
}

// The device against the model the renderer uses: joints sensed, joints driven, kinematics.
void OpenHapticsDriver::check_against(const Device& model, const DeviceInfo& info) {
  const std::string device = "the device (" + (info.model.empty() ? "HD" : info.model) + ")";
  const std::string scenario = "the device model (" + model.name() + ", " +
                               std::to_string(model.dof()) + " joints)";
  if (info.input_dof != model.dof()) {
    throw DriverError(DriverError::Kind::kMismatch,
                      device + " senses " + std::to_string(info.input_dof) +
                          " joints (HD_INPUT_DOF), " + scenario + " has " +
                          std::to_string(model.dof()) +
                          ": describe this device in the scenario's [device]");
  }
  for (int i = 0; i < model.dof(); ++i) {
    if (model.actuated(i) && i >= info.output_dof) {
      throw DriverError(DriverError::Kind::kMismatch,
                        scenario + " drives joint " + std::to_string(i) + ", " + device +
                            " has motors on its first " + std::to_string(info.output_dof) +
                            " joints only (HD_OUTPUT_DOF): make that joint passive in the "
                            "scenario's [device] (actuated)");
    }
  }
  if (model.name() == "PhantomOmni" && !omni_family(info.model)) {
    throw DriverError(DriverError::Kind::kMismatch,
                      device + " is not a PHANTOM Omni or Touch, whose kinematics " + scenario +
                          " describes (HD_DEVICE_MODEL_TYPE \"" + info.model +
                          "\"); describe this device as [device] type = \"Device\" with its "
                          "own joints");
  }
}

void OpenHapticsDriver::start_scheduler() {
  if (scheduler_started_) return;
  hd_.hdStartScheduler();
  throw_on_error("hdStartScheduler", DriverError::Kind::kDevice);
  scheduler_started_ = true;
}

Calibration OpenHapticsDriver::calibrate_device() {
  start_scheduler();
  CalibrationCall call{&hd_, device_, 0, 0};
  hd_.hdScheduleSynchronous(calibration_callback, &call, HD_MIN_SCHEDULER_PRIORITY);
  throw_on_error("hdCheckCalibration", DriverError::Kind::kDevice);
  if (call.status == HD_CALIBRATION_OK) return Calibration::kOk;
  if (call.status == HD_CALIBRATION_NEEDS_MANUAL_INPUT) return Calibration::kNeedsInkwell;
  // an update the device makes itself: the style it supports, automatic first
  HDint styles[1] = {0};
  hd_.hdGetIntegerv(HD_CALIBRATION_STYLE, styles);
  throw_on_error("hdGetIntegerv(HD_CALIBRATION_STYLE)", DriverError::Kind::kDevice);
  for (HDenum style : {HD_CALIBRATION_AUTO, HD_CALIBRATION_INKWELL, HD_CALIBRATION_ENCODER_RESET}) {
    if ((static_cast<HDenum>(styles[0]) & style) == 0) continue;
    call.style = style;
    hd_.hdScheduleSynchronous(calibration_callback, &call, HD_MIN_SCHEDULER_PRIORITY);
    throw_on_error("hdUpdateCalibration", DriverError::Kind::kDevice);
    break;
  }
  if (call.status == HD_CALIBRATION_OK) return Calibration::kUpdated;
  return Calibration::kNeedsInkwell;
}

void OpenHapticsDriver::start_servo() {
  hd_.hdEnable(HD_FORCE_OUTPUT);
  throw_on_error("hdEnable(HD_FORCE_OUTPUT)", DriverError::Kind::kDevice);
  schedule_ = hd_.hdScheduleAsynchronous(tick_callback, this, HD_MAX_SCHEDULER_PRIORITY);
  throw_on_error("hdScheduleAsynchronous", DriverError::Kind::kDevice);
  scheduled_ = true;
  start_scheduler();
}

HDCallbackCode OpenHapticsDriver::tick_callback(void* driver) {
  static_cast<OpenHapticsDriver*>(driver)->tick();
  return HD_CALLBACK_CONTINUE;
}

std::uint32_t OpenHapticsDriver::read_joints(double* q) noexcept {
  hd_.hdBeginFrame(device_);
  hd_.hdGetDoublev(HD_CURRENT_JOINT_ANGLES, q);
  hd_.hdGetDoublev(HD_CURRENT_GIMBAL_ANGLES, q + 3);
  return hd_.hdGetError().errorCode;
}

std::uint32_t OpenHapticsDriver::write_torques(const double* tau) noexcept {
  for (int i = 0; i < 3; ++i) joint_torque_[i] = 1000.0 * tau[i];  // N·m -> mN·m
  hd_.hdSetDoublev(HD_CURRENT_JOINT_TORQUE, joint_torque_);
  if (gimbal_torque_) {
    for (int i = 0; i < 3; ++i) gimbal_torque_mnm_[i] = 1000.0 * tau[3 + i];
    hd_.hdSetDoublev(HD_CURRENT_GIMBAL_TORQUE, gimbal_torque_mnm_);
  }
  hd_.hdEndFrame(device_);
  return hd_.hdGetError().errorCode;
}

void OpenHapticsDriver::stop_servo() noexcept {
  if (scheduler_started_) {
    hd_.hdStopScheduler();
    scheduler_started_ = false;
  }
  if (scheduled_) {
    hd_.hdUnschedule(schedule_);
    scheduled_ = false;
  }
}

void OpenHapticsDriver::close_device() noexcept {
  stop_servo();  // a scheduler started for the calibration alone
  if (device_ != HD_INVALID_HANDLE) {
    hd_.hdDisableDevice(device_);
    device_ = HD_INVALID_HANDLE;
  }
  // errors left on HD's stack (reported already) do not outlive the device
  for (int i = 0; i < 64 && hd_.hdGetError != nullptr; ++i) {
    if (hd_.hdGetError().errorCode == HD_SUCCESS) break;
  }
}

}  // namespace virtmech::drivers
