// Geometry objects: curves and surfaces evaluated with derivatives, for mechanisms that
// follow a shape (a probe on a surface, a guide along a curve).
//
// NURBS after Piegl & Tiller, The NURBS Book, 2nd ed., 1997 (docs/geometry.md): find span
// (A2.1), basis functions and their derivatives (A2.3), curve and surface derivatives
// (A3.2, A3.6) of the homogeneous form, rational derivatives (A4.2, A4.4). Analytic
// shapes: Sphere, Cylinder, Plane with the parametrisations documented on each class.
//
// Every evaluation method is const, noexcept and allocation-free: work arrays are
// fixed-size on the stack (degree <= kMaxNurbsDegree, checked by the constructors), and
// closest_point searches samples computed at construction. The objects are immutable after
// construction, so one object may be evaluated from several threads at once.
//
// Derivative orders: `derivatives` fills orders 0..order with order <= kMaxDerivativeOrder
// (a larger order is clamped). The real-time users need order 2 at most (position,
// tangents, curvature); the higher orders are there for testing and the Python API.
#pragma once

#include <vector>

#include "virtmech/types.hpp"

namespace virtmech {

/// Largest NURBS degree (fixed-size work arrays).
constexpr int kMaxNurbsDegree = 7;
/// Largest derivative order `derivatives` computes.
constexpr int kMaxDerivativeOrder = kMaxNurbsDegree;
/// Largest number of closest-point samples a NurbsSurface takes (max(8, 2 degree) per
/// non-empty knot span and direction, plus one, in u times in v: 1577 x 1577 for 200 x 200
/// control points of degree 3). The samples, their cells and the cells' hierarchy take
/// about 230 bytes a sample (about 1 GB at the limit), and the constructor's time grows with
/// them (about 20 s for 200 x 200 points): a larger surface is refused.
constexpr long kMaxNurbsSurfaceSamples = 1L << 22;

/// Column k: the k-th derivative d^k C / du^k (column 0 the point).
using CurveDerivatives = Eigen::Matrix<double, 3, kMaxDerivativeOrder + 1>;

/// Partial derivatives of a surface: (k, l) = d^(k+l) S / du^k dv^l ((0, 0) the point).
/// `derivatives(..., order, d)` fills every (k, l) with k, l <= order, mixed orders up to
/// 2 order included (geomdl's convention).
struct SurfaceDerivatives {
  static constexpr int kSize = kMaxDerivativeOrder + 1;
  Eigen::Vector3d d[kSize][kSize];
  Eigen::Vector3d& operator()(int k, int l) noexcept { return d[k][l]; }
  const Eigen::Vector3d& operator()(int k, int l) const noexcept { return d[k][l]; }
};

/// Mean and Gaussian curvature of a surface [1/m, 1/m^2], signed with respect to normal():
/// a sphere with outward normals has mean curvature -1/r.
struct SurfaceCurvature {
  double mean = 0.0;
  double gaussian = 0.0;
};

/// A parametric curve C(u), u in [lower(), upper()] (interface).
class Curve {
 public:
  virtual ~Curve() = default;
  /// Parameter bounds; parameters outside are clamped to them.
  virtual double lower() const noexcept = 0;
  virtual double upper() const noexcept = 0;
  /// The point C(u).
  virtual Eigen::Vector3d evaluate(double u) const noexcept = 0;
  /// Columns 0..order of d: C(u) and its derivatives (order clamped to
  /// [0, kMaxDerivativeOrder]; the other columns are left as they were).
  virtual void derivatives(double u, int order, CurveDerivatives& d) const noexcept = 0;
  /// The parameter of the point of the curve closest to p; the point in `point`.
  virtual double closest_point(const Eigen::Vector3d& p, Eigen::Vector3d& point) const noexcept = 0;

