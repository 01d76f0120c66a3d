// What the bindings share: Python values to the core's (arrays of a shape, a kind's
// parameters) with errors that name the parameter, and the core's Params back to Python.
#pragma once

#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <string>
#include <vector>

#include "virtmech/registry.hpp"
#include "virtmech/validate.hpp"
#include "virtmech/virtmech.hpp"

namespace vmpy {

namespace nb = nanobind;
using namespace virtmech;

/// `obj` as numbers of `shape` (-1: any size on that axis, named by the next letter of
/// `axes` in messages): TypeError naming `name` for a value that is not numbers, ValueError
/// for another shape.
Array array_arg(const std::string& name, nb::handle obj, const std::vector<long>& shape,
                const char* axes = "nmk");
Eigen::VectorXd vector_arg(const std::string& name, nb::handle obj, long n = -1);
Eigen::MatrixXd matrix_arg(const std::string& name, nb::handle obj, long rows, long cols);
/// A (4, 4) rigid transform (identity for None).
Pose pose_arg(const std::string& name, nb::handle obj);

/// Joint values of a chain of n joints: a float64 array read in place (no object made per
/// call), anything else converted as vector_arg.
JointVector joints_arg(const char* name, nb::handle obj, int n);
/// A writable float64 array of n entries to fill in place, or nullptr; TypeError naming
/// `name` for anything else.
class OutArray {
 public:
  OutArray(const char* name, nb::handle obj, int n);
  ~OutArray();
  OutArray(const OutArray&) = delete;
  OutArray& operator=(const OutArray&) = delete;
  double* data() const { return ok_ ? static_cast<double*>(view_.buf) : nullptr; }

 private:
  Py_buffer view_{};
  bool ok_ = false;
};

/// A kind's parameters from Python: positional arguments in the kind's order, then
/// keywords (None: not given); TypeError for an unknown or repeated name.
Params params_from(const std::vector<ParamSpec>& specs, nb::args args, nb::kwargs kwargs,
                   const std::string& kind);
/// A kind's parameters from a dict (a scenario table; its "type" kept).
Params params_from(const std::vector<ParamSpec>& specs, nb::dict table, const std::string& where);
/// A table naming its kind ("type"): its parameters by that kind's (`find` looks it up), or
/// the type alone for an unknown kind (whose factory then lists the known ones).
template <class K>
Params kind_table(const K* (Registry::*find)(const std::string&) const, nb::dict table,
                  const std::string& where) {
  const std::string type = table.contains("type") ? nb::cast<std::string>(nb::str(table["type"])) : "";
  const K* kind = (registry().*find)(type);
  return kind ? params_from(kind->params, table, where) : Params(type);
}

/// A value to Python: arrays as NumPy arrays or, with lists, nested lists; shapes as the
/// objects or, with lists, their described dicts; tables as dicts.
nb::object to_python(const ParamValue& value, bool lists);
nb::dict to_python(const Params& params, bool lists = true);

/// The parameters' description for Python (name, kind, shape, default, required, range,
/// unit, doc, choices, fields).
nb::list describe_specs(const std::vector<ParamSpec>& specs);

/// The names of a status word's bits (virtmech::status::kNames).
nb::list status_names(std::uint32_t status);

}  // namespace vmpy
