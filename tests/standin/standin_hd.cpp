// A stand-in for the OpenHaptics HD library (libHD.so), built by the project so that the
// OpenHaptics driver runs end to end without the SDK or a device: it exports the same C
// functions (virtmech/drivers/hd_api.h, VM_HD_FUNCTIONS), runs the scheduler at 1 kHz in its
// own thread (at real-time priority where the system grants it, as HD's servo thread runs),
// and serves a device in HD's units and conventions:
//
//   mode script   a fixed synthetic motion of the Omni's joints (no configuration needed)
//   mode replay   joint and gimbal angles recorded beforehand, one row per tick
//   mode mujoco   the simulated Omni: the simulation's own loop (virtmech::sim::ServoLoop) on
//                 the MuJoCo model the simulation builds, with a scripted hand (the hand's plan
//                 rows), its encoders' readings served as HD_CURRENT_JOINT_ANGLES and
//                 HD_CURRENT_GIMBAL_ANGLES and the HD_CURRENT_JOINT_TORQUE the callbacks set
//                 [mN·m] driving its motors
//
// It can inject an error in a tick, late ticks, a stalled scheduler, a failing
// hdInitDevice and an uncalibrated start, and it checks how it is used: every hdSet inside a
// frame, frames balanced, the priorities asked for, force output enabled before torque is
// sent. What it saw is written when the device is disabled: a summary (key value lines) and
// one row per tick (the angles served, the torques set).
//
// Configuration: the file named by the environment variable VIRTMECH_STANDIN_CONFIG, one
// "key value..." per line ('#' starts a comment); every key is optional (defaults below).
//
//   mode script|replay|mujoco        trace PATH (summary; the ticks go to PATH.ticks)
//   model_type TEXT  vendor TEXT  serial TEXT  driver_version TEXT
//   input_dof N  output_dof N  update_rate HZ  rate_hz HZ  realtime 0|1
//   nominal_max_force N  nominal_max_continuous_force N  nominal_max_stiffness N/mm
//   nominal_max_damping N·s/mm  calibration_style MASK
//   device_names NAME...             names hdInitDevice accepts besides the default (NULL)
//   init_error CODE INTERNAL         hdInitDevice fails with this error
//   calibration ok|needs_update|needs_manual_input   inkwell_after_checks N
//   error_at TICK CODE INTERNAL      hdBeginFrame of that tick puts the error on the stack
//   late_at TICK MS                  the tick comes MS milliseconds late
//   stall_at TICK                    from that tick on no callback runs
//   max_ticks N                      ticks traced (default 120000: 2 min)
//   replay_file PATH  replay_rows N  (float64, N x 6: joints then gimbal [rad])
//   mujoco: l1 M  l2 M, and the simulated device's keys (standin_sim.hpp)
//           hold_until_servo 0|1  (default 1: no cycle runs before a callback is scheduled,
//           so that the simulated session starts with the driver's servo)
#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "standin_config.hpp"
#include "virtmech/drivers/hd_api.h"

#if VM_STANDIN_MUJOCO
#include "standin_sim.hpp"
#endif

#define VM_STANDIN_EXPORT extern "C" __attribute__((visibility("default")))

// the library's functions with HD's signatures, checked against the one declaration
#define VM_STANDIN_DECLARE(ret, name, params) VM_STANDIN_EXPORT ret name params;
VM_HD_FUNCTIONS(VM_STANDIN_DECLARE)
#undef VM_STANDIN_DECLARE

namespace {

constexpr int kJoints = 6;
constexpr HHD kHandle = 0;

// --- configuration: standin_config.hpp ----------------------------------------------------

using standin_config::Config;

std::vector<double> read_doubles(const std::string& path, size_t count) {
  return standin_config::read_doubles(path, count, "standin libHD");
}

// --- the tick's trace ----------------------------------------------------------------------

// one row per tick: tick, angles served (6), joint torque set (3, NaN: none), gimbal torque
// set (3, NaN: none), error injected, callbacks run, frames begun, the gap since the last
// tick [s]
constexpr int kTraceWidth = 18;

struct Scheduled {
  HDSchedulerCallback callback = nullptr;
  void* data = nullptr;
  HDushort priority = 0;
  HDSchedulerHandle handle = 0;
};

struct Synchronous {
  HDSchedulerCallback callback;
  void* data;
  bool done = false;
};

class Standin {
 public:
  Config config;

