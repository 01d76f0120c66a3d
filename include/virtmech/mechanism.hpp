// Virtual mechanisms: the constraint the user feels, as a kinematic chain whose handle
// frame the device's handle is held to (paper section III, Figs. 3 and 4).
//
// Handle-frame convention (docs/theory.md): origin at the grip point, local +z along the
// stylus, pointing from the hand toward the probe tip.
//
// `Mechanism` is the interface the controller uses: joint count, kinds and limits, home, a
// length scale, and the handle pose with its geometric Jacobian at joint values x. A new
// mechanism is one subclass; serial chains derive from `ChainMechanism`.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "virtmech/geometry.hpp"
#include "virtmech/kinematic_chain.hpp"

namespace virtmech {

/// One placement's weights and warm start, and where its result goes (Mechanism::place_pair):
/// place()'s arguments for one weighting.
struct PlacementIO {
  const Vector6* w;
  const JointVector* start;
  JointVector* theta;
  Pose* T;
  Jacobian* J;
  Vector6* e;
};

/// A virtual mechanism (interface). A mechanism and its shapes are immutable once built
/// (every query is const and writes nothing): controllers on any number of threads may
/// share one; a subclass keeps that so (no mutable caches).
class Mechanism {
 public:
  virtual ~Mechanism() = default;

  int dof() const noexcept { return dof_; }
  const std::string& type_name() const noexcept { return type_; }
  /// Characteristic length [m]: the probe or arm length; weights rotations against
  /// translations (docs/theory.md, section 1).
  double length_scale() const noexcept { return length_scale_; }
  /// Default joint values, the first placement's warm start (within the limits).
  const JointVector& home() const noexcept { return home_; }
  /// Joint limits [rad or m]; -inf / +inf where a joint has none.
  const JointVector& lower() const noexcept { return lower_; }
  const JointVector& upper() const noexcept { return upper_; }
  /// Kind of joint i (0 <= i < dof()): revolute [rad] or prismatic [m].
  JointType joint_type(int i) const noexcept { return kinds_[static_cast<size_t>(i)]; }
  /// The lift-off joint of a unilateral mechanism (its lower limit 0 is the contact: the
  /// tip touches while that joint is held at it), or -1 for a bilateral one.
  int contact_joint() const noexcept { return contact_joint_; }

  /// Handle pose at joint values x (dof() entries). The default evaluates
  /// forward_jacobian; override it when the pose alone is cheaper.
  virtual void forward(const double* x, Pose& T) const noexcept;
  /// Handle pose and geometric Jacobian (6 x dof(), rows [v; w], world axes) at x.
  virtual void forward_jacobian(const double* x, Pose& T, Jacobian& J) const noexcept = 0;

  /// Optional closed-form placement: theta (dof() entries) minimising the weighted pose
  /// error e^T diag(w) e, e = pose_error(target, forward(theta)), within the limits, on the
  /// branch nearest `start`. Returns false where it has none for these weights; the
  /// placement then runs the weighted Gauss-Newton of eqs. 18-20. On true, T and J are the
  /// handle pose and Jacobian at theta (forward_jacobian's, to rounding) and e the pose
  /// error pose_error(target, T): a closed form has most of them at hand, and the placement
  /// needs them next. noexcept, allocation-free.
  virtual bool place(const Pose& target, const Vector6& w, const JointVector& start,
                     JointVector& theta, Pose& T, Jacobian& J, Vector6& e) const noexcept {
    (void)target, (void)w, (void)start, (void)theta, (void)T, (void)J, (void)e;
    return false;
  }

  /// Optional closed-form placement of one target for two weightings at once: the cycle's
  /// nearest and un-powered placements (eqs. 18-20, 25), which share all that depends on the
  /// target alone. Each result is place()'s for its weights and start. Returns false where
  /// place() would for either (then neither result is used, and the cycle places each on its
  /// own); the default returns false. noexcept, allocation-free.
  virtual bool place_pair(const Pose& target, const PlacementIO& a,
                          const PlacementIO& b) const noexcept {
    (void)target, (void)a, (void)b;
    return false;
  }

