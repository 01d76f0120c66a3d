// Conversions between Python and the core (convert.hpp).
#include "convert.hpp"

#include <nanobind/ndarray.h>

#include <cmath>

namespace vmpy {

using namespace nb::literals;

namespace {

std::string short_repr(nb::handle h) {
  std::string s = nb::cast<std::string>(nb::repr(h));
  return s.size() > 80 ? s.substr(0, 77) + "..." : s;
}

std::string shape_text(const std::vector<long>& shape, const char* axes = "nmk") {
  std::string out = "(";
  for (size_t i = 0, unknown = 0; i < shape.size(); ++i) {
    out += i ? ", " : "";
    out += shape[i] >= 0 ? std::to_string(shape[i]) : std::string(1, axes[unknown++ % std::char_traits<char>::length(axes)]);
  }
  return out + (shape.size() == 1 ? ",)" : ")");
}

}  // namespace

Array array_arg(const std::string& name, nb::handle obj, const std::vector<long>& shape,
                const char* axes) {
  static nb::object* asarray =  // leaked on purpose: must outlive the interpreter's finalisation
      new nb::object(nb::module_::import_("numpy").attr("ascontiguousarray"));
  const std::string expected = "an array of shape " + shape_text(shape, axes);
  nb::object a;
  try {
    if (obj.is_none()) throw nb::python_error();
    a = (*asarray)(obj, "dtype"_a = "float64");
  } catch (nb::python_error&) {
    throw nb::type_error((name + ": expected " + expected + ", got " + short_repr(obj)).c_str());
  }
  auto arr = nb::cast<nb::ndarray<const double, nb::c_contig, nb::device::cpu>>(a);
  Array out;
  for (size_t i = 0; i < arr.ndim(); ++i) out.shape.push_back(static_cast<long>(arr.shape(i)));
  bool ok = out.shape.size() == shape.size();
  for (size_t i = 0; ok && i < shape.size(); ++i) ok = shape[i] < 0 || shape[i] == out.shape[i];
  if (!ok) {
    throw nb::value_error((name + ": expected " + expected + ", got shape " +
                           shape_text(out.shape) + " (" + short_repr(obj) + ")").c_str());
  }
  out.data.assign(arr.data(), arr.data() + arr.size());
  return out;
}

Eigen::VectorXd vector_arg(const std::string& name, nb::handle obj, long n) {
  const Array a = array_arg(name, obj, {n});
  return Eigen::Map<const Eigen::VectorXd>(a.data.data(), a.shape[0]);
}

Eigen::MatrixXd matrix_arg(const std::string& name, nb::handle obj, long rows, long cols) {
  const Array a = array_arg(name, obj, {rows, cols});
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  return Eigen::Map<const RowMajor>(a.data.data(), a.shape[0], a.shape[1]);
}

Pose pose_arg(const std::string& name, nb::handle obj) {
  Pose T = Pose::Identity();
  if (obj.is_none()) return T;
  T.matrix() = matrix_arg(name, obj, 4, 4);
  require_pose(name, T);
  return T;
}

// A float64 buffer of n doubles read in place: NumPy says the type through dtype.num
// (12: float64) without building a format string anew on every request.
OutArray::OutArray(const char* name, nb::handle obj, int n) {
  static PyObject* const kDtype = PyUnicode_InternFromString("dtype");  // made once
  static PyObject* const kNum = PyUnicode_InternFromString("num");
  int numpy_type = -1;
  if (PyObject* dt = PyObject_GetAttr(obj.ptr(), kDtype)) {
    if (PyObject* num = PyObject_GetAttr(dt, kNum)) {
      numpy_type = static_cast<int>(PyLong_AsLong(num));
      Py_DECREF(num);
    }
    Py_DECREF(dt);
  }
  PyErr_Clear();
  const bool writable = name != nullptr;
  if (PyObject_CheckBuffer(obj.ptr()) &&
      PyObject_GetBuffer(obj.ptr(), &view_, PyBUF_C_CONTIGUOUS | (writable ? PyBUF_WRITABLE : 0) |
                                                (numpy_type < 0 ? PyBUF_FORMAT : 0)) == 0) {
    const bool is_double = numpy_type >= 0 ? numpy_type == 12
                                           : view_.format && std::string(view_.format) == "d";
    ok_ = is_double && view_.ndim == 1 && view_.shape[0] == n && view_.itemsize == 8;
  }
  PyErr_Clear();
  if (!ok_ && writable) {
    throw nb::type_error((std::string(name) + ": expected a writable, contiguous float64 array "
                          "of shape (" + std::to_string(n) + ",), got " + short_repr(obj)).c_str());
  }
}

OutArray::~OutArray() {
  if (view_.obj) PyBuffer_Release(&view_);
}

JointVector joints_arg(const char* name, nb::handle obj, int n) {
  const OutArray in(nullptr, obj, n);
  if (in.data()) return Eigen::Map<const JointVector>(in.data(), n);
  return vector_arg(name, obj, n);
}

namespace {

ParamValue value_from(const ParamSpec& s, nb::handle v, const std::string& name);

Params table_from(const std::vector<ParamSpec>& specs, nb::handle obj, const std::string& where) {
  if (!nb::isinstance<nb::dict>(obj)) {
    throw nb::type_error((where + ": expected a table (a dict), got " + short_repr(obj)).c_str());
  }
  return params_from(specs, nb::borrow<nb::dict>(obj), where);
}

// a shape parameter: the object, or its table described by its kind's parameters
template <class Shape, class K>
ParamValue shape_from(nb::handle v, const std::string& name,
                      const K* (Registry::*find)(const std::string&) const, const char* what) {
  if (nb::isinstance<Shape>(v)) return nb::cast<std::shared_ptr<const Shape>>(v);
  if (nb::isinstance<nb::dict>(v)) {
    return std::vector<Params>{kind_table(find, nb::borrow<nb::dict>(v), name)};  // made later
  }
  throw nb::type_error((name + ": expected a " + what + " (a virtmech." + what +
                        " or a dict with its type), got " + short_repr(v)).c_str());
}

ParamValue value_from(const ParamSpec& s, nb::handle v, const std::string& name) {
  switch (s.kind) {
    case ParamKind::kNumber:
      if (PyBool_Check(v.ptr()) || !PyNumber_Check(v.ptr())) {
        throw nb::type_error((name + ": expected a number, got " + short_repr(v)).c_str());
      }
      return nb::cast<double>(v);
    case ParamKind::kInteger:
      if (PyBool_Check(v.ptr()) || !PyIndex_Check(v.ptr())) {
        throw nb::type_error((name + ": expected an integer, got " + short_repr(v)).c_str());
      }
      return nb::cast<long long>(v.attr("__index__")());
    case ParamKind::kBool:
      return nb::cast<bool>(v);
    case ParamKind::kString:
      return nb::cast<std::string>(v);
    case ParamKind::kArray:
      return array_arg(name, v, s.shape);
    case ParamKind::kBools: {
      std::vector<bool> out;
      for (nb::handle b : v) out.push_back(nb::cast<bool>(b));
      return out;
    }
    case ParamKind::kCurve:
      return shape_from<Curve, CurveKind>(v, name, &Registry::curve, "Curve");
    case ParamKind::kSurface:
      return shape_from<Surface, SurfaceKind>(v, name, &Registry::surface, "Surface");
    case ParamKind::kTables: {
      std::vector<Params> out;
      size_t i = 0;
      for (nb::handle t : v) out.push_back(table_from(s.fields, t, name + "[" + std::to_string(i++) + "]"));
      return out;
    }
  }
  return {};
}

}  // namespace

Params params_from(const std::vector<ParamSpec>& specs, nb::args args, nb::kwargs kwargs,
                   const std::string& kind) {
  if (args.size() > specs.size()) {
    throw nb::type_error((kind + "() takes at most " + std::to_string(specs.size()) +
                          " positional arguments, got " + std::to_string(args.size())).c_str());
  }
  Params p;
  for (size_t i = 0; i < specs.size(); ++i) {
    const ParamSpec& s = specs[i];
    nb::handle v;
    if (i < args.size()) v = args[i];
    if (kwargs.contains(s.name.c_str())) {
      if (v.is_valid()) {
        throw nb::type_error((kind + "() got multiple values for argument '" + s.name + "'").c_str());
      }
      v = kwargs[s.name.c_str()];
    }
    if (v.is_valid() && !v.is_none()) {
      p.set(s.name, value_from(s, v, s.name));
    } else if (s.required) {
      throw nb::type_error((s.name + ": expected " + s.doc + ", got " +
                            (v.is_valid() ? "None" : "nothing (a required argument of " + kind + ")")).c_str());
    }
  }
  for (auto [key, value] : kwargs) {
    const std::string k = nb::cast<std::string>(key);
    bool known = false;
    for (const ParamSpec& s : specs) known = known || s.name == k;
    if (!known) {
      std::string names;
      for (const ParamSpec& s : specs) names += (names.empty() ? "" : ", ") + s.name;
      throw nb::type_error((kind + "() got an unexpected keyword argument '" + k +
                            "'; expected one of " + names).c_str());
    }
  }
  return p;
}

Params params_from(const std::vector<ParamSpec>& specs, nb::dict table, const std::string& where) {
  Params p;
  for (auto [key, value] : table) {
    const std::string k = nb::cast<std::string>(key);
    const std::string at = where.empty() ? k : where + "." + k;
    const ParamSpec* spec = nullptr;
    for (const ParamSpec& s : specs) spec = s.name == k ? &s : spec;
    if (k == "type") {
      p.set(k, nb::cast<std::string>(nb::str(value)));
    } else if (!spec) {
      p.set(k, std::string());  // complete() names it, with the known ones
    } else if (!value.is_none()) {
      p.set(k, value_from(*spec, value, at));
    }
  }
  return p;
}

nb::object to_python(const ParamValue& value, bool lists) {
  return std::visit(
      [lists](const auto& v) -> nb::object {
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, std::monostate>) {
          return nb::none();
        } else if constexpr (std::is_same_v<T, Array>) {
          std::vector<size_t> shape(v.shape.begin(), v.shape.end());
          nb::object a = nb::cast(nb::ndarray<nb::numpy, const double>(
                                      v.data.data(), shape.size(), shape.data()))
                             .attr("copy")();
          return lists ? a.attr("tolist")() : a;
        } else if constexpr (std::is_same_v<T, std::shared_ptr<const Curve>> ||
                             std::is_same_v<T, std::shared_ptr<const Surface>>) {
          return lists ? nb::object(to_python(describe(*v), true)) : nb::cast(v);
        } else if constexpr (std::is_same_v<T, std::vector<Params>>) {
          nb::list out;
          for (const Params& p : v) out.append(to_python(p, lists));
          return out;
        } else {
          return nb::cast(v);
        }
      },
      value);
}

