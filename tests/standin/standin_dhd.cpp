// A stand-in for the Force Dimension DHD library (libdhd.so), built by the project so that the
// Force Dimension driver runs end to end without the SDK or a device: it exports the same C
// functions (virtmech/drivers/dhd_api.h, VM_DHD_FUNCTIONS) and serves a device in DHD's units
// and conventions (SI; the handle's position and its orientation frame R = Rx(a) Ry(b) Rz(c)):
//
//   mode hold     the handle held still at `position` and `rotation` (a b c), or moving along
//                 a straight line at `velocity` from there (the ticks count the time)
//   mode mujoco   the simulated device (standin_sim.hpp: the simulation's own loop on the
//                 MuJoCo model `virtmech run` builds, with a scripted hand): a
//                 CartesianDevice of `device_model` whose encoders' reading is served as the
//                 SDK's pose, its true rates as the SDK's velocities, and the force and
//                 torque set, as coordinate torques (J^T [f; m] at the pose served), driving
//                 its motors for one control cycle
//
// DHD has no scheduler: the application's own thread reads the pose and sets the force once
// per tick; a tick here is one dhdGetPositionAndOrientationFrame call. In mode mujoco one
// control cycle runs per force set, so the simulated device holds still until the first. The stand-in can refuse
// dhdOpen, report any system type (dhdGetSystemType), and fail a call of one tick; it checks
// how it is used: force set only while forces are enabled, no call after dhdClose, dhdStop
// before dhdClose, no force but zero after a failed call. What it saw is written at dhdClose:
// a summary (key value lines) and one row per tick (the pose served, the force, torque and
// gripper force set).
//
// Configuration: the file named by VIRTMECH_STANDIN_CONFIG, one "key value..." per line ('#'
// starts a comment); every key is optional.
//
//   trace PATH (summary; the ticks go to PATH.ticks)    max_ticks N (default 120000)
//   system_type N (default 34, an omega.6)    open_error TEXT (dhdOpen fails with it)
//   position X Y Z [m]    rotation A B C [rad]    velocity VX VY VZ [m/s]
//   error_at TICK pose|velocity|force        the call of that tick fails
//   mode hold|mujoco    mujoco: device_model NAME (default omega.6)  handle_rotation 3
//                       (a rotation vector [rad]), and the simulated device's keys
//                       (standin_sim.hpp)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#include "standin_config.hpp"
#include "virtmech/drivers/dhd_api.h"

#if VM_STANDIN_MUJOCO
#include <memory>

#include "standin_sim.hpp"
#include "virtmech/cartesian_device.hpp"
#include "virtmech/se3.hpp"
#endif

#define VM_STANDIN_EXPORT extern "C" __attribute__((visibility("default")))

// the library's functions with DHD's signatures, checked against the one declaration
#define VM_STANDIN_DECLARE(ret, name, params) VM_STANDIN_EXPORT ret name params;
VM_DHD_FUNCTIONS(VM_STANDIN_DECLARE)
#undef VM_STANDIN_DECLARE

namespace {

// one row per tick: tick, position served (3), gimbal angles served (3), force set (3),
// torque set (3), gripper force set (NaN: none), the call that set it (1 dhdSetForceAndTorque,
// 2 ...AndGripperForce, 0 none), failure injected (0 none, 1 pose, 2 velocity, 3 force), the
// gap since the last tick [s]
constexpr int kTraceWidth = 17;

using standin_config::Config;

enum Failure { kNone = 0, kPose = 1, kVelocity = 2, kForce = 3 };

class Standin {
 public:
  int open();
  int close(char id);
  int system_type(char id);
  int enable_force(unsigned char on, char id);
  int pose(double* px, double* py, double* pz, double R[3][3], char id);
  int linear_velocity(double* vx, double* vy, double* vz, char id);
  int angular_velocity(double* wx, double* wy, double* wz, char id);
  int set_force(double fx, double fy, double fz, double tx, double ty, double tz, double fg,
                int call, char id);
  int stop(char id);
  const char* last_error() const { return error_.c_str(); }

 private:
  bool usable(char id);
  bool failing(Failure f);
  void write_trace();
  // the pose served this tick: position p, gimbal angles abc (zero where not sensed), R
  void served_pose(double* p, double* abc, double R[3][3]);
  void served_velocity(double* v, double* w);
#if VM_STANDIN_MUJOCO
  bool load_mujoco();
  void simulate(const double* f, const double* m);

  // the simulated device's controller: the coordinate torques of the wrench last set
  class Serve final : public virtmech::sim::ExternalController {
   public:
    explicit Serve(Standin& s) : s_(s) {}
    void control(double, const double* qm, const double*, double* torque) override {
      const int n = s_.device_->dof();
      for (int i = 0; i < n; ++i) {
        if (qm[i] != s_.q_[i]) ++s_.reading_mismatches_;
        torque[i] = s_.tau_[i];
      }
    }

