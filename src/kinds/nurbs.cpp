// NURBS curves and surfaces as kinds. Weights default to ones, knots to the clamped uniform
// vector of the degree (the curve or surface passes through its first and last control
// points).
#include "kinds.hpp"

namespace virtmech::kinds {

namespace {

// n + degree + 1 knots: degree + 1 zeros, evenly spaced interior knots, degree + 1 ones
Eigen::VectorXd clamped_uniform_knots(long n, long degree) {
  Eigen::VectorXd U(n + degree + 1);
  const double step = 1.0 / static_cast<double>(n - degree);
  for (long i = 0; i < U.size(); ++i) {
    const long interior = i - degree;  // 1 .. n - degree - 1 inside
    U[i] = i <= degree ? 0.0 : i >= n ? 1.0 : static_cast<double>(interior) * step;
  }
  return U;
}

Eigen::VectorXd knots_or_default(const Params& p, const char* name, long n, long degree) {
  return p.has(name) ? p.vector(name) : clamped_uniform_knots(n, degree);
}

using RowPoints = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

std::vector<double> row_major(const Eigen::MatrixXd& M) {
  std::vector<double> out;
  for (Eigen::Index r = 0; r < M.rows(); ++r)
    for (Eigen::Index c = 0; c < M.cols(); ++c) out.push_back(M(r, c));
  return out;
}

}  // namespace

void add_nurbs_curve(Registry& r) {
  CurveKind k;
  k.name = "NurbsCurve";
  k.doc = "A NURBS curve (Piegl & Tiller, The NURBS Book).";
  k.params = {array_param("control_points", {-1, 3}, std::nullopt, "m", "n points of 3 numbers"),
              optional(array_param("weights", {-1}, std::nullopt, "",
                                   "n numbers > 0 (default ones)")),
              optional(array_param("knots", {-1}, std::nullopt, "",
                                   "n + degree + 1 non-decreasing numbers (default clamped "
                                   "uniform)")),
              integer_param("degree", 3, 1, kMaxNurbsDegree, "the degree")};
  k.type = typeid(NurbsCurve);
  k.make = [](const Params& p) {
    const Array& P = p.array("control_points");
    const long n = P.shape[0], degree = p.integer("degree");
    const Eigen::MatrixX3d points = Eigen::Map<const RowPoints>(P.data.data(), n, 3);
    const Eigen::VectorXd w = p.has("weights") ? p.vector("weights") : Eigen::VectorXd::Ones(n);
    if (n < degree + 1) {
      throw std::invalid_argument("control_points: expected at least degree + 1 = " +
                                  std::to_string(degree + 1) + " points, got " + std::to_string(n));
    }
    return std::make_shared<const NurbsCurve>(points, w, knots_or_default(p, "knots", n, degree),
                                              static_cast<int>(degree));
  };
  k.describe = [](const Curve& curve) {
    const auto& c = static_cast<const NurbsCurve&>(curve);
    return Params("NurbsCurve")
        .set("control_points", Array{{c.size(), 3}, row_major(c.control_points())})
        .set_vector("weights", c.weights())
        .set_vector("knots", c.knots())
        .set("degree", c.degree());
  };
  r.add(std::move(k));
}

void add_nurbs_surface(Registry& r) {
  SurfaceKind k;
  k.name = "NurbsSurface";
  k.doc = "A tensor-product NURBS surface (Piegl & Tiller).";
  k.params = {array_param("control_points", {-1, -1, 3}, std::nullopt, "m",
                          "nu rows of nv points of 3 numbers"),
              optional(array_param("weights", {-1, -1}, std::nullopt, "",
                                   "nu rows of nv numbers > 0 (default ones)")),
              optional(array_param("knots_u", {-1}, std::nullopt, "",
                                   "nu + degree_u + 1 numbers (default clamped uniform)")),
              optional(array_param("knots_v", {-1}, std::nullopt, "",
                                   "nv + degree_v + 1 numbers (default clamped uniform)")),
              integer_param("degree_u", 3, 1, kMaxNurbsDegree, "the degree in u"),
              integer_param("degree_v", 3, 1, kMaxNurbsDegree, "the degree in v")};
  k.type = typeid(NurbsSurface);
  k.make = [](const Params& p) {
    const Array& P = p.array("control_points");
    const long nu = P.shape[0], nv = P.shape[1];
    const long du = p.integer("degree_u"), dv = p.integer("degree_v");
    Eigen::MatrixXd W = Eigen::MatrixXd::Ones(nu, nv);
    if (p.has("weights")) {
      W = p.matrix("weights");
      if (W.rows() != nu || W.cols() != nv) {
        throw std::invalid_argument(
            "weights: expected an array of shape (" + std::to_string(nu) + ", " +
            std::to_string(nv) + ") (the control points'), got shape (" +
            std::to_string(W.rows()) + ", " + std::to_string(W.cols()) + ")");
      }
    }
    const Eigen::MatrixX3d points = Eigen::Map<const RowPoints>(P.data.data(), nu * nv, 3);
    return std::make_shared<const NurbsSurface>(points, W, knots_or_default(p, "knots_u", nu, du),
                                                knots_or_default(p, "knots_v", nv, dv),
                                                static_cast<int>(du), static_cast<int>(dv));
  };
  k.describe = [](const Surface& surface) {
    const auto& s = static_cast<const NurbsSurface&>(surface);
    return Params("NurbsSurface")
        .set("control_points", Array{{s.size_u(), s.size_v(), 3}, row_major(s.control_points())})
        .set_matrix("weights", s.weights())
        .set_vector("knots_u", s.knots_u())
        .set_vector("knots_v", s.knots_v())
        .set("degree_u", s.degree_u())
        .set("degree_v", s.degree_v());
  };
  r.add(std::move(k));
}

}  // namespace virtmech::kinds
