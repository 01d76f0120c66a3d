// The process's registry of kinds, the lookups over it and the generic fallbacks
// (include/virtmech/registry.hpp).
#include "virtmech/registry.hpp"

#include <cmath>
#include <limits>
#include <mutex>
#include <stdexcept>

#include "../kinds/kinds.hpp"

namespace virtmech {

namespace {

template <class K>
void add_kind(std::vector<std::unique_ptr<K>>& kinds, K kind, const char* what) {
  if (kind.name.empty() || !kind.make || !kind.describe || kind.type == typeid(void)) {
    throw std::invalid_argument(std::string(what) + " kind '" + kind.name +
                                "': expected a name, a type, make and describe");
  }
  for (const auto& k : kinds) {
    if (k->name == kind.name) {
      throw std::invalid_argument(std::string(what) + " kind '" + kind.name +
                                  "' is already registered");
    }
  }
  kinds.push_back(std::make_unique<K>(std::move(kind)));
}

template <class K>
const K* find(const std::vector<std::unique_ptr<K>>& kinds, const std::string& name) {
  for (const auto& k : kinds)
    if (k->name == name) return k.get();
  return nullptr;
}

template <class K>
std::vector<const K*> all(const std::vector<std::unique_ptr<K>>& kinds) {
  std::vector<const K*> out;
  for (const auto& k : kinds) out.push_back(k.get());
  return out;
}

// The kinds are added under a lock and never removed: a kind found stays valid.
class ProcessRegistry final : public Registry {
 public:
  void add(MechanismKind kind) override {
    std::lock_guard<std::mutex> lock(mutex_);
    add_kind(mechanisms_, std::move(kind), "mechanism");
  }
  void add(DeviceKind kind) override {
    std::lock_guard<std::mutex> lock(mutex_);
    add_kind(devices_, std::move(kind), "device");
  }
  void add(CurveKind kind) override {
    std::lock_guard<std::mutex> lock(mutex_);
    add_kind(curves_, std::move(kind), "curve");
  }
  void add(SurfaceKind kind) override {
    std::lock_guard<std::mutex> lock(mutex_);
    add_kind(surfaces_, std::move(kind), "surface");
  }
  const MechanismKind* mechanism(const std::string& name) const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return find(mechanisms_, name);
  }
  const DeviceKind* device(const std::string& name) const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return find(devices_, name);
  }
  const CurveKind* curve(const std::string& name) const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return find(curves_, name);
  }
  const SurfaceKind* surface(const std::string& name) const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return find(surfaces_, name);
  }
  std::vector<const MechanismKind*> mechanisms() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return all(mechanisms_);
  }
  std::vector<const DeviceKind*> devices() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return all(devices_);
  }
  std::vector<const CurveKind*> curves() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return all(curves_);
  }
  std::vector<const SurfaceKind*> surfaces() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return all(surfaces_);
  }

 private:
  mutable std::mutex mutex_;
  std::vector<std::unique_ptr<MechanismKind>> mechanisms_;
  std::vector<std::unique_ptr<DeviceKind>> devices_;
  std::vector<std::unique_ptr<CurveKind>> curves_;
  std::vector<std::unique_ptr<SurfaceKind>> surfaces_;
};

template <class K>
std::string names_of(const std::vector<const K*>& kinds) {
  std::string out;
  for (size_t i = 0; i < kinds.size(); ++i) {
    out += (i ? (i + 1 == kinds.size() ? " or '" : ", '") : "'") + kinds[i]->name + "'";
  }
  return out;
}

template <class Base, class K>
std::shared_ptr<const Base> make_from(const K* kind, const std::vector<const K*>& known,
                                      const Params& params, const std::string& where) {
  if (!kind) {
    throw std::invalid_argument(where + ".type: expected " + names_of(known) + ", got '" +
                                params.type() + "'");
  }
  return kind->make(complete(kind->params, params, where));
}

template <class Base, class K>
Params describe_with(const std::vector<const K*>& kinds, const Base& object, const char* what) {
  for (const K* k : kinds)
    if (k->type == std::type_index(typeid(object))) return k->describe(object);
  throw std::invalid_argument(std::string(what) + ": no registered kind describes the class " +
                              typeid(object).name());
}

}  // namespace

