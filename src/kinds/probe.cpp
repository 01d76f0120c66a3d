// Probe (paper Fig. 3) as a kind: the tip on a plane.
#include <cmath>

#include "kinds.hpp"

namespace virtmech::kinds {

void add_probe(Registry& r) {
  MechanismKind k;
  k.name = "Probe";
  k.doc = "Paper Fig. 3, PPRRR: the tip slides on the plane (plane_point, unit plane_normal); "
          "three revolute joints meet at the tip; the handle is `length` back along the stylus. "
          "unilateral: the tip may leave the plane toward +plane_normal (a lift-off joint with "
          "lower limit 0 after the two in-plane ones), so the plane pushes but never pulls.";
  k.params = {point_param("plane_point", std::nullopt, "a point of the plane [m]"),
              direction_param("plane_normal", std::nullopt, "the plane's normal (unit)"),
              number_param("length", std::nullopt, 0.0, 10.0, "m", "the probe's length", true),
              optional(direction_param("tangent", std::nullopt,
                                       "the in-plane axis of the first joint (default: automatic)")),
              bool_param("unilateral", false,
                         "the tip may lift off toward +plane_normal: the plane pushes but never "
                         "pulls")};
  k.type = typeid(Probe);
  k.make = [](const Params& p) {
    return std::make_shared<const Probe>(p.vector3("plane_point"), p.vector3("plane_normal"),
                                         p.number("length"), p.vector3_or_zero("tangent"),
                                         p.boolean("unilateral"));
  };
  k.describe = [](const Mechanism& m) {
    const auto& a = static_cast<const Probe&>(m);
    return Params("Probe")
        .set("plane_point", a.plane_point())
        .set("plane_normal", a.plane_normal())
        .set("length", a.length())
        .set("tangent", a.tangent())
        .set("unilateral", a.unilateral());
  };
  k.point = "tip";
  k.target = "the plane";
  k.signed_label = "tip height above the plane";
  k.negative = "the tip is behind the plane";
  // the tip's signed height above the plane (unilateral: only the depth behind it counts)
  k.distance = [](const Mechanism& m, const Eigen::Vector3d& p, const Eigen::Vector3d& s) {
    const auto& a = static_cast<const Probe&>(m);
    const double h = (tip_of(a.length(), p, s) - a.plane_point()).dot(unit(a.plane_normal()));
    return Distances{a.unilateral() ? std::max(-h, 0.0) : std::abs(h), h, h, 0.0};
  };
  k.constrained = [](const Mechanism& m, const Eigen::Vector3d&) {
    const auto& a = static_cast<const Probe&>(m);
    return std::vector<NamedDirection>{{"into the plane", -unit(a.plane_normal())}};
  };
  k.sketch = [](const Mechanism& m) {
    const auto& a = static_cast<const Probe&>(m);
    Eigen::Vector3d u, v;
    plane_basis(a.plane_normal(), u, v);
    constexpr double kHalf = 0.08;  // [m]
    Sketch::Mesh quad;
    for (const auto& st : {std::array<double, 2>{-1, -1}, {1, -1}, {1, 1}, {-1, 1}}) {
      quad.vertices.push_back(a.plane_point() + kHalf * (st[0] * u + st[1] * v));
    }
    quad.faces = {{0, 1, 2}, {0, 2, 3}};
    Sketch s;
    s.lines.push_back(quad.vertices);
    s.lines.back().push_back(quad.vertices.front());
    s.meshes.push_back(std::move(quad));
    return s;
  };
  r.add(std::move(k));
}

}  // namespace virtmech::kinds