  /// Unit tangent C'/|C'| (zero where C' vanishes).
  Eigen::Vector3d tangent(double u) const noexcept;
  /// Curvature |C' x C''| / |C'|^3 [1/m] (0 where C' vanishes).
  double curvature(double u) const noexcept;
};

/// A parametric surface S(u, v), (u, v) within [lower(), upper()] (interface).
class Surface {
 public:
  virtual ~Surface() = default;
  /// Parameter bounds (u, v); may be infinite. Parameters outside are clamped to them.
  virtual Eigen::Vector2d lower() const noexcept = 0;
  virtual Eigen::Vector2d upper() const noexcept = 0;
  /// The point S(u, v).
  virtual Eigen::Vector3d evaluate(double u, double v) const noexcept = 0;
  /// d(k, l) = d^(k+l) S / du^k dv^l for k, l in 0..order (order clamped to
  /// [0, kMaxDerivativeOrder]), as geomdl: the mixed ones up to k + l = 2 order included.
  virtual void derivatives(double u, double v, int order,
                           SurfaceDerivatives& d) const noexcept = 0;
  /// Unit normal. The default: S_u x S_v normalised (at a degenerate point, such as a
  /// collapsed edge, taken a little inside the patch).
  virtual Eigen::Vector3d normal(double u, double v) const noexcept;
  /// The parameters (u, v) of the point of the surface closest to p; the point in `point`.
  virtual Eigen::Vector2d closest_point(const Eigen::Vector3d& p,
                                        Eigen::Vector3d& point) const noexcept = 0;
  /// The local closest point reached from `start` (clamped to [lo, hi]) by the closest
  /// point's refinement (projected Newton on |S - p|^2 / 2 within [lo, hi], which may be
  /// infinite where u wraps): the nearest point near a known one, as when tracking a point
  /// cycle to cycle, not the global one. The point in `point`.
  Eigen::Vector2d closest_point_from(const Eigen::Vector3d& p, const Eigen::Vector2d& start,
                                     const Eigen::Vector2d& lo, const Eigen::Vector2d& hi,
                                     Eigen::Vector3d& point) const noexcept;

  /// Mean and Gaussian curvature from the fundamental forms, with respect to normal().
  SurfaceCurvature curvature(double u, double v) const noexcept;
  /// u is an angle that wraps (S(u + 2 pi, v) = S(u, v)): a mechanism on the surface leaves
  /// it unbounded instead of stopping at lower()[0], upper()[0].
  virtual bool periodic_u() const noexcept { return false; }
};

/// A NURBS curve of degree p with n control points, weights and n + p + 1 knots.
class NurbsCurve final : public Curve {
 public:
  /// control_points (n, 3) [m]; weights (n,) > 0; knots: n + degree + 1 non-decreasing
  /// values (clamped or not; a knot's multiplicity at most degree + 1); 1 <= degree <=
  /// kMaxNurbsDegree, n >= degree + 1. Throws std::invalid_argument naming the parameter.
  NurbsCurve(const Eigen::MatrixX3d& control_points, const Eigen::VectorXd& weights,
             const Eigen::VectorXd& knots, int degree);

  double lower() const noexcept override { return lower_; }
  double upper() const noexcept override { return upper_; }
  Eigen::Vector3d evaluate(double u) const noexcept override;
  void derivatives(double u, int order, CurveDerivatives& d) const noexcept override;
  double closest_point(const Eigen::Vector3d& p, Eigen::Vector3d& point) const noexcept override;

  int degree() const noexcept { return p_; }
  int size() const noexcept { return n_; }
  Eigen::MatrixX3d control_points() const;
  Eigen::VectorXd weights() const;
  const Eigen::VectorXd& knots() const noexcept { return knots_; }

 private:
  // derivatives within knot span `span` (a one-sided limit at a knot), from taylor_
  void derivatives_in_span(double u, int span, int order, CurveDerivatives& d) const noexcept;
  // the homogeneous curve's derivatives to order nd from the basis functions of `span`
  // (The NURBS Book, A3.2), for taylor_
  void homogeneous_from_basis(double u, int span, int nd,
                              Eigen::Vector4d (&Cw)[kMaxDerivativeOrder + 1]) const noexcept;

  // closest_point's view of the samples from a point (nurbs_curve.cpp)
  struct Search;

