#include "virtmech/mechanism.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "closed_form.hpp"
#include "rotation_log.hpp"
#include "virtmech/se3.hpp"
#include "virtmech/validate.hpp"

namespace virtmech {

namespace {

Joint make_joint(JointType type, const Eigen::Vector3d& axis,
                 const Pose& origin = Pose::Identity()) {
  Joint j;
  j.type = type;
  j.axis = axis;
  j.origin = origin;
  return j;
}

// the stylus rotated a half turn about local x: z_handle = -z_tip, handle `length` back
Pose handle_behind_tip(double length) {
  Pose H = Pose::Identity();
  H.translation() = Eigen::Vector3d(0.0, 0.0, length);
  H.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  return H;
}

// frame with columns [t1, n x t1, n] at p
Pose tangent_frame(const Eigen::Vector3d& p, const Eigen::Vector3d& n,
                   const Eigen::Vector3d& t1) {
  Eigen::Matrix3d R;
  R.col(0) = t1;
  R.col(1) = n.cross(t1);
  R.col(2) = n;
  return make_pose(R, p);
}

Eigen::Vector3d tangent_or_default(const std::string& name, const Eigen::Vector3d& t,
                                   const Eigen::Vector3d& n) {
  if (t.isZero(0.0)) return any_orthogonal(n);
  const Eigen::Vector3d u = require_unit(name, t);
  if (std::abs(u.dot(n)) > 1e-6) {
    throw std::invalid_argument(name + ": expected a unit vector orthogonal to " +
                                format_vector(n) + ", got " + format_vector(t));
  }
  return (u - u.dot(n) * n).normalized();
}

std::vector<Joint> wrist_rrr() {
  return {make_joint(JointType::kRevolute, Eigen::Vector3d::UnitX()),
          make_joint(JointType::kRevolute, Eigen::Vector3d::UnitY()),
          make_joint(JointType::kRevolute, Eigen::Vector3d::UnitZ())};
}

}  // namespace

Mechanism::Mechanism(std::string type, const std::vector<JointType>& kinds,
                     const JointVector& lower, const JointVector& upper, const JointVector& home,
                     double length_scale)
    : type_(std::move(type)), lower_(lower), upper_(upper), home_(home),
      length_scale_(length_scale) {
  require_positive("length_scale", length_scale_);
  if (kinds.empty() || kinds.size() > static_cast<size_t>(kMaxDof)) {
    std::ostringstream os;
    os << "joints: expected 1 to " << kMaxDof << " joints, got " << kinds.size();
    throw std::invalid_argument(os.str());
  }
  dof_ = static_cast<int>(kinds.size());
  for (int i = 0; i < dof_; ++i) kinds_[static_cast<size_t>(i)] = kinds[static_cast<size_t>(i)];
  if (lower_.size() != dof_ || upper_.size() != dof_ || home_.size() != dof_) {
    std::ostringstream os;
    os << "lower/upper/home: expected " << dof_ << " values each, got " << lower_.size() << ", "
       << upper_.size() << ", " << home_.size();
    throw std::invalid_argument(os.str());
  }
  require_finite("home", home_);
  require_ordered("lower/upper", lower_, upper_);
  for (int i = 0; i < dof_; ++i) {
    home_[i] = std::min(std::max(home_[i], lower_[i]), upper_[i]);
  }
}

void Mechanism::set_contact_joint(int i) {
  if (i < 0 || i >= dof_ || kinds_[static_cast<size_t>(i)] != JointType::kPrismatic ||
      lower_[i] != 0.0) {
    throw std::invalid_argument("contact_joint: expected a prismatic joint with lower limit 0, "
                                "got joint " + std::to_string(i));
  }
  contact_joint_ = i;
}

void Mechanism::forward(const double* x, Pose& T) const noexcept {
  Jacobian J;
  forward_jacobian(x, T, J);
}

namespace {

JointVector as_joint_vector(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

}  // namespace

ChainMechanism::ChainMechanism(std::string type, KinematicChain chain, double length_scale,
                               const JointVector& home)
    : Mechanism(std::move(type), chain.kinds(), as_joint_vector(chain.lower()),
                as_joint_vector(chain.upper()), home, length_scale),
      chain_(std::move(chain)) {}

// ---------------------------------------------------------------------------------------

static double checked_length(double length) {
  require_positive("length", length);
  return length;
}

static KinematicChain planar_arm_chain(const Eigen::Vector3d& pivot, const Eigen::Vector3d& n,
                                       double length, const Eigen::Vector3d& d) {
  // base frame: x = d, y = n x d, z = n; the handle at length*d with z_h = -d, y_h = n
  const Pose base = tangent_frame(pivot, n, d);
  Eigen::Matrix3d Rh;
  Rh.col(2) = -Eigen::Vector3d::UnitX();              // stylus toward the pivot
  Rh.col(1) = Eigen::Vector3d::UnitZ();               // plane normal
  Rh.col(0) = Rh.col(1).cross(Rh.col(2));             // x = y cross z
  const Pose handle = make_pose(Rh, Eigen::Vector3d(length, 0.0, 0.0));
  return KinematicChain(base, {make_joint(JointType::kRevolute, Eigen::Vector3d::UnitZ())},
                        handle);
}

static Eigen::Vector3d checked_zero_direction(const Eigen::Vector3d& d, const Eigen::Vector3d& n) {
  if (d.isZero(0.0)) {  // automatic: world x projected into the plane (world y if x is normal)
    Eigen::Vector3d a = Eigen::Vector3d::UnitX() - n.x() * n;
    if (a.norm() < 1e-6) a = Eigen::Vector3d::UnitY() - n.y() * n;
    return a.normalized();
  }
  const Eigen::Vector3d u = require_unit("zero_direction", d);
  if (std::abs(u.dot(n)) > 1e-6) {
    throw std::invalid_argument("zero_direction: expected a unit vector in the plane (orthogonal "
                                "to normal " + format_vector(n) + "), got " + format_vector(d));
  }
  return (u - u.dot(n) * n).normalized();
}

PlanarArm::PlanarArm(const Eigen::Vector3d& pivot, const Eigen::Vector3d& normal, double length,
                     const Eigen::Vector3d& zero_direction)
    : ChainMechanism("PlanarArm",
                planar_arm_chain(pivot, require_unit("normal", normal), checked_length(length),
                                 checked_zero_direction(zero_direction, normal.normalized())),
                length, JointVector::Zero(1)),
      pivot_(pivot), normal_(normal.normalized()),
      zero_direction_(checked_zero_direction(zero_direction, normal.normalized())),
      length_(length) {
  require_finite("pivot", pivot);
  require_positive("length", length);
  Pose T;
  const double zero = 0.0;
  chain().forward(&zero, T);
  rest_ = T.linear();
  zero_cross_ = normal_.cross(zero_direction_);
  for (int j = 0; j < 3; ++j) {
    rest_cross_.col(j) = normal_.cross(rest_.col(j));
    rest_axial_.col(j) = normal_.dot(rest_.col(j)) * normal_;
  }
}


// What both placements of one handle pose share: the handle's distance from the pivot in
// the plane, the rotation's terms, the arc's ends (detail::arc_setup), and the pose error's
// rotation as a function of the angle x: R_R R(x)^T = (R_n(x) M)^T, its 1 + trace
// tr0 + trA cos x + trB sin x and its axis part dc cos x + ds sin x + d0
struct PlanarArm::Setup {
  double r = 0.0, b = 0.0, c = 0.0;
  detail::ArcSetup arc;
  double tr0 = 0.0, trA = 0.0, trB = 0.0;
  Eigen::Vector3d dc, ds, d0;
};

PlanarArm::Setup PlanarArm::setup(const Pose& target) const noexcept {
  Setup g;
  // position: |pivot + L R_n(x) d - p_R|^2 = const - 2 L r cos(x - theta_p)
  const Eigen::Vector3d v = target.translation() - pivot_;
  const double vx = v.dot(zero_direction_), vy = v.dot(zero_cross_);
  // (plain square roots: lengths and traces far from overflow; below 1e-154, where the
  // squares underflow, a term that small is as good as absent)
  g.r = std::sqrt(vx * vx + vy * vy);
  // rotation: with M = R_0 R_R^T, tr(R_n(x) M) = n'Mn + A cos x + B sin x, and the angle
  // between R_n(x) R_0 and R_R has cosine (tr - 1) / 2; B = tr([n]x M) written out
  const Eigen::Matrix3d M = rest_ * target.linear().transpose();
  const double nMn = normal_.dot(M * normal_);
  const double A = M.trace() - nMn;
  const double B = normal_.dot(
      Eigen::Vector3d(M(1, 2) - M(2, 1), M(2, 0) - M(0, 2), M(0, 1) - M(1, 0)));
  g.b = 0.5 * std::sqrt(A * A + B * B);
  g.c = 0.5 * (nMn - 1.0);
  g.arc = detail::arc_setup(Eigen::Vector2d(vx, vy), Eigen::Vector2d(A, B));
  // R_n(x) = cos x (I - n n^T) + sin x [n]x + n n^T, so the axis part a(Y) = (Y21 - Y12,
  // Y02 - Y20, Y10 - Y01) of X = R_n(x) M is cos x (m - k) + sin x h + k with m = a(M),
  // k = a(n n^T M) = (M^T n) x n, h = a([n]x M) = (tr(M) I - M) n; the error's rotation is
  // X^T, whose axis part is the negative
  g.tr0 = 1.0 + nMn;
  g.trA = A;
  g.trB = B;
  const Eigen::Vector3d m(M(2, 1) - M(1, 2), M(0, 2) - M(2, 0), M(1, 0) - M(0, 1));
  const Eigen::Vector3d k = (M.transpose() * normal_).cross(normal_);
  g.dc = k - m;
  g.ds = M * normal_ - M.trace() * normal_;
  g.d0 = -k;
  return g;
}

double PlanarArm::angle(const Setup& g, double w_p, double w_r, double& c,
                        double& s) const noexcept {
  return detail::arc_minimiser(g.arc, 2.0 * w_p * length_ * g.r, g.b, g.c, w_r, c, s);
}

void PlanarArm::finish(const Setup& g, const Pose& target, double x, double c, double s,
                       const JointVector& start, JointVector& theta, Pose& T, Jacobian& J,
                       Vector6& e) const noexcept {
  theta.resize(1);
  // nearest the start
  theta[0] = x + 2.0 * M_PI * detail::round_half_away((start[0] - x) / (2.0 * M_PI));
  // the pose and Jacobian from the solve's cosine and sine (the chain's to rounding): the
  // rest orientation turned by x about n, the handle at L (c d + s n x d) from the pivot
  const Eigen::Vector3d arm = length_ * (c * zero_direction_ + s * zero_cross_);
  T.linear() = c * (rest_ - rest_axial_) + s * rest_cross_ + rest_axial_;
  T.translation() = pivot_ + arm;
  T.makeAffine();
  J.resize(6, 1);
  J.col(0) << normal_.cross(arm), normal_;
  // pose_error(target, T) from the setup's terms, below 2 pi / 3 (near pi from T)
  const double tr1 = g.tr0 + g.trA * c + g.trB * s;
  if (tr1 > 1.0) {
    e << target.translation() - T.translation(),
        detail::log_from_axis_part(c * g.dc + s * g.ds + g.d0, tr1);
  } else {
    e = pose_error(target, T);
  }
}

bool PlanarArm::place(const Pose& target, const Vector6& w, const JointVector& start,
                      JointVector& theta, Pose& T, Jacobian& J, Vector6& e) const noexcept {
  double w_p, w_r;
  if (!detail::isotropic_blocks(w, w_p, w_r)) return false;
  double c, s;
  const Setup g = setup(target);
  const double x = angle(g, w_p, w_r, c, s);
  finish(g, target, x, c, s, start, theta, T, J, e);
  return true;
}

bool PlanarArm::place_pair(const Pose& target, const PlacementIO& a,
                           const PlacementIO& b) const noexcept {
  double wp_a, wr_a, wp_b, wr_b;
  if (!detail::isotropic_blocks(*a.w, *b.w, wp_a, wr_a, wp_b, wr_b)) return false;
  const Setup g = setup(target);
  // (one after the other: side by side, as Probe::place_pair does, measured slower here)
  double c, s;
  const double xa = angle(g, wp_a, wr_a, c, s);
  finish(g, target, xa, c, s, *a.start, *a.theta, *a.T, *a.J, *a.e);
  const double xb = angle(g, wp_b, wr_b, c, s);
  finish(g, target, xb, c, s, *b.start, *b.theta, *b.T, *b.J, *b.e);
  return true;
}

// ---------------------------------------------------------------------------------------

// the tip's lift-off along the surface normal (local z of the tangent frame): a prismatic
// joint with lower limit 0, so the surface pushes but never pulls
static Joint lift_off() {
  Joint j = make_joint(JointType::kPrismatic, Eigen::Vector3d::UnitZ());
  j.lower = 0.0;
  return j;
}

static KinematicChain probe_chain(const Eigen::Vector3d& p, const Eigen::Vector3d& n,
                                  const Eigen::Vector3d& t1, double length, bool unilateral) {
  std::vector<Joint> joints = {make_joint(JointType::kPrismatic, Eigen::Vector3d::UnitX()),
                               make_joint(JointType::kPrismatic, Eigen::Vector3d::UnitY())};
  if (unilateral) joints.push_back(lift_off());
  for (const Joint& j : wrist_rrr()) joints.push_back(j);
  return KinematicChain(tangent_frame(p, n, t1), joints, handle_behind_tip(length));
}

Probe::Probe(const Eigen::Vector3d& plane_point, const Eigen::Vector3d& plane_normal,
             double length, const Eigen::Vector3d& tangent, bool unilateral)
    : ChainMechanism("Probe",
                     probe_chain(plane_point, require_unit("plane_normal", plane_normal),
                                 tangent_or_default("tangent", tangent, plane_normal.normalized()),
                                 checked_length(length), unilateral),
                     length, JointVector::Zero(unilateral ? 6 : 5)),
      point_(plane_point), normal_(plane_normal.normalized()),
      tangent_(tangent_or_default("tangent", tangent, plane_normal.normalized())),
      length_(length), unilateral_(unilateral) {
  require_finite("plane_point", plane_point);
  if (unilateral) set_contact_joint(2);
}

namespace detail {

void wrist_at_tip(const Eigen::Matrix3d& B, const Eigen::Vector3d& tip, double length,
                  const Pose& target, const Eigen::Matrix3d& R, const Eigen::Vector3d& turn,
                  const double* start, int wrist, JointVector& theta, Pose& T, Jacobian& J,
                  Vector6& e) noexcept {
  Eigen::Matrix3d R_tip;
  R_tip << R.col(0), -R.col(1), -R.col(2);
  double ca, sa;
  theta.segment<3>(wrist) = euler_xyz_nearest(
      B.transpose() * R_tip, Eigen::Vector3d(start[0], start[1], start[2]), ca, sa);
  const Eigen::Vector3d arm = -length * R.col(2);  // tip to handle
  T.linear() = R;
  T.translation() = tip + arm;
  T.makeAffine();
  const Eigen::Vector3d axes[3] = {B.col(0), ca * B.col(1) + sa * B.col(2), R_tip.col(2)};
  for (int i = 0; i < 3; ++i) J.col(wrist + i) << axes[i].cross(arm), axes[i];
  e << target.translation() - T.translation(), -turn;
}

Eigen::Vector3d wrist_direction(const Eigen::Matrix3d& B, const double* abc) noexcept {
  const double sa = std::sin(abc[0]), ca = std::cos(abc[0]);
  const double sb = std::sin(abc[1]), cb = std::cos(abc[1]);
  return B * Eigen::Vector3d(sb, -sa * cb, ca * cb);
}

}  // namespace detail

namespace {

// the tip frame [t1, n x t1, n] of probe-like mechanisms
Eigen::Matrix3d tip_base(const Eigen::Vector3d& n, const Eigen::Vector3d& t1) {
  Eigen::Matrix3d B;
  B << t1, n.cross(t1), n;
  return B;
}

// The slides' part of a probe-like placement: the tip moved from `origin` by theta[i] along
// the columns slides[i] of B (i < wrist), their columns of J; then the wrist
// (detail::wrist_at_tip).
void place_wrist(const Eigen::Matrix3d& B, const Eigen::Vector3d& origin, const int* slides,
                 double length, const Pose& target, const Eigen::Matrix3d& R,
                 const Eigen::Vector3d& turn, const JointVector& start, int wrist,
                 JointVector& theta, Pose& T, Jacobian& J, Vector6& e) noexcept {
  J.resize(6, wrist + 3);
  Eigen::Vector3d tip = origin;
  for (int i = 0; i < wrist; ++i) {
    const Eigen::Vector3d slide = B.col(slides[i]);
    tip += theta[i] * slide;
    J.col(i) << slide, 0.0, 0.0, 0.0;
  }
  detail::wrist_at_tip(B, tip, length, target, R, turn, start.data() + wrist, wrist, theta, T,
                       J, e);
}

}  // namespace

// What both placements of one handle pose share: the tip's frame, the tilt's cost (the tip's
// height as the stylus tilts) and its setup (detail::tilt_setup)
struct Probe::Setup {
  Eigen::Matrix3d B;
  detail::TiltCost cost;
  detail::TiltSetup tilt;
};

Probe::Setup Probe::setup(const Pose& target) const noexcept {
  Setup g;
  g.B = tip_base(normal_, tangent_);
  const double d = normal_.dot(target.translation() - point_);  // handle height [m]
  // tip height d - L cos(phi), phi the stylus's angle from n
  if (unilateral_) {
    g.cost.one_sided = true;
    g.cost.a = d;
    g.cost.b = length_;
  } else {
    g.cost.p2 = length_ * length_;
    g.cost.p1 = -2.0 * d * length_;
  }
  g.tilt = detail::tilt_setup(target.linear(), normal_, g.cost);
  return g;
}

void Probe::tilt(const Setup& g, const Pose& target, double w_p, double w_r,
                 const JointVector& start, Eigen::Matrix3d& R,
                 Eigen::Vector3d& turn) const noexcept {
  const int wrist = unilateral_ ? 3 : 2;  // index of the first wrist joint
  const auto start_direction = [&] { return detail::wrist_direction(g.B, start.data() + wrist); };
  detail::tilt_about_axis(g.tilt, target.linear(), normal_, g.cost, w_p, w_r,
                          detail::LazyDirection(start_direction), R, turn);
}

void Probe::finish(const Setup& g, const Pose& target, const Eigen::Matrix3d& R,
                   const Eigen::Vector3d& turn, const JointVector& start, JointVector& theta,
                   Pose& T, Jacobian& J, Vector6& e) const noexcept {
  const int wrist = unilateral_ ? 3 : 2;
  const Eigen::Matrix3d& B = g.B;
  // the tip below the handle for that orientation, brought onto the plane (or left in
  // front of it when one-sided)
  Eigen::Vector3d tip = target.translation() + length_ * R.col(2);
  const double height = normal_.dot(tip - point_);
  // in contact the tip sits exactly on the plane, the lift-off joint on its bound
  const double lift = unilateral_ && height > 1e-12 * length_ ? height : 0.0;
  tip -= (height - lift) * normal_;
  theta.resize(dof());
  theta[0] = B.col(0).dot(tip - point_);
  theta[1] = B.col(1).dot(tip - point_);
  if (unilateral_) theta[2] = lift;
  constexpr int kSlides[3] = {0, 1, 2};  // t1, t2, n
  place_wrist(B, point_, kSlides, length_, target, R, turn, start, wrist, theta, T, J, e);
}

bool Probe::place(const Pose& target, const Vector6& w, const JointVector& start,
                  JointVector& theta, Pose& T, Jacobian& J, Vector6& e) const noexcept {
  double w_p, w_r;
  if (!detail::isotropic_blocks(w, w_p, w_r)) return false;
  const Setup g = setup(target);
  Eigen::Matrix3d R;
  Eigen::Vector3d turn;
  tilt(g, target, w_p, w_r, start, R, turn);
  finish(g, target, R, turn, start, theta, T, J, e);
  return true;
}

bool Probe::place_pair(const Pose& target, const PlacementIO& a,
                       const PlacementIO& b) const noexcept {
  double wp_a, wr_a, wp_b, wr_b;
  if (!detail::isotropic_blocks(*a.w, *b.w, wp_a, wr_a, wp_b, wr_b)) return false;
  const Setup g = setup(target);
  // both tilts, then both wrists: each is a chain of dependent steps, and side by side the
  // processor overlaps the two
  Eigen::Matrix3d Ra, Rb;
  Eigen::Vector3d turn_a, turn_b;
  tilt(g, target, wp_a, wr_a, *a.start, Ra, turn_a);
  tilt(g, target, wp_b, wr_b, *b.start, Rb, turn_b);
  finish(g, target, Ra, turn_a, *a.start, *a.theta, *a.T, *a.J, *a.e);
  finish(g, target, Rb, turn_b, *b.start, *b.theta, *b.T, *b.J, *b.e);
  return true;
}

bool Probe::constraint_wrench(const double* x, const Pose& T, const Jacobian& J,
                              std::uint32_t locked, Vector6& n) const noexcept {
  (void)x, (void)J;
  const std::uint32_t contact = unilateral_ ? 1u << 2 : 0u;  // the lift-off joint locked
  // The wrist's axes (t1, then the turned t2, then the stylus) span every rotation unless
  // the stylus lies along t1 (its middle angle b at +-pi/2: J has rank 4 there); |cos b| is
  // |t1 x z|, and 1e-6 keeps clear of the factorisation's rank cut
  const Eigen::Vector3d z = T.linear().col(2);
  if (locked != contact || !(tangent_.cross(z).squaredNorm() > 1e-12)) return false;
  // the tip L z ahead of the handle stays on the plane: the normal force there
  n << normal_, (length_ * z).cross(normal_);
  return true;
}

namespace {

// The weighted optimum of a stylus whose tip is held to `set` (weights w_p, w_r): the
// handle orientation R (R = exp([turn]x) R_target) and the tip's offsets along the set's free
// and one-sided directions.
// `wrist` indexes the start's first wrist angle.
void place_on_tip_set(const detail::TipSet& set, double length, const Eigen::Matrix3d& B,
                      const Pose& target, double w_p, double w_r, const JointVector& start,
                      int wrist, Eigen::Matrix3d& R, Eigen::Vector3d& turn, double& along,
                      double& lift) noexcept {
  const Eigen::Vector3d u =
      detail::stylus_direction(set, target.translation(), length, target.linear(),
                               detail::wrist_direction(B, start.data() + wrist), w_p, w_r);
  R = detail::turn_stylus(target.linear(), u, turn);
  const Eigen::Vector3d q = target.translation() - length * u - set.point;
  along = set.free.dot(q);
  // in contact the tip sits exactly on the set, the lift-off joint on its bound
  lift = set.one_sided.dot(q);
  if (!(lift > 1e-12 * length)) lift = 0.0;
}

}  // namespace

bool PointPivot::place(const Pose& target, const Vector6& w, const JointVector& start,
                       JointVector& theta, Pose& T, Jacobian& J, Vector6& e) const noexcept {
  if (insertion_) return false;
  double w_p, w_r;
  if (!detail::isotropic_blocks(w, w_p, w_r)) return false;
  // the tip at the point, or on the half-line point + lambda normal, lambda >= 0
  const Eigen::Matrix3d B = tip_base(normal_, tangent_);
  detail::TipSet set;
  set.point = point_;
  if (unilateral_) set.one_sided = normal_;
  const int wrist = unilateral_ ? 1 : 0;
  Eigen::Matrix3d R;
  Eigen::Vector3d turn;
  double along, lift;
  place_on_tip_set(set, length_, B, target, w_p, w_r, start, wrist, R, turn, along, lift);
  theta.resize(dof());
  if (unilateral_) theta[0] = lift;
  constexpr int kSlides[1] = {2};  // n
  place_wrist(B, point_, kSlides, length_, target, R, turn, start, wrist, theta, T, J, e);
  return true;
}

bool LineGuide::place(const Pose& target, const Vector6& w, const JointVector& start,
                      JointVector& theta, Pose& T, Jacobian& J, Vector6& e) const noexcept {
  double w_p, w_r;
  if (!detail::isotropic_blocks(w, w_p, w_r)) return false;
  // the tip on the line, or on the half-plane line + lambda normal, lambda >= 0
  const Eigen::Matrix3d B = tip_base(normal_, direction_);
  detail::TipSet set;
  set.point = point_;
  set.free = direction_;
  if (unilateral_) set.one_sided = normal_;
  const int wrist = unilateral_ ? 2 : 1;
  Eigen::Matrix3d R;
  Eigen::Vector3d turn;
  double along, lift;
  place_on_tip_set(set, length_, B, target, w_p, w_r, start, wrist, R, turn, along, lift);
  theta.resize(dof());
  theta[0] = along;
  if (unilateral_) theta[1] = lift;
  constexpr int kSlides[2] = {0, 2};  // the line, n
  place_wrist(B, point_, kSlides, length_, target, R, turn, start, wrist, theta, T, J, e);
  return true;
}

static std::vector<Joint> pivot_joints(bool unilateral, bool insertion, double length) {
  std::vector<Joint> joints;
  if (unilateral) joints.push_back(lift_off());
  for (const Joint& j : wrist_rrr()) joints.push_back(j);
  if (insertion) {
    // along the stylus (the tip frame's z, toward the handle): the handle at length + s
    Joint s = make_joint(JointType::kPrismatic, Eigen::Vector3d::UnitZ());
    s.lower = -0.9 * length;
    s.upper = 0.0;
    joints.push_back(s);
  }
  return joints;
}

static JointVector pivot_home(bool unilateral, bool insertion, double length) {
  JointVector h = JointVector::Zero((unilateral ? 4 : 3) + (insertion ? 1 : 0));
  if (insertion) h[h.size() - 1] = -length / 3.0;
  return h;
}

PointPivot::PointPivot(const Eigen::Vector3d& point, const Eigen::Vector3d& normal,
                       double length, const Eigen::Vector3d& tangent, bool unilateral,
                       bool insertion)
    : ChainMechanism("PointPivot",
                     KinematicChain(tangent_frame(point, require_unit("normal", normal),
                                                  tangent_or_default("tangent", tangent,
                                                                     normal.normalized())),
                                    pivot_joints(unilateral, insertion, checked_length(length)),
                                    handle_behind_tip(length)),
                     length, pivot_home(unilateral, insertion, length)),
      point_(point), normal_(normal.normalized()),
      tangent_(tangent_or_default("tangent", tangent, normal.normalized())), length_(length),
      unilateral_(unilateral), insertion_(insertion) {
  require_finite("point", point);
  if (unilateral) set_contact_joint(0);
}

// the line is the tangent frame's x axis, the normal its z axis
static std::vector<Joint> line_joints(bool unilateral) {
  std::vector<Joint> joints = {make_joint(JointType::kPrismatic, Eigen::Vector3d::UnitX())};
  if (unilateral) joints.push_back(lift_off());
  for (const Joint& j : wrist_rrr()) joints.push_back(j);
  return joints;
}

LineGuide::LineGuide(const Eigen::Vector3d& point, const Eigen::Vector3d& direction,
                     double length, const Eigen::Vector3d& normal, bool unilateral)
    : ChainMechanism(
          "LineGuide",
          KinematicChain(
              tangent_frame(point,
                            tangent_or_default("normal", normal,
                                               require_unit("direction", direction)),
                            direction.normalized()),
              line_joints(unilateral), handle_behind_tip(checked_length(length))),
          length, JointVector::Zero(unilateral ? 5 : 4)),
      point_(point), direction_(direction.normalized()),
      normal_(tangent_or_default("normal", normal, direction.normalized())), length_(length),
      unilateral_(unilateral) {
  require_finite("point", point);
  if (unilateral) set_contact_joint(1);
}

static JointVector home_within_limits(const KinematicChain& chain) {
  // zero, moved into the joint limits
  JointVector home = JointVector::Zero(chain.dof());
  for (int i = 0; i < chain.dof(); ++i) {
    home[i] = std::min(std::max(0.0, chain.joint(i).lower), chain.joint(i).upper);
  }
  return home;
}

SerialChain::SerialChain(const std::vector<Joint>& joints, const Pose& handle, const Pose& base,
                         double length_scale)
    : SerialChain(KinematicChain(base, joints, handle), length_scale) {}

SerialChain::SerialChain(const KinematicChain& chain, double length_scale)
    : ChainMechanism("SerialChain", chain, length_scale, home_within_limits(chain)) {}

}  // namespace virtmech
