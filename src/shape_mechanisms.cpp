// Mechanisms on a geometry: SurfaceProbe (a probe's tip on any surface), CurveGuide (a
// probe's tip on a curve), HandlePath (the handle on a curve). docs/theory.md, section 7.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "closed_form.hpp"
#include "virtmech/mechanism.hpp"
#include "virtmech/se3.hpp"
#include "virtmech/validate.hpp"

namespace virtmech {

namespace {

constexpr double kTiny = 1e-300;

// the base of a probe's wrist for a fixed normal: [t1, n x t1, n]
Eigen::Matrix3d fixed_base(const Eigen::Vector3d& n) {
  const Eigen::Vector3d t1 = any_orthogonal(n);
  Eigen::Matrix3d B;
  B << t1, n.cross(t1), n;
  return B;
}

// Rx(a) Ry(b) Rz(c)
Eigen::Matrix3d euler_xyz(const double* abc) noexcept {
  return (Eigen::AngleAxisd(abc[0], Eigen::Vector3d::UnitX()) *
          Eigen::AngleAxisd(abc[1], Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(abc[2], Eigen::Vector3d::UnitZ()))
      .toRotationMatrix();
}

// The handle pose of a probe with its tip at `tip`, wrist base B and wrist angles abc,
// `length` from the tip along the stylus (R_tip z); the wrist's three columns of J from
// column `col`: axes B x, B Rx(a) y and the stylus, all through the tip.
void probe_wrist(const Eigen::Matrix3d& B, const Eigen::Vector3d& tip, const double* abc,
                 double length, int col, Pose& T, Jacobian& J) noexcept {
  const Eigen::Matrix3d R_tip = B * euler_xyz(abc);
  const Eigen::Vector3d arm = length * R_tip.col(2);  // tip to handle
  // the handle: the tip frame turned a half turn about x (z_handle = -z_tip)
  T.linear() << R_tip.col(0), -R_tip.col(1), -R_tip.col(2);
  T.translation() = tip + arm;
  T.makeAffine();
  const double ca = std::cos(abc[0]), sa = std::sin(abc[0]);
  const Eigen::Vector3d axes[3] = {B.col(0), ca * B.col(1) + sa * B.col(2), R_tip.col(2)};
  for (int i = 0; i < 3; ++i) J.col(col + i) << axes[i].cross(arm), axes[i];
}

// Wrist angles of a handle orientation R_h over the base B (R_tip = R_h Rx(pi)), nearest
// the start's.
Eigen::Vector3d wrist_angles(const Eigen::Matrix3d& B, const Eigen::Matrix3d& R_h,
                             const Eigen::Vector3d& start) noexcept {
  Eigen::Matrix3d R_tip;
  R_tip << R_h.col(0), -R_h.col(1), -R_h.col(2);
  double ca, sa;
  return detail::euler_xyz_nearest(B.transpose() * R_tip, start, ca, sa);
}

// The surface frame B = [t1, n x t1, n] at S's derivatives d (order 2), its angular rates
// w_u, w_v (dB/du = [w_u]x B) and the normal's derivatives n_u, n_v. At a degenerate point
// (S_u or S_u x S_v vanishing) the missing vectors are completed and their rates left zero.
struct SurfaceFrame {
  Eigen::Matrix3d B;
  Eigen::Vector3d w_u, w_v, n_u, n_v;
};

// The frame B alone, from S's first derivatives in d (order 1 suffices); false at a
// degenerate point, where it is completed from the surface's own normal.
bool surface_basis(const Surface& s, double u, double v, const SurfaceDerivatives& d,
                   Eigen::Matrix3d& B) noexcept {
  const Eigen::Vector3d& Su = d(1, 0);
  const Eigen::Vector3d& Sv = d(0, 1);
  const Eigen::Vector3d m = Su.cross(Sv);
  const double mn = m.norm(), sun = Su.norm();
  const bool regular = mn > 1e-12 * std::max(Su.squaredNorm() + Sv.squaredNorm(), kTiny) &&
                       sun > kTiny;
  if (!regular) {
    const Eigen::Vector3d n = s.normal(u, v);
    Eigen::Vector3d t1 = Su - Su.dot(n) * n;
    t1 = t1.norm() > kTiny ? Eigen::Vector3d(t1.normalized()) : any_orthogonal(n);
    B << t1, n.cross(t1), n;
    return false;
  }
  const Eigen::Vector3d n = m / mn;
  const Eigen::Vector3d t1 = Su / sun;
  B << t1, n.cross(t1), n;
  return true;
}

void surface_frame(const Surface& s, double u, double v, const SurfaceDerivatives& d,
                   SurfaceFrame& f) noexcept {
  if (!surface_basis(s, u, v, d, f.B)) {
    f.w_u.setZero();
    f.w_v.setZero();
    f.n_u.setZero();
    f.n_v.setZero();
    return;
  }
  const Eigen::Vector3d& Su = d(1, 0);
  const Eigen::Vector3d& Sv = d(0, 1);
  const double mn = Su.cross(Sv).norm(), sun = Su.norm();
  const Eigen::Vector3d t1 = f.B.col(0), t2 = f.B.col(1), n = f.B.col(2);
  // derivatives of the unit vectors: d(x / |x|) = (I - x^ x^T) dx / |x|
  const auto unit_rate = [](const Eigen::Vector3d& e, double norm, const Eigen::Vector3d& dx) {
    return Eigen::Vector3d((dx - e.dot(dx) * e) / norm);
  };
  const Eigen::Vector3d m_u = d(2, 0).cross(Sv) + Su.cross(d(1, 1));
  const Eigen::Vector3d m_v = d(1, 1).cross(Sv) + Su.cross(d(0, 2));
  f.n_u = unit_rate(n, mn, m_u);
  f.n_v = unit_rate(n, mn, m_v);
  const Eigen::Vector3d t1_u = unit_rate(t1, sun, d(2, 0));
  const Eigen::Vector3d t1_v = unit_rate(t1, sun, d(1, 1));
  const Eigen::Vector3d t2_u = f.n_u.cross(t1) + n.cross(t1_u);
  const Eigen::Vector3d t2_v = f.n_v.cross(t1) + n.cross(t1_v);
  // the angular rate of an orthonormal frame: w = (sum_i b_i x db_i) / 2
  f.w_u = 0.5 * (t1.cross(t1_u) + t2.cross(t2_u) + n.cross(f.n_u));
  f.w_v = 0.5 * (t1.cross(t1_v) + t2.cross(t2_v) + n.cross(f.n_v));
}

// A SurfaceProbe's columns of J for u, v (and h where one-sided): sliding the tip at height
// h turns the wrist's base with the surface frame, `arm` the tip-to-handle vector.
void surface_columns(const SurfaceDerivatives& d, const SurfaceFrame& f, double h,
                     const Eigen::Vector3d& arm, bool unilateral, Jacobian& J) noexcept {
  J.col(0) << d(1, 0) + h * f.n_u + f.w_u.cross(arm), f.w_u;
  J.col(1) << d(0, 1) + h * f.n_v + f.w_v.cross(arm), f.w_v;
  if (unilateral) J.col(2) << f.B.col(2), 0.0, 0.0, 0.0;
}

// u nearest the start's turn where it wraps (Surface::periodic_u)
double wrapped_near(const Surface& s, double u, double start) noexcept {
  if (!s.periodic_u()) return u;
  return u + 2.0 * M_PI * detail::round_half_away((start - u) / (2.0 * M_PI));
}

std::vector<JointType> probe_kinds(int slides) {
  std::vector<JointType> k(static_cast<size_t>(slides), JointType::kPrismatic);
  for (int i = 0; i < 3; ++i) k.push_back(JointType::kRevolute);
  return k;
}

const Surface& checked_surface(const std::shared_ptr<const Surface>& s) {
  if (!s) throw std::invalid_argument("surface: expected a surface, got null");
  return *s;
}

const Curve& checked_curve(const std::shared_ptr<const Curve>& c) {
  if (!c) throw std::invalid_argument("curve: expected a curve, got null");
  return *c;
}

double middle(double lo, double hi) {
  if (std::isfinite(lo) && std::isfinite(hi)) return 0.5 * (lo + hi);
  if (std::isfinite(lo)) return std::max(lo, 0.0);
  if (std::isfinite(hi)) return std::min(hi, 0.0);
  return 0.0;
}

JointVector surface_limit(const Surface& s, bool unilateral, bool upper) {
  const int n = unilateral ? 6 : 5;
  JointVector v = JointVector::Constant(n, upper ? kInf : -kInf);
  const Eigen::Vector2d b = upper ? s.upper() : s.lower();
  if (!s.periodic_u()) v[0] = b[0];
  v[1] = b[1];
  if (unilateral && !upper) v[2] = 0.0;
  return v;
}

JointVector surface_home(const Surface& s, bool unilateral) {
  JointVector h = JointVector::Zero(unilateral ? 6 : 5);
  h[0] = s.periodic_u() ? 0.0 : middle(s.lower()[0], s.upper()[0]);
  h[1] = middle(s.lower()[1], s.upper()[1]);
  return h;
}

JointVector curve_limit(const Curve& c, bool upper) {
  JointVector v = JointVector::Constant(4, upper ? kInf : -kInf);
  v[0] = upper ? c.upper() : c.lower();
  return v;
}

JointVector curve_home(const Curve& c) {
  JointVector h = JointVector::Zero(4);
  h[0] = middle(c.lower(), c.upper());
  return h;
}

double positive_length(const std::string& name, double length) {
  require_positive(name, length);
  return length;
}

// The weights count positions only (an under-actuated device's nearest placement): the
// rotation weights, per length squared, below 1e-3 of the position weights.
bool positions_only(const Vector6& w, double length) noexcept {
  const double positions = w.head<3>().minCoeff();
  const double rotations = w.tail<3>().maxCoeff() / (length * length);
  return rotations < 1e-3 * positions;
}

// A probe's seed matches the handle's orientation. Where the weights count positions only,
// a stylus along the position error is a stationary point of the cost that is not its
// least (tilting reaches the handle), and Gauss-Newton, which sees no curvature, would
// stay: a CurveGuide's seed starts tilted a little instead (a SurfaceProbe's goes to the
// least directly: SurfaceProbe::reach_seed).
void tilt_if_positions_only(const Vector6& w, double length, JointVector& theta,
                            int wrist) noexcept {
  constexpr double kTilt = 0.1;  // [rad]
  if (positions_only(w, length)) theta[wrist + 1] += kTilt;
}

// the tip a handle pose points to: `length` along its stylus (local z)
Eigen::Vector3d tip_of(const Pose& handle, double length) noexcept {
  return handle.translation() + length * handle.linear().col(2);
}

}  // namespace

// --- SurfaceProbe ------------------------------------------------------------------------

SurfaceProbe::SurfaceProbe(std::shared_ptr<const Surface> surface, double length,
                           bool unilateral)
    : Mechanism("SurfaceProbe", probe_kinds(unilateral ? 3 : 2),
                surface_limit(checked_surface(surface), unilateral, false),
                surface_limit(*surface, unilateral, true), surface_home(*surface, unilateral),
                positive_length("length", length)),
      surface_(std::move(surface)), sphere_(dynamic_cast<const Sphere*>(surface_.get())),
      length_(length), unilateral_(unilateral) {
  if (unilateral) set_contact_joint(2);
}

void SurfaceProbe::forward_jacobian(const double* x, Pose& T, Jacobian& J) const noexcept {
  const int wrist = unilateral_ ? 3 : 2;
  const double h = unilateral_ ? x[2] : 0.0;
  SurfaceDerivatives d;
  surface_->derivatives(x[0], x[1], 2, d);
  SurfaceFrame f;
  surface_frame(*surface_, x[0], x[1], d, f);
  const Eigen::Vector3d n = f.B.col(2);
  const Eigen::Vector3d tip = d(0, 0) + h * n;
  J.resize(6, wrist + 3);
  probe_wrist(f.B, tip, x + wrist, length_, wrist, T, J);
  surface_columns(d, f, h, T.translation() - tip, unilateral_, J);
}

bool SurfaceProbe::constraint_wrench(const double* x, const Pose& T, const Jacobian& J,
                                     std::uint32_t locked, Vector6& n) const noexcept {
  (void)x;
  const std::uint32_t contact = unilateral_ ? 1u << 2 : 0u;  // the lift-off joint locked
  if (locked != contact) return false;
  // the tip, L z ahead of the handle, moves with v + w x (L z) along each column: along the
  // two surface joints by S_u and S_v (on the surface: no lift), along the wrist's not at all
  const Eigen::Vector3d z = T.linear().col(2), r = length_ * z;
  const Eigen::Vector3d Su = J.col(0).head<3>() + J.col(0).tail<3>().cross(r);
  const Eigen::Vector3d Sv = J.col(1).head<3>() + J.col(1).tail<3>().cross(r);
  const Eigen::Vector3d m = Su.cross(Sv);
  const double mn = m.norm();
  // a regular point (J has rank 5 only there), and the wrist's first axis t1 = S_u / |S_u|
  // away from the stylus (its gimbal lock)
  if (!(mn > 1e-6 * Su.norm() * Sv.norm()) || !(Su.cross(z).norm() > 1e-6 * Su.norm())) {
    return false;
  }
  const Eigen::Vector3d N = m / mn;
  n << N, r.cross(N);
  return true;
}

void SurfaceProbe::seed(const Pose& target, const Vector6& w, JointVector& theta) const noexcept {
  Eigen::Vector3d point;
  const Eigen::Vector2d uv = surface_->closest_point(tip_of(target, length_), point);
  seed_from(target, w, uv, point, theta);
}

bool SurfaceProbe::seed_pair(const Pose& target, const Vector6& w_a, const Vector6& w_b,
                             JointVector& a, JointVector& b) const noexcept {
  Eigen::Vector3d point;
  const Eigen::Vector2d uv = surface_->closest_point(tip_of(target, length_), point);
  seed_from(target, w_a, uv, point, a);
  seed_from(target, w_b, uv, point, b);
  return true;
}

// seed() from the tip's global closest point, at uv_tip
void SurfaceProbe::seed_from(const Pose& target, const Vector6& w, const Eigen::Vector2d& uv_tip,
                             const Eigen::Vector3d& point, JointVector& theta) const noexcept {
  const Eigen::Vector3d tip = tip_of(target, length_);
  Eigen::Vector2d uv = uv_tip;
  SurfaceDerivatives d;
  surface_->derivatives(uv[0], uv[1], 1, d);
  Eigen::Matrix3d B;
  surface_basis(*surface_, uv[0], uv[1], d, B);
  const int wrist = unilateral_ ? 3 : 2;
  Eigen::Matrix3d R = target.linear();
  double lift = std::max(0.0, B.col(2).dot(tip - point));
  if (positions_only(w, length_) && reach_seed(target, d, B, uv, R, lift)) {
    surface_->derivatives(uv[0], uv[1], 1, d);
    surface_basis(*surface_, uv[0], uv[1], d, B);
  }
  theta[0] = uv[0];
  theta[1] = uv[1];
  if (unilateral_) theta[2] = lift;
  theta.segment<3>(wrist) = wrist_angles(B, R, Eigen::Vector3d(theta.segment<3>(wrist)));
}

// A nearest placement's seed (positions only): the placements that put the handle exactly
// where it is form a circle of tips, where the stylus of length L reaches the surface from
// the handle, and the least of them is the one whose stylus is nearest the handle's (the
// rotation term, however small, decides). Over the tangent plane at a point S of the
// surface, with normal n and the handle at height h above the plane: the circle's centre
// (the handle's foot on the plane), its radius sqrt(L^2 - h^2), and the tip the centre
// moved against the stylus's tangential part (where the handle is farther than L, the
// centre itself: the stylus along the normal). The parameters from that step by least
// squares, within the bounds; the pass repeated from the point reached (from the closest
// point to the handle's own tip first), at most four times or until a pass moves the tip
// less than 1e-4 L; R the handle's orientation turned least to the stylus reaching the
// handle from there. Starting there, Newton's method converges in a few steps, where a
// start at the handle's own stylus (a stationary point of the cost: the error along the
// stylus) had to be tilted and crept along the valley, its tip moving at most a tenth of
// the stylus a step. False where no pass moves the parameters.
bool SurfaceProbe::reach_seed(const Pose& target, const SurfaceDerivatives& d0,
                              const Eigen::Matrix3d& B0, Eigen::Vector2d& uv, Eigen::Matrix3d& R,
                              double& lift) const noexcept {
  constexpr int kPasses = 4;
  const double L = length_;
  const Eigen::Vector3d& p = target.translation();
  const Eigen::Vector3d u_R = -target.linear().col(2);
  const Eigen::Vector2d lo(lower()[0], lower()[1]), hi(upper()[0], upper()[1]);
  SurfaceDerivatives d = d0;
  Eigen::Matrix3d B = B0;
  bool moved = false;
  for (int pass = 0; pass < kPasses; ++pass) {
    if (pass > 0) {
      surface_->derivatives(uv[0], uv[1], 1, d);
      surface_basis(*surface_, uv[0], uv[1], d, B);
    }
    const Eigen::Vector3d n = B.col(2);
    const Eigen::Vector3d rel = p - d(0, 0);
    const double h = n.dot(rel);
    Eigen::Vector3d step = rel - h * n;  // to the circle's centre
    if (std::abs(h) < L) {
      Eigen::Vector3d side = u_R - n.dot(u_R) * n;
      const double sn = side.norm();
      side = sn > 1e-6 ? Eigen::Vector3d(side / sn) : Eigen::Vector3d(B.col(0));
      step -= std::sqrt(L * L - h * h) * side;
      lift = 0.0;
    } else {
      lift = unilateral_ ? std::max(0.0, h - L) : 0.0;
    }
    Eigen::Matrix<double, 3, 2> D;
    D << d(1, 0), d(0, 1);
    const Eigen::Vector2d duv = (D.transpose() * D).ldlt().solve(D.transpose() * step);
    if (!duv.allFinite()) break;
    const Eigen::Vector2d next = (uv + duv).cwiseMax(lo).cwiseMin(hi);
    if (next == uv) break;
    uv = next;
    moved = true;
    if ((D * duv).norm() < 1e-4 * L) break;  // (the next pass would move it by its square)
  }
  if (!moved) return false;
  const Eigen::Vector3d to_handle = p - surface_->evaluate(uv[0], uv[1]);
  const double reach = to_handle.norm();
  if (!(reach > 1e-9 * L)) return true;
  Eigen::Vector3d turn;
  R = detail::turn_stylus(target.linear(), to_handle / reach, turn);
  return true;
}

bool SurfaceProbe::place(const Pose& target, const Vector6& w, const JointVector& start,
                         JointVector& theta, Pose& T, Jacobian& J, Vector6& e) const noexcept {
  double w_p, w_r;
  if (!detail::isotropic_blocks(w, w_p, w_r)) return false;
  if (!sphere_) return place_on_surface(target, w_p, w_r, start, theta, T, J, e);
  // The tip nearest the point q = p_R - L u below the handle is the sphere's point along q's
  // direction from the centre (or q itself, lifted, when one-sided and outside), so the
  // position cost depends on u only through its angle from v, the centre-to-handle
  // direction: one angle, as for a pivot (the stylus turns toward v)
  const Eigen::Vector3d& c = sphere_->center();
  const Eigen::Vector3d v = target.translation() - c;
  const double vn = v.norm();
  if (!std::isfinite(vn)) return false;
  detail::TiltCost cost;
  cost.sphere = true;
  cost.sa = vn * vn + length_ * length_;
  cost.sb = length_ * vn;
  cost.radius = sphere_->radius();
  cost.one_sided = unilateral_;
  const int wrist = unilateral_ ? 3 : 2;
  const auto start_direction = [&] {
    Pose T0;
    forward(start.data(), T0);
    return Eigen::Vector3d(-T0.linear().col(2));
  };
  Eigen::Matrix3d R = target.linear();
  if (vn > 1e-9 * length_) {
    Eigen::Vector3d turn;
    detail::tilt_about_axis(target.linear(), v / vn, cost, w_p, w_r,
                            detail::LazyDirection(start_direction), R, turn);
  }
  // else the handle at the centre: every stylus direction puts the tip's nearest point at
  // the same distance, so the rotation term alone decides (R = R_R) and only a
  // rounding-level position term is left out
  const Eigen::Vector3d q = target.translation() + length_ * R.col(2);  // p_R - L u
  Eigen::Vector3d point;
  const Eigen::Vector2d uv = sphere_->closest_point(q, point);
  if (!((q - c).norm() > 1e-9 * cost.radius)) return false;
  theta.resize(dof());
  // u is periodic: the turn nearest the start's
  theta[0] = wrapped_near(*sphere_, uv[0], start[0]);
  theta[1] = uv[1];
  if (unilateral_) {
    // in contact the tip sits exactly on the sphere, the lift-off joint on its bound
    const double lift = (q - c).norm() - cost.radius;
    theta[2] = lift > 1e-12 * length_ ? lift : 0.0;
  }
  SurfaceDerivatives d;
  sphere_->derivatives(uv[0], uv[1], 2, d);
  SurfaceFrame f;
  surface_frame(*sphere_, uv[0], uv[1], d, f);
  theta.segment<3>(wrist) =
      wrist_angles(f.B, R, Eigen::Vector3d(start.segment<3>(wrist)));
  forward_jacobian(theta.data(), T, J);
  e = pose_error(target, T);
  return true;
}

// The handle's own pose where the stylus kept at its orientation puts the tip above the
// surface (a one-sided probe lifted off: the pose error zero, the cost's least): the tip
// q = p_R + L z_R projected onto the surface locally from uv; false where q is not above
// it along the normal at that point (or the projection ends on a parameter bound, where
// q - S is not along the normal).
bool SurfaceProbe::place_lifted(const Pose& target, const JointVector& start, Eigen::Vector2d& uv,
                                JointVector& theta, Pose& T, Jacobian& J,
                                Vector6& e) const noexcept {
  const Eigen::Vector3d q = tip_of(target, length_);
  const Eigen::Vector2d lo(lower()[0], lower()[1]), hi(upper()[0], upper()[1]);
  Eigen::Vector3d foot;
  uv = surface_->closest_point_from(q, uv, lo, hi, foot);
  SurfaceDerivatives d;
  surface_->derivatives(uv[0], uv[1], 2, d);
  SurfaceFrame f;
  surface_frame(*surface_, uv[0], uv[1], d, f);
  const Eigen::Vector3d& n = f.B.col(2);
  const double h = n.dot(q - foot);
  if (!(h > 0.0) || !((q - foot - h * n).norm() <= 1e-10 * length_)) return false;
  theta.resize(dof());
  theta[0] = wrapped_near(*surface_, uv[0], start[0]);
  theta[1] = uv[1];
  theta[2] = h;
  J.resize(6, 6);
  const Eigen::Vector3d tip = foot + h * n;
  detail::wrist_at_tip(f.B, tip, length_, target, target.linear(), Eigen::Vector3d::Zero(),
                       start.data() + 3, 3, theta, T, J, e);
  surface_columns(d, f, h, T.translation() - tip, true, J);
  return true;
}

bool SurfaceProbe::place_on_surface(const Pose& target, double w_p, double w_r,
                                    const JointVector& start, JointVector& theta, Pose& T,
                                    Jacobian& J, Vector6& e) const noexcept {
  const int wrist = unilateral_ ? 3 : 2;
  Eigen::Vector2d uv(start[0], start[1]);
  // one-sided and lifted at the start: lifted still if the handle's own pose allows it,
  // else in contact from the tip's nearest point
  if (unilateral_ && !(start[2] == 0.0) && place_lifted(target, start, uv, theta, T, J, e)) {
    return true;
  }
  SurfaceDerivatives d;
  surface_->derivatives(uv[0], uv[1], 1, d);  // the start's frame, for its stylus direction
  SurfaceFrame f;
  surface_basis(*surface_, uv[0], uv[1], d, f.B);
  Eigen::Vector3d u = detail::wrist_direction(f.B, start.data() + wrist);  // tip to handle
  const Eigen::Vector2d lo(lower()[0], lower()[1]), hi(upper()[0], upper()[1]);
  const detail::StylusObjective objective{target.translation(), -target.linear().col(2), length_,
                                          w_p, w_r};
  if (!detail::surface_stylus_newton(*surface_, objective, lo, hi, uv, u)) {
    // declined from a contact start: the handle may have lifted the tip off
    if (!unilateral_ || !(start[2] == 0.0)) return false;
    uv = Eigen::Vector2d(start[0], start[1]);
    return place_lifted(target, start, uv, theta, T, J, e);
  }
  surface_->derivatives(uv[0], uv[1], 2, d);
  surface_frame(*surface_, uv[0], uv[1], d, f);
  const Eigen::Vector3d& n = f.B.col(2);
  // one-sided: in contact only where the cost would press the tip into the surface (its
  // derivative in the height, 2 w_p r . n, is >= 0); else it lifts off
  const Eigen::Vector3d r = d(0, 0) + length_ * u - target.translation();
  if (unilateral_ && r.dot(n) < 0.0) {
    if (!(start[2] == 0.0)) return false;  // (tried above)
    uv = Eigen::Vector2d(start[0], start[1]);
    return place_lifted(target, start, uv, theta, T, J, e);
  }
  Eigen::Vector3d turn;
  const Eigen::Matrix3d R = detail::turn_stylus(target.linear(), u, turn);
  theta.resize(dof());
  theta[0] = wrapped_near(*surface_, uv[0], start[0]);
  theta[1] = uv[1];
  if (unilateral_) theta[2] = 0.0;
  J.resize(6, wrist + 3);
  detail::wrist_at_tip(f.B, d(0, 0), length_, target, R, turn, start.data() + wrist, wrist,
                       theta, T, J, e);
  surface_columns(d, f, 0.0, T.translation() - d(0, 0), unilateral_, J);
  return true;
}

// --- CurveGuide --------------------------------------------------------------------------

CurveGuide::CurveGuide(std::shared_ptr<const Curve> curve, double length,
                       const Eigen::Vector3d& normal)
    : Mechanism("CurveGuide", probe_kinds(1), curve_limit(checked_curve(curve), false),
                curve_limit(*curve, true), curve_home(*curve), positive_length("length", length)),
      curve_(std::move(curve)), length_(length), normal_(require_unit("normal", normal)),
      base_(fixed_base(normal_)) {}

void CurveGuide::forward_jacobian(const double* x, Pose& T, Jacobian& J) const noexcept {
  CurveDerivatives d;
  curve_->derivatives(x[0], 1, d);
  J.resize(6, 4);
  probe_wrist(base_, d.col(0), x + 1, length_, 1, T, J);
  J.col(0) << d.col(1), 0.0, 0.0, 0.0;
}

void CurveGuide::seed(const Pose& target, const Vector6& w, JointVector& theta) const noexcept {
  Eigen::Vector3d point;
  theta[0] = curve_->closest_point(tip_of(target, length_), point);
  theta.segment<3>(1) =
      wrist_angles(base_, target.linear(), Eigen::Vector3d(theta.segment<3>(1)));
  tilt_if_positions_only(w, length_, theta, 1);
}

bool CurveGuide::place(const Pose& target, const Vector6& w, const JointVector& start,
                       JointVector& theta, Pose& T, Jacobian& J, Vector6& e) const noexcept {
  double w_p, w_r;
  if (!detail::isotropic_blocks(w, w_p, w_r)) return false;
  double s = start[0];
  Eigen::Vector3d u = detail::wrist_direction(base_, start.data() + 1);  // tip to handle
  const detail::StylusObjective objective{target.translation(), -target.linear().col(2), length_,
                                          w_p, w_r};
  if (!detail::curve_stylus_newton(*curve_, objective, s, u)) {
    return false;
  }
  Eigen::Vector3d turn;
  const Eigen::Matrix3d R = detail::turn_stylus(target.linear(), u, turn);
  theta.resize(4);
  theta[0] = s;
  CurveDerivatives d;
  curve_->derivatives(s, 1, d);
  J.resize(6, 4);
  J.col(0) << d.col(1), 0.0, 0.0, 0.0;
  detail::wrist_at_tip(base_, d.col(0), length_, target, R, turn, start.data() + 1, 1, theta, T,
                       J, e);
  return true;
}

// --- HandlePath --------------------------------------------------------------------------

HandlePath::HandlePath(std::shared_ptr<const Curve> curve, const Eigen::Vector3d& normal,
                       double length_scale)
    : Mechanism("HandlePath", probe_kinds(1), curve_limit(checked_curve(curve), false),
                curve_limit(*curve, true), curve_home(*curve),
                positive_length("length_scale", length_scale)),
      curve_(std::move(curve)), normal_(require_unit("normal", normal)),
      base_(fixed_base(normal_)) {}

void HandlePath::forward_jacobian(const double* x, Pose& T, Jacobian& J) const noexcept {
  CurveDerivatives d;
  curve_->derivatives(x[0], 1, d);
  J.resize(6, 4);
  // the probe's wrist with its tip at the handle (zero length): rotations about the handle
  probe_wrist(base_, d.col(0), x + 1, 0.0, 1, T, J);
  J.col(0) << d.col(1), 0.0, 0.0, 0.0;
}

void HandlePath::seed(const Pose& target, const Vector6& w, JointVector& theta) const noexcept {
  (void)w;
  Eigen::Vector3d point;
  theta[0] = curve_->closest_point(target.translation(), point);
  theta.segment<3>(1) =
      wrist_angles(base_, target.linear(), Eigen::Vector3d(theta.segment<3>(1)));
}

}  // namespace virtmech
