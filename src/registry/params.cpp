// Parameter descriptions and values (include/virtmech/params.hpp).
#include "virtmech/params.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "virtmech/registry.hpp"
#include "virtmech/se3.hpp"
#include "virtmech/validate.hpp"

namespace virtmech {

namespace {

template <class T>
std::shared_ptr<const ParamValue> value_of(T v) {
  return std::make_shared<const ParamValue>(std::move(v));
}

ParamSpec spec(std::string name, ParamKind kind, std::string unit, std::string doc) {
  ParamSpec s;
  s.name = std::move(name);
  s.kind = kind;
  s.unit = std::move(unit);
  s.doc = std::move(doc);
  return s;
}

std::string shape_text(const std::vector<long>& shape) {
  static const char* const kAxes[] = {"n", "m", "k"};
  std::string out = "(";
  for (size_t i = 0; i < shape.size(); ++i) {
    out += i ? ", " : "";
    out += shape[i] >= 0 ? std::to_string(shape[i]) : std::string(kAxes[std::min<size_t>(i, 2)]);
  }
  return out + (shape.size() == 1 ? ",)" : ")");
}

std::string number_text(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

// "a number > 0 and <= 10 [m]"
std::string range_text(const ParamSpec& s, const char* what) {
  std::string out = what;
  if (std::isfinite(s.min)) out += (s.min_exclusive ? " > " : " >= ") + number_text(s.min);
  if (std::isfinite(s.max)) out += (std::isfinite(s.min) ? " and <= " : " <= ") + number_text(s.max);
  if (!s.unit.empty()) out += " [" + s.unit + "]";
  return out;
}

bool in_range(const ParamSpec& s, double v) {
  return std::isfinite(v) && (s.min_exclusive ? v > s.min : v >= s.min) && v <= s.max;
}

[[noreturn]] void wrong_kind(const std::string& where, const char* expected) {
  throw std::invalid_argument(where + ": expected " + expected);
}

ParamValue checked(const ParamSpec& s, const ParamValue& v, const std::string& where);

Params checked_table(const std::vector<ParamSpec>& specs, const Params& given,
                     const std::string& where) {
  return complete(specs, given, where);
}

ParamValue checked_shape(const ParamSpec& s, const ParamValue& v, const std::string& where) {
  const bool surface = s.kind == ParamKind::kSurface;
  if (surface && std::holds_alternative<std::shared_ptr<const Surface>>(v) &&
      std::get<std::shared_ptr<const Surface>>(v)) {
    return v;
  }
  if (!surface && std::holds_alternative<std::shared_ptr<const Curve>>(v) &&
      std::get<std::shared_ptr<const Curve>>(v)) {
    return v;
  }
  if (const auto* t = std::get_if<std::vector<Params>>(&v); t && t->size() == 1) {
    if (surface) return make_surface(t->front(), where);
    return make_curve(t->front(), where);
  }
  wrong_kind(where, surface ? "a surface (a Surface, or a table with its type)"
                            : "a curve (a Curve, or a table with its type)");
}

ParamValue checked_array(const ParamSpec& s, const ParamValue& v, const std::string& where) {
  const auto* a = std::get_if<Array>(&v);
  if (!a) wrong_kind(where, ("an array of shape " + shape_text(s.shape)).c_str());
  bool ok = a->shape.size() == s.shape.size();
  for (size_t i = 0; ok && i < s.shape.size(); ++i) ok = s.shape[i] < 0 || a->shape[i] == s.shape[i];
  if (!ok) {
    throw std::invalid_argument(where + ": expected an array of shape " + shape_text(s.shape) +
                                ", got shape " + shape_text(a->shape));
  }
  for (double x : a->data) {
    if (!in_range(s, x)) {
      throw std::invalid_argument(where + ": expected " + range_text(s, "numbers") + ", got " +
                                  number_text(x));
    }
  }
  if (s.nonzero) {
    double sq = 0.0;
    for (double x : a->data) sq += x * x;
    if (!(std::sqrt(sq) >= 1e-9)) {
      throw std::invalid_argument(where + ": expected a non-zero vector (a direction), got " +
                                  format_vector(Eigen::Map<const Eigen::VectorXd>(
                                      a->data.data(), static_cast<Eigen::Index>(a->data.size()))));
    }
  }
  return v;
}

ParamValue checked_number(const ParamSpec& s, const ParamValue& v, const std::string& where) {
  double x = 0.0;
  if (const auto* d = std::get_if<double>(&v)) {
    x = *d;
  } else if (const auto* i = std::get_if<long long>(&v)) {
    x = static_cast<double>(*i);
  } else {
    wrong_kind(where, range_text(s, "a number").c_str());
  }
  if (!in_range(s, x)) {
    throw std::invalid_argument(where + ": expected " + range_text(s, "a number") + ", got " +
                                number_text(x));
  }
  return x;
}

ParamValue checked_integer(const ParamSpec& s, const ParamValue& v, const std::string& where) {
  const auto* i = std::get_if<long long>(&v);
  if (!i) wrong_kind(where, range_text(s, "an integer").c_str());
  if (!in_range(s, static_cast<double>(*i))) {
    throw std::invalid_argument(where + ": expected " + range_text(s, "an integer") + ", got " +
                                std::to_string(*i));
  }
  return v;
}

ParamValue checked_string(const ParamSpec& s, const ParamValue& v, const std::string& where) {
  const auto* t = std::get_if<std::string>(&v);
  if (!t) wrong_kind(where, "a string");
  if (s.choices.empty()) return v;
  bool known = false;
  std::string list;  // "'a', 'b' or 'c'"
  for (size_t i = 0; i < s.choices.size(); ++i) {
    known = known || *t == s.choices[i];
    list += (i ? (i + 1 == s.choices.size() ? " or '" : ", '") : "'") + s.choices[i] + "'";
  }
  if (!known) throw std::invalid_argument(where + ": expected " + list + ", got '" + *t + "'");
  return v;
}

ParamValue checked_bools(const ParamSpec& s, const ParamValue& v, const std::string& where) {
  const auto* b = std::get_if<std::vector<bool>>(&v);
  if (!b) wrong_kind(where, "a list of true or false");
  const long n = s.shape.empty() ? -1 : s.shape[0];
  if (n >= 0 && static_cast<long>(b->size()) != n) {
    throw std::invalid_argument(where + ": expected " + std::to_string(n) +
                                " values true or false, got " + std::to_string(b->size()));
  }
  return v;
}

ParamValue checked_tables(const ParamSpec& s, const ParamValue& v, const std::string& where) {
  const auto* t = std::get_if<std::vector<Params>>(&v);
  if (!t) wrong_kind(where, "an array of tables");
  std::vector<Params> out;
  for (size_t i = 0; i < t->size(); ++i) {
    out.push_back(checked_table(s.fields, (*t)[i], where + "[" + std::to_string(i) + "]"));
  }
  return out;
}

ParamValue checked(const ParamSpec& s, const ParamValue& v, const std::string& where) {
  switch (s.kind) {
    case ParamKind::kNumber:
      return checked_number(s, v, where);
    case ParamKind::kInteger:
      return checked_integer(s, v, where);
    case ParamKind::kBool:
      if (!std::holds_alternative<bool>(v)) wrong_kind(where, "true or false");
      return v;
    case ParamKind::kString:
      return checked_string(s, v, where);
    case ParamKind::kArray:
      return checked_array(s, v, where);
    case ParamKind::kBools:
      return checked_bools(s, v, where);
    case ParamKind::kCurve:
    case ParamKind::kSurface:
      return checked_shape(s, v, where);
    case ParamKind::kTables:
      return checked_tables(s, v, where);
  }
  return v;
}

std::string joined(const std::string& where, const std::string& name) {
  return where.empty() ? name : where + "." + name;
}

}  // namespace

// ---- builders --------------------------------------------------------------------------

ParamSpec number_param(std::string name, std::optional<double> value, double min, double max,
                       std::string unit, std::string doc, bool min_exclusive) {
  ParamSpec s = spec(std::move(name), ParamKind::kNumber, std::move(unit), std::move(doc));
  if (value) s.default_value = value_of(*value);
  s.required = !value;
  s.min = min;
  s.max = max;
  s.min_exclusive = min_exclusive;
  return s;
}

ParamSpec integer_param(std::string name, std::optional<long long> value, long long min,
                        long long max, std::string doc) {
  ParamSpec s = spec(std::move(name), ParamKind::kInteger, "", std::move(doc));
  if (value) s.default_value = value_of(*value);
  s.required = !value;
  s.min = static_cast<double>(min);
  s.max = static_cast<double>(max);
  return s;
}

ParamSpec bool_param(std::string name, bool value, std::string doc) {
  ParamSpec s = spec(std::move(name), ParamKind::kBool, "", std::move(doc));
  s.default_value = value_of(value);
  return s;
}

ParamSpec array_param(std::string name, std::vector<long> shape,
                      std::optional<std::vector<double>> value, std::string unit,
                      std::string doc) {
  ParamSpec s = spec(std::move(name), ParamKind::kArray, std::move(unit), std::move(doc));
  s.shape = shape;
  if (value) {
    std::vector<long> vshape = shape;
    if (vshape.size() == 1 && vshape[0] < 0) vshape[0] = static_cast<long>(value->size());
    s.default_value = value_of(Array{vshape, *value});
  }
  s.required = !value;
  return s;
}

ParamSpec direction_param(std::string name, std::optional<Eigen::Vector3d> value,
                          std::string doc) {
  ParamSpec s = array_param(std::move(name), {3},
                            value ? std::optional<std::vector<double>>(
                                        std::vector<double>{value->x(), value->y(), value->z()})
                                  : std::nullopt,
                            "", doc.empty() ? "3 numbers, not all zero" : std::move(doc));
  s.nonzero = true;
  return s;
}

ParamSpec point_param(std::string name, std::optional<Eigen::Vector3d> value, std::string doc) {
  return array_param(std::move(name), {3},
                     value ? std::optional<std::vector<double>>(
                                 std::vector<double>{value->x(), value->y(), value->z()})
                           : std::nullopt,
                     "m", std::move(doc));
}

ParamSpec bools_param(std::string name, long length, std::optional<std::vector<bool>> value,
                      std::string doc) {
  ParamSpec s = spec(std::move(name), ParamKind::kBools, "", std::move(doc));
  s.shape = {length};
  if (value) s.default_value = value_of(*value);
  s.required = !value;
  return s;
}

ParamSpec string_param(std::string name, std::optional<std::string> value,
                       std::vector<std::string> choices, std::string doc) {
  ParamSpec s = spec(std::move(name), ParamKind::kString, "", std::move(doc));
  if (value) s.default_value = value_of(*value);
  s.required = !value;
  s.choices = std::move(choices);
  return s;
}

ParamSpec shape_param(std::string name, ParamKind kind, std::string doc) {
  ParamSpec s = spec(std::move(name), kind, "", std::move(doc));
  s.required = true;
  return s;
}

ParamSpec tables_param(std::string name, std::vector<ParamSpec> fields, std::string doc) {
  ParamSpec s = spec(std::move(name), ParamKind::kTables, "", std::move(doc));
  s.fields = std::move(fields);
  s.required = true;
  return s;
}

ParamSpec optional(ParamSpec spec) {
  spec.required = false;
  spec.default_value.reset();
  return spec;
}

// ---- values ----------------------------------------------------------------------------

bool Params::has(const std::string& name) const {
  for (size_t i = 0; i < names_.size(); ++i)
    if (names_[i] == name) return !std::holds_alternative<std::monostate>(values_[i]);
  return false;
}

const ParamValue& Params::get(const std::string& name) const {
  static const ParamValue kNone;
  for (size_t i = 0; i < names_.size(); ++i)
    if (names_[i] == name) return values_[i];
  return kNone;
}

Params& Params::set(const std::string& name, ParamValue value) {
  for (size_t i = 0; i < names_.size(); ++i) {
    if (names_[i] == name) {
      values_[i] = std::move(value);
      return *this;
    }
  }
  names_.push_back(name);
  values_.push_back(std::move(value));
  return *this;
}

Params& Params::set_vector(const std::string& name, const Eigen::Ref<const Eigen::VectorXd>& v) {
  return set(name, Array{{static_cast<long>(v.size())}, std::vector<double>(v.data(), v.data() + v.size())});
}

Params& Params::set_matrix(const std::string& name, const Eigen::Ref<const Eigen::MatrixXd>& M) {
  Array a{{static_cast<long>(M.rows()), static_cast<long>(M.cols())}, {}};
  for (Eigen::Index r = 0; r < M.rows(); ++r)
    for (Eigen::Index c = 0; c < M.cols(); ++c) a.data.push_back(M(r, c));
  return set(name, std::move(a));
}

std::string Params::type() const {
  const auto* t = std::get_if<std::string>(&get("type"));
  return t ? *t : std::string();
}

namespace {

template <class T>
const T& typed(const Params& p, const std::string& name, const char* expected) {
  const auto* v = std::get_if<T>(&p.get(name));
  if (!v) throw std::invalid_argument(name + ": expected " + expected);
  return *v;
}

}  // namespace

double Params::number(const std::string& name) const {
  if (const auto* i = std::get_if<long long>(&get(name))) return static_cast<double>(*i);
  return typed<double>(*this, name, "a number");
}

long long Params::integer(const std::string& name) const {
  return typed<long long>(*this, name, "an integer");
}

bool Params::boolean(const std::string& name) const {
  return typed<bool>(*this, name, "true or false");
}

const std::string& Params::string(const std::string& name) const {
  return typed<std::string>(*this, name, "a string");
}

const Array& Params::array(const std::string& name) const {
  return typed<Array>(*this, name, "an array");
}

Eigen::Vector3d Params::vector3(const std::string& name) const {
  const Array& a = array(name);
  if (a.data.size() != 3) throw std::invalid_argument(name + ": expected 3 numbers");
  return {a.data[0], a.data[1], a.data[2]};
}

Eigen::Vector3d Params::vector3_or_zero(const std::string& name) const {
  return has(name) ? vector3(name) : Eigen::Vector3d::Zero();
}

Eigen::VectorXd Params::vector(const std::string& name) const {
  const Array& a = array(name);
  return Eigen::Map<const Eigen::VectorXd>(a.data.data(), static_cast<Eigen::Index>(a.data.size()));
}

Eigen::MatrixXd Params::matrix(const std::string& name) const {
  const Array& a = array(name);
  if (a.shape.size() != 2) throw std::invalid_argument(name + ": expected a 2-D array");
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  return Eigen::Map<const RowMajor>(a.data.data(), a.shape[0], a.shape[1]);
}

Pose Params::pose(const std::string& name) const {
  const Eigen::MatrixXd M = matrix(name);
  if (M.rows() != 4 || M.cols() != 4) throw std::invalid_argument(name + ": expected a (4, 4) pose");
  Pose T;
  T.matrix() = M;
  require_pose(name, T);
  return T;
}

const std::vector<bool>& Params::bools(const std::string& name) const {
  return typed<std::vector<bool>>(*this, name, "a list of true or false");
}

std::shared_ptr<const Curve> Params::curve(const std::string& name) const {
  const ParamValue& v = get(name);
  if (const auto* t = std::get_if<std::vector<Params>>(&v); t && t->size() == 1) {
    return make_curve(t->front(), name);
  }
  return typed<std::shared_ptr<const Curve>>(*this, name, "a curve");
}

std::shared_ptr<const Surface> Params::surface(const std::string& name) const {
  const ParamValue& v = get(name);
  if (const auto* t = std::get_if<std::vector<Params>>(&v); t && t->size() == 1) {
    return make_surface(t->front(), name);
  }
  return typed<std::shared_ptr<const Surface>>(*this, name, "a surface");
}

const std::vector<Params>& Params::tables(const std::string& name) const {
  return typed<std::vector<Params>>(*this, name, "an array of tables");
}

Params complete(const std::vector<ParamSpec>& specs, const Params& given,
                const std::string& where) {
  for (const std::string& name : given.names()) {
    if (name == "type") continue;
    bool known = false;
    for (const ParamSpec& s : specs) known = known || s.name == name;
    if (!known) {
      std::string list;
      for (size_t i = 0; i < specs.size(); ++i) list += (i ? ", " : "") + specs[i].name;
      throw std::invalid_argument(joined(where, name) + ": unknown parameter; expected one of " +
                                  list);
    }
  }
  Params out;
  if (given.has("type")) out.set("type", given.type());
  for (const ParamSpec& s : specs) {
    const std::string at = joined(where, s.name);
    if (given.has(s.name)) {
      out.set(s.name, checked(s, given.get(s.name), at));
    } else if (s.default_value) {
      out.set(s.name, *s.default_value);
    } else if (s.required) {
      throw std::invalid_argument(at + ": missing required parameter" +
                                  (s.doc.empty() ? std::string() : " (" + s.doc + ")"));
    }
  }
  return out;
}

Pose pose_from(const Eigen::Vector3d& position, const Eigen::Vector3d& rotation) {
  Pose T = Pose::Identity();
  T.linear() = so3_exp(rotation);
  T.translation() = position;
  return T;
}

}  // namespace virtmech
