// The helix guide (helix_guide.hpp) as a kind of mechanism, in a plugin: a shared library
// that a scenario names (`plugins = ["libhelix_guide.so"]`, then `[mechanism] type =
// "HelixGuide"`) and virtmech loads at run time. Its parameters, factory and description
// are all it must give; it draws itself (sketch) and, having no distance measure of its
// own, the log's distance is its placement's error. Build it against an installed virtmech
// (examples/cpp/plugin/CMakeLists.txt, `python -m virtmech --cmake-dir`).
#include <cmath>

#include "helix_guide.hpp"
#include "virtmech/registry.hpp"

namespace {

using namespace virtmech;
using helix::HelixGuide;
using helix::HelixParams;

void add_helix(Registry& r) {
  const HelixParams d;
  MechanismKind k;
  k.name = "HelixGuide";
  k.doc = "the handle held to a helix, the stylus free to turn (examples/cpp/helix_guide.hpp)";
  k.params = {point_param("centre", d.centre, "a point on the helix's axis [m]"),
              direction_param("axis", d.axis, "the axis the helix rises along"),
              direction_param("zero_direction", d.zero_direction, "axis to handle at phi = 0"),
              number_param("radius", d.radius, 0.0, 10.0, "m", "the helix's radius", true),
              number_param("pitch", d.pitch, -1.0, 1.0, "m", "rise per turn"),
              number_param("turns", d.turns, 0.0, 100.0, "", "phi within +-turns full turns", true),
              number_param("length_scale", d.length_scale, 0.0, 10.0, "m",
                           "weighs rotations against translations", true)};
  k.type = typeid(HelixGuide);
  k.make = [](const Params& p) {
    HelixParams h;
    h.centre = p.vector3("centre");
    h.axis = p.vector3("axis");
    h.zero_direction = p.vector3("zero_direction");
    h.radius = p.number("radius");
    h.pitch = p.number("pitch");
    h.turns = p.number("turns");
    h.length_scale = p.number("length_scale");
    return std::make_shared<const HelixGuide>(h);
  };
  k.describe = [](const Mechanism& m) {
    const HelixParams& h = static_cast<const HelixGuide&>(m).params();
    return Params("HelixGuide")
        .set("centre", h.centre)
        .set("axis", h.axis)
        .set("zero_direction", h.zero_direction)
        .set("radius", h.radius)
        .set("pitch", h.pitch)
        .set("turns", h.turns)
        .set("length_scale", h.length_scale);
  };
  k.target = "the helix";
  // the helix itself, over its turns
  k.sketch = [](const Mechanism& m) {
    const HelixParams& h = static_cast<const HelixGuide&>(m).params();
    Sketch s;
    s.lines.emplace_back();
    JointVector x = JointVector::Zero(4);
    Pose T;
    constexpr int kPoints = 400;
    for (int i = 0; i < kPoints; ++i) {
      x[0] = 2.0 * M_PI * h.turns * (2.0 * i / (kPoints - 1) - 1.0);
      m.forward(x.data(), T);
      s.lines.back().push_back(T.translation());
    }
    return s;
  };
  r.add(std::move(k));
}

}  // namespace

VIRTMECH_PLUGIN(add_helix)