  /// Optional constraint wrench at x: a wrench n ([f; m] about the handle origin, world
  /// axes, any length) that does no work on any motion of the joints not in `locked` (bit i:
  /// joint i held at a limit), J_free^T n = 0, where J_free (J without the locked columns)
  /// has rank 5, so that n spans its left null space. T and J are the handle pose and the
  /// Jacobian at x. Returns false where it has none (another rank, or not known); the cycle
  /// then finds the left null space by factorising J_free. With it, the placement's rate
  /// needs no factorisation (docs/theory.md, section 5). noexcept, allocation-free.
  virtual bool constraint_wrench(const double* x, const Pose& T, const Jacobian& J,
                                 std::uint32_t locked, Vector6& n) const noexcept {
    (void)x, (void)T, (void)J, (void)locked, (void)n;
    return false;
  }

  /// Optional start of the first placement (after a start, a reset or a fault) for the
  /// handle at `target` with the placement's weights w: theta holds the last placement
  /// (home at the start) and may be moved, within the limits, near the global optimum, so
  /// that a mechanism whose placement has several local optima (a point on a curved surface
  /// or path) starts in the right basin. The default keeps theta. noexcept,
  /// allocation-free; may cost more than a cycle's placement (once).
  virtual void seed(const Pose& target, const Vector6& w, JointVector& theta) const noexcept {
    (void)target, (void)w, (void)theta;
  }

  /// Optional: both seeds of a first cycle at once, the nearest placement's (weights w_a)
  /// into a and the un-powered one's (w_b) into b, each as seed() would give it, where the
  /// two share a costly part (a SurfaceProbe's global closest point); a and b hold the last
  /// placement. False (the default, nothing written) where the controller is to call seed()
  /// for each instead (the un-powered one's then from the nearest's converged placement).
  virtual bool seed_pair(const Pose& target, const Vector6& w_a, const Vector6& w_b,
                         JointVector& a, JointVector& b) const noexcept {
    (void)target, (void)w_a, (void)w_b, (void)a, (void)b;
    return false;
  }

 protected:
  /// Validates and stores the joint description; throws std::invalid_argument naming the
  /// bad parameter. `home` is moved into the limits.
  Mechanism(std::string type, const std::vector<JointType>& kinds, const JointVector& lower,
            const JointVector& upper, const JointVector& home, double length_scale);
  /// Names joint i the lift-off joint (lower limit 0; see contact_joint()).
  void set_contact_joint(int i);

 private:
  std::string type_;
  int dof_ = 0;
  int contact_joint_ = -1;
  std::array<JointType, kMaxDof> kinds_{};
  JointVector lower_, upper_, home_;
  double length_scale_ = 0.1;
};

/// A mechanism that is a serial chain of revolute and prismatic joints.
class ChainMechanism : public Mechanism {
 public:
  const KinematicChain& chain() const noexcept { return chain_; }
  void forward(const double* x, Pose& T) const noexcept override { chain_.forward(x, T); }
  void forward_jacobian(const double* x, Pose& T, Jacobian& J) const noexcept override {
    chain_.forward_jacobian(x, T, J);
  }

 protected:
  ChainMechanism(std::string type, KinematicChain chain, double length_scale,
                 const JointVector& home);