  // --- device ---
  HHD init(HDstring name);
  void disable(HHD h);

  // --- errors ---
  void push_error(HDerror code, int internal) {
    std::lock_guard<std::mutex> lock(errors_mutex_);
    if (error_count_ < kErrorStack) errors_[error_count_++] = HDErrorInfo{code, internal, kHandle};
  }
  HDErrorInfo pop_error() {
    std::lock_guard<std::mutex> lock(errors_mutex_);
    if (error_count_ == 0) return HDErrorInfo{HD_SUCCESS, 0, kHandle};
    return errors_[--error_count_];
  }

  // --- frames ---
  void begin_frame(HHD h);
  void end_frame(HHD h);
  void get_doubles(HDenum name, HDdouble* v);
  void get_integers(HDenum name, HDint* v);
  HDstring get_string(HDenum name);
  void set_doubles(HDenum name, const HDdouble* v);

  // --- capabilities, calibration ---
  void enable(HDenum cap, bool on) {
    if (cap == HD_FORCE_OUTPUT) {
      force_output_.store(on);
      ++(on ? enables_ : disables_);
    } else {
      push_error(HD_INVALID_ENUM, 0);
    }
  }
  bool enabled(HDenum cap) const { return cap == HD_FORCE_OUTPUT && force_output_.load(); }
  HDenum check_calibration();
  void update_calibration(HDenum style);

  // --- scheduler ---
  void start_scheduler();
  void stop_scheduler();
  HDSchedulerHandle schedule(HDSchedulerCallback cb, void* data, HDushort priority);
  void schedule_synchronous(HDSchedulerCallback cb, void* data, HDushort priority);
  void unschedule(HDSchedulerHandle h);

  ~Standin() {
    stop_scheduler();
    if (initialized_) write_trace();  // a run that never disabled the device
  }

 private:
  static constexpr int kErrorStack = 16;
  static constexpr int kMaxCallbacks = 32;

  void reset_session();
  void scheduler_main();
  void tick(long k, double gap_s);
  void serve(const double* q) {
    std::copy(q, q + kJoints, q_);
  }
  void run_callbacks();
  void write_trace();
#if VM_STANDIN_MUJOCO
  bool load_mujoco();
  void free_mujoco();
#endif

  // device
  bool initialized_ = false, trace_written_ = false;
  int init_calls_ = 0, disable_calls_ = 0;
  std::string init_names_;
  double q_[kJoints] = {0, 0, 0, 0, 0, 0};
  HDdouble joint_torque_[3] = {0, 0, 0}, gimbal_torque_[3] = {0, 0, 0};
  bool joint_set_ = false, gimbal_set_ = false;
  double last_joint_torque_[3] = {0, 0, 0}, last_gimbal_torque_[3] = {0, 0, 0};
  std::atomic<bool> force_output_{false};
  int enables_ = 0, disables_ = 0;

  // errors
  std::mutex errors_mutex_;
  HDErrorInfo errors_[kErrorStack] = {};
  int error_count_ = 0;

  // frames (the servo thread's; a synchronous call outside the scheduler runs in its caller)
  int frame_depth_ = 0;
  long frames_begun_ = 0, frames_ended_ = 0, illegal_begin_ = 0, illegal_end_ = 0,
       sets_outside_frame_ = 0, bad_handle_ = 0, torque_sets_ = 0, gimbal_sets_ = 0,
       torque_without_force_output_ = 0, nonzero_torque_after_error_ = 0;
  long tick_frames_ = 0;

  // calibration
  int calibration_state_ = HD_CALIBRATION_OK;
  long calibration_checks_ = 0, calibration_updates_ = 0, calibration_checks_outside_frame_ = 0;

  // scheduler
  std::mutex callbacks_mutex_;
  std::vector<Scheduled> callbacks_;  // reserved kMaxCallbacks: the tick copies, no allocation
  HDSchedulerHandle next_handle_ = 1;
  std::vector<int> priorities_;  // every priority asked for, in order
  std::vector<Synchronous*> synchronous_;
  std::condition_variable synchronous_done_;
  std::thread thread_;
  std::atomic<bool> running_{false};
  bool realtime_ = false;
  long scheduler_starts_ = 0, scheduler_stops_ = 0, unscheduled_ = 0, ticks_ = 0;
  long late_ticks_injected_ = 0;
  double worst_gap_s_ = 0.0;
  long error_tick_ = -1;  // the tick an error was injected in
  long error_at_ = -1;    // the tick to inject it in (error_at), its code and internal code
  HDerror error_code_ = HD_COMM_ERROR;
  int error_internal_ = 0;

