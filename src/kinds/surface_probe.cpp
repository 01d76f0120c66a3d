// SurfaceProbe as a kind: the tip on a surface.
#include <cmath>

#include "kinds.hpp"

namespace virtmech::kinds {

void add_surface_probe(Registry& r) {
  MechanismKind k;
  k.name = "SurfaceProbe";
  k.doc = "Paper Fig. 3 on any surface: the probe's tip slides on `surface` (joints u, v), "
          "three revolute joints meet at the tip over the surface frame [t1, n x t1, n], the "
          "handle `length` back along the stylus, which points along -n at wrist angles 0; "
          "unilateral: the surface pushes but never pulls.";
  k.params = {shape_param("surface", ParamKind::kSurface,
                          "a surface (NurbsSurface, Sphere, Cylinder, Plane)"),
              number_param("length", 0.1, 0.0, 10.0, "m", "the probe's length", true),
              bool_param("unilateral", false,
                         "the tip may leave the surface toward its normal: the surface pushes "
                         "but never pulls")};
  k.type = typeid(SurfaceProbe);
  k.make = [](const Params& p) {
    return std::make_shared<const SurfaceProbe>(p.surface("surface"), p.number("length"),
                                                p.boolean("unilateral"));
  };
  k.describe = [](const Mechanism& m) {
    const auto& a = static_cast<const SurfaceProbe&>(m);
    return Params("SurfaceProbe")
        .set("surface", a.surface_ptr())
        .set("length", a.length())
        .set("unilateral", a.unilateral());
  };
  k.point = "tip";
  k.target = "the surface";
  k.signed_label = "tip height above the surface";
  k.negative = "the tip is behind the surface";
  // the tip's signed height above the surface along the normal at its closest point
  k.distance = [](const Mechanism& m, const Eigen::Vector3d& p, const Eigen::Vector3d& s) {
    const auto& a = static_cast<const SurfaceProbe&>(m);
    const Eigen::Vector3d x = tip_of(a.length(), p, s);
    Eigen::Vector3d point;
    const Eigen::Vector2d uv = a.surface().closest_point(x, point);
    const double h = (x - point).dot(a.surface().normal(uv[0], uv[1]));
    return Distances{a.unilateral() ? std::max(-h, 0.0) : std::abs(h), h, h, 0.0};
  };
  k.constrained = [](const Mechanism& m, const Eigen::Vector3d& at) {
    const Surface& surface = static_cast<const SurfaceProbe&>(m).surface();
    Eigen::Vector3d point;
    const Eigen::Vector2d uv = surface.closest_point(at, point);
    return std::vector<NamedDirection>{{"into the surface", -surface.normal(uv[0], uv[1])}};
  };
  k.sketch = [](const Mechanism& m) {
    Sketch s;
    s.meshes.push_back(surface_mesh(static_cast<const SurfaceProbe&>(m).surface()));
    return s;
  };
  r.add(std::move(k));
}

}  // namespace virtmech::kinds