 private:
  KinematicChain chain_;
};

/// Paper Fig. 4 / eq. 2 in 3-D: a revolute joint at `pivot` about the unit `normal`; the
/// handle lies at distance `length` from the pivot in direction R(theta) zero_direction;
/// the stylus points from the handle to the pivot (the probe's tip rests at the pivot).
/// Handle frame: z = -R(theta) d, y = normal, x = y x z. A zero `zero_direction` takes
/// world x projected into the plane (world y where x is normal to it).
class PlanarArm final : public ChainMechanism {
 public:
  PlanarArm(const Eigen::Vector3d& pivot, const Eigen::Vector3d& normal, double length,
            const Eigen::Vector3d& zero_direction);
  const Eigen::Vector3d& pivot() const noexcept { return pivot_; }
  const Eigen::Vector3d& normal() const noexcept { return normal_; }
  double length() const noexcept { return length_; }
  const Eigen::Vector3d& zero_direction() const noexcept { return zero_direction_; }
  /// Closed form for weights isotropic within position and within rotation.
  bool place(const Pose& target, const Vector6& w, const JointVector& start,
             JointVector& theta, Pose& T, Jacobian& J, Vector6& e) const noexcept override;
  /// Both placements sharing the target's geometry (the arc's ends): place()'s results.
  bool place_pair(const Pose& target, const PlacementIO& a,
                  const PlacementIO& b) const noexcept override;

 private:
  struct Setup;  // what both placements of one target share
  Setup setup(const Pose& target) const noexcept;
  double angle(const Setup& g, double w_p, double w_r, double& c, double& s) const noexcept;
  void finish(const Setup& g, const Pose& target, double x, double c, double s,
              const JointVector& start,
              JointVector& theta, Pose& T, Jacobian& J, Vector6& e) const noexcept;
  Eigen::Vector3d pivot_, normal_, zero_direction_;
  double length_;
  Eigen::Matrix3d rest_;  // the handle's orientation at theta = 0
  // R_n(x) u = (u - a) cos x + (n x u) sin x + a, a = (n . u) n (Rodrigues), for the zero
  // direction and the columns of rest_: their n x u and a, once
  Eigen::Vector3d zero_cross_;
  Eigen::Matrix3d rest_cross_, rest_axial_;
};

/// Paper Fig. 3, PPRRR: the tip slides on the plane through `plane_point` with unit
/// `plane_normal` (two prismatic joints along in-plane axes t1, t2 = n x t1), then three
/// revolute joints whose axes meet at the tip (about t1, then the rotated t2, then the
/// stylus). The handle is `length` back from the tip along the stylus; at theta = 0 the
/// stylus points along -plane_normal (the hand is on the +normal side).
///
/// `unilateral`: the tip may also leave the plane toward +plane_normal (a third prismatic
/// joint along n, after t1 and t2, with lower limit 0), so the plane pushes but never pulls:
/// PPPRRR, theta = [t1, t2, height, a, b, c].
class Probe final : public ChainMechanism {
 public:
  Probe(const Eigen::Vector3d& plane_point, const Eigen::Vector3d& plane_normal, double length,
        const Eigen::Vector3d& tangent, bool unilateral = false);
  const Eigen::Vector3d& plane_point() const noexcept { return point_; }
  const Eigen::Vector3d& plane_normal() const noexcept { return normal_; }
  const Eigen::Vector3d& tangent() const noexcept { return tangent_; }
  double length() const noexcept { return length_; }
  bool unilateral() const noexcept { return unilateral_; }
  /// Closed form for weights isotropic within position and within rotation (every default).
  bool place(const Pose& target, const Vector6& w, const JointVector& start,
             JointVector& theta, Pose& T, Jacobian& J, Vector6& e) const noexcept override;
  /// Both placements sharing the target's geometry (the tilt's setup): place()'s results.
  bool place_pair(const Pose& target, const PlacementIO& a,
                  const PlacementIO& b) const noexcept override;
  /// The plane's normal force at the tip, [n; (L z) x n] (z the stylus), with the tip on
  /// the plane (the lift-off joint locked when unilateral, no other joint locked) and the
  /// wrist away from its gimbal lock (|cos b| > 1e-6).
  bool constraint_wrench(const double* x, const Pose& T, const Jacobian& J,
                         std::uint32_t locked, Vector6& n) const noexcept override;