  // trace
  std::vector<double> trace_;
  long max_ticks_ = 120000;
  long row_ = -1;  // the current tick's row

  // replay
  std::vector<double> replay_;

#if VM_STANDIN_MUJOCO
  // the simulated device: the simulation's loop with the HD callbacks as its controller
  class Serve final : public virtmech::sim::ExternalController {
   public:
    explicit Serve(Standin& s) : s_(s) {}
    void control(double, const double* qm, const double*, double* torque) override {
      s_.serve(qm);
      s_.run_callbacks();
      for (int i = 0; i < 3; ++i) torque[i] = s_.joint_torque_[i] / 1000.0;  // mN·m -> N·m
      if (s_.gimbal_set_) {
        for (int i = 0; i < 3; ++i) torque[3 + i] = s_.gimbal_torque_[i] / 1000.0;
      }
    }

   private:
    Standin& s_;
  };
  std::unique_ptr<virtmech::PhantomOmni> omni_;
  std::unique_ptr<Serve> serve_;
  standin_sim::SimulatedDevice sim_;
  bool hold_until_servo_ = true;  // no cycle runs before a callback is scheduled
#endif
};

Standin& standin() {
  static Standin s;
  return s;
}

// --- device --------------------------------------------------------------------------------

// a library left loaded between sessions (dlclose may keep it) starts each one afresh
void Standin::reset_session() {
  init_calls_ = disable_calls_ = 0;
  init_names_.clear();
  std::fill(q_, q_ + kJoints, 0.0);
  std::fill(last_joint_torque_, last_joint_torque_ + 3, 0.0);
  std::fill(last_gimbal_torque_, last_gimbal_torque_ + 3, 0.0);
  force_output_.store(false);
  enables_ = disables_ = 0;
  error_count_ = 0;
  frame_depth_ = 0;
  frames_begun_ = frames_ended_ = illegal_begin_ = illegal_end_ = sets_outside_frame_ = 0;
  bad_handle_ = torque_sets_ = gimbal_sets_ = torque_without_force_output_ = 0;
  nonzero_torque_after_error_ = 0;
  calibration_checks_ = calibration_updates_ = calibration_checks_outside_frame_ = 0;
  callbacks_.clear();
  priorities_.clear();
  scheduler_starts_ = scheduler_stops_ = unscheduled_ = ticks_ = late_ticks_injected_ = 0;
  worst_gap_s_ = 0.0;
  error_tick_ = -1;
  replay_.clear();
}

HHD Standin::init(HDstring name) {
  if (!initialized_ && !running_.load()) reset_session();
  ++init_calls_;
  init_names_ += std::string(init_names_.empty() ? "" : ",") + (name ? name : "(default)");
  config = Config();
  config.load();
  if (config.has("init_error")) {
    push_error(static_cast<HDerror>(config.integer("init_error", HD_DEVICE_FAULT, 0)),
               static_cast<int>(config.integer("init_error", 0, 1)));
    return HD_INVALID_HANDLE;
  }
  if (name != nullptr) {
    bool known = std::string(name) == "Default Device";
    for (const auto& n : config.words("device_names")) known |= n == name;
    if (!known) {
      push_error(HD_COMM_CONFIG_ERROR, -1);
      return HD_INVALID_HANDLE;
    }
  }
  if (initialized_) {
    push_error(HD_DEVICE_ALREADY_INITIATED, 0);
    return HD_INVALID_HANDLE;
  }
  const std::string cal = config.text("calibration", "ok");
  calibration_state_ = cal == "needs_update"         ? HD_CALIBRATION_NEEDS_UPDATE
                       : cal == "needs_manual_input" ? HD_CALIBRATION_NEEDS_MANUAL_INPUT
                                                     : HD_CALIBRATION_OK;
  max_ticks_ = config.integer("max_ticks", 120000);
  error_at_ = config.integer("error_at", -1, 0);
  error_code_ = static_cast<HDerror>(config.integer("error_at", HD_COMM_ERROR, 1));
  error_internal_ = static_cast<int>(config.integer("error_at", 0, 2));
  trace_.assign(static_cast<size_t>(max_ticks_) * kTraceWidth,
                std::numeric_limits<double>::quiet_NaN());
  callbacks_.reserve(kMaxCallbacks);
  priorities_.reserve(kMaxCallbacks);
  const std::string mode = config.text("mode", "script");
  if (mode == "replay") {
    const long rows = config.integer("replay_rows", 0);
    replay_ = read_doubles(config.text("replay_file", ""), static_cast<size_t>(rows) * kJoints);
    if (replay_.size() < kJoints) {
      push_error(HD_DEVICE_FAULT, -2);
      return HD_INVALID_HANDLE;
    }
  } else if (mode == "mujoco") {
#if VM_STANDIN_MUJOCO
    if (!load_mujoco()) {
      push_error(HD_DEVICE_FAULT, -3);
      return HD_INVALID_HANDLE;
    }
#else
    std::fprintf(stderr, "standin libHD: built without MuJoCo (mode mujoco unavailable)\n");
    push_error(HD_DEVICE_FAULT, -3);
    return HD_INVALID_HANDLE;
#endif
  }
  initialized_ = true;
  trace_written_ = false;
  return kHandle;
}

void Standin::disable(HHD h) {
  ++disable_calls_;
  if (!initialized_ || h != kHandle) {
    ++bad_handle_;
    push_error(HD_BAD_HANDLE, 0);
    return;
  }
  stop_scheduler();
  write_trace();
  initialized_ = false;
#if VM_STANDIN_MUJOCO
  free_mujoco();
#endif
}

#if VM_STANDIN_MUJOCO
bool Standin::load_mujoco() {
  virtmech::PhantomOmniParams p;
  p.l1 = config.number("l1", p.l1);
  p.l2 = config.number("l2", p.l2);
  omni_ = std::make_unique<virtmech::PhantomOmni>(p);
  serve_ = std::make_unique<Serve>(*this);
  if (!sim_.load(config, *omni_, *serve_, max_ticks_, "standin libHD")) return false;
  hold_until_servo_ = config.integer("hold_until_servo", 1) != 0;
  sim_.sensed(q_);  // before the first cycle the encoders read the start pose
  return true;
}

void Standin::free_mujoco() { sim_.unload(); }
#endif

// --- frames --------------------------------------------------------------------------------

void Standin::begin_frame(HHD h) {
  if (h != kHandle || !initialized_) {
    ++bad_handle_;
    push_error(HD_BAD_HANDLE, 0);
    return;
  }
  if (frame_depth_ > 0) {
    ++illegal_begin_;
    push_error(HD_ILLEGAL_BEGIN, 0);
    return;
  }
  frame_depth_ = 1;
  ++frames_begun_;
  ++tick_frames_;
  if (error_tick_ < 0 && row_ >= 0 && row_ == error_at_) {
    error_tick_ = row_;
    push_error(error_code_, error_internal_);
  }
}

void Standin::end_frame(HHD h) {
  if (h != kHandle) {
    ++bad_handle_;
    push_error(HD_BAD_HANDLE, 0);
  }
  if (frame_depth_ == 0) {
    ++illegal_end_;
    push_error(HD_ILLEGAL_END, 0);
    return;
  }
  frame_depth_ = 0;
  ++frames_ended_;
}

void Standin::get_doubles(HDenum name, HDdouble* v) {
  switch (name) {
    case HD_CURRENT_JOINT_ANGLES:
      std::copy(q_, q_ + 3, v);
      return;
    case HD_CURRENT_GIMBAL_ANGLES:
      std::copy(q_ + 3, q_ + 6, v);
      return;
    case HD_NOMINAL_MAX_FORCE:
      v[0] = config.number("nominal_max_force", 3.3);
      return;
    case HD_NOMINAL_MAX_CONTINUOUS_FORCE:
      v[0] = config.number("nominal_max_continuous_force", 0.88);
      return;
    case HD_NOMINAL_MAX_STIFFNESS:
      v[0] = config.number("nominal_max_stiffness", 0.5);
      return;
    case HD_NOMINAL_MAX_DAMPING:
      v[0] = config.number("nominal_max_damping", 0.005);
      return;
    default:
      push_error(HD_INVALID_ENUM, static_cast<int>(name));
  }
}

void Standin::get_integers(HDenum name, HDint* v) {
  switch (name) {
    case HD_INPUT_DOF:
      v[0] = static_cast<HDint>(config.integer("input_dof", 6));
      return;
    case HD_OUTPUT_DOF:
      v[0] = static_cast<HDint>(config.integer("output_dof", 3));
      return;
    case HD_UPDATE_RATE:
      v[0] = static_cast<HDint>(config.integer("update_rate", 1000));
      return;
    case HD_CALIBRATION_STYLE:
      v[0] = static_cast<HDint>(config.integer("calibration_style", HD_CALIBRATION_AUTO));
      return;
    default:
      push_error(HD_INVALID_ENUM, static_cast<int>(name));
  }
}

HDstring Standin::get_string(HDenum name) {
  static std::string value;  // HD's strings stay valid until the next call
  switch (name) {
    case HD_DEVICE_MODEL_TYPE:
      value = config.text("model_type", "Touch");
      break;
    case HD_DEVICE_VENDOR:
      value = config.text("vendor", "virtmech stand-in");
      break;
    case HD_DEVICE_SERIAL_NUMBER:
      value = config.text("serial", "standin-0001");
      break;
    case HD_DEVICE_DRIVER_VERSION:
      value = config.text("driver_version", "standin");
      break;
    case HD_VERSION:
      value = "3.4.0 (virtmech stand-in)";
      break;
    default:
      push_error(HD_INVALID_ENUM, static_cast<int>(name));
      return nullptr;
  }
  return value.c_str();
}

void Standin::set_doubles(HDenum name, const HDdouble* v) {
  if (frame_depth_ == 0) {
    ++sets_outside_frame_;
    push_error(HD_ILLEGAL_END, static_cast<int>(name));
    return;
  }
  const bool torque = name == HD_CURRENT_JOINT_TORQUE || name == HD_CURRENT_GIMBAL_TORQUE;
  if (!torque) {
    push_error(HD_INVALID_ENUM, static_cast<int>(name));
    return;
  }
  if (!force_output_.load()) ++torque_without_force_output_;
  HDdouble* dst = name == HD_CURRENT_JOINT_TORQUE ? joint_torque_ : gimbal_torque_;
  std::copy(v, v + 3, dst);
  (name == HD_CURRENT_JOINT_TORQUE ? joint_set_ : gimbal_set_) = true;
  ++(name == HD_CURRENT_JOINT_TORQUE ? torque_sets_ : gimbal_sets_);
  if (error_tick_ >= 0 && row_ >= error_tick_ && (v[0] != 0.0 || v[1] != 0.0 || v[2] != 0.0)) {
    ++nonzero_torque_after_error_;
  }
}

// --- calibration -----------------------------------------------------------------------------

HDenum Standin::check_calibration() {
  ++calibration_checks_;
  if (frame_depth_ == 0) ++calibration_checks_outside_frame_;
  if (calibration_state_ == HD_CALIBRATION_NEEDS_MANUAL_INPUT &&
      calibration_checks_ > config.integer("inkwell_after_checks", 1000000000L)) {
    calibration_state_ = HD_CALIBRATION_NEEDS_UPDATE;  // the stylus is in the inkwell now
  }
  return static_cast<HDenum>(calibration_state_);
}

void Standin::update_calibration(HDenum style) {
  ++calibration_updates_;
  const long supported = config.integer("calibration_style", HD_CALIBRATION_AUTO);
  if ((static_cast<long>(style) & supported) == 0) {
    push_error(HD_INVALID_VALUE, static_cast<int>(style));
    return;
  }
  if (calibration_state_ == HD_CALIBRATION_NEEDS_UPDATE) calibration_state_ = HD_CALIBRATION_OK;
}

// --- scheduler -------------------------------------------------------------------------------

void Standin::start_scheduler() {
  ++scheduler_starts_;
  if (running_.load()) return;
  running_.store(true);
  thread_ = std::thread([this] { scheduler_main(); });
}

void Standin::stop_scheduler() {
  if (!running_.load()) return;
  ++scheduler_stops_;
  running_.store(false);
  if (thread_.joinable()) thread_.join();
  // synchronous calls left waiting: none run any more
  std::lock_guard<std::mutex> lock(callbacks_mutex_);
  for (Synchronous* s : synchronous_) s->done = true;
  synchronous_.clear();
  synchronous_done_.notify_all();
}

HDSchedulerHandle Standin::schedule(HDSchedulerCallback cb, void* data, HDushort priority) {
  std::lock_guard<std::mutex> lock(callbacks_mutex_);
  if (static_cast<int>(callbacks_.size()) >= kMaxCallbacks) {
    push_error(HD_SCHEDULER_FULL, 0);
    return 0;
  }
  priorities_.push_back(priority);
  const Scheduled s{cb, data, priority, next_handle_++};
  // highest priority first, in the order scheduled among equals
  auto at = std::find_if(callbacks_.begin(), callbacks_.end(),
                         [&](const Scheduled& o) { return o.priority < priority; });
  callbacks_.insert(at, s);
  return s.handle;
}

void Standin::schedule_synchronous(HDSchedulerCallback cb, void* data, HDushort priority) {
  priorities_.push_back(priority);
  Synchronous call{cb, data};
  if (!running_.load()) {  // no scheduler: the call runs here
    while (cb(data) == HD_CALLBACK_CONTINUE) {
    }
    return;
  }
  std::unique_lock<std::mutex> lock(callbacks_mutex_);
  synchronous_.push_back(&call);
  synchronous_done_.wait(lock, [&] { return call.done; });
}

void Standin::unschedule(HDSchedulerHandle h) {
  std::lock_guard<std::mutex> lock(callbacks_mutex_);
  auto it = std::find_if(callbacks_.begin(), callbacks_.end(),
                         [&](const Scheduled& s) { return s.handle == h; });
  if (it == callbacks_.end()) {
    push_error(HD_INVALID_OPERATION, static_cast<int>(h));
    return;
  }
  callbacks_.erase(it);
  ++unscheduled_;
}

void Standin::run_callbacks() {
  Scheduled now[kMaxCallbacks];
  int count = 0;
  {
    std::lock_guard<std::mutex> lock(callbacks_mutex_);
    for (const Scheduled& s : callbacks_) now[count++] = s;
  }
  // HD's force output is what this tick's frames command: zero until a callback sets it
  std::fill(joint_torque_, joint_torque_ + 3, 0.0);
  std::fill(gimbal_torque_, gimbal_torque_ + 3, 0.0);
  joint_set_ = gimbal_set_ = false;
  for (int i = 0; i < count; ++i) {
    if (now[i].callback(now[i].data) == HD_CALLBACK_DONE) {
      std::lock_guard<std::mutex> lock(callbacks_mutex_);
      auto it = std::find_if(callbacks_.begin(), callbacks_.end(),
                             [&](const Scheduled& s) { return s.handle == now[i].handle; });
      if (it != callbacks_.end()) callbacks_.erase(it);
    }
  }
  // the synchronous calls queued by other threads, each to its end
  std::unique_lock<std::mutex> lock(callbacks_mutex_);
  if (!synchronous_.empty()) {
    std::vector<Synchronous*> calls;
    calls.swap(synchronous_);
    lock.unlock();
    for (Synchronous* s : calls) {
      while (s->callback(s->data) == HD_CALLBACK_CONTINUE) {
      }
    }
    lock.lock();
    for (Synchronous* s : calls) s->done = true;
    synchronous_done_.notify_all();
  }
  if (joint_set_) std::copy(joint_torque_, joint_torque_ + 3, last_joint_torque_);
  if (gimbal_set_) std::copy(gimbal_torque_, gimbal_torque_ + 3, last_gimbal_torque_);
}

void Standin::scheduler_main() {
  sched_param param{};
  param.sched_priority = 80;
  realtime_ = config.integer("realtime", 1) != 0 &&
              pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) == 0;
  using Clock = std::chrono::steady_clock;
  const double rate = config.number("rate_hz", 1000.0);
  const auto period = std::chrono::nanoseconds(static_cast<long>(1e9 / rate));
  const long stall_at = config.integer("stall_at", -1);
  const long late_at = config.integer("late_at", -1, 0);
  const double late_ms = config.number("late_at", 0.0, 1);
  auto next = Clock::now();
  auto last = next;
  long k = 0;
  while (running_.load()) {
    next += period;
    if (k == late_at) {
      next += std::chrono::microseconds(static_cast<long>(late_ms * 1e3));
      ++late_ticks_injected_;
    }
    std::this_thread::sleep_until(next);
    const auto now = Clock::now();
    if (now - next > 10 * period) next = now;  // fallen far behind: no burst to catch up
    if (stall_at >= 0 && k >= stall_at) {
      std::lock_guard<std::mutex> lock(callbacks_mutex_);  // no tick; still answer sync calls
      for (Synchronous* s : synchronous_) s->done = true;
      synchronous_.clear();
      synchronous_done_.notify_all();
      continue;
    }
    const double gap = std::chrono::duration<double>(now - last).count();
    last = now;
    tick(k, k == 0 ? 0.0 : gap);
    ++k;
  }
}

