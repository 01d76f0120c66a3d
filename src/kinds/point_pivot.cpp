// PointPivot as a kind: the tip pinned at a point (or a trocar through it).
#include <cmath>

#include "kinds.hpp"

namespace virtmech::kinds {

void add_point_pivot(Registry& r) {
  MechanismKind k;
  k.name = "PointPivot";
  k.doc = "A probe whose tip is pinned at `point` (RRR at the tip). unilateral: the tip may "
          "lift off toward +normal. insertion: a trocar, the stylus passes through the point "
          "and slides along itself (a last joint s in [-0.9 length, 0], the handle at length + "
          "s from the point).";
  k.params = {point_param("point", std::nullopt, "the pivot [m]"),
              direction_param("normal", Eigen::Vector3d::UnitZ(), "the side the hand is on (unit)"),
              number_param("length", 0.1, 0.0, 10.0, "m", "the probe's length", true),
              optional(direction_param("tangent", std::nullopt,
                                       "the first joint's axis (default: automatic)")),
              bool_param("unilateral", false,
                         "the tip may lift off toward +normal (a joint with lower limit 0)"),
              bool_param("insertion", false,
                         "a trocar: the stylus passes through the point and slides along itself")};
  k.type = typeid(PointPivot);
  k.make = [](const Params& p) {
    return std::make_shared<const PointPivot>(p.vector3("point"), p.vector3("normal"),
                                              p.number("length"), p.vector3_or_zero("tangent"),
                                              p.boolean("unilateral"), p.boolean("insertion"));
  };
  k.describe = [](const Mechanism& m) {
    const auto& a = static_cast<const PointPivot&>(m);
    return Params("PointPivot")
        .set("point", a.point())
        .set("normal", a.normal())
        .set("length", a.length())
        .set("tangent", a.tangent())
        .set("unilateral", a.unilateral())
        .set("insertion", a.insertion());
  };
  k.point = "tip";
  k.target = "the point";
  k.signed_label = "tip distance from the point";
  k.negative = "the tip is below the point along its normal";
  // the tip from the point (unilateral: from the ray above it along the normal); a trocar:
  // the point's distance from the stylus's line, and how far the tip has gone in past it
  k.distance = [](const Mechanism& m, const Eigen::Vector3d& p, const Eigen::Vector3d& s) {
    const auto& a = static_cast<const PointPivot&>(m);
    if (a.insertion()) {
      const Eigen::Vector3d w = a.point() - p;
      const double along = w.dot(s);
      const double line = (w - along * s).norm();
      return Distances{line, line, a.length() - along, line};
    }
    const Eigen::Vector3d n = unit(a.normal());
    const Eigen::Vector3d w = tip_of(a.length(), p, s) - a.point();
    const double h = w.dot(n);
    return one_sided(h, (w - h * n).norm(), a.unilateral());
  };
  k.constrained = [](const Mechanism&, const Eigen::Vector3d&) {
    return std::vector<NamedDirection>{{"x", Eigen::Vector3d::UnitX()},
                                       {"y", Eigen::Vector3d::UnitY()},
                                       {"z", Eigen::Vector3d::UnitZ()}};
  };
  k.sketch = [](const Mechanism& m) {
    Sketch s;
    s.points.push_back(static_cast<const PointPivot&>(m).point());
    return s;
  };
  r.add(std::move(k));
}

}  // namespace virtmech::kinds