  int n_ = 0, p_ = 1;
  // derivatives_in_span's arithmetic, an instance for the degree p (loops unrolled)
  void (*kernel_)(const Eigen::Vector4d* taylor, double x, int p, int order,
                  CurveDerivatives& d) noexcept = nullptr;
  Eigen::Matrix4Xd pw_;  // homogeneous control points (w x, w y, w z, w)
  // per span (span - p), p + 1 coefficients C_a of the homogeneous curve, a polynomial
  // there: sum C_a (u - u_mid)^a, u_mid the span's middle; zero for an empty span
  std::vector<Eigen::Vector4d> taylor_;
  Eigen::VectorXd knots_;
  double lower_ = 0.0, upper_ = 1.0;
  // closest point: the samples' parameters and points; the first derivative at the start
  // of interval i (from the right) and at its end (from the left), i < samples - 1
  std::vector<double> sample_u_;
  std::vector<Eigen::Vector3d> sample_p_, sample_d_start_, sample_d_end_;
  // a sphere holding the curve over sample interval i (closest_point skips an interval
  // farther than a minimum it has found)
  std::vector<Eigen::Vector3d> interval_center_;
  std::vector<double> interval_radius_;
};

namespace detail {
/// Vectors alpha axis + rest with alpha in [alpha_lo, alpha_hi] and rest in a box: a bound
/// on vectors of about one direction whose length varies (a box alone would spread a
/// length's change over every coordinate a slanted axis has).
struct VectorBound {
  Eigen::Vector3d axis = Eigen::Vector3d::Zero();
  double alpha_lo = 0.0, alpha_hi = 0.0;
  Eigen::AlignedBox3d rest;
};

/// A block of sample cells [i0, i1) x [j0, j1) (cell (i, j) between samples (i, j) and
/// (i + 1, j + 1)) in NurbsSurface::closest_point's hierarchy, with bounds on what the
/// search reads there: the cells' bounding spheres; the samples [i0 - 1, i1 + 1] x
/// [j0 - 1, j1 + 1] (those in range); the steps between neighbouring samples along u that
/// end in rows [i0, i1 + 1] of columns [j0, j1], and along v likewise; the first
/// derivatives S_u (both sides) and S_v (both sides) at the cells' corners.
struct NurbsCellBlock {
  Eigen::AlignedBox3d spheres, samples;
  VectorBound step_u, step_v, su, sv;
  int i0 = 0, i1 = 0, j0 = 0, j1 = 0;
  int first_child = -1, children = 0;  ///< the children follow one another
};
}  // namespace detail

/// A tensor-product NURBS surface of degrees (p, q) with nu x nv control points.
///
/// closest_point searches a hierarchy of the samples' cells built by the constructor
/// (linear in the number of samples), so that its cost grows with the part of the surface
/// near the point rather than with the whole surface.
class NurbsSurface final : public Surface {
 public:
  /// control_points (nu * nv, 3), row i * nv + j the point P_ij [m]; weights (nu, nv) > 0
  /// (its shape gives nu, nv); knots_u: nu + degree_u + 1 values, knots_v: nv + degree_v +
  /// 1 (non-decreasing, multiplicity at most degree + 1); 1 <= degree <= kMaxNurbsDegree;
  /// at most kMaxNurbsSurfaceSamples closest-point samples (about 260 x 260 control points
  /// of degree 3, fewer of a higher degree). Throws std::invalid_argument naming the
  /// parameter.
  NurbsSurface(const Eigen::MatrixX3d& control_points, const Eigen::MatrixXd& weights,
               const Eigen::VectorXd& knots_u, const Eigen::VectorXd& knots_v, int degree_u,
               int degree_v);

  Eigen::Vector2d lower() const noexcept override { return lower_; }
  Eigen::Vector2d upper() const noexcept override { return upper_; }
  Eigen::Vector3d evaluate(double u, double v) const noexcept override;
  void derivatives(double u, double v, int order, SurfaceDerivatives& d) const noexcept override;
  Eigen::Vector2d closest_point(const Eigen::Vector3d& p,
                                Eigen::Vector3d& point) const noexcept override;