   private:
    Standin& s_;
  };
  std::unique_ptr<virtmech::CartesianDevice> device_;
  std::unique_ptr<Serve> serve_;
  standin_sim::SimulatedDevice sim_;
  double q_[6] = {0, 0, 0, 0, 0, 0};    // the coordinates served this tick
  double tau_[6] = {0, 0, 0, 0, 0, 0};  // the coordinate torques of the wrench set
  long reading_mismatches_ = 0;         // cycles whose sensing was not the reading served
#endif

  Config config_;
  bool open_ = false;
  std::string error_;
  int system_type_ = VM_DHD_OMEGA6_RIGHT;
  double position_[3] = {0, 0, 0}, angles_[3] = {0, 0, 0}, velocity_[3] = {0, 0, 0};
  double period_s_ = 1e-3;
  bool force_enabled_ = false, failed_ = false;
  long opens_ = 0, closes_ = 0, stops_ = 0, enables_ = 0, disables_ = 0, bad_id_ = 0;
  long sets_ = 0, sets_without_force_ = 0, nonzero_after_failure_ = 0, calls_closed_ = 0;
  long stop_before_close_ = 0, ticks_ = 0, error_at_ = -1;
  Failure error_call_ = kNone;
  std::vector<double> trace_;
  long max_ticks_ = 120000;
  std::chrono::steady_clock::time_point last_{};
};

Standin& standin() {
  static Standin s;
  return s;
}

void gimbal(const double* abc, double R[3][3]) {
  const double sa = std::sin(abc[0]), ca = std::cos(abc[0]), sb = std::sin(abc[1]),
               cb = std::cos(abc[1]), sc = std::sin(abc[2]), cc = std::cos(abc[2]);
  const double M[3][3] = {{cb * cc, -cb * sc, sb},
                          {sa * sb * cc + ca * sc, -sa * sb * sc + ca * cc, -sa * cb},
                          {-ca * sb * cc + sa * sc, ca * sb * sc + sa * cc, ca * cb}};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) R[i][j] = M[i][j];
  }
}

int Standin::open() {
  config_ = Config();
  config_.load();
  if (config_.has("open_error")) {
    error_ = config_.text("open_error", "no device found");
    return -1;
  }
  if (open_) {
    error_ = "the device is already open";
    return -1;
  }
  open_ = true;
  failed_ = force_enabled_ = false;
  opens_ = 1;
  closes_ = stops_ = enables_ = disables_ = bad_id_ = sets_ = sets_without_force_ = 0;
  nonzero_after_failure_ = calls_closed_ = stop_before_close_ = ticks_ = 0;
  error_.clear();
  system_type_ = static_cast<int>(config_.number("system_type", VM_DHD_OMEGA6_RIGHT));
  for (int i = 0; i < 3; ++i) {
    position_[i] = config_.number("position", 0.0, static_cast<size_t>(i));
    angles_[i] = config_.number("rotation", 0.0, static_cast<size_t>(i));
    velocity_[i] = config_.number("velocity", 0.0, static_cast<size_t>(i));
  }
  period_s_ = config_.number("period_s", 1e-3);
  error_at_ = static_cast<long>(config_.number("error_at", -1.0));
  const std::string call = config_.text("error_at", "");
  error_call_ = call.find("velocity") != std::string::npos ? kVelocity
                : call.find("force") != std::string::npos  ? kForce
                : call.find("pose") != std::string::npos   ? kPose
                                                           : kNone;
  max_ticks_ = static_cast<long>(config_.number("max_ticks", 120000));
  trace_.assign(static_cast<size_t>(max_ticks_) * kTraceWidth,
                std::numeric_limits<double>::quiet_NaN());
  if (config_.text("mode", "hold") == "mujoco") {
#if VM_STANDIN_MUJOCO
    if (!load_mujoco()) {
      error_ = "the simulated device cannot be loaded (stand-in)";
      open_ = false;
      return -1;
    }
#else
    error_ = "mode mujoco: the stand-in was built without MuJoCo";
    open_ = false;
    return -1;
#endif
  }
  return 0;  // the device's ID
}

#if VM_STANDIN_MUJOCO
bool Standin::load_mujoco() {
  Eigen::Vector3d handle(M_PI, 0.0, 0.0);
  for (int i = 0; i < 3; ++i) {
    handle[i] = config_.number("handle_rotation", handle[i], static_cast<size_t>(i));
  }
  try {
    device_ = std::make_unique<virtmech::CartesianDevice>(config_.text("device_model", "omega.6"),
                                                          virtmech::so3_exp(handle));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "standin libdhd: %s\n", e.what());
    return false;
  }
  serve_ = std::make_unique<Serve>(*this);
  reading_mismatches_ = 0;
  std::fill(tau_, tau_ + 6, 0.0);
  return sim_.load(config_, *device_, *serve_, max_ticks_, "standin libdhd");
}

