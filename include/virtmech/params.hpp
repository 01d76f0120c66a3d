// A kind's parameters as data: the description of each parameter (ParamSpec: name, kind,
// shape, default, range, unit, meaning) and a set of values (Params), so that one list per
// kind of mechanism, device or shape serves its factory, its description (describe()), the
// Python constructors, the scenario format and its documentation (include/virtmech/registry.hpp).
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "virtmech/geometry.hpp"
#include "virtmech/kinematic_chain.hpp"
#include "virtmech/settings.hpp"

namespace virtmech {

/// The names users write for a joint's kind.
template <>
struct EnumNames<JointType> {
  static constexpr EnumName kValues[] = {
      {static_cast<int>(JointType::kRevolute), "revolute", "rotation about the axis [rad]"},
      {static_cast<int>(JointType::kPrismatic), "prismatic", "translation along the axis [m]"}};
};

/// What a parameter holds.
enum class ParamKind : int {
  kNumber = 0,   //!< a double in [min, max]
  kInteger = 1,  //!< an integer in [min, max]
  kBool = 2,
  kString = 3,   //!< one of `choices` where given
  kArray = 4,    //!< numbers of the given shape (row-major), e.g. (3,), (n, 3), (nu, nv, 3)
  kBools = 5,    //!< one bool per entry of the given length (-1: any)
  kCurve = 6,    //!< a Curve, or a table describing one (its "type" and parameters)
  kSurface = 7,  //!< a Surface, or a table describing one
  kTables = 8,   //!< an array of tables, each of the parameters `fields` (joints of a chain)
};

/// Numbers of a shape, row-major: a vector (3,), points (n, 3), a grid (nu, nv, 3), ...
struct Array {
  std::vector<long> shape;
  std::vector<double> data;
};

class Params;

/// One parameter's value (std::monostate: not given).
using ParamValue =
    std::variant<std::monostate, double, long long, bool, std::string, Array,
                 std::shared_ptr<const Curve>, std::shared_ptr<const Surface>,
                 std::vector<Params>, std::vector<bool>>;

/// One parameter of a kind.
struct ParamSpec {
  std::string name;
  ParamKind kind = ParamKind::kNumber;
  /// kArray: the shape (-1: any size along that axis); kBools: {length} (-1: any).
  std::vector<long> shape;
  /// The default; std::monostate: none (required, or optional without a default: see
  /// `required`).
  std::shared_ptr<const ParamValue> default_value;
  bool required = false;
  double min = -kInf, max = kInf;  //!< kNumber, kInteger, and each entry of a kArray
  bool min_exclusive = false;
  bool nonzero = false;  //!< kArray (3,): a direction, not all zero
  std::vector<std::string> choices;  //!< kString
  std::vector<ParamSpec> fields;     //!< kTables: each table's parameters
  std::string unit, doc;
};

/// Builders of ParamSpecs, one per kind, for the kinds' lists (src/kinds/).
ParamSpec number_param(std::string name, std::optional<double> value, double min, double max,
                       std::string unit, std::string doc, bool min_exclusive = false);
ParamSpec integer_param(std::string name, std::optional<long long> value, long long min,
                        long long max, std::string doc);
ParamSpec bool_param(std::string name, bool value, std::string doc);
/// An array of the given shape; `value` (row-major) its default where given.
ParamSpec array_param(std::string name, std::vector<long> shape,
                      std::optional<std::vector<double>> value, std::string unit,
                      std::string doc);
/// A direction: 3 numbers, not all zero; `value` its default where given.
ParamSpec direction_param(std::string name, std::optional<Eigen::Vector3d> value,
                          std::string doc);
/// A point or a 3-vector [m] (required unless `value`).
ParamSpec point_param(std::string name, std::optional<Eigen::Vector3d> value, std::string doc);
ParamSpec bools_param(std::string name, long length, std::optional<std::vector<bool>> value,
                      std::string doc);
ParamSpec string_param(std::string name, std::optional<std::string> value,
                       std::vector<std::string> choices, std::string doc);
ParamSpec shape_param(std::string name, ParamKind kind, std::string doc);
ParamSpec tables_param(std::string name, std::vector<ParamSpec> fields, std::string doc);
/// Makes a parameter optional without a default (a factory's automatic choice).
ParamSpec optional(ParamSpec spec);

/// A set of named parameter values, in the order they were set.
class Params {
 public:
  Params() = default;
  explicit Params(std::string type) { set("type", std::move(type)); }

  bool has(const std::string& name) const;
  const ParamValue& get(const std::string& name) const;  //!< monostate where absent
  Params& set(const std::string& name, ParamValue value);
  Params& set(const std::string& name, double value) { return set(name, ParamValue(value)); }
  Params& set(const std::string& name, bool value) { return set(name, ParamValue(value)); }
  Params& set(const std::string& name, int value) { return set(name, ParamValue(static_cast<long long>(value))); }
  Params& set(const std::string& name, const char* value) { return set(name, ParamValue(std::string(value))); }
  Params& set(const std::string& name, const Eigen::Vector3d& v) { return set_vector(name, v); }
  Params& set(const std::string& name, const Pose& T) { return set_matrix(name, T.matrix()); }
  Params& set_vector(const std::string& name, const Eigen::Ref<const Eigen::VectorXd>& v);
  Params& set_matrix(const std::string& name, const Eigen::Ref<const Eigen::MatrixXd>& M);

  const std::vector<std::string>& names() const noexcept { return names_; }
  const std::vector<ParamValue>& values() const noexcept { return values_; }
  std::string type() const;  //!< the "type" entry ("" where absent)

  // Typed reads; std::invalid_argument naming the parameter where it is absent or of
  // another kind.
  double number(const std::string& name) const;
  long long integer(const std::string& name) const;
  bool boolean(const std::string& name) const;
  const std::string& string(const std::string& name) const;
  const Array& array(const std::string& name) const;
  Eigen::Vector3d vector3(const std::string& name) const;
  /// The 3-vector, or zero where absent (a factory's "automatic").
  Eigen::Vector3d vector3_or_zero(const std::string& name) const;
  Eigen::VectorXd vector(const std::string& name) const;
  Eigen::MatrixXd matrix(const std::string& name) const;  //!< a 2-D array
  Pose pose(const std::string& name) const;               //!< a (4, 4) rigid transform
  const std::vector<bool>& bools(const std::string& name) const;
  /// A curve or a surface: the object given, or built from its table (registry()).
  std::shared_ptr<const Curve> curve(const std::string& name) const;
  std::shared_ptr<const Surface> surface(const std::string& name) const;
  const std::vector<Params>& tables(const std::string& name) const;

 private:
  std::vector<std::string> names_;
  std::vector<ParamValue> values_;
};

/// `given` checked against `specs` and completed with the defaults: every parameter named
/// (std::invalid_argument for an unknown name, listing the known ones), every required one
/// present, each of its kind, shape and range (messages name `where` + the parameter, e.g.
/// "mechanism.length: expected a number > 0 and <= 10 [m], got -1"). Tables and shapes
/// within are checked the same way.
Params complete(const std::vector<ParamSpec>& specs, const Params& given,
                const std::string& where = "");

/// A rotation matrix from a rotation vector and a rigid transform from a position and a
/// rotation vector (the scenario format's poses).
Pose pose_from(const Eigen::Vector3d& position, const Eigen::Vector3d& rotation);

}  // namespace virtmech
