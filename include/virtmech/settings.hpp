// The settings' vocabulary, generated from include/virtmech/settings_table.h: the
// enumerations a setting chooses from (with the names users write, "auto", "energy_tank",
// ...), and a description of every setting (name, kind, default, range, unit, doc) that
// the checks, the bindings, the scenario format and the documentation read.
#pragma once

#include <iterator>
#include <string>
#include <vector>

#include "virtmech/settings_table.h"

namespace virtmech {

#define VM_ENUMERATOR(cpp, c, value, name, doc) cpp = value,
/// Which control law the cycle evaluates (values: VM_CONTROL_LAWS).
enum class ControlLaw : int { VM_CONTROL_LAWS(VM_ENUMERATOR) };
/// How the error velocity is formed from the joint velocities (VM_ERROR_VELOCITIES).
enum class ErrorVelocity : int { VM_ERROR_VELOCITIES(VM_ENUMERATOR) };
/// Whether the cycle keeps the rendering passive (docs/theory.md, "Passivity";
/// VM_PASSIVITIES).
enum class Passivity : int { VM_PASSIVITIES(VM_ENUMERATOR) };
#undef VM_ENUMERATOR

/// One value of an enumeration: its integer, the name users write and what it means.
struct EnumName {
  int value;
  const char* name;
  const char* doc;
};

/// The names of an enumeration's values (specialised for each enumeration above).
template <class E>
struct EnumNames;

#define VM_ENUM_NAME(cpp, c, value, name, doc) {value, name, doc},
template <>
struct EnumNames<ControlLaw> {
  static constexpr EnumName kValues[] = {VM_CONTROL_LAWS(VM_ENUM_NAME)};
};
template <>
struct EnumNames<ErrorVelocity> {
  static constexpr EnumName kValues[] = {VM_ERROR_VELOCITIES(VM_ENUM_NAME)};
};
template <>
struct EnumNames<Passivity> {
  static constexpr EnumName kValues[] = {VM_PASSIVITIES(VM_ENUM_NAME)};
};
#undef VM_ENUM_NAME

/// The values of enumeration E as a list (name, integer, doc).
template <class E>
std::vector<EnumName> enum_names() {
  return {std::begin(EnumNames<E>::kValues), std::end(EnumNames<E>::kValues)};
}

/// The name users write for a value ("auto", "energy_tank", ...).
template <class E>
const char* name_of(E e) noexcept {
  for (const EnumName& n : EnumNames<E>::kValues)
    if (n.value == static_cast<int>(e)) return n.name;
  return "?";
}

namespace detail {
[[noreturn]] void throw_bad_name(const std::string& param, const std::vector<EnumName>& names,
                                 const std::string& got);
[[noreturn]] void throw_bad_value(const std::string& param, const std::vector<EnumName>& names,
                                  long long got);
}  // namespace detail

/// The value named `name`; std::invalid_argument naming `param` and the names otherwise.
template <class E>
E enum_from_name(const std::string& param, const std::string& name) {
  for (const EnumName& n : EnumNames<E>::kValues)
    if (name == n.name) return static_cast<E>(n.value);
  detail::throw_bad_name(param, enum_names<E>(), name);
}

/// The value whose integer is `value`, checked as an integer before any conversion (a C
/// caller's int); std::invalid_argument naming `param` and the values otherwise.
template <class E>
E enum_from_int(const std::string& param, long long value) {
  for (const EnumName& n : EnumNames<E>::kValues)
    if (value == n.value) return static_cast<E>(n.value);
  detail::throw_bad_value(param, enum_names<E>(), value);
}

/// What a setting holds.
enum class SettingKind : int {
  kVector6 = 0,  //!< an optional 6-vector of values >= 0 (unset: derived)
  kReal = 1,     //!< a number in a range
  kInteger = 2,  //!< an integer in a range
  kChoice = 3,   //!< one of an enumeration's names
};

/// One setting, as its table row says: the checks, the bindings, the scenario format and
/// the documentation are made from these.
struct SettingInfo {
  const char* name;
  SettingKind kind;
  double default_value;  //!< kReal, kInteger; kChoice: the value's integer; kVector6: unused
  double min, max;       //!< the range (kReal, kInteger); max may be +inf
  int flags;             //!< VM_RANGE_* (kReal)
  const char* unit;      //!< "" where none
  const char* doc;
  std::vector<EnumName> choices;  //!< kChoice: the enumeration's values
};

/// The controller's settings (ControllerSettings), in the table's order.
const std::vector<SettingInfo>& controller_setting_infos();
/// A mechanism set's settings (MechanismSetSettings), in the table's order.
const std::vector<SettingInfo>& set_setting_infos();

/// Requires `value` within `info`'s range (a kReal or kInteger setting); throws
/// std::invalid_argument naming `name` (e.g. "settings.period_s"), the range and the value.
void require_setting(const std::string& name, const SettingInfo& info, double value);

}  // namespace virtmech
