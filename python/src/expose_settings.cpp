// The settings (include/virtmech/settings_table.h): the enumerations with the names users
// write, ControllerSettings and MechanismSetSettings with one property per row, and the
// tables themselves (name, kind, default, range, unit, doc) for the scenario format and the
// documentation.
#include <nanobind/stl/optional.h>

#include <sstream>

#include "expose.hpp"

namespace vmpy {

const char* keep(std::string text);

namespace {

template <class E>
void def_enum(nb::module_& m, const char* name, const char* doc) {
  nb::enum_<E> e(m, name, doc);
  for (const EnumName& n : enum_names<E>()) e.value(n.name, static_cast<E>(n.value), n.doc);
}

// an enumeration's value from itself or from its name ("auto")
template <class E>
E enum_arg(const char* name, nb::handle v) {
  if (nb::isinstance<nb::str>(v)) return enum_from_name<E>(name, nb::cast<std::string>(v));
  if (nb::isinstance<E>(v)) return nb::cast<E>(v);
  throw nb::type_error((std::string(name) + ": expected one of the names of virtmech." +
                        nb::cast<std::string>(nb::type<E>().attr("__name__")) + ", got " +
                        nb::cast<std::string>(nb::repr(v))).c_str());
}

template <class T>
T number_arg(const char* name, nb::handle v) {
  if (PyBool_Check(v.ptr()) || !(std::is_integral_v<T> ? PyIndex_Check(v.ptr()) : PyNumber_Check(v.ptr()))) {
    throw nb::type_error((std::string(name) + ": expected " +
                          (std::is_integral_v<T> ? "an integer" : "a number") + ", got " +
                          nb::cast<std::string>(nb::repr(v))).c_str());
  }
  return nb::cast<T>(v);
}

// "doc [unit]"
const char* with_unit(const char* doc, const char* unit) {
  return keep(std::string(doc) + (*unit ? std::string(" [") + unit + "]" : ""));
}

nb::list infos_to_python(const std::vector<SettingInfo>& infos) {
  static const char* const kKinds[] = {"vector6", "number", "integer", "choice"};
  nb::list out;
  for (const SettingInfo& s : infos) {
    nb::dict d;
    d["name"] = s.name;
    d["kind"] = kKinds[static_cast<int>(s.kind)];
    nb::list choices;
    nb::object choice = nb::none();
    for (const EnumName& c : s.choices) {
      choices.append(c.name);
      if (c.value == static_cast<int>(s.default_value)) choice = nb::str(c.name);
    }
    d["choices"] = choices;
    d["default"] = s.kind == SettingKind::kVector6 ? nb::none()
                   : s.kind == SettingKind::kInteger ? nb::cast(static_cast<long>(s.default_value))
                   : s.kind == SettingKind::kChoice ? choice
                   : nb::cast(s.default_value);
    d["min"] = s.min;
    d["max"] = s.max;
    d["min_exclusive"] = (s.flags & VM_RANGE_ABOVE_MIN) != 0;
    d["inf_allowed"] = (s.flags & VM_RANGE_INF_ALLOWED) != 0;
    d["unit"] = s.unit;
    d["doc"] = s.doc;
    out.append(d);
  }
  return out;
}

}  // namespace

const char* keep(std::string text) {
  static std::vector<std::unique_ptr<std::string>> kept;  // for the life of the module
  kept.push_back(std::make_unique<std::string>(std::move(text)));
  return kept.back()->c_str();
}

SettingsDoc settings_doc(const std::vector<SettingInfo>& infos, const std::string& head,
                         const std::string& intro) {
  std::ostringstream sig, doc, units;
  sig.precision(15);
  sig << "def __init__(" << head << ", *";
  doc << intro << "\n";
  units << "Units:";
  for (const SettingInfo& s : infos) {
    sig << ", " << s.name << ": ";
    if (s.kind == SettingKind::kVector6) {
      sig << "collections.abc.Sequence[float] | None = None";
    } else if (s.kind == SettingKind::kChoice) {
      for (const EnumName& c : s.choices)
        if (c.value == static_cast<int>(s.default_value)) sig << "str = '" << c.name << "'";
    } else {
      sig << (s.kind == SettingKind::kInteger ? "int = " : "float = ") << s.default_value;
    }
    // "name: doc [unit]; the rest": the unit after the doc's first clause
    std::string line = std::string(s.doc);
    if (*s.unit) {
      const size_t semi = line.find(';');
      const std::string u = std::string(" [") + s.unit + "]";
      line = semi == std::string::npos ? line + u : line.substr(0, semi) + u + line.substr(semi);
      units << (units.tellp() > 6 ? ", " : " ") << s.name << " [" << s.unit << "]";
    }
    if (s.kind == SettingKind::kChoice) {
      line += " (";
      for (size_t i = 0; i < s.choices.size(); ++i) line += (i ? " | '" : "'") + std::string(s.choices[i].name) + "'";
      line += ")";
    }
    doc << "\n" << s.name << ": " << line << ".";
  }
  sig << ") -> None";
  units << ".";
  return {keep(sig.str()), keep(doc.str() + "\n\n" + units.str())};
}

void expose_settings(nb::module_& m) {
  def_enum<ControlLaw>(m, "ControlLaw", "Which control law the cycle evaluates.");
  def_enum<ErrorVelocity>(m, "ErrorVelocity", "How the error velocity is formed.");
  def_enum<Passivity>(m, "Passivity", "Whether the cycle keeps the rendering passive.");

  nb::class_<ControllerSettings> cs(
      m, "ControllerSettings",
      "The controller's settings, one property per row of CONTROLLER_SETTINGS (units, "
      "defaults, ranges); the keywords of Controller(device, mechanism, **settings).");
  cs.def(nb::init<>());
#define VM_PY_VEC6(name, unit, doc)                                                        \
  cs.def_prop_rw(#name, [](const ControllerSettings& s) { return s.name; },                \
                 [](ControllerSettings& s, nb::handle v) {                                 \
                   s.name = v.is_none() ? std::nullopt                                      \
                                        : std::optional<Vector6>(vector_arg(#name, v, 6)); \
                 }, with_unit(doc, unit));
#define VM_PY_REAL(name, value, min, max, flags, unit, doc)                                  \
  cs.def_prop_rw(#name, [](const ControllerSettings& s) { return s.name; },                  \
                 [](ControllerSettings& s, nb::handle v) { s.name = number_arg<double>(#name, v); }, \
                 with_unit(doc, unit));
#define VM_PY_INT(name, value, min, max, unit, doc)                                      \
  cs.def_prop_rw(#name, [](const ControllerSettings& s) { return s.name; },              \
                 [](ControllerSettings& s, nb::handle v) { s.name = number_arg<int>(#name, v); }, \
                 doc);
#define VM_PY_ENUM(name, Type, value, doc)                                                    \
  cs.def_prop_rw(#name, [](const ControllerSettings& s) { return s.name; },                   \
                 [](ControllerSettings& s, nb::handle v) { s.name = enum_arg<Type>(#name, v); }, \
                 doc);
  VM_CONTROLLER_SETTINGS(VM_PY_VEC6, VM_PY_REAL, VM_PY_INT, VM_PY_ENUM)
#undef VM_PY_VEC6
#undef VM_PY_REAL
#undef VM_PY_INT
#undef VM_PY_ENUM

  nb::class_<MechanismSetSettings> ss(
      m, "MechanismSetSettings",
      "A mechanism set's settings, one property per row of SET_SETTINGS; the keywords of "
      "MechanismSet(device, capacity, **settings).");
  ss.def(nb::init<>());
#define VM_PY_REAL(name, value, min, max, flags, unit, doc)                                    \
  ss.def_prop_rw(#name, [](const MechanismSetSettings& s) { return s.name; },                  \
                 [](MechanismSetSettings& s, nb::handle v) { s.name = number_arg<double>(#name, v); }, \
                 with_unit(doc, unit));
  VM_SET_SETTINGS(VM_PY_REAL)
#undef VM_PY_REAL

  m.attr("CONTROLLER_SETTINGS") = infos_to_python(controller_setting_infos());
  m.attr("SET_SETTINGS") = infos_to_python(set_setting_infos());
  nb::dict defaults;  // every setting's default (the 6-vectors': derived, so absent)
  for (nb::handle row : nb::borrow<nb::list>(m.attr("CONTROLLER_SETTINGS"))) {
    if (!row["default"].is_none()) defaults[row["name"]] = row["default"];
  }
  m.attr("CONTROLLER_DEFAULTS") = defaults;
}

}  // namespace vmpy