  int degree_u() const noexcept { return p_; }
  int degree_v() const noexcept { return q_; }
  int size_u() const noexcept { return nu_; }
  int size_v() const noexcept { return nv_; }
  Eigen::MatrixX3d control_points() const;
  Eigen::MatrixXd weights() const;
  const Eigen::VectorXd& knots_u() const noexcept { return knots_u_; }
  const Eigen::VectorXd& knots_v() const noexcept { return knots_v_; }

 private:
  // derivatives within knot spans su, sv (one-sided limits at knots), from taylor_
  void derivatives_in_spans(double u, double v, int su, int sv, int order,
                            SurfaceDerivatives& d) const noexcept;
  // the homogeneous surface's derivatives to order nd (every k, l <= nd) from the basis
  // functions of spans su, sv (The NURBS Book, A3.6), for taylor_
  void homogeneous_from_basis(double u, double v, int su, int sv, int nd,
                              Eigen::Vector4d (&Sw)[kMaxDerivativeOrder + 1]
                                                   [kMaxDerivativeOrder + 1]) const noexcept;

  // the constructor's stages: each non-empty span pair's Taylor coefficients, the samples
  // with their first derivatives, the cells' bounding spheres (after the samples), their
  // hierarchy (after the spheres)
  void build_taylor();
  void build_samples();
  void build_cell_bounds();
  void build_blocks();
  void build_block(int index, int i0, int i1, int j0, int j1, int depth);
  void fill_block(detail::NurbsCellBlock& b) const;
  // the number of samples along knots (nurbs_basis' sample_parameters' count)
  static long sample_count(const Eigen::VectorXd& knots, int n, int p) noexcept;
  // closest_point's view of the samples, cells and blocks from a point
  // (nurbs_surface_search.hpp)
  struct Search;


  int nu_ = 0, nv_ = 0, p_ = 1, q_ = 1;
  // derivatives_in_spans' arithmetic, an instance for the degrees (p, q) (loops unrolled)
  void (*kernel_)(const Eigen::Vector4d* taylor, double x, double y, int p, int q, int order,
                  SurfaceDerivatives& d) noexcept = nullptr;
  Eigen::Matrix4Xd pw_;  // column i * nv + j
  // per span pair (su - p) * (nv - q) + (sv - q), (p + 1)(q + 1) coefficients C_ab (index
  // a * (q + 1) + b) of the homogeneous surface, a polynomial there: sum C_ab (u - u_mid)^a
  // (v - v_mid)^b about the span pair's middle; zero for an empty span
  std::vector<Eigen::Vector4d> taylor_;
  Eigen::VectorXd knots_u_, knots_v_;
  Eigen::Vector2d lower_, upper_;
  std::vector<double> sample_u_, sample_v_;
  // index i * sample_v_.size() + j: the point and its first derivatives S_u, S_v
  std::vector<Eigen::Vector3d> sample_p_, sample_su_, sample_sv_;
  // the same S_u from the left in u and S_v from below in v (they differ from the above
  // across a crease: a cell's corners take their derivatives from inside it)
  std::vector<Eigen::Vector3d> sample_su_left_, sample_sv_below_;
  // a sphere holding the surface over sample cell i * (sample_v_.size() - 1) + j
  // (closest_point skips a start whose cells are all farther than a minimum it has found)
  std::vector<Eigen::Vector3d> cell_center_;
  std::vector<double> cell_radius_;
  std::vector<detail::NurbsCellBlock> blocks_;  // the hierarchy, its root first
  int block_depth_ = 0;  // the hierarchy's depth (the root's children: 1)
  bool kinked_ = false;  // an interior knot across which the surface is not C^2
  bool creased_ = false;  // ... nor C^1
};

/// Sphere S(u, v) = c + r (cos u cos v e1 + sin u cos v e2 + sin v a): u the longitude in
/// [-pi, pi] (periodic), v the latitude in [-pi/2, pi/2]; the normal points outward. `axis`
/// a (normalised) points to the pole v = pi/2; e1 is world x made orthogonal to a (world y
/// where a is along x), e2 = a x e1: the default axis z gives (e1, e2) = (x, y). The poles
/// are the parametrisation's singular points: a mechanism on the sphere puts them where it
/// is not used.
class Sphere final : public Surface {
 public:
  /// radius > 0, axis non-zero. Throws std::invalid_argument naming the parameter.
  Sphere(const Eigen::Vector3d& center, double radius,
         const Eigen::Vector3d& axis = Eigen::Vector3d::UnitZ());
  Eigen::Vector2d lower() const noexcept override;
  Eigen::Vector2d upper() const noexcept override;
  Eigen::Vector3d evaluate(double u, double v) const noexcept override;
  void derivatives(double u, double v, int order, SurfaceDerivatives& d) const noexcept override;
  Eigen::Vector3d normal(double u, double v) const noexcept override;
  /// For p at the centre: the point at (u, v) = (0, 0).
  Eigen::Vector2d closest_point(const Eigen::Vector3d& p,
                                Eigen::Vector3d& point) const noexcept override;
  bool periodic_u() const noexcept override { return true; }
  const Eigen::Vector3d& center() const noexcept { return c_; }
  double radius() const noexcept { return r_; }
  Eigen::Vector3d axis() const noexcept { return A_.col(2); }
  Eigen::Vector3d e1() const noexcept { return A_.col(0); }
  Eigen::Vector3d e2() const noexcept { return A_.col(1); }

