// Closed-form placements of probe-like mechanisms (a stylus of length L whose tip is held to
// a plane or a point, the three wrist joints meeting at the tip). Internal to the core; the
// solvers live in src/closed_form/, one source each (tilt, stylus_direction,
// stylus_newton, arc, euler_xyz).
//
// With weights isotropic within the position block (w_p) and within the rotation block
// (w_r), the weighted optimum of e^T W e reduces to one angle: for a stylus whose tip-to-
// handle direction u makes the angle phi with a reference axis, the nearest orientation to
// the handle's is the handle's own turned about (u_R x axis) by phi_R - phi (no rotation of
// a frame is shorter than the angle it turns one of its vectors through), and the best tip
// for that orientation follows in closed form. What is left is
//   f(phi) = w_p * position(phi) + w_r * (phi - phi_R)^2,
// minimised between the position term's minimiser and phi_R, where f' changes sign from -
// to +: one bracketed Newton solve (docs/theory.md, section 4).
#pragma once

#include <cmath>

#include "virtmech/geometry.hpp"
#include "virtmech/types.hpp"

namespace virtmech::detail {

/// Position and rotation weights when W is isotropic within each block (w[0] = w[1] =
/// w[2], w[3] = w[4] = w[5]); false otherwise.
bool isotropic_blocks(const Vector6& w, double& w_p, double& w_r) noexcept;
/// isotropic_blocks for both weightings of a pair (Mechanism::place_pair): false unless both.
inline bool isotropic_blocks(const Vector6& w_a, const Vector6& w_b, double& wp_a, double& wr_a,
                             double& wp_b, double& wr_b) noexcept {
  return isotropic_blocks(w_a, wp_a, wr_a) && isotropic_blocks(w_b, wp_b, wr_b);
}

/// The position cost of a stylus as a function of c = cos(phi), phi the angle between its
/// tip-to-handle direction and a reference axis: p2 c^2 + p1 c (+ a constant). `one_sided`:
/// zero where b c <= a (a probe's tip in front of its plane), else (a - b c)^2.
/// `sphere`: a tip held to a sphere of radius `radius`, the axis from its centre to the
/// handle: (rho - radius)^2 with rho = sqrt(sa - 2 sb c) the distance from the centre of
/// the point `length` below the handle (sa = |v|^2 + L^2, sb = L |v|, v the handle's offset
/// from the centre); `one_sided`: zero where rho >= radius (the tip lifted off).
struct TiltCost {
  double p2 = 0.0, p1 = 0.0;
  bool one_sided = false;
  double a = 0.0, b = 0.0;
  bool sphere = false;
  double sa = 0.0, sb = 0.0, radius = 0.0;
};

/// A direction computed only where it is used: a reference to a callable returning it (a
/// placement's start direction costs sines and cosines, and a tilt needs it only with the
/// stylus exactly along the axis). The callable must outlive the call it is passed to.
class LazyDirection {
 public:
  template <typename F>
  explicit LazyDirection(const F& f) noexcept
      : f_(&f), call_([](const void* g) noexcept -> Eigen::Vector3d {
          return (*static_cast<const F*>(g))();
        }) {}
  Eigen::Vector3d operator()() const noexcept { return call_(f_); }