 private:
  struct Setup;  // what both placements of one target share
  Setup setup(const Pose& target) const noexcept;
  void tilt(const Setup& g, const Pose& target, double w_p, double w_r,
            const JointVector& start, Eigen::Matrix3d& R, Eigen::Vector3d& turn) const noexcept;
  void finish(const Setup& g, const Pose& target, const Eigen::Matrix3d& R,
              const Eigen::Vector3d& turn, const JointVector& start, JointVector& theta,
              Pose& T, Jacobian& J, Vector6& e) const noexcept;
  Eigen::Vector3d point_, normal_, tangent_;
  double length_;
  bool unilateral_;
};

/// A probe whose tip is pinned at `point` (RRR about the tip, as in Probe). At theta = 0 the
/// stylus points along -normal. `unilateral`: the tip may lift off toward +normal (a
/// prismatic joint along the normal with lower limit 0 before the RRR).
///
/// `insertion`: a trocar (a remote centre of motion): the stylus passes through `point` and
/// slides along itself, a prismatic joint s after the RRR, the handle at length + s from the
/// point along the stylus, s in [-0.9 length, 0] (0: the tool's tip at the point; the tip
/// may go in through it up to 0.9 length, never out). home s = -length / 3.
class PointPivot final : public ChainMechanism {
 public:
  PointPivot(const Eigen::Vector3d& point, const Eigen::Vector3d& normal, double length,
             const Eigen::Vector3d& tangent, bool unilateral = false, bool insertion = false);
  const Eigen::Vector3d& point() const noexcept { return point_; }
  const Eigen::Vector3d& normal() const noexcept { return normal_; }
  const Eigen::Vector3d& tangent() const noexcept { return tangent_; }
  double length() const noexcept { return length_; }
  bool unilateral() const noexcept { return unilateral_; }
  bool insertion() const noexcept { return insertion_; }
  /// Closed form for weights isotropic within position and within rotation (bilateral: one
  /// scalar solve; unilateral: one solve in the stylus's two tilt angles). None with
  /// insertion (the Gauss-Newton placement).
  bool place(const Pose& target, const Vector6& w, const JointVector& start,
             JointVector& theta, Pose& T, Jacobian& J, Vector6& e) const noexcept override;

 private:
  Eigen::Vector3d point_, normal_, tangent_;
  double length_;
  bool unilateral_;
  bool insertion_;
};

/// A probe whose tip slides on the line through `point` along the unit `direction`
/// (P + RRR). At theta = 0 the stylus points along -normal, normal being orthogonal to the
/// line. `unilateral`: the tip may lift off the line toward +normal (a prismatic joint
/// along the normal with lower limit 0 after the one along the line).
class LineGuide final : public ChainMechanism {
 public:
  LineGuide(const Eigen::Vector3d& point, const Eigen::Vector3d& direction, double length,
            const Eigen::Vector3d& normal, bool unilateral = false);
  const Eigen::Vector3d& point() const noexcept { return point_; }
  const Eigen::Vector3d& direction() const noexcept { return direction_; }
  const Eigen::Vector3d& normal() const noexcept { return normal_; }
  double length() const noexcept { return length_; }
  bool unilateral() const noexcept { return unilateral_; }
  /// Closed form for weights isotropic within position and within rotation: the tip's
  /// position and the roll about the stylus drop out exactly, one solve in the stylus's two
  /// tilt angles remains.
  bool place(const Pose& target, const Vector6& w, const JointVector& start,
             JointVector& theta, Pose& T, Jacobian& J, Vector6& e) const noexcept override;