// one control cycle under the wrench (f, m) set at the pose served
void Standin::simulate(const double* f, const double* m) {
  virtmech::Pose T;
  virtmech::Jacobian J;
  device_->forward_jacobian(q_, T, J);
  Eigen::Matrix<double, 6, 1> w;
  w << f[0], f[1], f[2], m[0], m[1], m[2];
  const Eigen::VectorXd tau = J.transpose() * w;
  for (int i = 0; i < device_->dof(); ++i) tau_[i] = tau[i];
  sim_.cycle();
}
#endif

void Standin::served_pose(double* p, double* abc, double R[3][3]) {
#if VM_STANDIN_MUJOCO
  if (sim_.loaded()) {
    sim_.sensed(q_);
    Eigen::Vector3d pos;
    Eigen::Matrix3d rot;
    device_->sdk_pose(q_, pos, rot);
    const bool wrist = device_->orientation_sensed();
    for (int i = 0; i < 3; ++i) {
      p[i] = pos[i];
      abc[i] = wrist ? q_[3 + i] : 0.0;
      for (int j = 0; j < 3; ++j) R[i][j] = rot(i, j);
    }
    return;
  }
#endif
  const double t = static_cast<double>(ticks_ - 1) * period_s_;
  for (int i = 0; i < 3; ++i) {
    p[i] = position_[i] + velocity_[i] * t;
    abc[i] = angles_[i];
  }
  gimbal(angles_, R);
}

void Standin::served_velocity(double* v, double* w) {
  for (int i = 0; i < 3; ++i) {
    v[i] = velocity_[i];
    w[i] = 0.0;
  }
#if VM_STANDIN_MUJOCO
  if (sim_.loaded()) {
    double dq[6] = {0, 0, 0, 0, 0, 0};
    sim_.rates(dq);
    virtmech::Pose T;
    virtmech::Jacobian J;
    device_->forward_jacobian(q_, T, J);
    const Eigen::VectorXd twist = J * Eigen::Map<const Eigen::VectorXd>(dq, device_->dof());
    for (int i = 0; i < 3; ++i) {
      v[i] = twist[i];
      w[i] = twist[3 + i];
    }
  }
#endif
}

bool Standin::usable(char id) {
  if (!open_) {
    ++calls_closed_;
    error_ = "no device open";
    return false;
  }
  if (id != 0 && id != -1) {
    ++bad_id_;
    error_ = "invalid device ID";
    return false;
  }
  return true;
}

bool Standin::failing(Failure f) {
  if (ticks_ - 1 != error_at_ || error_call_ != f) return false;
  failed_ = true;
  error_ = "communication error (stand-in: injected at tick " + std::to_string(error_at_) + ")";
  const long row = ticks_ - 1;
  if (row >= 0 && row < max_ticks_) trace_[static_cast<size_t>(row * kTraceWidth + 15)] = f;
  return true;
}

int Standin::close(char id) {
  if (!usable(id)) return -1;
  ++closes_;
  write_trace();
  open_ = false;
#if VM_STANDIN_MUJOCO
  sim_.unload();
#endif
  return 0;
}

int Standin::system_type(char id) { return usable(id) ? system_type_ : -1; }

int Standin::enable_force(unsigned char on, char id) {
  if (!usable(id)) return -1;
  force_enabled_ = on != 0;
  ++(on ? enables_ : disables_);
  return 0;
}

int Standin::pose(double* px, double* py, double* pz, double R[3][3], char id) {
  if (!usable(id)) return -1;
  const auto now = std::chrono::steady_clock::now();
  const double gap = ticks_ > 0 ? std::chrono::duration<double>(now - last_).count()
                                : std::numeric_limits<double>::quiet_NaN();
  last_ = now;
  const long row = ticks_++;
  if (failing(kPose)) return -1;
  double p[3], abc[3];
  served_pose(p, abc, R);
  *px = p[0];
  *py = p[1];
  *pz = p[2];
  if (row < max_ticks_) {
    double* r = &trace_[static_cast<size_t>(row * kTraceWidth)];
    r[0] = static_cast<double>(row);
    for (int i = 0; i < 3; ++i) {
      r[1 + i] = p[i];
      r[4 + i] = abc[i];
    }
    r[14] = 0.0;
    r[15] = 0.0;
    r[16] = gap;
  }
  return 0;
}

int Standin::linear_velocity(double* vx, double* vy, double* vz, char id) {
  if (!usable(id)) return -1;
  if (failing(kVelocity)) return -1;
  double v[3], w[3];
  served_velocity(v, w);
  *vx = v[0];
  *vy = v[1];
  *vz = v[2];
  return 0;
}