void Standin::tick(long k, double gap_s) {
  row_ = k;
  tick_frames_ = 0;
  if (k > 0) worst_gap_s_ = std::max(worst_gap_s_, gap_s);
  if (replay_.size() >= kJoints) {
    const size_t rows = replay_.size() / kJoints;
    const size_t r = std::min(static_cast<size_t>(k), rows - 1);
    serve(&replay_[r * kJoints]);
    run_callbacks();
#if VM_STANDIN_MUJOCO
  } else if (sim_.loaded()) {
    bool servo = true;
    if (hold_until_servo_) {
      std::lock_guard<std::mutex> lock(callbacks_mutex_);
      servo = !callbacks_.empty();
    }
    if (!servo) {  // the simulated session starts with the servo: until then it holds still
      run_callbacks();
    } else {
      sim_.cycle();
    }
#endif
  } else {  // the synthetic motion of the old example: waist and shoulder swinging
    const double t = static_cast<double>(k) * 1e-3;
    const double q[kJoints] = {0.2 * std::sin(2.0 * t), 0.5 + 0.1 * std::sin(3.0 * t), 0.3,
                               0.0, 0.6, 0.0};
    serve(q);
    run_callbacks();
  }
  ++ticks_;
  if (k < max_ticks_) {
    double* row = &trace_[static_cast<size_t>(k) * kTraceWidth];
    row[0] = static_cast<double>(k);
    std::copy(q_, q_ + kJoints, row + 1);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (int i = 0; i < 3; ++i) {
      row[7 + i] = joint_set_ ? joint_torque_[i] : nan;
      row[10 + i] = gimbal_set_ ? gimbal_torque_[i] : nan;
    }
    row[13] = k == error_tick_ ? 1.0 : 0.0;
    row[14] = 0.0;
    row[15] = static_cast<double>(tick_frames_);
    row[16] = gap_s;
    row[17] = realtime_ ? 1.0 : 0.0;
  }
  row_ = -1;
}

