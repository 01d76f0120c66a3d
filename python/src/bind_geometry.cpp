// Python bindings of the geometry objects (include/virtmech/geometry.hpp): translation
// only. Shapes are checked here so that errors name the parameter; every other rule (knots,
// weights, degrees) lives in the C++ core, whose std::invalid_argument becomes ValueError.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <cmath>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

#include "virtmech/geometry.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using namespace virtmech;

namespace {

using Rows3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

std::string shape_str(const std::vector<long>& s) {
  std::string out = "(";
  for (size_t i = 0; i < s.size(); ++i) out += (i ? ", " : "") + std::to_string(s[i]);
  return out + (s.size() == 1 ? ",)" : ")");
}

// `obj` as a float64 C-contiguous array with ndim dimensions; its shape in `shape`, data
// copied into `data`. ValueError / TypeError naming `name` and the expected shape.
std::vector<double> as_doubles(const char* name, nb::handle obj, size_t ndim,
                               const char* expected, std::vector<long>& shape) {
  static nb::object* asarray =  // leaked on purpose: must outlive finalisation
      new nb::object(nb::module_::import_("numpy").attr("ascontiguousarray"));
  if (obj.is_none()) {
    throw nb::type_error((std::string(name) + ": expected " + expected + ", got None").c_str());
  }
  nb::object a;
  try {
    a = (*asarray)(obj, "dtype"_a = "float64");
  } catch (nb::python_error&) {
    throw nb::type_error((std::string(name) + ": expected " + expected + ", got " +
                          nb::cast<std::string>(nb::repr(obj)).substr(0, 80)).c_str());
  }
  auto arr = nb::cast<nb::ndarray<const double, nb::c_contig, nb::device::cpu>>(a);
  shape.clear();
  for (size_t i = 0; i < arr.ndim(); ++i) shape.push_back(static_cast<long>(arr.shape(i)));
  if (arr.ndim() != ndim) {
    throw nb::value_error((std::string(name) + ": expected " + expected + ", got shape " +
                           shape_str(shape)).c_str());
  }
  return std::vector<double>(arr.data(), arr.data() + arr.size());
}

Eigen::Vector3d to_point(const char* name, nb::handle obj) {
  std::vector<long> s;
  auto d = as_doubles(name, obj, 1, "an array of shape (3,)", s);
  if (s[0] != 3) {
    throw nb::value_error((std::string(name) + ": expected an array of shape (3,), got shape " +
                           shape_str(s)).c_str());
  }
  return {d[0], d[1], d[2]};
}

Eigen::VectorXd to_vec(const char* name, nb::handle obj) {
  std::vector<long> s;
  auto d = as_doubles(name, obj, 1, "a 1-D array", s);
  return Eigen::Map<const Eigen::VectorXd>(d.data(), static_cast<Eigen::Index>(d.size()));
}

double to_number(const char* name, nb::handle obj) {
  try {
    return nb::cast<double>(obj);
  } catch (...) {
    throw nb::type_error((std::string(name) + ": expected a number, got " +
                          nb::cast<std::string>(nb::repr(obj)).substr(0, 80)).c_str());
  }
}

int to_degree(const char* name, nb::handle obj) {
  if (!PyLong_Check(obj.ptr()) && !PyIndex_Check(obj.ptr())) {
    throw nb::type_error((std::string(name) + ": expected an integer, got " +
                          nb::cast<std::string>(nb::repr(obj)).substr(0, 80)).c_str());
  }
  const long v = nb::cast<long>(obj.attr("__index__")());
  if (v < 1 || v > kMaxNurbsDegree) {
    throw nb::value_error((std::string(name) + ": expected 1 to " +
                           std::to_string(kMaxNurbsDegree) + ", got " + std::to_string(v)).c_str());
  }
  return static_cast<int>(v);
}

int check_order(int order, int max_order) {
  if (order < 0 || order > max_order) {
    throw nb::value_error(("order: expected 0 to " + std::to_string(max_order) + ", got " +
                           std::to_string(order)).c_str());
  }
  return order;
}

nb::object surface_derivatives(const Surface& s, double u, double v, int order) {
  check_order(order, kMaxDerivativeOrder);
  SurfaceDerivatives d;
  s.derivatives(u, v, order, d);
  const int n = order + 1;
  Rows3 out(n * n, 3);
  for (int k = 0; k < n; ++k)
    for (int l = 0; l < n; ++l) out.row(k * n + l) = d(k, l).transpose();
  return nb::cast(out).attr("reshape")(n, n, 3);
}

nb::tuple surface_closest(const Surface& s, nb::handle p) {
  Eigen::Vector3d point;
  const Eigen::Vector2d uv = s.closest_point(to_point("p", p), point);
  return nb::make_tuple(uv, point);
}

// (u, v): an array of shape (2,), finite unless `bound` (a parameter bound may be +-inf)
Eigen::Vector2d to_parameters(const char* name, nb::handle obj, bool bound) {
  std::vector<long> s;
  auto d = as_doubles(name, obj, 1, "an array of shape (2,)", s);
  if (s[0] != 2) {
    throw nb::value_error((std::string(name) + ": expected an array of shape (2,), got shape " +
                           shape_str(s)).c_str());
  }
  if (std::isnan(d[0]) || std::isnan(d[1]) ||
      (!bound && !(std::isfinite(d[0]) && std::isfinite(d[1])))) {
    throw nb::value_error((std::string(name) + ": expected " + (bound ? "numbers" : "finite numbers") +
                           ", got (" + std::to_string(d[0]) + ", " + std::to_string(d[1]) + ")").c_str());
  }
  return {d[0], d[1]};
}

nb::tuple surface_closest_from(const Surface& s, nb::handle p, nb::handle start, nb::handle lo,
                               nb::handle hi) {
  const Eigen::Vector3d x = to_point("p", p);
  const Eigen::Vector2d x0 = to_parameters("start", start, false);
  const Eigen::Vector2d l = lo.is_none() ? s.lower() : to_parameters("lo", lo, true);
  const Eigen::Vector2d h = hi.is_none() ? s.upper() : to_parameters("hi", hi, true);
  if (!(l[0] <= h[0] && l[1] <= h[1])) {
    throw nb::value_error(("hi: expected >= lo in each parameter, got lo (" + std::to_string(l[0]) +
                           ", " + std::to_string(l[1]) + "), hi (" + std::to_string(h[0]) + ", " +
                           std::to_string(h[1]) + ")").c_str());
  }
  Eigen::Vector3d point;
  const Eigen::Vector2d uv = s.closest_point_from(x, x0, l, h, point);
  return nb::make_tuple(uv, point);
}

nb::dict curvature_dict(const Surface& s, double u, double v) {
  const SurfaceCurvature c = s.curvature(u, v);
  nb::dict d;
  d["mean"] = c.mean;
  d["gaussian"] = c.gaussian;
  return d;
}

}  // namespace