int Standin::angular_velocity(double* wx, double* wy, double* wz, char id) {
  if (!usable(id)) return -1;
  double v[3], w[3];
  served_velocity(v, w);
  *wx = w[0];
  *wy = w[1];
  *wz = w[2];
  return 0;
}

int Standin::set_force(double fx, double fy, double fz, double tx, double ty, double tz,
                       double fg, int call, char id) {
  if (!usable(id)) return -1;
  ++sets_;
  if (!force_enabled_) ++sets_without_force_;
  const bool nonzero = fx != 0 || fy != 0 || fz != 0 || tx != 0 || ty != 0 || tz != 0 || fg != 0;
  if (failed_ && nonzero) ++nonzero_after_failure_;
  const long row = ticks_ - 1;
  if (row >= 0 && row < max_ticks_) {
    double* r = &trace_[static_cast<size_t>(row * kTraceWidth)];
    const double v[7] = {fx, fy, fz, tx, ty, tz, fg};
    for (int i = 0; i < 7; ++i) r[7 + i] = v[i];
    r[14] = call;
  }
  if (failing(kForce)) return -1;
#if VM_STANDIN_MUJOCO
  if (sim_.loaded()) {
    const double f[3] = {fx, fy, fz}, m[3] = {tx, ty, tz};
    simulate(f, m);
  }
#endif
  return 0;
}

int Standin::stop(char id) {
  if (!usable(id)) return -1;
  ++stops_;
  if (closes_ == 0) ++stop_before_close_;
  force_enabled_ = false;
  return 0;
}

void Standin::write_trace() {
  const std::string path = config_.text("trace", "");
  if (path.empty()) return;
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) return;
  std::fprintf(f,
               "opens %ld\ncloses %ld\nstops %ld\nstop_before_close %ld\nenables %ld\n"
               "disables %ld\nsets %ld\nsets_without_force %ld\nnonzero_after_failure %ld\n"
               "calls_closed %ld\nbad_id %ld\nticks %ld\nsystem_type %d\n",
               opens_, closes_, stops_, stop_before_close_, enables_, disables_, sets_,
               sets_without_force_, nonzero_after_failure_, calls_closed_, bad_id_, ticks_,
               system_type_);
#if VM_STANDIN_MUJOCO
  if (sim_.loaded()) {
    std::fprintf(f, "cycles %ld\nreading_mismatches %ld\n", sim_.cycles(), reading_mismatches_);
    sim_.write_truth(config_.text("truth_file", ""));
  }
#endif
  std::fclose(f);
  std::FILE* t = std::fopen((path + ".ticks").c_str(), "wb");
  if (t == nullptr) return;
  const long rows = std::min(ticks_, max_ticks_);
  std::fwrite(trace_.data(), sizeof(double), static_cast<size_t>(rows * kTraceWidth), t);
  std::fclose(t);
}

}  // namespace

VM_STANDIN_EXPORT int dhdOpen(void) { return standin().open(); }
VM_STANDIN_EXPORT int dhdClose(char id) { return standin().close(id); }
VM_STANDIN_EXPORT int dhdGetSystemType(char id) { return standin().system_type(id); }
VM_STANDIN_EXPORT int dhdEnableForce(unsigned char on, char id) {
  return standin().enable_force(on, id);
}
VM_STANDIN_EXPORT int dhdGetPositionAndOrientationFrame(double* px, double* py, double* pz,
                                                        double matrix[3][3], char id) {
  return standin().pose(px, py, pz, matrix, id);
}
VM_STANDIN_EXPORT int dhdGetLinearVelocity(double* vx, double* vy, double* vz, char id) {
  return standin().linear_velocity(vx, vy, vz, id);
}
VM_STANDIN_EXPORT int dhdGetAngularVelocityRad(double* wx, double* wy, double* wz, char id) {
  return standin().angular_velocity(wx, wy, wz, id);
}
VM_STANDIN_EXPORT int dhdSetForceAndTorque(double fx, double fy, double fz, double tx, double ty,
                                           double tz, char id) {
  return standin().set_force(fx, fy, fz, tx, ty, tz, 0.0, 1, id);
}
VM_STANDIN_EXPORT int dhdSetForceAndTorqueAndGripperForce(double fx, double fy, double fz,
                                                          double tx, double ty, double tz,
                                                          double fg, char id) {
  return standin().set_force(fx, fy, fz, tx, ty, tz, fg, 2, id);
}
VM_STANDIN_EXPORT int dhdGetButton(int, char id) { return standin().system_type(id) < 0 ? -1 : 0; }
VM_STANDIN_EXPORT int dhdStop(char id) { return standin().stop(id); }
VM_STANDIN_EXPORT const char* dhdErrorGetLastStr(void) { return standin().last_error(); }
