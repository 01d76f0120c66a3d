// Several mechanisms at once: a MechanismSet holds up to a fixed number of members (each a
// Controller of its own mechanism on the one device) and renders at most one of them per
// cycle. A member engages when the handle comes within a snap distance of it and lets go
// beyond a larger release distance (hysteresis, as OpenHaptics' HL constraints snap); a
// unilateral member's distance is its tip's height above its surface, zero in contact, so it
// engages on contact at the latest. When the rendered member changes, the output wrench
// moves from the old one to the new one at no more than a set rate, so that switching never
// steps the force; after a fault the force comes back from zero at the same rate.
// docs/theory.md, section 7.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "virtmech/controller.hpp"

namespace virtmech {

/// Largest capacity of a MechanismSet (fixed-size diagnostics).
constexpr int kMaxSetMembers = 16;

/// A set's settings, one member per row of VM_SET_SETTINGS
/// (include/virtmech/settings_table.h: units, defaults, ranges); release_distance must be
/// at least snap_distance (the hysteresis).
struct MechanismSetSettings {
#define VM_SETTING_REAL(name, value, min, max, flags, unit, doc) double name = value;
  VM_SET_SETTINGS(VM_SETTING_REAL)
#undef VM_SETTING_REAL
};

/// Checks every setting against its row's range and the hysteresis (std::invalid_argument
/// naming the setting).
void check_settings(const MechanismSetSettings& settings);

/// Everything one cycle of a set reports. Fixed capacity: copying never allocates.
struct MechanismSetOutput {
  /// The rendered member's cycle with torque and wrench replaced by the set's output (while
  /// switching, the blend); with no member engaged, member 0's cycle with zero force.
  CycleOutput cycle;
  int active = -1;  //!< the member rendered, -1 for none
  int size = 0;     //!< members in the set
  /// Each member's engagement distance from the handle [m], what the set switches on: the
  /// larger position error of its two placements (the un-powered one is where the user's
  /// tip is on an under-actuated device); for a unilateral member out of contact its tip's
  /// height, in contact 0. It is read off the placements every member makes each cycle
  /// anyway (no search of its own, a bounded cost), and is not the simulation log's `dist`
  /// (the kind's geometric measure, virtmech::distance): the two agree where a placement
  /// reaches its optimum, and differ where the rotational weights pull the placement off
  /// the point's nearest one. NaN on a faulted cycle (which engages no member and keeps the
  /// engaged one).
  std::array<double, kMaxSetMembers> distance{};
  std::uint32_t contact = 0;  //!< bit i: member i is unilateral and in contact
  /// The output is moving from one member's force to another's, or back from a fault.
  bool switching = false;
};

/// Several mechanisms on one device, one of them rendered at a time. Not for concurrent use:
/// one thread steps a set (a set per thread); its members' devices and mechanisms are
/// immutable and may be shared with controllers and sets on other threads.
class MechanismSet {
 public:
  /// capacity in 1..kMaxSetMembers; settings checked (throws std::invalid_argument).
  MechanismSet(std::shared_ptr<const Device> device, int capacity,
               const MechanismSetSettings& settings = MechanismSetSettings());
  MechanismSet(const MechanismSet&) = delete;
  MechanismSet& operator=(const MechanismSet&) = delete;
  MechanismSet(MechanismSet&&) = default;
  MechanismSet& operator=(MechanismSet&&) = default;

  /// Adds a member (a copy of `member`, whose device must be this set's). Not real-time
  /// (allocates); throws std::invalid_argument past the capacity or for another device.
  /// Returns the member's index.
  int add(const Controller& member);
  /// As above, building the member's controller.
  int add(std::shared_ptr<const Mechanism> mechanism,
          const ControllerSettings& settings = ControllerSettings());

  /// One servo cycle: every member places (Controller::place, from the device's kinematics
  /// computed once for all: their placements follow the handle and give their distances),
  /// the set chooses the member to render, which renders
  /// (Controller::render) while the others end their cycles without a wrench
  /// (Controller::unrendered), and blends its force in. noexcept, allocation-free.
  /// With no member added the torque is zero.
  std::uint32_t step(const double* q, const double* dq, MechanismSetOutput& out,
                     double t_s = std::numeric_limits<double>::quiet_NaN()) noexcept;

  /// Restarts every member and the selection.
  void reset() noexcept;

  int size() const noexcept { return static_cast<int>(members_.size()); }
  int capacity() const noexcept { return capacity_; }
  const Device& device() const noexcept { return *device_; }
  std::shared_ptr<const Device> device_ptr() const noexcept { return device_; }
  const Controller& member(int i) const { return *members_.at(static_cast<size_t>(i)); }
  const MechanismSetSettings& settings() const noexcept { return settings_; }
  int active() const noexcept { return active_; }
  /// The last cycle's output.
  const MechanismSetOutput& last() const noexcept { return last_; }

 private:
  // step()'s stages: every member placed, its distance recorded (returns the input's
  // faults); the member to render chosen; the chosen one rendered and the others
  // unrendered; the output of a faulted cycle; the blend toward the rendered member's force
  // while switching
  std::uint32_t place_members(const double* q, const double* dq, MechanismSetOutput& out,
                              double t_s) noexcept;
  void choose_member(std::uint32_t faults, MechanismSetOutput& out) noexcept;
  void render_members(MechanismSetOutput& out) noexcept;
  std::uint32_t faulted(std::uint32_t faults, MechanismSetOutput& out) noexcept;
  void blend(MechanismSetOutput& out) noexcept;

  std::shared_ptr<const Device> device_;
  int capacity_;
  MechanismSetSettings settings_;
  std::vector<std::unique_ptr<Controller>> members_;
  std::vector<CycleOutput> outputs_;
  DeviceKinematics kinematics_;  // the device's at the cycle's q, shared by the members
  int active_ = -1;
  bool switching_ = false;
  Vector6 wrench_ = Vector6::Zero();  // the wrench output last cycle
  MechanismSetOutput last_;
};

}  // namespace virtmech
