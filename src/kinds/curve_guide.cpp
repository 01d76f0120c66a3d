// CurveGuide as a kind: the tip on a curve.
#include "kinds.hpp"

namespace virtmech::kinds {

namespace {

// the tip (or handle) held on a curve: the directions across it
std::vector<NamedDirection> across_curve(const Curve& curve, const Eigen::Vector3d& normal,
                                         const Eigen::Vector3d& at) {
  Eigen::Vector3d point;
  const Eigen::Vector3d t = curve.tangent(curve.closest_point(at, point));
  const Eigen::Vector3d a = across(t, normal);
  return {{"along the normal", a}, {"across", t.cross(a)}};
}

Sketch curve_sketch(const Curve& curve) {
  Sketch s;
  s.lines.push_back(curve_polyline(curve));
  return s;
}

}  // namespace

void add_curve_guide(Registry& r) {
  MechanismKind k;
  k.name = "CurveGuide";
  k.doc = "A probe whose tip is held on a curve, the path to trace (joint u, then RRR at the "
          "tip over the fixed base [t1, normal x t1, normal]); the handle `length` back along "
          "the stylus, which points along -normal at wrist angles 0.";
  k.params = {shape_param("curve", ParamKind::kCurve, "a curve (NurbsCurve)"),
              number_param("length", 0.1, 0.0, 10.0, "m", "the probe's length", true),
              direction_param("normal", Eigen::Vector3d::UnitZ(), "the side the hand is on")};
  k.type = typeid(CurveGuide);
  k.make = [](const Params& p) {
    return std::make_shared<const CurveGuide>(p.curve("curve"), p.number("length"),
                                              p.vector3("normal"));
  };
  k.describe = [](const Mechanism& m) {
    const auto& a = static_cast<const CurveGuide&>(m);
    return Params("CurveGuide")
        .set("curve", a.curve_ptr())
        .set("length", a.length())
        .set("normal", a.normal());
  };
  k.point = "tip";
  k.target = "the curve";
  k.signed_label = "tip distance from the curve";
  k.negative = "(never: unsigned)";
  k.distance = [](const Mechanism& m, const Eigen::Vector3d& p, const Eigen::Vector3d& s) {
    const auto& a = static_cast<const CurveGuide&>(m);
    return from_curve(a.curve(), a.normal(), tip_of(a.length(), p, s));
  };
  k.constrained = [](const Mechanism& m, const Eigen::Vector3d& at) {
    const auto& a = static_cast<const CurveGuide&>(m);
    return across_curve(a.curve(), a.normal(), at);
  };
  k.sketch = [](const Mechanism& m) {
    return curve_sketch(static_cast<const CurveGuide&>(m).curve());
  };
  r.add(std::move(k));
}

void add_handle_path(Registry& r) {
  MechanismKind k;
  k.name = "HandlePath";
  k.doc = "The handle itself held on a curve, its orientation free (joint u, then RRR about "
          "the handle point; the stylus along -normal at wrist angles 0).";
  k.params = {shape_param("curve", ParamKind::kCurve, "a curve (NurbsCurve)"),
              direction_param("normal", Eigen::Vector3d::UnitZ(), "the side the hand is on"),
              number_param("length_scale", 0.1, 0.0, 10.0, "m",
                           "weighs rotations against translations", true)};
  k.type = typeid(HandlePath);
  k.make = [](const Params& p) {
    return std::make_shared<const HandlePath>(p.curve("curve"), p.vector3("normal"),
                                              p.number("length_scale"));
  };
  k.describe = [](const Mechanism& m) {
    const auto& a = static_cast<const HandlePath&>(m);
    return Params("HandlePath")
        .set("curve", a.curve_ptr())
        .set("normal", a.normal())
        .set("length_scale", a.length_scale());
  };
  k.point = "handle";
  k.target = "the curve";
  k.signed_label = "handle distance from the curve";
  k.negative = "(never: unsigned)";
  k.distance = [](const Mechanism& m, const Eigen::Vector3d& p, const Eigen::Vector3d&) {
    const auto& a = static_cast<const HandlePath&>(m);
    return from_curve(a.curve(), a.normal(), p);
  };
  k.constrained = [](const Mechanism& m, const Eigen::Vector3d& at) {
    const auto& a = static_cast<const HandlePath&>(m);
    return across_curve(a.curve(), a.normal(), at);
  };
  k.sketch = [](const Mechanism& m) {
    return curve_sketch(static_cast<const HandlePath&>(m).curve());
  };
  r.add(std::move(k));
}

}  // namespace virtmech::kinds