// The constructor's arguments as a JSON-ready dict: {"type": type, key: self.attr, ...}
// (arrays as nested lists).
nb::dict shape_dict(nb::handle self, const char* type,
                    std::initializer_list<std::pair<const char*, const char*>> keys) {
  nb::dict d;
  d["type"] = type;
  for (const auto& [key, attr] : keys) {
    nb::object v = self.attr(attr);
    if (nb::hasattr(v, "tolist")) v = v.attr("tolist")();
    d[key] = v;
  }
  return d;
}

// `obj` as n points (n, 3), row-major; ValueError naming `name` otherwise.
std::vector<double> to_points(const char* name, nb::handle obj, long& n) {
  std::vector<long> s;
  auto d = as_doubles(name, obj, 2, "an array of shape (n, 3)", s);
  if (s[1] != 3) {
    throw nb::value_error((std::string(name) + ": expected an array of shape (n, 3), got shape " +
                           shape_str(s)).c_str());
  }
  n = s[0];
  return d;
}

void bind_geometry(nb::module_& m) {
  m.attr("MAX_NURBS_DEGREE") = kMaxNurbsDegree;

  nb::class_<Curve>(m, "Curve", "A parametric curve C(u) (base class).")
      .def_prop_ro("lower", &Curve::lower, "Lower parameter bound.")
      .def_prop_ro("upper", &Curve::upper, "Upper parameter bound.")
      .def("evaluate", &Curve::evaluate, "u"_a,
           "The point C(u) (3,); u is clamped to [lower, upper].")
      .def(
          "derivatives",
          [](const Curve& c, double u, int order) {
            check_order(order, kMaxDerivativeOrder);
            CurveDerivatives d;
            c.derivatives(u, order, d);
            return Rows3(d.leftCols(order + 1).transpose());
          },
          "u"_a, "order"_a = 2,
          "(order + 1, 3): row k the k-th derivative d^k C / du^k (row 0 the point).")
      .def("tangent", &Curve::tangent, "u"_a, "Unit tangent (3,).")
      .def("curvature", &Curve::curvature, "u"_a, "Curvature [1/m].")
      .def(
          "closest_point",
          [](const Curve& c, nb::handle p) {
            Eigen::Vector3d point;
            const double u = c.closest_point(to_point("p", p), point);
            return nb::make_tuple(u, point);
          },
          "p"_a, "(u, point): the parameter and the point (3,) of the curve closest to p.")
      .def(
          "closest_points",
          [](const Curve& c, nb::handle X) {
            long n = 0;
            const std::vector<double> x = to_points("X", X, n);
            Eigen::VectorXd u(n);
            Rows3 points(n, 3);
            {
              nb::gil_scoped_release release;
              for (long i = 0; i < n; ++i) {
                Eigen::Vector3d point;
                u[i] = c.closest_point(Eigen::Vector3d(x[3 * i], x[3 * i + 1], x[3 * i + 2]), point);
                points.row(i) = point.transpose();
              }
            }
            return nb::make_tuple(u, points);
          },
          "X"_a,
          "(u (n,), points (n, 3)): closest_point for each row of X (n, 3), in one call.");

  nb::class_<Surface>(m, "Surface", "A parametric surface S(u, v) (base class).")
      .def_prop_ro("lower", &Surface::lower, "Lower parameter bounds (u, v) (may be -inf).")
      .def_prop_ro("upper", &Surface::upper, "Upper parameter bounds (u, v) (may be inf).")
      .def_prop_ro("periodic_u", &Surface::periodic_u,
                   "u is an angle that wraps (sphere, cylinder): unbounded on a mechanism.")
      .def("evaluate", &Surface::evaluate, "u"_a, "v"_a, "The point S(u, v) (3,).")
      .def("derivatives", &surface_derivatives, "u"_a, "v"_a, "order"_a = 2,
           "(order + 1, order + 1, 3): entry [k, l] = d^(k+l) S / du^k dv^l for every "
           "k, l <= order (geomdl's convention).")
      .def("normal", &Surface::normal, "u"_a, "v"_a, "Unit normal (3,).")
      .def("curvature", &curvature_dict, "u"_a, "v"_a,
           "{'mean', 'gaussian'}: curvatures with respect to normal() [1/m, 1/m^2].")
      .def("closest_point", &surface_closest, "p"_a,
           "(parameters (2,), point (3,)): the point of the surface closest to p.")
      .def("closest_point_from", &surface_closest_from, "p"_a, "start"_a, "lo"_a = nb::none(),
           "hi"_a = nb::none(),
           "(parameters (2,), point (3,)): the local closest point to p reached from the "
           "parameters `start` within [lo, hi] (default the surface's bounds): the nearest "
           "point near a known one, as when tracking a point, not the global one.")
      .def(
          "closest_points",
          [](const Surface& sf, nb::handle X) {
            long n = 0;
            const std::vector<double> x = to_points("X", X, n);
            Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor> uv(n, 2);
            Rows3 points(n, 3), normals(n, 3);
            {
              nb::gil_scoped_release release;
              for (long i = 0; i < n; ++i) {
                Eigen::Vector3d point;
                const Eigen::Vector2d w =
                    sf.closest_point(Eigen::Vector3d(x[3 * i], x[3 * i + 1], x[3 * i + 2]), point);
                uv.row(i) = w.transpose();
                points.row(i) = point.transpose();
                normals.row(i) = sf.normal(w[0], w[1]).transpose();
              }
            }
            return nb::make_tuple(uv, points, normals);
          },
          "X"_a,
          "(parameters (n, 2), points (n, 3), normals (n, 3)): closest_point for each row of X "
          "(n, 3), and the unit normal there, in one call.");

  nb::class_<NurbsCurve, Curve>(m, "NurbsCurve",
                                "A NURBS curve (Piegl & Tiller, The NURBS Book).")
      .def(
          "__init__",
          [](NurbsCurve* self, nb::handle control_points, nb::handle weights, nb::handle knots,
             nb::handle degree) {
            std::vector<long> s;
            auto P = as_doubles("control_points", control_points, 2, "an array of shape (n, 3)", s);
            if (s[1] != 3) {
              throw nb::value_error(("control_points: expected an array of shape (n, 3), got "
                                     "shape " + shape_str(s)).c_str());
            }
            const Eigen::MatrixX3d Pm = Eigen::Map<const Rows3>(P.data(), s[0], 3);
            const Eigen::VectorXd w = to_vec("weights", weights);
            const Eigen::VectorXd U = to_vec("knots", knots);
            const int p = to_degree("degree", degree);
            nb::gil_scoped_release release;
            new (self) NurbsCurve(Pm, w, U, p);
          },
          "control_points"_a, "weights"_a, "knots"_a, "degree"_a,
          "control_points (n, 3) [m]; weights (n,) > 0; knots: n + degree + 1 non-decreasing "
          "values; 1 <= degree <= MAX_NURBS_DEGREE.")
      .def_prop_ro("degree", &NurbsCurve::degree)
      .def_prop_ro("control_points", [](const NurbsCurve& c) { return Rows3(c.control_points()); })
      .def_prop_ro("weights", &NurbsCurve::weights)
      .def_prop_ro("knots", &NurbsCurve::knots)
      .def("to_dict", [](nb::handle self) {
        return shape_dict(self, "NurbsCurve", {{"control_points", "control_points"},
                                               {"weights", "weights"}, {"knots", "knots"},
                                               {"degree", "degree"}});
      }, "The constructor's arguments as a JSON-ready dict (with 'type').");

  nb::class_<NurbsSurface, Surface>(m, "NurbsSurface",
                                    "A tensor-product NURBS surface (Piegl & Tiller).")
      .def(
          "__init__",
          [](NurbsSurface* self, nb::handle control_points, nb::handle weights,
             nb::handle knots_u, nb::handle knots_v, nb::handle degree_u, nb::handle degree_v) {
            std::vector<long> s, sw;
            auto P = as_doubles("control_points", control_points, 3,
                                "an array of shape (nu, nv, 3)", s);
            if (s[2] != 3) {
              throw nb::value_error(("control_points: expected an array of shape (nu, nv, 3), "
                                     "got shape " + shape_str(s)).c_str());
            }
            auto W = as_doubles("weights", weights, 2, "an array of shape (nu, nv)", sw);
            if (sw[0] != s[0] || sw[1] != s[1]) {
              throw nb::value_error(("weights: expected an array of shape " +
                                     shape_str({s[0], s[1]}) + " (the control points'), got "
                                     "shape " + shape_str(sw)).c_str());
            }
            const Eigen::MatrixX3d Pm = Eigen::Map<const Rows3>(P.data(), s[0] * s[1], 3);
            using RowsX = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
            const Eigen::MatrixXd Wm = Eigen::Map<const RowsX>(W.data(), sw[0], sw[1]);
            const Eigen::VectorXd Uu = to_vec("knots_u", knots_u);
            const Eigen::VectorXd Uv = to_vec("knots_v", knots_v);
            const int p = to_degree("degree_u", degree_u);
            const int q = to_degree("degree_v", degree_v);
            nb::gil_scoped_release release;
            new (self) NurbsSurface(Pm, Wm, Uu, Uv, p, q);
          },
          "control_points"_a, "weights"_a, "knots_u"_a, "knots_v"_a, "degree_u"_a,
          "degree_v"_a,
          "control_points (nu, nv, 3) [m]; weights (nu, nv) > 0; knots_u: nu + degree_u + 1 "
          "values, knots_v: nv + degree_v + 1 (non-decreasing).")
      .def_prop_ro("degree_u", &NurbsSurface::degree_u)
      .def_prop_ro("degree_v", &NurbsSurface::degree_v)
      .def_prop_ro("control_points",
                   [](const NurbsSurface& s) {
                     return nb::cast(Rows3(s.control_points()))
                         .attr("reshape")(s.size_u(), s.size_v(), 3);
                   })
      .def_prop_ro("weights", &NurbsSurface::weights)
      .def_prop_ro("knots_u", &NurbsSurface::knots_u)
      .def_prop_ro("knots_v", &NurbsSurface::knots_v)
      .def("to_dict", [](nb::handle self) {
        return shape_dict(self, "NurbsSurface",
                          {{"control_points", "control_points"}, {"weights", "weights"},
                           {"knots_u", "knots_u"}, {"knots_v", "knots_v"},
                           {"degree_u", "degree_u"}, {"degree_v", "degree_v"}});
      }, "The constructor's arguments as a JSON-ready dict (with 'type').");

  nb::class_<Sphere, Surface>(
      m, "Sphere",
      "Sphere S(u, v) = c + r (cos u cos v e1 + sin u cos v e2 + sin v a): u the longitude "
      "in [-pi, pi] (periodic), v the latitude in [-pi/2, pi/2]; outward normal. `axis` a "
      "points to the pole v = pi/2; e1 = world x made orthogonal to a (y where a is along x), "
      "e2 = a x e1: the default axis z gives (e1, e2) = (x, y).")
      .def(
          "__init__",
          [](Sphere* self, nb::handle center, nb::handle radius, nb::handle axis) {
            new (self) Sphere(to_point("center", center), to_number("radius", radius),
                              axis.is_none() ? Eigen::Vector3d::UnitZ()
                                             : to_point("axis", axis));
          },
          "center"_a, "radius"_a, "axis"_a = nb::none())
      .def_prop_ro("center", &Sphere::center)
      .def_prop_ro("radius", &Sphere::radius)
      .def_prop_ro("axis", &Sphere::axis)
      .def_prop_ro("e1", &Sphere::e1)
      .def_prop_ro("e2", &Sphere::e2)
      .def("to_dict", [](nb::handle self) {
        return shape_dict(self, "Sphere",
                          {{"center", "center"}, {"radius", "radius"}, {"axis", "axis"}});
      }, "The constructor's arguments as a JSON-ready dict (with 'type').");

  nb::class_<Cylinder, Surface>(
      m, "Cylinder",
      "Infinite cylinder S(u, v) = a + r (cos u e1 + sin u e2) + v d: d the unit axis, "
      "e1 = an orthogonal unit vector (e1 property), e2 = d x e1; normal away from the axis.")
      .def(
          "__init__",
          [](Cylinder* self, nb::handle point, nb::handle direction, nb::handle radius) {
            new (self) Cylinder(to_point("point", point), to_point("direction", direction),
                                to_number("radius", radius));
          },
          "point"_a, "direction"_a, "radius"_a)
      .def_prop_ro("point", &Cylinder::point)
      .def_prop_ro("direction", &Cylinder::direction)
      .def_prop_ro("radius", &Cylinder::radius)
      .def_prop_ro("e1", &Cylinder::e1)
      .def_prop_ro("e2", &Cylinder::e2)
      .def("to_dict", [](nb::handle self) {
        return shape_dict(self, "Cylinder", {{"point", "point"}, {"direction", "direction"},
                                             {"radius", "radius"}});
      }, "The constructor's arguments as a JSON-ready dict (with 'type').");

  nb::class_<Plane, Surface>(
      m, "Plane",
      "Infinite plane S(u, v) = o + u e1 + v e2: n the unit normal, e1 an orthogonal unit "
      "vector (e1 property), e2 = n x e1.")
      .def(
          "__init__",
          [](Plane* self, nb::handle point, nb::handle normal) {
            new (self) Plane(to_point("point", point), to_point("normal", normal));
          },
          "point"_a, "normal"_a)
      .def_prop_ro("point", &Plane::point)
      .def_prop_ro("normal_vector", [](const Plane& p) { return p.normal(); },
                   "The unit normal (3,).")
      .def_prop_ro("e1", &Plane::e1)
      .def_prop_ro("e2", &Plane::e2)
      .def("to_dict", [](nb::handle self) {
        return shape_dict(self, "Plane", {{"point", "point"}, {"normal", "normal_vector"}});
      }, "The constructor's arguments as a JSON-ready dict (with 'type').");
}