Registry& registry() {
  static ProcessRegistry* r = [] {
    auto* made = new ProcessRegistry();  // never destroyed: plugins' kinds live to the end
    kinds::add_builtin(*made);
    return made;
  }();
  return *r;
}

std::shared_ptr<const Mechanism> make_mechanism(const Params& params, const std::string& where) {
  Registry& r = registry();
  return make_from<Mechanism>(r.mechanism(params.type()), r.mechanisms(), params, where);
}

std::shared_ptr<const Device> make_device(const Params& params, const std::string& where) {
  Registry& r = registry();
  return make_from<Device>(r.device(params.type()), r.devices(), params, where);
}

std::shared_ptr<const Curve> make_curve(const Params& params, const std::string& where) {
  Registry& r = registry();
  return make_from<Curve>(r.curve(params.type()), r.curves(), params, where);
}

std::shared_ptr<const Surface> make_surface(const Params& params, const std::string& where) {
  Registry& r = registry();
  return make_from<Surface>(r.surface(params.type()), r.surfaces(), params, where);
}

Params describe(const Mechanism& m) { return describe_with(registry().mechanisms(), m, "mechanism"); }
Params describe(const Device& d) { return describe_with(registry().devices(), d, "device"); }
Params describe(const Curve& c) { return describe_with(registry().curves(), c, "curve"); }
Params describe(const Surface& s) { return describe_with(registry().surfaces(), s, "surface"); }

const MechanismKind* kind_of(const Mechanism& mechanism) {
  for (const MechanismKind* k : registry().mechanisms())
    if (k->type == std::type_index(typeid(mechanism))) return k;
  return nullptr;
}

namespace {

Distances distance_by(const MechanismKind* k, const Mechanism& mechanism, const Eigen::Vector3d& p,
                      const Eigen::Vector3d& s, const Eigen::Vector3d& position_error) {
  if (k && k->distance) return k->distance(mechanism, p, s);
  const double d = position_error.norm();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  return {d, d, nan, nan};
}

}  // namespace

Distances distance(const Mechanism& mechanism, const Eigen::Vector3d& p, const Eigen::Vector3d& s,
                   const Eigen::Vector3d& position_error) {
  return distance_by(kind_of(mechanism), mechanism, p, s, position_error);
}

void distances(const Mechanism& mechanism, long n, const double* p, const double* s,
               const double* position_error, double* out) {
  const MechanismKind* k = kind_of(mechanism);
  using Row = Eigen::Map<const Eigen::Vector3d>;
  for (long i = 0; i < n; ++i) {
    const Distances d = distance_by(k, mechanism, Row(p + 3 * i), Row(s + 3 * i),
                                    Row(position_error + 3 * i));
    out[4 * i] = d.dist;
    out[4 * i + 1] = d.dist_signed;
    out[4 * i + 2] = d.dist_normal;
    out[4 * i + 3] = d.dist_across;
  }
}

std::vector<NamedDirection> constrained_directions(const Mechanism& mechanism,
                                                   const Eigen::Vector3d& at) {
  const MechanismKind* k = kind_of(mechanism);
  if (k && k->constrained) return k->constrained(mechanism, at);
  return {};
}

Sketch sketch(const Mechanism& mechanism) {
  const MechanismKind* k = kind_of(mechanism);
  if (k && k->sketch) return k->sketch(mechanism);
  // the handle's path as joint 0 sweeps its range (at most +-pi, or +-0.1 m along a
  // prismatic joint), the others at home
  const bool revolute = mechanism.joint_type(0) == JointType::kRevolute;
  const double reach = revolute ? M_PI : 0.1;
  const double lo = std::max(mechanism.lower()[0], mechanism.home()[0] - reach);
  const double hi = std::min(mechanism.upper()[0], mechanism.home()[0] + reach);
  Sketch out;
  out.lines.emplace_back();
  JointVector x = mechanism.home();
  Pose T;
  constexpr int kSamples = 101;
  for (int i = 0; i < kSamples; ++i) {
    x[0] = lo + (hi - lo) * i / (kSamples - 1);
    mechanism.forward(x.data(), T);
    out.lines.back().push_back(T.translation());
  }
  return out;
}

}  // namespace virtmech
