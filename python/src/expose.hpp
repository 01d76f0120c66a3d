// The module's parts, one per concept (as Pinocchio's expose-*.cpp): each binds its classes
// and functions; module.cpp calls them in order (a base class before its subclasses).
#pragma once

#include "convert.hpp"

namespace vmpy {

void expose_math(nb::module_& m);         // pose errors, rotations, filters, placement
void expose_settings(nb::module_& m);     // enumerations, ControllerSettings, tables
void expose_geometry(nb::module_& m);     // curves and surfaces
void expose_mechanisms(nb::module_& m);   // joints and mechanisms
void expose_devices(nb::module_& m);      // devices
void expose_controller(nb::module_& m);   // Controller, MechanismSet and their outputs
void expose_registry(nb::module_& m);     // kinds, describe, distances, plugins

/// A constructor's signature and docstring taking a settings table's rows as keywords
/// (`head`: the parameters before them; `intro`: the first paragraph), kept for the module's
/// life.
struct SettingsDoc {
  const char* signature;
  const char* doc;
};
SettingsDoc settings_doc(const std::vector<SettingInfo>& infos, const std::string& head,
                         const std::string& intro);

/// `made`, once its kind has rebuilt it from its description (make_device / make_mechanism):
/// a constructor that is not its kind's (Device, SerialChain, Planar3R) refuses what the kind
/// refuses (its ranges, one source), and what it makes is what run.json's table rebuilds.
template <class T>
T rebuildable(T made) {
  if constexpr (std::is_base_of_v<Device, T>) {
    make_device(describe(made), "");
  } else {
    make_mechanism(describe(made), "");
  }
  return made;
}

/// Binds the constructor and the parameter properties of a registered kind's class: its
/// parameters in the kind's order (positional or keywords), made by the kind's factory.
template <class T, class Cls, class Make>
void def_kind(Cls& cls, const std::vector<ParamSpec>& params, const std::string& kind, Make make) {
  cls.def(nb::new_([params, kind, make](nb::args args, nb::kwargs kwargs) {
            std::shared_ptr<const T> made = std::dynamic_pointer_cast<const T>(
                make(params_from(params, args, kwargs, kind)));
            if (!made) throw nb::type_error((kind + "(): the parameters make another class").c_str());
            return std::const_pointer_cast<T>(made);
          }),
          ("(*args, **kwargs): " + kind + "(" + [&] {
            std::string s;
            for (const ParamSpec& p : params) s += (s.empty() ? "" : ", ") + p.name;
            return s;
          }() + ")").c_str());
  for (const ParamSpec& p : params) {
    if (nb::hasattr(cls, p.name.c_str())) continue;  // the base's (a Plane's normal(u, v))
    const std::string name = p.name;
    cls.def_prop_ro(name.c_str(), [name](nb::handle self) {
      return to_python(describe(*nb::inst_ptr<T>(self)).get(name), false);
    }, (p.doc + (p.unit.empty() ? "" : " [" + p.unit + "]")).c_str());
  }
}

}  // namespace vmpy
