#include "virtmech/drivers/force_dimension.hpp"

#include <pthread.h>
#include <sched.h>
#include <time.h>

#include <cerrno>
#include <cstring>
#include <limits>
#include <utility>

namespace virtmech::drivers {

namespace {

const char* call_of(std::uint32_t code) {
  switch (code) {
    case dhd_error::kReadPose:
      return "dhdGetPositionAndOrientationFrame";
    case dhd_error::kReadVelocity:
      return "dhdGetLinearVelocity / dhdGetAngularVelocityRad";
    case dhd_error::kWriteForce:
      return "dhdSetForceAndTorque";
    default:
      return "a DHD call";
  }
}

// at most size - 1 characters of s into out, terminated (no allocation: the tick calls it)
void copy_text(char* out, std::size_t size, const char* s) noexcept {
  std::size_t i = 0;
  for (; s != nullptr && s[i] != '\0' && i + 1 < size; ++i) out[i] = s[i];
  out[i] = '\0';
}

timespec add_ns(timespec t, long ns) noexcept {
  t.tv_nsec += ns;
  while (t.tv_nsec >= 1000000000L) {
    t.tv_nsec -= 1000000000L;
    ++t.tv_sec;
  }
  return t;
}

bool before(const timespec& a, const timespec& b) noexcept {
  return a.tv_sec < b.tv_sec || (a.tv_sec == b.tv_sec && a.tv_nsec < b.tv_nsec);
}

}  // namespace

ForceDimensionDriver::ForceDimensionDriver(ForceDimensionSettings settings)
    : settings_(std::move(settings)) {}

ForceDimensionDriver::~ForceDimensionDriver() {
  stop();
  vm_dhd_unload(&dhd_);
}

std::string ForceDimensionDriver::describe_error(std::uint32_t code) const {
  std::string out = std::string(call_of(code)) + " failed";
  if (failed_.load(std::memory_order_acquire) == code && failure_[0] != '\0') {
    out += ": " + std::string(failure_);
  } else if (dhd_.dhdErrorGetLastStr != nullptr) {
    const char* what = dhd_.dhdErrorGetLastStr();
    if (what != nullptr && what[0] != '\0') out += ": " + std::string(what);
  }
  return out + " (dhdErrorGetLastStr)";
}

std::string ForceDimensionDriver::priority_note() const { return priority_note_; }

void ForceDimensionDriver::throw_sdk(const char* call, DriverError::Kind kind,
                                     const std::string& advice) {
  const char* what = dhd_.dhdErrorGetLastStr ? dhd_.dhdErrorGetLastStr() : nullptr;
  throw DriverError(kind, std::string(call) + " failed: " +
                              (what && what[0] ? what : "no message from the SDK") +
                              " (dhdErrorGetLastStr)" + (advice.empty() ? "" : "; " + advice));
}

void ForceDimensionDriver::open_device(const Device& model, DeviceInfo& info) {
  if (dhd_.library == nullptr) {
    char error[1024];
    if (vm_dhd_load(settings_.library.c_str(), &dhd_, error, sizeof error) != 0) {
      throw DriverError(DriverError::Kind::kLibrary, error);
    }
  }
  info.library = dhd_.path;
  const int id = dhd_.dhdOpen();
  if (id < 0) {
    throw_sdk("dhdOpen", DriverError::Kind::kDevice,
              "check that the device is connected by USB and powered, that its calibration "
              "finished (the vendor's tools), and that you may use its port");
  }
  id_ = static_cast<char>(id);
  open_ = true;
  system_type_ = dhd_.dhdGetSystemType(id_);
  if (system_type_ < 0) throw_sdk("dhdGetSystemType", DriverError::Kind::kDevice, "");
  const char* name = vm_dhd_model_name(system_type_);
  if (name == nullptr) {
    const char* known = vm_dhd_system_name(system_type_);
    throw DriverError(DriverError::Kind::kMismatch,
                      "dhdGetSystemType: the device is " +
                          (known ? "a " + std::string(known) : std::string("of an unknown kind")) +
                          " (system type " + std::to_string(system_type_) +
                          "), which virtmech does not model; it drives the omega.3, omega.6, "
                          "omega.7, sigma.7 and Novint Falcon");
  }
  const CartesianModel& m = cartesian_model(name);
  info.vendor = system_type_ == VM_DHD_FALCON ? "Novint (Force Dimension SDK)" : "Force Dimension";
  info.model = name;
  info.input_dof = m.orientation_sensed ? 6 : 3;
  info.output_dof = m.torque_actuated ? 6 : 3;
  info.nominal_max_force_n = m.max_force;
  device_ = dynamic_cast<const CartesianDevice*>(&model);
  if (device_ == nullptr) {
    throw DriverError(DriverError::Kind::kMismatch,
                      "the device is a " + std::string(name) + ", the device model (" +
                          model.name() + ") is not a Cartesian device; describe it as [device] "
                          "type = \"CartesianDevice\", model = \"" + name + "\"");
  }
  if (device_->model().name != name) {
    throw DriverError(DriverError::Kind::kMismatch,
                      "the device is a " + std::string(name) + " (dhdGetSystemType " +
                          std::to_string(system_type_) + "), the device model is a " +
                          device_->model().name + ": set [device] model = \"" + name + "\"");
  }
}

void ForceDimensionDriver::start_servo() {
  failed_.store(0);
  failure_[0] = '\0';
  have_q_ = false;
  if (dhd_.dhdEnableForce(1, id_) < 0) {
    throw_sdk("dhdEnableForce", DriverError::Kind::kDevice, "");
  }
  force_enabled_ = true;
  run_.store(true, std::memory_order_release);
  thread_ = std::thread([this] { loop(); });
  // the loop's priority: SCHED_FIFO where the system permits it
  realtime_.store(false);
  priority_note_.clear();
  if (settings_.realtime_priority > 0) {
    sched_param p{};
    p.sched_priority = settings_.realtime_priority;
    const int e = pthread_setschedparam(thread_.native_handle(), SCHED_FIFO, &p);
    if (e == 0) {
      realtime_.store(true);
    } else {
      priority_note_ = std::string("SCHED_FIFO not permitted (") + std::strerror(e) +
                       "): the servo thread runs at normal priority and its timing jitters "
                       "with the system's load (grant the user real-time priority, e.g. "
                       "rtprio in /etc/security/limits.conf)";
    }
  } else {
    priority_note_ = "real-time priority not asked for: the servo thread runs at normal priority";
  }
}

void ForceDimensionDriver::loop() noexcept {
  const long period_ns = static_cast<long>(servo()->settings().period_s * 1e9);
  timespec next{};
  clock_gettime(CLOCK_MONOTONIC, &next);
  while (run_.load(std::memory_order_acquire)) {
    tick();
    next = add_ns(next, period_ns);
    timespec now{};
    clock_gettime(CLOCK_MONOTONIC, &now);
    if (before(next, now)) next = now;  // behind: the next tick now, never a burst
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, nullptr) == EINTR) {
    }
  }
}