 private:
  Eigen::Vector3d point_, direction_, normal_;
  double length_;
  bool unilateral_;
};

/// Paper Fig. 3 on any surface: the probe's tip slides on `surface` (joints u, v, the
/// surface's parameters), three revolute joints meet at the tip (about t1, the rotated t2,
/// the stylus) and the handle is `length` back along the stylus. The wrist's base at (u, v)
/// is the surface frame B = [t1, n x t1, n], t1 = S_u / |S_u|, n = S_u x S_v normalised
/// (the surface's normal): at wrist angles 0 the stylus points along -n, the hand on the
/// side n points to. The wrist is singular only with the stylus along t1, in the tangent
/// plane, which a probe touching the surface never is.
///
/// `unilateral`: the tip may leave the surface toward +n (a prismatic joint along n after
/// u, v, lower limit 0): theta = [u, v, h, a, b, c]; else [u, v, a, b, c].
/// u and v are limited to the surface's parameter bounds (u unbounded where it wraps,
/// Surface::periodic_u) and count as prismatic for the placement's step cap. At a point
/// where the parametrisation is singular (a sphere's pole) the mechanism loses a direction
/// of motion and renders it as a constraint: put such points where the probe is not used.
/// home: the middle of the parameter bounds (0 where unbounded); the first placement is
/// seeded by the surface's global closest point (seed()).
class SurfaceProbe final : public Mechanism {
 public:
  /// surface: non-null; length > 0. Throws std::invalid_argument naming the parameter.
  SurfaceProbe(std::shared_ptr<const Surface> surface, double length, bool unilateral = false);
  const Surface& surface() const noexcept { return *surface_; }
  const std::shared_ptr<const Surface>& surface_ptr() const noexcept { return surface_; }
  double length() const noexcept { return length_; }
  bool unilateral() const noexcept { return unilateral_; }
  void forward_jacobian(const double* x, Pose& T, Jacobian& J) const noexcept override;
  /// The tip target (the handle's point `length` along its stylus) projected onto the
  /// surface; the wrist angles of the handle's orientation there. Where w weighs positions
  /// only (a nearest placement): the tip moved, over that point's tangent plane, to where
  /// the stylus reaches the surface from the handle, nearest the handle's stylus, and the
  /// wrist turned to it (with the stylus along the error the position-only cost is
  /// stationary but not least, and Gauss-Newton would not leave it).
  void seed(const Pose& target, const Vector6& w, JointVector& theta) const noexcept override;
  /// Both seeds from one global closest point.
  bool seed_pair(const Pose& target, const Vector6& w_a, const Vector6& w_b, JointVector& a,
                 JointVector& b) const noexcept override;
  /// With weights isotropic per block. On a Sphere: the weighted optimum in closed form
  /// (the stylus turns in the plane of the handle's stylus and the centre-to-handle
  /// direction, one angle; docs/theory.md, section 4). On every other surface: with the
  /// tip in contact, Newton's method on the tip's surface parameters and the stylus
  /// direction, with exact second derivatives (the roll about the stylus drops out);
  /// one-sided and lifted off, the handle's own pose (the tip's nearest surface point
  /// tracked from the start: "above the surface" is judged there, locally, as Gauss-Newton
  /// would). False where a parameter would leave its bounds, Newton does not converge and
  /// the tip is not above the surface, or the KKT sign says lift while the tip is below
  /// the surface where its nearest point is tracked: Gauss-Newton then.
  bool place(const Pose& target, const Vector6& w, const JointVector& start,
             JointVector& theta, Pose& T, Jacobian& J, Vector6& e) const noexcept override;
  /// The surface's normal force at the tip, [N; (L z) x N], N = S_u x S_v normalised (S_u,
  /// S_v: the tip's velocities along the two surface joints, from J), with the tip on the
  /// surface (the lift-off joint locked when unilateral, no other joint locked), away from
  /// a degenerate point of the surface and from the wrist's gimbal lock (both 1e-6).
  bool constraint_wrench(const double* x, const Pose& T, const Jacobian& J,
                         std::uint32_t locked, Vector6& n) const noexcept override;

