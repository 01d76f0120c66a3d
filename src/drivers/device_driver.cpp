#include "virtmech/drivers/device_driver.hpp"

#include <chrono>
#include <cmath>
#include <sstream>
#include <thread>
#include <type_traits>

#include "../cycle_clock.hpp"

namespace virtmech::drivers {

using detail::CycleClock;

namespace {

std::string number(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

DeviceDriver::~DeviceDriver() = default;

void DeviceDriver::open(const Device& model) {
  stop();
  model_ = &model;
  info_ = DeviceInfo{};
  try {
    open_device(model, info_);
  } catch (...) {
    close_device();
    throw;
  }
  q_.setZero(model.dof());
  tau_.setZero(model.dof());
  open_ = true;
}

Calibration DeviceDriver::calibrate() {
  if (!open_) throw std::logic_error("calibrate: open() the device first");
  return calibrate_device();
}

template <typename Renderer>
void DeviceDriver::start_with(Renderer& renderer, const ServoSettings& settings) {
  if (!open_) throw std::logic_error("start: open() the device first");
  if (running_) throw std::logic_error("start: the servo is running; stop() it first");
  const Device& d = renderer.device();
  bool same = d.dof() == model_->dof() && d.name() == model_->name();
  for (int i = 0; same && i < d.dof(); ++i) same = d.actuated(i) == model_->actuated(i);
  if (!same) {
    throw std::invalid_argument("renderer: its device (" + d.name() + ", " +
                                std::to_string(d.dof()) +
                                " joints) is not the device model the driver was opened with (" +
                                model_->name() + ", " + std::to_string(model_->dof()) + " joints)");
  }
  constexpr bool kSet = std::is_same_v<Renderer, MechanismSet>;
  int members = 1;
  if constexpr (kSet) members = renderer.size();
  for (int i = 0; i < members; ++i) {
    const Controller* c = nullptr;
    if constexpr (kSet) {
      c = &renderer.member(i);
    } else {
      c = &renderer;
    }
    const ControllerModel& m = c->model();
    const double nominal = info_.nominal_max_force_n;
    if (std::isfinite(nominal) && m.max_force > nominal * (1.0 + 1e-12)) {
      throw DriverError(DriverError::Kind::kMismatch,
                        "max_force: the controller's force limit " + number(m.max_force) +
                            " N exceeds the device's nominal maximum " + number(nominal) +
                            " N (" + info_.model + "); give max_force <= " + number(nominal));
    }
  }
  servo_ = std::make_unique<DriverServo>(renderer, settings);
  servo_->reset();
  clock0_ = CycleClock::now();
  last_tick_.store(clock0_, std::memory_order_relaxed);
  running_ = true;
  try {
    start_servo();
  } catch (...) {
    running_ = false;
    throw;
  }
}

void DeviceDriver::start(Controller& controller, const ServoSettings& settings) {
  start_with(controller, settings);
}

void DeviceDriver::start(MechanismSet& set, const ServoSettings& settings) {
  start_with(set, settings);
}

void DeviceDriver::stop() noexcept {
  if (running_) {
    servo_->request_stop();
    // a whole tick after the request (the one in progress may have read the old state)
    const std::uint64_t ticks = servo_->stats().ticks;
    for (int i = 0; i < 200 && servo_->stats().ticks < ticks + 2; ++i) {
      std::this_thread::sleep_for(std::chrono::microseconds(500));
    }
    stop_servo();
    running_ = false;
  }
  if (open_) {
    close_device();
    open_ = false;
  }
}

bool DeviceDriver::stalled(double stall_s) const noexcept {
  if (!running_) return false;
  const double idle_us =
      CycleClock::microseconds(last_tick_.load(std::memory_order_relaxed), CycleClock::now());
  return idle_us > stall_s * 1e6;
}

void DeviceDriver::tick() noexcept {
  const std::uint64_t c0 = CycleClock::now();
  last_tick_.store(c0, std::memory_order_relaxed);
  const double t_s = CycleClock::microseconds(clock0_, c0) * 1e-6;
  DriverServo& servo = *servo_;
  const std::uint32_t read_error = read_joints(q_.data());
  servo.device_error(read_error);
  servo.tick(q_.data(), t_s, tau_.data(), read_velocities());
  const std::uint32_t write_error = write_torques(tau_.data());
  servo.end_tick(write_error, CycleClock::microseconds(c0, CycleClock::now()));
}

}  // namespace virtmech::drivers