void ForceDimensionDriver::stop_servo() noexcept {
  run_.store(false, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
}

void ForceDimensionDriver::close_device() noexcept {
  stop_servo();
  if (open_) {
    dhd_.dhdStop(id_);  // forces off, brakes on
    dhd_.dhdClose(id_);
    open_ = false;
  }
  force_enabled_ = false;
  id_ = -1;
}

std::uint32_t ForceDimensionDriver::fail(std::uint32_t code) noexcept {
  std::uint32_t none = 0;
  if (failed_.load(std::memory_order_relaxed) == 0) {
    copy_text(failure_, sizeof failure_, dhd_.dhdErrorGetLastStr());
    failed_.compare_exchange_strong(none, code, std::memory_order_release);
  }
  return code;
}

std::uint32_t ForceDimensionDriver::read_joints(double* q) noexcept {
  double p[3], R[3][3];
  if (dhd_.dhdGetPositionAndOrientationFrame(&p[0], &p[1], &p[2], R, id_) < 0) {
    return fail(dhd_error::kReadPose);
  }
  Eigen::Matrix3d Rm;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) Rm(i, j) = R[i][j];
  }
  device_->coordinates(Eigen::Vector3d(p[0], p[1], p[2]), Rm, have_q_ ? q_ : nullptr, q_);
  have_q_ = true;
  const int n = device_->dof();
  for (int i = 0; i < n; ++i) q[i] = q_[i];
  double v[3], w[3] = {0.0, 0.0, 0.0};
  if (dhd_.dhdGetLinearVelocity(&v[0], &v[1], &v[2], id_) < 0) {
    return fail(dhd_error::kReadVelocity);
  }
  if (device_->orientation_sensed() &&
      dhd_.dhdGetAngularVelocityRad(&w[0], &w[1], &w[2], id_) < 0) {
    return fail(dhd_error::kReadVelocity);
  }
  if (!device_->rates(q_, Eigen::Vector3d(v[0], v[1], v[2]), Eigen::Vector3d(w[0], w[1], w[2]),
                      dq_)) {
    // at the gimbal lock the servo's own estimate stands in (a reading not finite)
    for (int i = 3; i < n; ++i) dq_[i] = std::numeric_limits<double>::quiet_NaN();
  }
  return 0;
}

std::uint32_t ForceDimensionDriver::write_torques(const double* tau) noexcept {
  Eigen::Vector3d f, m;
  if (!device_->wrench(q_, tau, f, m)) m.setZero();  // at the gimbal lock: force alone
  const int r = device_->model().gripper
                    ? dhd_.dhdSetForceAndTorqueAndGripperForce(f.x(), f.y(), f.z(), m.x(), m.y(),
                                                               m.z(), 0.0, id_)
                    : dhd_.dhdSetForceAndTorque(f.x(), f.y(), f.z(), m.x(), m.y(), m.z(), id_);
  return r < 0 ? fail(dhd_error::kWriteForce) : 0;
}

}  // namespace virtmech::drivers