void Standin::write_trace() {
  if (trace_written_) return;
  trace_written_ = true;
  const std::string path = config.text("trace", "");
  if (path.empty()) return;
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) return;
  auto line = [&](const char* key, double v) { std::fprintf(f, "%s %.17g\n", key, v); };
  std::fprintf(f, "init_names %s\n", init_names_.c_str());
  line("init_calls", init_calls_);
  line("disable_calls", disable_calls_);
  line("ticks", static_cast<double>(ticks_));
  line("realtime", realtime_ ? 1 : 0);
  line("worst_gap_s", worst_gap_s_);
  line("late_ticks_injected", late_ticks_injected_);
  line("frames_begun", frames_begun_);
  line("frames_ended", frames_ended_);
  line("illegal_begin", illegal_begin_);
  line("illegal_end", illegal_end_);
  line("sets_outside_frame", sets_outside_frame_);
  line("bad_handle", bad_handle_);
  line("torque_sets", torque_sets_);
  line("gimbal_sets", gimbal_sets_);
  line("torque_without_force_output", torque_without_force_output_);
  line("force_output_enabled", force_output_.load() ? 1 : 0);
  line("force_output_enables", enables_);
  line("force_output_disables", disables_);
  line("error_tick", error_tick_);
  line("nonzero_torque_after_error", nonzero_torque_after_error_);
  line("calibration_checks", calibration_checks_);
  line("calibration_checks_outside_frame", calibration_checks_outside_frame_);
  line("calibration_updates", calibration_updates_);
  line("calibration_state", calibration_state_);
  line("scheduler_starts", scheduler_starts_);
  line("scheduler_stops", scheduler_stops_);
  line("scheduler_running", running_.load() ? 1 : 0);
  line("unscheduled", unscheduled_);
  line("callbacks_left", static_cast<double>(callbacks_.size()));
  std::fprintf(f, "priorities");
  for (int p : priorities_) std::fprintf(f, " %d", p);
  std::fprintf(f, "\n");
  std::fprintf(f, "last_joint_torque %.17g %.17g %.17g\n", last_joint_torque_[0],
               last_joint_torque_[1], last_joint_torque_[2]);
  std::fprintf(f, "last_gimbal_torque %.17g %.17g %.17g\n", last_gimbal_torque_[0],
               last_gimbal_torque_[1], last_gimbal_torque_[2]);
  std::fclose(f);
  const long rows = std::min(ticks_, max_ticks_);
  if (std::FILE* t = std::fopen((path + ".ticks").c_str(), "wb")) {
    std::fwrite(trace_.data(), sizeof(double), static_cast<size_t>(rows) * kTraceWidth, t);
    std::fclose(t);
  }
