// The registry (include/virtmech/registry.hpp): the kinds and their parameters, objects
// from scenario tables, descriptions, distances, constrained directions, sketches, plugins.
#include <nanobind/stl/string.h>

#include "expose.hpp"

namespace vmpy {

using namespace nb::literals;

namespace {

template <class K>
nb::list kinds_of(const std::vector<const K*>& kinds) {
  nb::list out;
  for (const K* k : kinds) {
    nb::dict d;
    d["name"] = k->name;
    d["doc"] = k->doc;
    d["params"] = describe_specs(k->params);
    if constexpr (std::is_same_v<K, MechanismKind>) {
      d["point"] = k->point;
      d["target"] = k->target;
      d["signed_label"] = k->signed_label;
      d["negative"] = k->negative;
      d["distance"] = static_cast<bool>(k->distance);
    }
    out.append(d);
  }
  return out;
}

using Rows3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

Rows3 rows(const std::vector<Eigen::Vector3d>& points) {
  Rows3 out(static_cast<Eigen::Index>(points.size()), 3);
  for (size_t i = 0; i < points.size(); ++i) out.row(static_cast<Eigen::Index>(i)) = points[i].transpose();
  return out;
}

}  // namespace

void expose_registry(nb::module_& m) {
  m.def("kinds", [](const std::string& what) {
        Registry& r = registry();
        if (what == "mechanism") return kinds_of(r.mechanisms());
        if (what == "device") return kinds_of(r.devices());
        if (what == "curve") return kinds_of(r.curves());
        if (what == "surface") return kinds_of(r.surfaces());
        throw nb::value_error(("what: expected 'mechanism', 'device', 'curve' or 'surface', got '" +
                               what + "'").c_str());
      }, "what"_a,
      "The registered kinds of mechanism, device, curve or surface: each kind's name, doc and "
      "parameters (name, kind, shape, default, required, range, unit, doc, choices, fields), "
      "for a mechanism how its distance is named.");
  m.def("make_mechanism", [](nb::dict t, const std::string& where) {
        return std::const_pointer_cast<Mechanism>(make_mechanism(kind_table(&Registry::mechanism, t, where), where));
      }, "table"_a, "where"_a = "mechanism",
      "A mechanism from a table of its kind's parameters ('type' the kind), as a scenario's "
      "[mechanism] writes it; ValueError naming where.key for a mistake.");
  m.def("make_device", [](nb::dict t, const std::string& where) {
        return std::const_pointer_cast<Device>(make_device(kind_table(&Registry::device, t, where), where));
      }, "table"_a, "where"_a = "device", "A device from a table of its kind's parameters.");
  m.def("make_shape", [](nb::dict t, const std::string& where) -> nb::object {
        const std::string type = t.contains("type") ? nb::cast<std::string>(nb::str(t["type"])) : "";
        if (registry().curve(type)) {
          return nb::cast(std::const_pointer_cast<Curve>(make_curve(kind_table(&Registry::curve, t, where), where)));
        }
        return nb::cast(std::const_pointer_cast<Surface>(make_surface(kind_table(&Registry::surface, t, where), where)));
      }, "table"_a, "where"_a = "shape", "A curve or a surface from a table of its kind's parameters.");
  m.def("distances", [](const Mechanism& mech, nb::handle p, nb::handle s, nb::handle e) {
        const Array P = array_arg("p", p, {-1, 3}), S = array_arg("s", s, {-1, 3}), E = array_arg("e", e, {-1, 3});
        if (S.shape[0] != P.shape[0] || E.shape[0] != P.shape[0]) {
          throw nb::value_error("p, s, e: expected the same number of rows");
        }
        Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor> out(P.shape[0], 4);
        {
          nb::gil_scoped_release release;
          distances(mech, P.shape[0], P.data.data(), S.data.data(), E.data.data(), out.data());
        }
        return out;
      }, "mechanism"_a, "p"_a, "s"_a, "e"_a,
      "The distance columns (n, 4) [dist, dist_signed, dist_normal, dist_across] [m] of handles "
      "at p (n, 3) with stylus directions s (n, 3), by the mechanism kind's measure (a kind "
      "without one: |e| of the nearest placement's position errors e (n, 3), NaN parts).");
  m.def("constrained_directions", [](const Mechanism& mech, nb::handle at) {
        nb::dict out;
        for (const NamedDirection& d : constrained_directions(mech, vector_arg("at", at, 3))) {
          out[d.name.c_str()] = d.direction;
        }
        return out;
      }, "mechanism"_a, "at"_a,
      "{name: unit direction (3,)}: the directions the mechanism holds its point in, with the "
      "point at rest at `at` (its kind's names: 'radial', 'into the plane', ...).");
  m.def("sketch", [](const Mechanism& mech) {
        const Sketch s = sketch(mech);
        nb::list lines, meshes;
        for (const auto& l : s.lines) lines.append(rows(l));
        for (const auto& mesh : s.meshes) {
          Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor> faces(static_cast<Eigen::Index>(mesh.faces.size()), 3);
          for (size_t i = 0; i < mesh.faces.size(); ++i)
            faces.row(static_cast<Eigen::Index>(i)) << mesh.faces[i][0], mesh.faces[i][1], mesh.faces[i][2];
          meshes.append(nb::make_tuple(rows(mesh.vertices), faces));
        }
        nb::dict d;
        d["lines"] = lines;
        d["points"] = rows(s.points);
        d["meshes"] = meshes;
        return d;
      }, "mechanism"_a,
      "How the mechanism is drawn: {'lines': [(k, 3) polylines], 'points': (k, 3), 'meshes': "
      "[(vertices (k, 3), faces (f, 3))]} in world axes [m].");
  m.def("load_plugin", &load_plugin, "path"_a,
        "Loads a plugin (a shared library declaring VIRTMECH_PLUGIN) and adds its kinds; a path "
        "loaded before is not loaded again. ValueError naming the path for a file that cannot be "
        "loaded, is no plugin or was built against other headers.");
  m.attr("ABI_TAG") = VIRTMECH_ABI_TAG;
}

}  // namespace vmpy
