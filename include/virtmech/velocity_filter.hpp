// The joint-velocity estimate a servo loop makes from sampled joint positions: the backward
// difference over the servo period through a first-order low-pass filter. The simulation's
// sensor model (virtmech.sim) and the device drivers (virtmech/drivers/) use this one filter,
// so that a controller sees the same velocity from a simulated and from a real device.
//
//     dq_k = dq_{k-1} + alpha ((q_k - q_{k-1}) / T - dq_{k-1}),   dq_0 = 0
//
// With alpha = T / (T + 1 / (2 pi f_c)) this is a first-order low-pass of cut-off f_c
// (within a few per cent for f_c well below the servo rate): at low frequencies it delays
// the velocity by 1 / (2 pi f_c) (the low-pass) plus T / 2 (the backward difference), 2.1 ms
// at f_c = 100 Hz and T = 1 ms. docs/devices.md, "Velocity estimate".
#pragma once

#include "virtmech/types.hpp"

namespace virtmech {

class VelocityFilter {
 public:
  /// An empty filter (no joints); assign a constructed one before use.
  VelocityFilter() = default;
  /// A filter of n joints (1 <= n <= kMaxDof) at period T = period_s [s] > 0 with gain alpha
  /// in (0, 1] (1: the plain backward difference). Throws std::invalid_argument naming the
  /// parameter.
  VelocityFilter(int n, double period_s, double alpha);

  /// The gain of a first-order low-pass of cut-off cutoff_hz [Hz] at period period_s [s]:
  /// T / (T + 1 / (2 pi f_c)); 1 (no filtering) where cutoff_hz <= 0.
  static double alpha_for_cutoff(double period_s, double cutoff_hz) noexcept;

  /// Takes the next sample q (dof() entries [rad or m]) and returns the velocity estimate
  /// [rad/s or m/s]; the first sample after construction or reset() gives zero. noexcept,
  /// allocation-free.
  const JointVector& update(const double* q) noexcept;
  /// The next sample starts the estimate afresh (zero velocity).
  void reset() noexcept;

  /// The last estimate [rad/s or m/s].
  const JointVector& velocity() const noexcept { return dq_; }
  int dof() const noexcept { return static_cast<int>(dq_.size()); }
  double period_s() const noexcept { return period_s_; }
  double alpha() const noexcept { return alpha_; }

 private:
  JointVector prev_, dq_;
  double period_s_ = 1e-3;
  double alpha_ = 1.0;
  bool primed_ = false;  // a sample has been taken since construction or reset()
};

}  // namespace virtmech
