// Curves and surfaces (include/virtmech/geometry.hpp); the shapes' constructors and
// parameters are their kinds' (src/kinds/nurbs.cpp, quadrics.cpp).
#include "expose.hpp"

namespace vmpy {

using namespace nb::literals;

namespace {

using Rows3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using Rows2 = Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>;

int checked_order(int order) {
  if (order < 0 || order > kMaxDerivativeOrder) {
    throw nb::value_error(("order: expected 0 to " + std::to_string(kMaxDerivativeOrder) +
                           ", got " + std::to_string(order)).c_str());
  }
  return order;
}

// (u, v): finite unless `bound` (a parameter bound may be +-inf)
Eigen::Vector2d parameters_arg(const char* name, nb::handle obj, bool bound) {
  const Eigen::Vector2d x = vector_arg(name, obj, 2);
  if (x.hasNaN() || (!bound && !x.allFinite())) {
    throw nb::value_error((std::string(name) + ": expected " + (bound ? "numbers" : "finite numbers") +
                           ", got " + format_vector(x)).c_str());
  }
  return x;
}

template <class T, class Base>
nb::class_<T, Base> def_shape(nb::module_& m, const char* name) {
  constexpr bool kSurface = std::is_base_of_v<Surface, T>;
  const auto* kind = [name] {
    if constexpr (kSurface) return registry().surface(name); else return registry().curve(name);
  }();
  nb::class_<T, Base> cls(m, name, kind->doc.c_str());
  def_kind<T>(cls, kind->params, name, [name](Params p) {
    p.set("type", name);
    if constexpr (kSurface) {
      return std::static_pointer_cast<const T>(make_surface(p, ""));
    } else {
      return std::static_pointer_cast<const T>(make_curve(p, ""));
    }
  });
  return cls;
}

void expose_curve(nb::module_& m) {
  nb::class_<Curve>(m, "Curve", "A parametric curve C(u) (base class).")
      .def("to_dict", [](const Curve& c) { return to_python(describe(c)); },
           "The curve's parameters ('type' first) as a JSON-ready dict (its kind's).")
      .def_prop_ro("lower", &Curve::lower, "Lower parameter bound.")
      .def_prop_ro("upper", &Curve::upper, "Upper parameter bound.")
      .def("evaluate", &Curve::evaluate, "u"_a, "The point C(u) (3,); u is clamped to [lower, upper].")
      .def("derivatives", [](const Curve& c, double u, int order) {
            CurveDerivatives d;
            c.derivatives(u, checked_order(order), d);
            return Rows3(d.leftCols(order + 1).transpose());
          }, "u"_a, "order"_a = 2,
          "(order + 1, 3): row k the k-th derivative d^k C / du^k (row 0 the point).")
      .def("tangent", &Curve::tangent, "u"_a, "Unit tangent (3,).")
      .def("curvature", &Curve::curvature, "u"_a, "Curvature [1/m].")
      .def("closest_point", [](const Curve& c, nb::handle p) {
            Eigen::Vector3d point;
            const double u = c.closest_point(vector_arg("p", p, 3), point);
            return nb::make_tuple(u, point);
          }, "p"_a, "(u, point): the parameter and the point (3,) of the curve closest to p.")
      .def("closest_points", [](const Curve& c, nb::handle X) {
            const Array x = array_arg("X", X, {-1, 3});
            const Eigen::Index n = x.shape[0];
            Eigen::VectorXd u(n);
            Rows3 points(n, 3);
            {
              nb::gil_scoped_release release;
              for (Eigen::Index i = 0; i < n; ++i) {
                Eigen::Vector3d point;
                u[i] = c.closest_point(Eigen::Map<const Eigen::Vector3d>(&x.data[3 * i]), point);
                points.row(i) = point.transpose();
              }
            }
            return nb::make_tuple(u, points);
          }, "X"_a, "(u (n,), points (n, 3)): closest_point for each row of X (n, 3), in one call.");
}

nb::class_<Surface> expose_surface(nb::module_& m) {
  nb::class_<Surface> cls(m, "Surface", "A parametric surface S(u, v) (base class).");
  cls.def("to_dict", [](const Surface& s) { return to_python(describe(s)); },
           "The surface's parameters ('type' first) as a JSON-ready dict (its kind's).")
      .def_prop_ro("lower", &Surface::lower, "Lower parameter bounds (u, v) (may be -inf).")
      .def_prop_ro("upper", &Surface::upper, "Upper parameter bounds (u, v) (may be inf).")
      .def_prop_ro("periodic_u", &Surface::periodic_u,
                   "u is an angle that wraps (sphere, cylinder): unbounded on a mechanism.")
      .def("evaluate", &Surface::evaluate, "u"_a, "v"_a, "The point S(u, v) (3,).")
      .def("derivatives", [](const Surface& s, double u, double v, int order) {
            SurfaceDerivatives d;
            s.derivatives(u, v, checked_order(order), d);
            const int n = order + 1;
            Rows3 out(n * n, 3);
            for (int k = 0; k < n; ++k)
              for (int l = 0; l < n; ++l) out.row(k * n + l) = d(k, l).transpose();
            return nb::cast(out).attr("reshape")(n, n, 3);
          }, "u"_a, "v"_a, "order"_a = 2,
          "(order + 1, order + 1, 3): entry [k, l] = d^(k+l) S / du^k dv^l for every k, l <= "
          "order (geomdl's convention).")
      .def("normal", &Surface::normal, "u"_a, "v"_a, "Unit normal (3,).")
      .def("curvature", [](const Surface& s, double u, double v) {
            const SurfaceCurvature c = s.curvature(u, v);
            nb::dict d;
            d["mean"] = c.mean;
            d["gaussian"] = c.gaussian;
            return d;
          }, "u"_a, "v"_a, "{'mean', 'gaussian'}: curvatures with respect to normal() [1/m, 1/m^2].");
  return cls;
}

// the surface's closest points: global, local from a start within bounds, many at once
void def_surface_queries(nb::class_<Surface>& cls) {
  cls.def("closest_point", [](const Surface& s, nb::handle p) {
            Eigen::Vector3d point;
            const Eigen::Vector2d uv = s.closest_point(vector_arg("p", p, 3), point);
            return nb::make_tuple(uv, point);
          }, "p"_a, "(parameters (2,), point (3,)): the point of the surface closest to p.")
      .def("closest_point_from", [](const Surface& s, nb::handle p, nb::handle start,
                                    nb::handle lo, nb::handle hi) {
            const Eigen::Vector3d x = vector_arg("p", p, 3);
            const Eigen::Vector2d x0 = parameters_arg("start", start, false);
            const Eigen::Vector2d l = lo.is_none() ? s.lower() : parameters_arg("lo", lo, true);
            const Eigen::Vector2d h = hi.is_none() ? s.upper() : parameters_arg("hi", hi, true);
            if (!(l[0] <= h[0] && l[1] <= h[1])) {
              throw nb::value_error(("hi: expected >= lo in each parameter, got lo " +
                                     format_vector(l) + ", hi " + format_vector(h)).c_str());
            }
            Eigen::Vector3d point;
            const Eigen::Vector2d uv = s.closest_point_from(x, x0, l, h, point);
            return nb::make_tuple(uv, point);
          }, "p"_a, "start"_a, "lo"_a = nb::none(), "hi"_a = nb::none(),
          "(parameters (2,), point (3,)): the local closest point to p reached from the "
          "parameters `start` within [lo, hi] (default the surface's bounds): the nearest point "
          "near a known one, as when tracking a point, not the global one.")
      .def("closest_points", [](const Surface& s, nb::handle X) {
            const Array x = array_arg("X", X, {-1, 3});
            const Eigen::Index n = x.shape[0];
            Rows2 uv(n, 2);
            Rows3 points(n, 3), normals(n, 3);
            {
              nb::gil_scoped_release release;
              for (Eigen::Index i = 0; i < n; ++i) {
                Eigen::Vector3d point;
                const Eigen::Vector2d w =
                    s.closest_point(Eigen::Map<const Eigen::Vector3d>(&x.data[3 * i]), point);
                uv.row(i) = w.transpose();
                points.row(i) = point.transpose();
                normals.row(i) = s.normal(w[0], w[1]).transpose();
              }
            }
            return nb::make_tuple(uv, points, normals);
          }, "X"_a,
          "(parameters (n, 2), points (n, 3), normals (n, 3)): closest_point for each row of X "
          "(n, 3), and the unit normal there, in one call.");
}

}  // namespace

void expose_geometry(nb::module_& m) {
  m.attr("MAX_NURBS_DEGREE") = kMaxNurbsDegree;
  expose_curve(m);
  nb::class_<Surface> surface = expose_surface(m);
  def_surface_queries(surface);
  def_shape<NurbsCurve, Curve>(m, "NurbsCurve");
  def_shape<NurbsSurface, Surface>(m, "NurbsSurface");
  def_shape<Sphere, Surface>(m, "Sphere").def_prop_ro("e1", &Sphere::e1).def_prop_ro("e2", &Sphere::e2);
  def_shape<Cylinder, Surface>(m, "Cylinder")
      .def_prop_ro("e1", &Cylinder::e1)
      .def_prop_ro("e2", &Cylinder::e2);
  def_shape<Plane, Surface>(m, "Plane")
      .def_prop_ro("normal_vector", [](const Plane& p) { return p.normal(); }, "The unit normal (3,).")
      .def_prop_ro("e1", &Plane::e1)
      .def_prop_ro("e2", &Plane::e2);
}

}  // namespace vmpy
