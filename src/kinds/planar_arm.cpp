// PlanarArm (paper Fig. 4, eq. 2) as a kind: parameters, distance from its circle, the
// directions it holds the handle in, its drawing.
#include <cmath>

#include "kinds.hpp"

namespace virtmech::kinds {

void add_planar_arm(Registry& r) {
  MechanismKind k;
  k.name = "PlanarArm";
  k.doc = "Paper Fig. 4 / eq. 2 in 3-D: a revolute joint at `pivot` about the unit `normal`, "
          "the handle at distance `length` in direction R(theta) zero_direction, the stylus "
          "pointing from the handle to the pivot.";
  k.params = {point_param("pivot", std::nullopt, "the circle's centre [m]"),
              direction_param("normal", Eigen::Vector3d::UnitZ(), "the plane's normal (unit)"),
              number_param("length", std::nullopt, 0.0, 10.0, "m", "the circle's radius", true),
              optional(direction_param("zero_direction", std::nullopt,
                                       "where theta = 0 points, in the plane (default: world x "
                                       "projected into it)"))};
  k.type = typeid(PlanarArm);
  k.make = [](const Params& p) {
    return std::make_shared<const PlanarArm>(p.vector3("pivot"), p.vector3("normal"),
                                             p.number("length"), p.vector3_or_zero("zero_direction"));
  };
  k.describe = [](const Mechanism& m) {
    const auto& a = static_cast<const PlanarArm&>(m);
    return Params("PlanarArm")
        .set("pivot", a.pivot())
        .set("normal", a.normal())
        .set("length", a.length())
        .set("zero_direction", a.zero_direction());
  };
  k.point = "handle";
  k.target = "the circle";
  k.signed_label = "handle's distance from the circle";
  k.negative = "inside the circle";
  // the handle from the circle: dist_normal out of the plane, dist_across r - length
  k.distance = [](const Mechanism& m, const Eigen::Vector3d& p, const Eigen::Vector3d&) {
    const auto& a = static_cast<const PlanarArm&>(m);
    const Eigen::Vector3d n = unit(a.normal());
    const Eigen::Vector3d w = p - a.pivot();
    const double h = w.dot(n);
    const double radial = (w - h * n).norm() - a.length();
    const double dist = std::hypot(radial, h);
    return Distances{dist, radial < 0.0 ? -dist : dist, h, radial};
  };
  k.constrained = [](const Mechanism& m, const Eigen::Vector3d& at) {
    const auto& a = static_cast<const PlanarArm&>(m);
    const Eigen::Vector3d n = unit(a.normal());
    Eigen::Vector3d radial = at - a.pivot();
    radial -= radial.dot(n) * n;
    return std::vector<NamedDirection>{{"radial", unit(radial)}, {"normal", n}};
  };
  k.sketch = [](const Mechanism& m) {
    const auto& a = static_cast<const PlanarArm&>(m);
    Eigen::Vector3d u, v;
    plane_basis(a.normal(), u, v);
    Sketch s;
    s.lines.emplace_back();
    constexpr int kPoints = 97;
    for (int i = 0; i < kPoints; ++i) {
      const double t = 2.0 * M_PI * i / (kPoints - 1);
      s.lines.back().push_back(a.pivot() + a.length() * (std::cos(t) * u + std::sin(t) * v));
    }
    s.points.push_back(a.pivot());
    return s;
  };
  r.add(std::move(k));
}

}  // namespace virtmech::kinds
