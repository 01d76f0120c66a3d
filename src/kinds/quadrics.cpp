// The sphere, the cylinder and the plane as kinds.
#include "kinds.hpp"

namespace virtmech::kinds {

void add_sphere(Registry& r) {
  SurfaceKind k;
  k.name = "Sphere";
  k.doc = "Sphere S(u, v) = c + r (cos u cos v e1 + sin u cos v e2 + sin v a): u the "
          "longitude in [-pi, pi] (periodic), v the latitude in [-pi/2, pi/2]; outward normal. "
          "`axis` a points to the pole v = pi/2; e1 = world x made orthogonal to a (y where a is "
          "along x), e2 = a x e1: the default axis z gives (e1, e2) = (x, y).";
  k.params = {point_param("center", std::nullopt, "the centre [m]"),
              number_param("radius", std::nullopt, 0.0, 10.0, "m", "the radius", true),
              direction_param("axis", Eigen::Vector3d::UnitZ(),
                              "the poles' direction (keep them where the probe is not used)")};
  k.type = typeid(Sphere);
  k.make = [](const Params& p) {
    return std::make_shared<const Sphere>(p.vector3("center"), p.number("radius"),
                                          p.vector3("axis"));
  };
  k.describe = [](const Surface& surface) {
    const auto& s = static_cast<const Sphere&>(surface);
    return Params("Sphere").set("center", s.center()).set("radius", s.radius()).set("axis", s.axis());
  };
  r.add(std::move(k));
}

void add_cylinder(Registry& r) {
  SurfaceKind k;
  k.name = "Cylinder";
  k.doc = "Infinite cylinder S(u, v) = a + r (cos u e1 + sin u e2) + v d: d the unit axis, "
          "e1 = an orthogonal unit vector (e1 property), e2 = d x e1; normal away from the axis.";
  k.params = {point_param("point", std::nullopt, "a point of its axis [m]"),
              direction_param("direction", std::nullopt, "the axis's direction"),
              number_param("radius", std::nullopt, 0.0, 10.0, "m", "the radius", true)};
  k.type = typeid(Cylinder);
  k.make = [](const Params& p) {
    return std::make_shared<const Cylinder>(p.vector3("point"), p.vector3("direction"),
                                            p.number("radius"));
  };
  k.describe = [](const Surface& surface) {
    const auto& c = static_cast<const Cylinder&>(surface);
    return Params("Cylinder")
        .set("point", c.point())
        .set("direction", c.direction())
        .set("radius", c.radius());
  };
  r.add(std::move(k));
}

void add_plane(Registry& r) {
  SurfaceKind k;
  k.name = "Plane";
  k.doc = "Infinite plane S(u, v) = o + u e1 + v e2: n the unit normal, e1 an orthogonal unit "
          "vector (e1 property), e2 = n x e1.";
  k.params = {point_param("point", std::nullopt, "a point of the plane [m]"),
              direction_param("normal", std::nullopt, "the plane's normal")};
  k.type = typeid(Plane);
  k.make = [](const Params& p) {
    return std::make_shared<const Plane>(p.vector3("point"), p.vector3("normal"));
  };
  k.describe = [](const Surface& surface) {
    const auto& s = static_cast<const Plane&>(surface);
    return Params("Plane").set("point", s.point()).set("normal", s.normal());
  };
  r.add(std::move(k));
}

}  // namespace virtmech::kinds