 private:
  Eigen::Vector3d c_;
  double r_;
  Eigen::Matrix3d A_;  // columns e1, e2, a
};

/// Infinite circular cylinder S(u, v) = a + r (cos u e1 + sin u e2) + v d: d the unit axis
/// direction, e1 = d.unitOrthogonal() (Eigen's), e2 = d x e1; u the angle in [-pi, pi], v
/// the axial coordinate [m] (unbounded). The normal points away from the axis.
class Cylinder final : public Surface {
 public:
  /// direction: non-zero (normalised); radius > 0. Throws std::invalid_argument.
  Cylinder(const Eigen::Vector3d& point, const Eigen::Vector3d& direction, double radius);
  Eigen::Vector2d lower() const noexcept override;
  Eigen::Vector2d upper() const noexcept override;
  Eigen::Vector3d evaluate(double u, double v) const noexcept override;
  void derivatives(double u, double v, int order, SurfaceDerivatives& d) const noexcept override;
  Eigen::Vector3d normal(double u, double v) const noexcept override;
  /// For p on the axis: the point at u = 0.
  Eigen::Vector2d closest_point(const Eigen::Vector3d& p,
                                Eigen::Vector3d& point) const noexcept override;
  bool periodic_u() const noexcept override { return true; }
  const Eigen::Vector3d& point() const noexcept { return a_; }
  const Eigen::Vector3d& direction() const noexcept { return d_; }
  double radius() const noexcept { return r_; }
  const Eigen::Vector3d& e1() const noexcept { return e1_; }
  const Eigen::Vector3d& e2() const noexcept { return e2_; }

 private:
  Eigen::Vector3d a_, d_, e1_, e2_;
  double r_;
};

/// Infinite plane S(u, v) = o + u e1 + v e2: n the unit normal, e1 = n.unitOrthogonal()
/// (Eigen's), e2 = n x e1; u, v in metres (unbounded).
class Plane final : public Surface {
 public:
  /// normal: non-zero (normalised). Throws std::invalid_argument naming the parameter.
  Plane(const Eigen::Vector3d& point, const Eigen::Vector3d& normal);
  Eigen::Vector2d lower() const noexcept override;
  Eigen::Vector2d upper() const noexcept override;
  Eigen::Vector3d evaluate(double u, double v) const noexcept override;
  void derivatives(double u, double v, int order, SurfaceDerivatives& d) const noexcept override;
  Eigen::Vector3d normal(double u, double v) const noexcept override;
  Eigen::Vector2d closest_point(const Eigen::Vector3d& p,
                                Eigen::Vector3d& point) const noexcept override;
  const Eigen::Vector3d& point() const noexcept { return o_; }
  const Eigen::Vector3d& normal() const noexcept { return n_; }
  const Eigen::Vector3d& e1() const noexcept { return e1_; }
  const Eigen::Vector3d& e2() const noexcept { return e2_; }

 private:
  Eigen::Vector3d o_, n_, e1_, e2_;
};

}  // namespace virtmech
