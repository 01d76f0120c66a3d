// The settings' descriptions and checks, generated from include/virtmech/settings_table.h.
#include "virtmech/settings.hpp"

#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "virtmech/controller.hpp"
#include "virtmech/mechanism_set.hpp"
#include "virtmech/validate.hpp"

#define VM_INF std::numeric_limits<double>::infinity()

namespace virtmech {

namespace detail {

namespace {

// "'a', 'b' or 'c'" (quote = true) or "0 (a), 1 (b) or 2 (c)"
std::string listed(const std::vector<EnumName>& names, bool quote) {
  std::ostringstream os;
  for (size_t i = 0; i < names.size(); ++i) {
    if (i) os << (i + 1 == names.size() ? " or " : ", ");
    if (quote) {
      os << "'" << names[i].name << "'";
    } else {
      os << names[i].value << " (" << names[i].name << ")";
    }
  }
  return os.str();
}

}  // namespace

void throw_bad_name(const std::string& param, const std::vector<EnumName>& names,
                    const std::string& got) {
  throw std::invalid_argument(param + ": expected " + listed(names, true) + ", got '" + got +
                              "'");
}

void throw_bad_value(const std::string& param, const std::vector<EnumName>& names,
                     long long got) {
  throw std::invalid_argument(param + ": expected " + listed(names, false) + ", got " +
                              std::to_string(got));
}

}  // namespace detail

const std::vector<SettingInfo>& controller_setting_infos() {
#define VM_INFO_VEC6(name, unit, doc) \
  {#name, SettingKind::kVector6, 0.0, 0.0, VM_INF, VM_RANGE_CLOSED, unit, doc, {}},
#define VM_INFO_REAL(name, value, min, max, flags, unit, doc) \
  {#name, SettingKind::kReal, value, min, max, flags, unit, doc, {}},
#define VM_INFO_INT(name, value, min, max, unit, doc) \
  {#name, SettingKind::kInteger, value, min, max, VM_RANGE_CLOSED, unit, doc, {}},
#define VM_INFO_ENUM(name, Type, value, doc) \
  {#name, SettingKind::kChoice, value, 0.0, 0.0, VM_RANGE_CLOSED, "", doc, enum_names<Type>()},
  static const std::vector<SettingInfo> infos = {
      VM_CONTROLLER_SETTINGS(VM_INFO_VEC6, VM_INFO_REAL, VM_INFO_INT, VM_INFO_ENUM)};
  return infos;
}

const std::vector<SettingInfo>& set_setting_infos() {
  static const std::vector<SettingInfo> infos = {VM_SET_SETTINGS(VM_INFO_REAL)};
  return infos;
}
#undef VM_INFO_VEC6
#undef VM_INFO_INT
#undef VM_INFO_ENUM

void require_setting(const std::string& name, const SettingInfo& info, double value) {
  const bool inf_allowed = (info.flags & VM_RANGE_INF_ALLOWED) != 0;
  const bool above = (info.flags & VM_RANGE_ABOVE_MIN) != 0;
  const bool finite = std::isfinite(value) || (inf_allowed && value == VM_INF);
  const bool in_range = (above ? value > info.min : value >= info.min) && value <= info.max;
  const bool integral = info.kind != SettingKind::kInteger || value == std::floor(value);
  if (finite && in_range && integral) return;
  std::ostringstream os;
  os << name << ": expected ";
  if (info.kind == SettingKind::kInteger) {
    os << "an integer ";
  } else if (!inf_allowed) {
    os << "a finite number ";
  }
  os << (above ? "> " : ">= ") << info.min;
  if (std::isfinite(info.max)) os << " and <= " << info.max;
  if (*info.unit) os << " [" << info.unit << "]";
  if (inf_allowed) os << " (inf: no limit)";
  os << ", got " << value;
  throw std::invalid_argument(os.str());
}

void check_settings(const ControllerSettings& s) {
  const auto& infos = controller_setting_infos();
  size_t row = 0;
#define VM_CHECK_VEC6(name, unit, doc) \
  ++row;                               \
  if (s.name) require_non_negative(#name, *s.name);
#define VM_CHECK_REAL(name, value, min, max, flags, unit, doc) \
  require_setting(#name, infos[row++], s.name);
#define VM_CHECK_INT(name, value, min, max, unit, doc) \
  require_setting(#name, infos[row++], static_cast<double>(s.name));
#define VM_CHECK_ENUM(name, Type, value, doc) \
  ++row;                                      \
  enum_from_int<Type>(#name, static_cast<long long>(s.name));
  VM_CONTROLLER_SETTINGS(VM_CHECK_VEC6, VM_CHECK_REAL, VM_CHECK_INT, VM_CHECK_ENUM)
#undef VM_CHECK_VEC6
#undef VM_CHECK_INT
#undef VM_CHECK_ENUM
}

void check_settings(const MechanismSetSettings& s) {
  const auto& infos = set_setting_infos();
  size_t row = 0;
  VM_SET_SETTINGS(VM_CHECK_REAL)
  if (!(s.release_distance >= s.snap_distance)) {
    std::ostringstream os;
    os << "release_distance: expected at least snap_distance = " << s.snap_distance
       << " m (the hysteresis), got " << s.release_distance;
    throw std::invalid_argument(os.str());
  }
}
#undef VM_CHECK_REAL

}  // namespace virtmech
