#include "virtmech/mechanism_set.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "flush_denormals.hpp"
#include "virtmech/validate.hpp"

namespace virtmech {

MechanismSet::MechanismSet(std::shared_ptr<const Device> device, int capacity,
                           const MechanismSetSettings& settings)
    : device_(std::move(device)), capacity_(capacity), settings_(settings) {
  if (!device_) throw std::invalid_argument("device: expected a device, got null");
  if (capacity < 1 || capacity > kMaxSetMembers) {
    std::ostringstream os;
    os << "capacity: expected 1 to " << kMaxSetMembers << " members, got " << capacity;
    throw std::invalid_argument(os.str());
  }
  check_settings(settings);
  members_.reserve(static_cast<size_t>(capacity));
  outputs_.resize(static_cast<size_t>(capacity));
}

int MechanismSet::add(const Controller& member) {
  if (size() >= capacity_) {
    std::ostringstream os;
    os << "member: the set is full (capacity " << capacity_ << ")";
    throw std::invalid_argument(os.str());
  }
  if (member.device_ptr() != device_) {
    throw std::invalid_argument("member: expected a controller of the set's device, got one of "
                                "another device object");
  }
  members_.push_back(std::make_unique<Controller>(member));
  return size() - 1;
}

int MechanismSet::add(std::shared_ptr<const Mechanism> mechanism,
                      const ControllerSettings& settings) {
  return add(Controller(device_, std::move(mechanism), settings));
}

void MechanismSet::reset() noexcept {
  for (auto& m : members_) m->reset();
  active_ = -1;
  switching_ = false;
  wrench_.setZero();
}

namespace {

// A member's distance from the handle (MechanismSetOutput::distance).
double member_distance(const Mechanism& mech, const CycleOutput& o) noexcept {
  const int c = mech.contact_joint();
  if (c >= 0) {
    const bool touching = ((o.active | o.active_star) >> c) & 1u;
    if (touching) return 0.0;
    // the tip's height where the user holds it (the un-powered placement; the nearest one
    // when the law has none, theta_star then equals theta)
    return std::max(o.theta_star[c], 0.0);
  }
  return std::max(o.error.head<3>().norm(), o.error_star.head<3>().norm());
}

}  // namespace

std::uint32_t MechanismSet::step(const double* q, const double* dq, MechanismSetOutput& out,
                                 double t_s) noexcept {
  const detail::FlushDenormals flush;
  const int n = size();
  out.size = n;
  out.contact = 0;
  out.distance.fill(0.0);
  if (n == 0) {
    out.cycle.torque.setZero(device_->dof());
    out.cycle.wrench.setZero();
    out.cycle.status = status::kOk;
    out.active = -1;
    out.switching = false;
    last_ = out;
    return status::kOk;
  }
  std::uint32_t faults = place_members(q, dq, out, t_s);
  choose_member(faults, out);
  if (!faults) render_members(out);
  // a fault of the rendered member's own output (non-finite) is the set's, as an input's is
  if (!faults && active_ >= 0) {
    faults = outputs_[static_cast<size_t>(active_)].status & status::kFaultMask;
  }
  const CycleOutput& src = outputs_[static_cast<size_t>(active_ >= 0 ? active_ : 0)];
  out.cycle = src;
  out.active = active_;
  if (faults) return faulted(faults, out);
  if (out.cycle.status & status::kWatchdog) {
    // a gap: the members ramp in again, and the force the device held over it is not known
    // (a driver zeroes the late tick): the set's blend starts from zero too, not from the
    // force it had before the gap
    wrench_.setZero();
    switching_ = true;
  }
  if (active_ < 0) {
    out.cycle.torque.setZero(device_->dof());
    out.cycle.wrench.setZero();
    out.cycle.wrench_null.setZero();
    out.cycle.wrench_range.setZero();
  }
  if (switching_) blend(out);
  wrench_ = out.cycle.wrench;
  out.switching = switching_;
  last_ = out;
  return out.cycle.status;
}

// every member's placements (Controller::place), its distance from them; the wrench only
// for the member rendered (Controller::render), once it is chosen
std::uint32_t MechanismSet::place_members(const double* q, const double* dq,
                                          MechanismSetOutput& out, double t_s) noexcept {
  std::uint32_t faults = 0;
  // the device's kinematics once, for every member (a member that finds the input
  // implausible faults before it reads them)
  device_->forward_jacobian(q, kinematics_.pose, kinematics_.J);
  for (int i = 0; i < size(); ++i) {
    CycleOutput& o = outputs_[static_cast<size_t>(i)];
    faults |= members_[static_cast<size_t>(i)]->place(q, dq, kinematics_, o, t_s) &
              status::kFaultMask;
    out.distance[static_cast<size_t>(i)] =
        member_distance(members_[static_cast<size_t>(i)]->mechanism(), o);
  }
  return faults;
}

// the member to render: the engaged one while within the release distance, else the
// nearest within the snap distance. A faulted cycle's outputs are cleared (no distances):
// it chooses nothing, and the engaged member stays as it was
void MechanismSet::choose_member(std::uint32_t faults, MechanismSetOutput& out) noexcept {
  int chosen = active_;
  if (faults) {
    out.distance.fill(std::numeric_limits<double>::quiet_NaN());
  } else if (chosen >= 0 && !(out.distance[static_cast<size_t>(chosen)] <= settings_.release_distance)) {
    chosen = -1;
  }
  if (!faults && chosen < 0) {
    double best = settings_.snap_distance;
    for (int i = 0; i < size(); ++i) {
      if (out.distance[static_cast<size_t>(i)] < best) {
        best = out.distance[static_cast<size_t>(i)];
        chosen = i;
      }
    }
  }
  if (chosen != active_) switching_ = true;
  active_ = chosen;
}

// the member rendered; the others end their cycles without a wrench, and as they did no
// work their tanks start afresh when they are rendered
void MechanismSet::render_members(MechanismSetOutput& out) noexcept {
  for (int i = 0; i < size(); ++i) {
    Controller& member = *members_[static_cast<size_t>(i)];
    CycleOutput& o = outputs_[static_cast<size_t>(i)];
    if (i == active_) {
      member.render(o);
    } else {
      member.unrendered(o);
      member.restart_energy();
    }
    const int c = member.mechanism().contact_joint();
    if (c >= 0 && (((o.active | o.active_star) >> c) & 1u)) out.contact |= 1u << i;
  }
}

// the members share the device's input: they fault together; zero torque
std::uint32_t MechanismSet::faulted(std::uint32_t faults, MechanismSetOutput& out) noexcept {
  out.cycle.torque.setZero(device_->dof());
  out.cycle.wrench.setZero();
  out.cycle.status |= faults;
  // the force comes back from zero at the set's rates once the input clears, whatever
  // the members' own ramp-in (a member that faulted alone does not ramp at all)
  wrench_.setZero();
  switching_ = true;
  out.switching = false;
  last_ = out;
  return out.cycle.status;
}

// move from the last output toward the new member's at the set rates
void MechanismSet::blend(MechanismSetOutput& out) noexcept {
  const Vector6 target = out.cycle.wrench;
  const Vector6 change = target - wrench_;
  double s = 1.0;
  const double df = change.head<3>().norm(), dm = change.tail<3>().norm();
  const double max_f = settings_.force_rate * settings_.period_s;
  const double max_m = settings_.moment_rate * settings_.period_s;
  if (df > max_f) s = std::min(s, max_f / df);
  if (dm > max_m) s = std::min(s, max_m / dm);
  if (!(s < 1.0)) {
    switching_ = false;
    return;
  }
  Vector6 f = wrench_ + s * change;
  // tau = J_R^T f, the passive joints at zero (the blend of two renderable wrenches
  // is renderable), within the joint torque limits
  const Controller& any = *members_[0];
  out.cycle.torque.noalias() = any.data().J_R.transpose() * f;
  double tscale = 1.0;
  for (int i = 0; i < device_->dof(); ++i) {
    if (!device_->actuated(i)) {
      out.cycle.torque[i] = 0.0;
      continue;
    }
    const double a = std::abs(out.cycle.torque[i]);
    if (a > device_->torque_limit()[i]) tscale = std::min(tscale, device_->torque_limit()[i] / a);
  }
  out.cycle.torque *= tscale;
  f *= tscale;
  out.cycle.wrench = f;
  out.cycle.status |= status::kSwitching;
  // the member's energy tank books the torque the motors hold, the blend's
  if (active_ >= 0) members_[static_cast<size_t>(active_)]->applied(out.cycle.torque.data());
}

}  // namespace virtmech