#if VM_STANDIN_MUJOCO
  sim_.write_truth(config.text("truth_file", ""));
#endif
}

}  // namespace

// --- the exported functions ---------------------------------------------------------------

VM_STANDIN_EXPORT HHD hdInitDevice(HDstring name) { return standin().init(name); }
VM_STANDIN_EXPORT void hdDisableDevice(HHD device) { standin().disable(device); }
VM_STANDIN_EXPORT void hdMakeCurrentDevice(HHD device) {
  if (device != kHandle) standin().push_error(HD_BAD_HANDLE, 0);
}
VM_STANDIN_EXPORT HHD hdGetCurrentDevice(void) { return kHandle; }
VM_STANDIN_EXPORT void hdBeginFrame(HHD device) { standin().begin_frame(device); }
VM_STANDIN_EXPORT void hdEndFrame(HHD device) { standin().end_frame(device); }
VM_STANDIN_EXPORT HDErrorInfo hdGetError(void) { return standin().pop_error(); }
VM_STANDIN_EXPORT HDstring hdGetErrorString(HDerror code) {
  switch (code) {
    case HD_SUCCESS:
      return "no error";
    case HD_COMM_ERROR:
      return "communication error (stand-in)";
    case HD_COMM_CONFIG_ERROR:
      return "communication configuration error: no such device (stand-in)";
    case HD_DEVICE_FAULT:
      return "device fault (stand-in)";
    default:
      return "an error the stand-in raised";
  }
}
VM_STANDIN_EXPORT void hdEnable(HDenum capability) { standin().enable(capability, true); }
VM_STANDIN_EXPORT void hdDisable(HDenum capability) { standin().enable(capability, false); }
VM_STANDIN_EXPORT HDboolean hdIsEnabled(HDenum capability) {
  return standin().enabled(capability) ? 1 : 0;
}
VM_STANDIN_EXPORT void hdGetDoublev(HDenum name, HDdouble* values) {
  standin().get_doubles(name, values);
}
VM_STANDIN_EXPORT void hdGetIntegerv(HDenum name, HDint* values) {
  standin().get_integers(name, values);
}
VM_STANDIN_EXPORT HDstring hdGetString(HDenum name) { return standin().get_string(name); }
VM_STANDIN_EXPORT void hdSetDoublev(HDenum name, const HDdouble* values) {
  standin().set_doubles(name, values);
}
VM_STANDIN_EXPORT HDenum hdCheckCalibration(void) { return standin().check_calibration(); }
VM_STANDIN_EXPORT void hdUpdateCalibration(HDenum style) { standin().update_calibration(style); }
VM_STANDIN_EXPORT void hdStartScheduler(void) { standin().start_scheduler(); }
VM_STANDIN_EXPORT void hdStopScheduler(void) { standin().stop_scheduler(); }
VM_STANDIN_EXPORT HDSchedulerHandle hdScheduleAsynchronous(HDSchedulerCallback callback,
                                                           void* user_data, HDushort priority) {
  return standin().schedule(callback, user_data, priority);
}
VM_STANDIN_EXPORT void hdScheduleSynchronous(HDSchedulerCallback callback, void* user_data,
                                             HDushort priority) {
  standin().schedule_synchronous(callback, user_data, priority);
}
VM_STANDIN_EXPORT void hdUnschedule(HDSchedulerHandle handle) { standin().unschedule(handle); }