nb::dict to_python(const Params& params, bool lists) {
  nb::dict d;
  for (size_t i = 0; i < params.names().size(); ++i) {
    d[params.names()[i].c_str()] = to_python(params.values()[i], lists);
  }
  return d;
}

nb::list describe_specs(const std::vector<ParamSpec>& specs) {
  static const char* const kKinds[] = {"number", "integer", "bool",  "string", "array",
                                       "bools",  "curve",   "surface", "tables"};
  nb::list out;
  for (const ParamSpec& s : specs) {
    nb::dict d;
    d["name"] = s.name;
    d["kind"] = kKinds[static_cast<int>(s.kind)];
    d["shape"] = nb::tuple(nb::cast(s.shape));
    d["required"] = s.required;
    if (s.default_value) d["default"] = to_python(*s.default_value, true);
    d["min"] = s.min;
    d["max"] = s.max;
    d["min_exclusive"] = s.min_exclusive;
    d["nonzero"] = s.nonzero;
    d["choices"] = s.choices;
    d["unit"] = s.unit;
    d["doc"] = s.doc;
    d["fields"] = describe_specs(s.fields);
    out.append(d);
  }
  return out;
}

nb::list status_names(std::uint32_t s) {
  nb::list l;
  for (const auto& [bit, name] : status::kNames)
    if (s & bit) l.append(name);
  return l;
}

}  // namespace vmpy