 private:
  const void* f_;
  Eigen::Vector3d (*call_)(const void*) noexcept;
};

/// The handle orientation R minimising w_p * cost(cos angle(u, axis)) + w_r * angle(R, R_R)^2,
/// u = -R z the stylus's tip-to-handle direction; R_R is the handle's orientation. Where
/// u_R is along the axis, the stylus tilts toward `hint` (any length; the axis's
/// orthogonal complement's first direction if that is degenerate too). `turn`: the rotation
/// vector of that turn, R = exp([turn]x) R_R (angle at most pi), so that the pose error's
/// rotation part is -turn without a logarithm.
void tilt_about_axis(const Eigen::Matrix3d& R_R, const Eigen::Vector3d& axis,
                     const TiltCost& cost, double w_p, double w_r, const LazyDirection& hint,
                     Eigen::Matrix3d& R, Eigen::Vector3d& turn) noexcept;

/// What tilt_about_axis derives from R_R, the axis and the cost alone, before the weights:
/// the stylus's turn axis and its angle from the axis (cosine and sine), and the position
/// cost's minimiser measured from that angle (its difference, cosine and sine). Shared by
/// the cycle's two placements of one handle pose.
struct TiltSetup {
  Eigen::Vector3d k;  // u_R x axis
  double kn = 0.0, cr = 1.0;  // |u_R x axis|, u_R . axis
  double phi0_x = 0.0, phi0_c = 1.0, phi0_s = 0.0;
};
TiltSetup tilt_setup(const Eigen::Matrix3d& R_R, const Eigen::Vector3d& axis,
                     const TiltCost& cost) noexcept;
/// tilt_about_axis from its setup (the same R_R, axis and cost).
void tilt_about_axis(const TiltSetup& setup, const Eigen::Matrix3d& R_R,
                     const Eigen::Vector3d& axis, const TiltCost& cost, double w_p, double w_r,
                     const LazyDirection& hint, Eigen::Matrix3d& R,
                     Eigen::Vector3d& turn) noexcept;

/// The handle orientation R_R turned by the least rotation that takes its stylus's tip-to-
/// handle direction -R_R z to the unit vector u (about u_R x u; a half turn about any axis
/// orthogonal to u_R where u = -u_R); `turn` as for tilt_about_axis.
Eigen::Matrix3d turn_stylus(const Eigen::Matrix3d& R_R, const Eigen::Vector3d& u,
                            Eigen::Vector3d& turn) noexcept;

/// The set a stylus's tip is held to: point + s * free + lambda * one_sided, s any, lambda
/// >= 0; either direction zero when absent (unit and orthogonal otherwise): a point, a line,
/// a half-line or a half-plane.
struct TipSet {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d free = Eigen::Vector3d::Zero();
  Eigen::Vector3d one_sided = Eigen::Vector3d::Zero();
  /// q's offset from its nearest point of the set; `lifted`: lambda > 0 there.
  Eigen::Vector3d residual(const Eigen::Vector3d& q, bool& lifted) const noexcept;
};

/// The stylus's tip-to-handle direction u minimising
///   w_p dist(p_R - L u, set)^2 + w_r angle(u, u_R)^2
/// over the unit sphere, u_R = -R_R z the handle's own: the roll about the stylus and the
/// tip's position in the set drop out exactly, and the remaining two angles are solved by
/// Newton's method on the sphere with exact derivatives from u_R, `u_start` and the
/// directions that put the tip on the set, keeping the best. A one-sided set is first
/// solved relaxed (the direction made free: in closed form for a plane), which is exact
/// wherever the tip is lifted (docs/theory.md, section 4).
Eigen::Vector3d stylus_direction(const TipSet& set, const Eigen::Vector3d& p_R, double length,
                                 const Eigen::Matrix3d& R_R, const Eigen::Vector3d& u_start,
                                 double w_p, double w_r) noexcept;

/// The certificates that end a line-held stylus's search early (docs/theory.md, section 4),
/// for the cost f of stylus_direction() with the tip held to `line` (a TipSet with `free`
/// set) and `value` >= its global minimum (the lowest cost found). Every minimiser lies in
/// the certificate's caps, and f has at most one local minimum on each: the caps about the
/// directions that put the tip on the line (count 2: u = x + s z e with z = sqrt(1 -
/// |x|^2), s = +1 for cap 0 and -1 for cap 1, and |x - x0| <= eps, x = (I - e e^T) u),
/// or with the line beyond the stylus's reach one cap of chord `rho` about `centre[0]`
/// (count 1); count 0 where the bound fails.
struct LineCaps {
  Eigen::Vector3d centre[2] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  Eigen::Vector3d x0 = Eigen::Vector3d::Zero();
  double eps = 0.0;
  double rho = -1.0;  //!< the one cap's chord beyond the reach; -1 for two caps
  double chord = 0.0; //!< every direction u on a cap has |u - centre| <= chord
  int count = 0;      //!< 0: no certificate
};

/// u (unit) lies on cap i of `caps`; e the line's direction.
inline bool cap_holds(const LineCaps& caps, int i, const Eigen::Vector3d& u,
                      const Eigen::Vector3d& e) noexcept {
  if (caps.rho >= 0.0) return (u - caps.centre[0]).norm() <= caps.rho;
  const double z = u.dot(e);
  return (i == 0 ? z > 0.0 : z < 0.0) && (u - z * e - caps.x0).norm() <= caps.eps;
}

/// The stylus's tip-to-handle direction at wrist angles abc = (a, b, c): B Rx(a) Ry(b) z.
Eigen::Vector3d wrist_direction(const Eigen::Matrix3d& B, const double* abc) noexcept;

/// The wrist of a probe-like mechanism whose tip is at `tip`, for handle orientation R =
/// exp([turn]x) R_target (R_tip = R Rx(pi)): the wrist angles over the base B nearest
/// start[0..2] into theta from index `wrist`, and the handle pose, the wrist's columns of J
/// (wrist .. wrist + 2; J sized by the caller, its earlier columns the caller's) and the
/// pose error, built from R, the tip and the turn instead of by walking the chain: the
/// wrist's axes are B x, B Rx(a) y and the stylus, all through the tip, a's cosine and sine
/// come with the angles, and the error's rotation is -turn. The chain's forward_jacobian and
/// pose_error to rounding, without their sines, cosines and logarithm.
void wrist_at_tip(const Eigen::Matrix3d& B, const Eigen::Vector3d& tip, double length,
                  const Pose& target, const Eigen::Matrix3d& R, const Eigen::Vector3d& turn,
                  const double* start, int wrist, JointVector& theta, Pose& T, Jacobian& J,
                  Vector6& e) noexcept;

/// The caps above for a tip held to `line` (the handle at p_R, its stylus direction u_R).
LineCaps line_caps(const TipSet& line, const Eigen::Vector3d& p_R, const Eigen::Vector3d& u_R,
                   double length, double w_p, double w_r, double value) noexcept;

/// Whether the cap of angle sqrt(value / w_r) about u_R, which holds every minimiser, is
/// one where f is strictly geodesically convex (so holds exactly one local minimum).
bool handle_cap_certified(const TipSet& line, const Eigen::Vector3d& p_R,
                          const Eigen::Vector3d& u_R, double length, double w_p, double w_r,
                          double value) noexcept;

/// What a stylus's placement weighs: the handle's position p_R and its stylus's tip-to-
/// handle direction u_R = -R_R z, the stylus's length L, and the position and rotation
/// weights (W isotropic within each block).
struct StylusObjective {
  Eigen::Vector3d p_R = Eigen::Vector3d::Zero();
  Eigen::Vector3d u_R = Eigen::Vector3d::Zero();
  double length = 0.0, w_p = 0.0, w_r = 0.0;
};

/// The stylus of a probe whose tip is held to a curve C (a CurveGuide): the parameter s and
/// the tip-to-handle direction u at the local minimum of
///   w_p |C(s) + L u - p_R|^2 + w_r angle(u, u_R)^2
/// reached by Newton's method on R x S^2 with exact second derivatives (C'' included) from
/// (s, u) as given (where the Hessian is not positive definite, the saddle-free step with a
/// backtracking line search; steps capped at a tenth of the stylus and 0.2 rad). The roll
/// about the stylus drops out as for a line. Within the curve's bounds by projected Newton:
/// a step is cut at the first bound it meets, and a parameter at a bound that the descent
/// pushes out is held there (the minimum may lie on a stop). Returns false (s and u then
/// undefined) where no full Newton step at rounding level ends 30 steps, or no step
/// descends; the caller then runs Gauss-Newton.
bool curve_stylus_newton(const Curve& curve, const StylusObjective& objective, double& s,
                         Eigen::Vector3d& u) noexcept;

/// The same for a probe whose tip is held to a surface S (a SurfaceProbe in contact): the
/// parameters uv and the direction u at the local minimum of
///   w_p |S(uv) + L u - p_R|^2 + w_r angle(u, u_R)^2
/// by the same Newton's method on R^2 x S^2 (S's second derivatives included; steps capped
/// at a tenth of the stylus of tip motion), the same declines; uv within [lo, hi] (the
/// mechanism's joint limits: a wrapping u unbounded).
bool surface_stylus_newton(const Surface& surface, const StylusObjective& objective,
                           const Eigen::Vector2d& lo, const Eigen::Vector2d& hi,
                           Eigen::Vector2d& uv, Eigen::Vector3d& u) noexcept;

/// The angle x minimising -a cos(x - theta_p) + w_r acos(c + b cos(x - theta_o))^2 (a, b,
/// w_r >= 0): a position term least at theta_p and a rotation angle least at theta_o, as
/// for one revolute joint with weights isotropic per block; theta_p and theta_o are the
/// directions of the plane vectors p and o (any length). On the short arc between them.
/// cos_x, sin_x: its cosine and sine (to rounding), from the solve's and p's, for the
/// joint's pose and Jacobian.
double arc_minimiser(double a, const Eigen::Vector2d& p, double b, const Eigen::Vector2d& o,
                     double c, double w_r, double& cos_x, double& sin_x) noexcept;

/// What arc_minimiser derives from p and o alone, before the weights: theta_p (with its
/// cosine and sine), the short arc's sign and width from theta_p to theta_o (its cosine and
/// sine). Shared by the cycle's two placements.
struct ArcSetup {
  Eigen::Vector2d o = Eigen::Vector2d::Zero();
  double theta_p = 0.0, cp = 1.0, sp = 0.0;
  double span = 0.0;  // theta_o - theta_p in [-pi, pi]
  double dir = 1.0, width = 0.0, cs = 1.0, ss = 0.0;
};
ArcSetup arc_setup(const Eigen::Vector2d& p, const Eigen::Vector2d& o) noexcept;
/// arc_minimiser from its setup (the same p and o).
double arc_minimiser(const ArcSetup& setup, double a, double b, double c, double w_r,
                     double& cos_x, double& sin_x) noexcept;

/// std::round(t) written out: on baseline x86-64 std::round is a library call, and the
/// placements take several a cycle. Exact (t - trunc(t) has no rounding error); NaN and
/// |t| >= 2^52 (already integers, or not finite) go to std::round.
inline double round_half_away(double t) noexcept {
  if (!(std::abs(t) < 4503599627370496.0)) return std::round(t);
  const double k = static_cast<double>(static_cast<long long>(t));  // trunc(t)
  const double r = t - k;
  return r >= 0.5 ? k + 1.0 : (r <= -0.5 ? k - 1.0 : k);
}

/// Joint values of three revolute joints about x, y, z (in that order) giving the rotation
/// M = Rx(a) Ry(b) Rz(c), on the branch nearest `start` (each angle within pi of it);
/// cos_a, sin_a: the cosine and sine of the returned a (to rounding), which the wrist's
/// Jacobian needs.
Eigen::Vector3d euler_xyz_nearest(const Eigen::Matrix3d& M, const Eigen::Vector3d& start,
                                  double& cos_a, double& sin_a) noexcept;

}  // namespace virtmech::detail
