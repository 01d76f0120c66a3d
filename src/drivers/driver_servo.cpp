#include "virtmech/drivers/driver_servo.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <sstream>
#include <stdexcept>
#include <string>

#include "../cycle_clock.hpp"
#include "virtmech/validate.hpp"

namespace virtmech::drivers {

static_assert(std::atomic<double>::is_always_lock_free, "the servo's counters must be lock-free");
static_assert(std::atomic<std::uint64_t>::is_always_lock_free,
              "the servo's counters must be lock-free");

namespace {

using detail::CycleClock;

#define VM_RECORD_FIELD(name) \
  { #name, static_cast<int>(offsetof(TickRecord, name) / sizeof(double)), \
    static_cast<int>(sizeof(TickRecord::name) / sizeof(double)) }
const RecordField kFields[] = {
    VM_RECORD_FIELD(tick),        VM_RECORD_FIELD(t_s),         VM_RECORD_FIELD(gap_s),
    VM_RECORD_FIELD(tick_us),     VM_RECORD_FIELD(step_us),     VM_RECORD_FIELD(flags),
    VM_RECORD_FIELD(status),      VM_RECORD_FIELD(device_error), VM_RECORD_FIELD(member),
    VM_RECORD_FIELD(ramp),        VM_RECORD_FIELD(iterations),  VM_RECORD_FIELD(iterations_star),
    VM_RECORD_FIELD(q),           VM_RECORD_FIELD(dq),          VM_RECORD_FIELD(torque),
    VM_RECORD_FIELD(command),     VM_RECORD_FIELD(theta),       VM_RECORD_FIELD(theta_star),
    VM_RECORD_FIELD(handle_p),    VM_RECORD_FIELD(stylus),      VM_RECORD_FIELD(twist),
    VM_RECORD_FIELD(wrench),      VM_RECORD_FIELD(error),       VM_RECORD_FIELD(error_dot),
    VM_RECORD_FIELD(error_star),  VM_RECORD_FIELD(error_star_dot), VM_RECORD_FIELD(wrench_null),
    VM_RECORD_FIELD(wrench_range)};
#undef VM_RECORD_FIELD

// n numbers of src, then zeros up to width (a copy, little code: the tick runs with its code
// cold at a servo rate of 1 kHz)
void put(double* dst, const double* src, Eigen::Index n, int width) noexcept {
  if (n > 0) std::memcpy(dst, src, sizeof(double) * static_cast<std::size_t>(n));
  std::memset(dst + n, 0, sizeof(double) * static_cast<std::size_t>(width - n));
}

// a relaxed running maximum (one writer)
void raise_to(std::atomic<double>& a, double v) noexcept {
  if (v > a.load(std::memory_order_relaxed)) a.store(v, std::memory_order_relaxed);
}

// What a device needs of a controller beyond a simulation: a watchdog, and a ramp-in a hand
// does not feel as a step.
void require_device_ready(const Controller& c) {
  if (!(c.model().watchdog_s > 0.0)) {
    throw std::invalid_argument(
        "watchdog_s: the controller has no watchdog (0); a device needs one: a tick later "
        "than it zeroes the force and ramps it in again (e.g. 3 servo periods)");
  }
  // (ramp_cycles is ramp_time_s / period_s rounded to the nearest: within half a period)
  const double T = c.model().period_s;
  const double ramp_s = static_cast<double>(c.model().ramp_cycles) * T;
  if (ramp_s + 0.5 * T < kMinimumDeviceRampS - 1e-9) {
    std::ostringstream os;
    os << "ramp_time_s: expected at least " << kMinimumDeviceRampS
       << " s on a device (the force ramps in over it; shorter, it steps onto the hand), got "
       << "a ramp-in of " << ramp_s << " s";
    throw std::invalid_argument(os.str());
  }
}

}  // namespace

const RecordField* record_fields(int* count) noexcept {
  if (count) *count = static_cast<int>(sizeof(kFields) / sizeof(kFields[0]));
  return kFields;
}

DriverServo::DriverServo(Controller& controller, const ServoSettings& settings)
    : ctrl_(&controller),
      device_(&controller.device()),
      settings_(settings),
      ring_(settings.record_capacity) {
  init();
}

DriverServo::DriverServo(MechanismSet& set, const ServoSettings& settings)
    : set_(&set), device_(&set.device()), settings_(settings), ring_(settings.record_capacity) {
  if (set.size() < 1) {
    throw std::invalid_argument("set: expected a mechanism set with at least one member");
  }
  init();
}

void DriverServo::init() {
  const ServoSettings& s = settings_;
  require_positive("period_s", s.period_s);
  require_non_negative("velocity_cutoff_hz", s.velocity_cutoff_hz);
  require_non_negative("late_s", s.late_s);
  require_non_negative("fault_limit_s", s.fault_limit_s);
  const int members = ctrl_ ? 1 : set_->size();
  for (int i = 0; i < members; ++i) require_device_ready(ctrl_ ? *ctrl_ : set_->member(i));
  n_ = device_->dof();
  filter_ = VelocityFilter(n_, s.period_s, VelocityFilter::alpha_for_cutoff(s.period_s,
                                                                            s.velocity_cutoff_hz));
  zero_.setZero(n_);
  out_.torque.setZero(n_);
  set_out_.cycle.torque.setZero(n_);
  CycleClock::calibrate();
}

double DriverServo::max_force() const noexcept {
  return ctrl_ ? ctrl_->model().max_force : set_->member(0).model().max_force;
}

void DriverServo::reset() noexcept {
  if (ctrl_) {
    ctrl_->reset();
  } else {
    set_->reset();
  }
  filter_.reset();
  TickRecord sink[64];
  while (ring_.pop(sink, 64) > 0) {
  }
  pending_ = nullptr;
  last_t_ = first_t_ = fault_since_ = std::numeric_limits<double>::quiet_NaN();
  device_failed_ = false;
  tick_device_error_ = 0;
  for (auto* a : {&ticks_, &late_, &watchdog_, &zero_ticks_, &dropped_}) a->store(0);
  for (auto* a : {&elapsed_, &rate_, &worst_tick_, &worst_gap_, &force_}) a->store(0.0);
  for (auto* a : {&status_, &flags_, &device_error_, &fault_status_}) a->store(0);
  reason_.store(static_cast<int>(StopReason::kNone), std::memory_order_release);
}

void DriverServo::stop_for(StopReason reason) noexcept {
  int none = static_cast<int>(StopReason::kNone);
  reason_.compare_exchange_strong(none, static_cast<int>(reason), std::memory_order_acq_rel);
}

void DriverServo::request_stop() noexcept { stop_for(StopReason::kRequested); }

void DriverServo::device_error(std::uint32_t code) noexcept {
  if (code == 0) return;
  tick_device_error_ = code;
  if (!device_failed_) {
    device_failed_ = true;
    device_error_.store(code, std::memory_order_relaxed);
    stop_for(StopReason::kDeviceError);
  }
}

std::uint32_t DriverServo::tick(const double* q, double t_s, double* tau,
                                const double* dq_device) noexcept {
  const std::uint64_t entered = CycleClock::now();
  claim_record();
  double gap = 0.0;
  std::uint32_t flags = clock_in(t_s, gap);
  const StopReason stop = reason();
  double step_us = 0.0;
  const double* dq_served = nullptr;  // the device's velocities, where the tick used them
  if (stop != StopReason::kNone) {
    // the run has ended: zero torque, the renderer no longer stepped
    flags |= stop == StopReason::kRequested    ? driver_flag::kStopping
             : stop == StopReason::kDeviceError ? driver_flag::kDeviceError
                                                : driver_flag::kFaultHeld;
    for (int i = 0; i < n_; ++i) tau[i] = 0.0;
  } else {
    flags = render(q, t_s, dq_device, tau, flags, step_us, dq_served);
  }
  if (flags & driver_flag::kZeroMask) {
    zero_ticks_.fetch_add(1, std::memory_order_relaxed);
    if (stop != StopReason::kNone) force_.store(0.0, std::memory_order_relaxed);
  }
  flags_.store(flags, std::memory_order_relaxed);
  record(q, dq_served, t_s, gap, flags, step_us, tau, stop == StopReason::kNone, entered);
  return flags;
}

// The record's slot, claimed now and fetched while the renderer steps: at a servo rate of
// 1 kHz it is cold, and filling it cold would cost more than the rest of the tick.
void DriverServo::claim_record() noexcept {
  pending_ = ring_.claim();
#if defined(__GNUC__) || defined(__clang__)
  if (pending_ != nullptr) {
    const char* p = reinterpret_cast<const char*>(pending_);
    for (std::size_t at = 0; at < sizeof(TickRecord); at += 64) __builtin_prefetch(p + at, 1, 3);
  }
#endif
}

// The gap since the last tick (NaN on the first) and the late flag.
std::uint32_t DriverServo::clock_in(double t_s, double& gap) noexcept {
  gap = t_s - last_t_;
  std::uint32_t flags = 0;
  if (gap > settings_.period_s + settings_.late_s) {
    flags |= driver_flag::kLate;
    late_.fetch_add(1, std::memory_order_relaxed);
  }
  if (std::isnan(first_t_)) first_t_ = t_s;
  last_t_ = t_s;
  return flags;
}

// One step of the renderer on the reading (the device's velocities where it serves finite
// ones, else the filter's estimate), and its torque, zero where a flag says so.
std::uint32_t DriverServo::render(const double* q, double t_s, const double* dq_device,
                                  double* tau, std::uint32_t flags, double& step_us,
                                  const double*& dq_served) noexcept {
  const CycleOutput* out = ctrl_ ? &out_ : &set_out_.cycle;
  const Eigen::Map<const Eigen::VectorXd> qv(q, n_);
  if (!qv.allFinite()) {
    flags |= driver_flag::kBadReading;
    filter_.reset();  // the next good reading starts the estimate afresh
  }
  const JointVector& estimate = qv.allFinite() ? filter_.update(q) : zero_;
  const bool served =
      dq_device != nullptr && Eigen::Map<const Eigen::VectorXd>(dq_device, n_).allFinite();
  if (served) dq_served = dq_device;
  const double* dq_used = served ? dq_device : estimate.data();
  const std::uint64_t c0 = CycleClock::now();
  const std::uint32_t status =
      ctrl_ ? ctrl_->step(q, dq_used, out_, t_s) : set_->step(q, dq_used, set_out_, t_s);
  step_us = CycleClock::microseconds(c0, CycleClock::now());
  flags |= hold_faults(status, t_s);
  const bool zero = (flags & driver_flag::kZeroMask) != 0;
  for (int i = 0; i < n_; ++i) tau[i] = zero ? 0.0 : out->torque[i];
  status_.store(status, std::memory_order_relaxed);
  force_.store(zero ? 0.0 : out->wrench.head<3>().norm(), std::memory_order_relaxed);
  return flags;
}

// A late tick's watchdog (zero force now; the renderer ramps in again from the next tick),
// and a fault that lasts fault_limit_s ends the run.
std::uint32_t DriverServo::hold_faults(std::uint32_t status, double t_s) noexcept {
  std::uint32_t flags = 0;
  if (status & status::kWatchdog) {
    flags |= driver_flag::kWatchdog;
    watchdog_.fetch_add(1, std::memory_order_relaxed);
  }
  if (status & status::kFaultMask) {
    if (std::isnan(fault_since_)) fault_since_ = t_s;
    if (t_s - fault_since_ >= settings_.fault_limit_s) {
      fault_status_.store(status & status::kFaultMask, std::memory_order_relaxed);
      stop_for(StopReason::kFaultHeld);
      flags |= driver_flag::kFaultHeld;
    }
  } else {
    fault_since_ = std::numeric_limits<double>::quiet_NaN();
  }
  return flags;
}

// The counters, and the tick's record into its slot (or a dropped record).
void DriverServo::record(const double* q, const double* dq_served, double t_s, double gap,
                         std::uint32_t flags, double step_us, const double* tau, bool stepped,
                         std::uint64_t entered) noexcept {
  const std::uint64_t ticks = ticks_.load(std::memory_order_relaxed) + 1;
  elapsed_.store(t_s, std::memory_order_relaxed);
  if (ticks > 1 && t_s > first_t_) {
    rate_.store(static_cast<double>(ticks - 1) / (t_s - first_t_), std::memory_order_relaxed);
    raise_to(worst_gap_, gap);
  }
  if (pending_ != nullptr) {
    fill(*pending_, q, dq_served ? dq_served : filter_.velocity().data(), t_s, gap, flags,
         step_us, tau, stepped);
    pending_->device_error = static_cast<double>(tick_device_error_);
    pending_->tick_us = CycleClock::microseconds(entered, CycleClock::now());
  } else {
    dropped_.fetch_add(1, std::memory_order_relaxed);
  }
  ticks_.store(ticks, std::memory_order_release);
}

void DriverServo::fill(TickRecord& r, const double* q, const double* dq, double t_s,
                       double gap, std::uint32_t flags, double step_us, const double* tau,
                       bool stepped) const noexcept {
  const CycleOutput& o = ctrl_ ? out_ : set_out_.cycle;
  const Vector6& twist = ctrl_ ? ctrl_->data().v_R : set_->member(0).data().v_R;
  r.tick = static_cast<double>(ticks_.load(std::memory_order_relaxed));
  r.t_s = t_s;
  r.gap_s = gap;
  r.step_us = step_us;
  r.flags = static_cast<double>(flags);
  r.member = ctrl_ ? 0.0 : static_cast<double>(set_out_.active);
  put(r.q, q, n_, kMaxDof);
  put(r.dq, dq, n_, kMaxDof);
  put(r.command, tau, n_, kMaxDof);
  put(r.theta, o.theta.data(), o.theta.size(), kMaxDof);
  put(r.theta_star, o.theta_star.data(), o.theta_star.size(), kMaxDof);
  const double* pose = o.handle_pose.matrix().data();  // column-major 4 x 4
  put(r.handle_p, pose + 12, 3, 3);
  put(r.stylus, pose + 8, 3, 3);
  put(r.twist, twist.data(), 6, 6);
  put(r.error, o.error.data(), 6, 6);
  put(r.error_dot, o.error_dot.data(), 6, 6);
  put(r.error_star, o.error_star.data(), 6, 6);
  put(r.error_star_dot, o.error_star_dot.data(), 6, 6);
  if (stepped) {
    r.status = static_cast<double>(o.status);
    r.ramp = o.ramp;
    r.iterations = static_cast<double>(o.iterations);
    r.iterations_star = static_cast<double>(o.iterations_star);
    put(r.torque, o.torque.data(), o.torque.size(), kMaxDof);
    put(r.wrench, o.wrench.data(), 6, 6);
    put(r.wrench_null, o.wrench_null.data(), 6, 6);
    put(r.wrench_range, o.wrench_range.data(), 6, 6);
  } else {  // the run has ended: the renderer did not step this tick
    r.status = r.ramp = r.iterations = r.iterations_star = 0.0;
    put(r.torque, nullptr, 0, kMaxDof);
    put(r.wrench, nullptr, 0, 6);
    put(r.wrench_null, nullptr, 0, 6);
    put(r.wrench_range, nullptr, 0, 6);
  }
}

void DriverServo::end_tick(std::uint32_t device_error, double tick_us) noexcept {
  if (device_error != 0) this->device_error(device_error);
  if (pending_ != nullptr) {
    if (device_error != 0) pending_->device_error = static_cast<double>(device_error);
    if (!std::isnan(tick_us)) pending_->tick_us = tick_us;
    raise_to(worst_tick_, pending_->tick_us);
    ring_.publish();
    pending_ = nullptr;
  } else if (!std::isnan(tick_us)) {
    raise_to(worst_tick_, tick_us);
  }
  tick_device_error_ = 0;
}

ServoStats DriverServo::stats() const noexcept {
  ServoStats s;
  s.ticks = ticks_.load(std::memory_order_acquire);
  s.late = late_.load(std::memory_order_relaxed);
  s.watchdog = watchdog_.load(std::memory_order_relaxed);
  s.zero_ticks = zero_ticks_.load(std::memory_order_relaxed);
  s.dropped = dropped_.load(std::memory_order_relaxed);
  s.elapsed_s = elapsed_.load(std::memory_order_relaxed);
  s.rate_hz = rate_.load(std::memory_order_relaxed);
  s.worst_tick_us = worst_tick_.load(std::memory_order_relaxed);
  s.worst_gap_s = worst_gap_.load(std::memory_order_relaxed);
  s.force_n = force_.load(std::memory_order_relaxed);
  s.status = status_.load(std::memory_order_relaxed);
  s.flags = flags_.load(std::memory_order_relaxed);
  s.stop = reason();
  s.device_error = device_error_.load(std::memory_order_relaxed);
  s.fault_status = fault_status_.load(std::memory_order_relaxed);
  return s;
}

}  // namespace virtmech::drivers
