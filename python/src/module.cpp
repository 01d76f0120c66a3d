// virtmech._core: the core's Python bindings, translation only (one file per concept:
// expose_*.cpp; conversions: convert.cpp). Every rule, default and description lives in
// the C++ core.
#include <cctype>

#include "expose.hpp"

NB_MODULE(_core, m) {
  using namespace vmpy;
  m.doc() = "virtmech core (C++): devices, virtual mechanisms and the controller cycle.";
  m.attr("__version__") = VIRTMECH_VERSION_STRING;
  m.attr("MAX_DOF") = kMaxDof;
  // status bits (re-exported by virtmech.status)
  m.attr("STATUS_OK") = status::kOk;
  m.attr("STATUS_FAULT_MASK") = status::kFaultMask;
  for (const auto& [bit, name] : status::kNames) {
    std::string attr = std::string("STATUS_") + name;
    for (char& c : attr) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    m.attr(attr.c_str()) = bit;
  }
  m.def("status_names", &status_names, nb::arg("status"), "Names of the bits set in a status word.");
  expose_math(m);
  expose_settings(m);
  expose_geometry(m);
  expose_mechanisms(m);
  expose_devices(m);
  expose_controller(m);
  expose_registry(m);
}
