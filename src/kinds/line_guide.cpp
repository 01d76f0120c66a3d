// LineGuide as a kind: the tip on a line.
#include <cmath>

#include "kinds.hpp"

namespace virtmech::kinds {

void add_line_guide(Registry& r) {
  MechanismKind k;
  k.name = "LineGuide";
  k.doc = "A probe whose tip slides on a line (P + RRR at the tip); unilateral: the tip may "
          "lift off the line toward +normal.";
  k.params = {point_param("point", std::nullopt, "a point of the line [m]"),
              direction_param("direction", std::nullopt, "the line's direction (unit)"),
              number_param("length", 0.1, 0.0, 10.0, "m", "the probe's length", true),
              optional(direction_param("normal", std::nullopt,
                                       "the side the hand is on, across the line (default: "
                                       "automatic)")),
              bool_param("unilateral", false,
                         "the tip may lift off the line toward +normal (a joint with lower "
                         "limit 0)")};
  k.type = typeid(LineGuide);
  k.make = [](const Params& p) {
    return std::make_shared<const LineGuide>(p.vector3("point"), p.vector3("direction"),
                                             p.number("length"), p.vector3_or_zero("normal"),
                                             p.boolean("unilateral"));
  };
  k.describe = [](const Mechanism& m) {
    const auto& a = static_cast<const LineGuide&>(m);
    return Params("LineGuide")
        .set("point", a.point())
        .set("direction", a.direction())
        .set("length", a.length())
        .set("normal", a.normal())
        .set("unilateral", a.unilateral());
  };
  k.point = "tip";
  k.target = "the line";
  k.signed_label = "tip distance from the line";
  k.negative = "the tip is below the line along its normal";
  // the tip from the line (unilateral: from the half plane above it along the normal)
  k.distance = [](const Mechanism& m, const Eigen::Vector3d& p, const Eigen::Vector3d& s) {
    const auto& a = static_cast<const LineGuide&>(m);
    const Eigen::Vector3d d = unit(a.direction());
    Eigen::Vector3d n = unit(a.normal());
    n = unit(n - n.dot(d) * d);
    const Eigen::Vector3d w = tip_of(a.length(), p, s) - a.point();
    return one_sided(w.dot(n), w.dot(n.cross(d)), a.unilateral());
  };
  k.constrained = [](const Mechanism& m, const Eigen::Vector3d&) {
    const Eigen::Vector3d d = unit(static_cast<const LineGuide&>(m).direction());
    const Eigen::Vector3d a = orthogonal(d);
    return std::vector<NamedDirection>{{"across 1", a}, {"across 2", d.cross(a)}};
  };
  k.sketch = [](const Mechanism& m) {
    const auto& a = static_cast<const LineGuide&>(m);
    const Eigen::Vector3d d = unit(a.direction());
    Sketch s;
    s.lines.push_back({a.point() - 0.1 * d, a.point() + 0.1 * d});
    return s;
  };
  r.add(std::move(k));
}

}  // namespace virtmech::kinds