 private:
  bool place_on_surface(const Pose& target, double w_p, double w_r, const JointVector& start,
                        JointVector& theta, Pose& T, Jacobian& J, Vector6& e) const noexcept;
  bool place_lifted(const Pose& target, const JointVector& start, Eigen::Vector2d& uv,
                    JointVector& theta, Pose& T, Jacobian& J, Vector6& e) const noexcept;
  void seed_from(const Pose& target, const Vector6& w, const Eigen::Vector2d& uv_tip,
                 const Eigen::Vector3d& point, JointVector& theta) const noexcept;
  bool reach_seed(const Pose& target, const SurfaceDerivatives& d, const Eigen::Matrix3d& B,
                  Eigen::Vector2d& uv, Eigen::Matrix3d& R, double& lift) const noexcept;

  std::shared_ptr<const Surface> surface_;
  const Sphere* sphere_ = nullptr;  // surface_ when it is a Sphere
  double length_;
  bool unilateral_;
};

/// A probe whose tip is held on a curve, the path to trace (joint u, the curve's parameter,
/// then RRR at the tip about the fixed base B = [t1, normal x t1, normal], t1 =
/// any_orthogonal(normal)); the handle is `length` back along the stylus, which points
/// along -normal at wrist angles 0. theta = [u, a, b, c]; u within the curve's bounds (the
/// path's ends are stops), counted as prismatic for the step cap. The wrist is singular
/// with the stylus along t1. The first placement is seeded by the global closest point.
class CurveGuide final : public Mechanism {
 public:
  /// curve: non-null; length > 0; normal: unit (the side the hand is on).
  CurveGuide(std::shared_ptr<const Curve> curve, double length,
             const Eigen::Vector3d& normal = Eigen::Vector3d::UnitZ());
  const Curve& curve() const noexcept { return *curve_; }
  const std::shared_ptr<const Curve>& curve_ptr() const noexcept { return curve_; }
  double length() const noexcept { return length_; }
  const Eigen::Vector3d& normal() const noexcept { return normal_; }
  void forward_jacobian(const double* x, Pose& T, Jacobian& J) const noexcept override;
  void seed(const Pose& target, const Vector6& w, JointVector& theta) const noexcept override;
  /// With weights isotropic per block: Newton's method with exact second derivatives on
  /// the curve's parameter and the stylus's direction (the roll drops out), from the warm
  /// start; false where it is not the way (see docs/theory.md, section 4): Gauss-Newton.
  bool place(const Pose& target, const Vector6& w, const JointVector& start,
             JointVector& theta, Pose& T, Jacobian& J, Vector6& e) const noexcept override;

 private:
  std::shared_ptr<const Curve> curve_;
  double length_;
  Eigen::Vector3d normal_;
  Eigen::Matrix3d base_;
};

/// The handle itself held on a curve, its orientation free: joint u, then RRR about the
/// handle point (base B as CurveGuide's; at wrist angles 0 the stylus points along
/// -normal). theta = [u, a, b, c]. `length_scale` [m] weighs rotations against translations.
class HandlePath final : public Mechanism {
 public:
  HandlePath(std::shared_ptr<const Curve> curve,
             const Eigen::Vector3d& normal = Eigen::Vector3d::UnitZ(),
             double length_scale = 0.1);
  const Curve& curve() const noexcept { return *curve_; }
  const std::shared_ptr<const Curve>& curve_ptr() const noexcept { return curve_; }
  const Eigen::Vector3d& normal() const noexcept { return normal_; }
  void forward_jacobian(const double* x, Pose& T, Jacobian& J) const noexcept override;
  void seed(const Pose& target, const Vector6& w, JointVector& theta) const noexcept override;

 private:
  std::shared_ptr<const Curve> curve_;
  Eigen::Vector3d normal_;
  Eigen::Matrix3d base_;
};

/// Any serial chain of revolute / prismatic joints as a mechanism.
class SerialChain final : public ChainMechanism {
 public:
  SerialChain(const std::vector<Joint>& joints, const Pose& handle, const Pose& base,
              double length_scale);
  SerialChain(const KinematicChain& chain, double length_scale);
};

}  // namespace virtmech
