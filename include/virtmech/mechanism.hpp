// Virtual mechanisms: the constraint the user feels, as a kinematic chain whose handle
// frame the device's handle is held to (paper section III, Figs. 3 and 4).
//
// Handle-frame convention (DESIGN.md): origin at the grip point, local +z along the
// stylus, pointing from the hand toward the probe tip.
#pragma once

#include <string>
#include <vector>

#include "virtmech/kinematic_chain.hpp"

namespace virtmech {

/// A virtual mechanism: a kinematic chain with a name, a home configuration and a length
/// scale [m] used to make rotational weights comparable with translational ones.
class Mechanism {
 public:
  virtual ~Mechanism() = default;

  int dof() const noexcept { return chain_.dof(); }
  const std::string& type_name() const noexcept { return type_; }
  const KinematicChain& chain() const noexcept { return chain_; }
  /// Characteristic length [m]: the probe or arm length.
  double length_scale() const noexcept { return length_scale_; }
  /// Default warm start of the placement.
  const JointVector& home() const noexcept { return home_; }
  JointVector lower() const;
  JointVector upper() const;

  void forward(const double* theta, Pose& T) const noexcept { chain_.forward(theta, T); }
  void forward_jacobian(const double* theta, Pose& T, Jacobian& J) const noexcept {
    chain_.forward_jacobian(theta, T, J);
  }

 protected:
  Mechanism(std::string type, KinematicChain chain, double length_scale, JointVector home);

 private:
  std::string type_;
  KinematicChain chain_;
  double length_scale_ = 0.1;
  JointVector home_;
};

/// Paper Fig. 4 / eq. 2 in 3-D: a revolute joint at `pivot` about the unit `normal`; the
/// handle lies at distance `length` from the pivot in direction R(theta) zero_direction;
/// the stylus points from the handle to the pivot (the probe's tip rests at the pivot).
/// Handle frame: z = -R(theta) d, y = normal, x = y x z.
class PlanarArm final : public Mechanism {
 public:
  PlanarArm(const Eigen::Vector3d& pivot, const Eigen::Vector3d& normal, double length,
            const Eigen::Vector3d& zero_direction);
  const Eigen::Vector3d& pivot() const noexcept { return pivot_; }
  const Eigen::Vector3d& normal() const noexcept { return normal_; }
  double length() const noexcept { return length_; }
  const Eigen::Vector3d& zero_direction() const noexcept { return zero_direction_; }

 private:
  Eigen::Vector3d pivot_, normal_, zero_direction_;
  double length_;
};

/// Paper Fig. 3, PPRRR: the tip slides on the plane through `plane_point` with unit
/// `plane_normal` (two prismatic joints along in-plane axes t1, t2 = n x t1), then three
/// revolute joints whose axes meet at the tip (about t1, then the rotated t2, then the
/// stylus). The handle is `length` back from the tip along the stylus; at theta = 0 the
/// stylus points along -plane_normal (the hand is on the +normal side).
class Probe final : public Mechanism {
 public:
  Probe(const Eigen::Vector3d& plane_point, const Eigen::Vector3d& plane_normal, double length,
        const Eigen::Vector3d& tangent);
  const Eigen::Vector3d& plane_point() const noexcept { return point_; }
  const Eigen::Vector3d& plane_normal() const noexcept { return normal_; }
  const Eigen::Vector3d& tangent() const noexcept { return tangent_; }
  double length() const noexcept { return length_; }

 private:
  Eigen::Vector3d point_, normal_, tangent_;
  double length_;
};

/// A probe whose tip is pinned at `point` (RRR about the tip, as in Probe). At theta = 0 the
/// stylus points along -normal.
class PointPivot final : public Mechanism {
 public:
  PointPivot(const Eigen::Vector3d& point, const Eigen::Vector3d& normal, double length,
             const Eigen::Vector3d& tangent);
  const Eigen::Vector3d& point() const noexcept { return point_; }
  const Eigen::Vector3d& normal() const noexcept { return normal_; }
  const Eigen::Vector3d& tangent() const noexcept { return tangent_; }
  double length() const noexcept { return length_; }

 private:
  Eigen::Vector3d point_, normal_, tangent_;
  double length_;
};

/// A probe whose tip slides on the line through `point` along the unit `direction`
/// (P + RRR). At theta = 0 the stylus points along -normal, normal being orthogonal to the
/// line.
class LineGuide final : public Mechanism {
 public:
  LineGuide(const Eigen::Vector3d& point, const Eigen::Vector3d& direction, double length,
            const Eigen::Vector3d& normal);
  const Eigen::Vector3d& point() const noexcept { return point_; }
  const Eigen::Vector3d& direction() const noexcept { return direction_; }
  const Eigen::Vector3d& normal() const noexcept { return normal_; }
  double length() const noexcept { return length_; }

 private:
  Eigen::Vector3d point_, direction_, normal_;
  double length_;
};

/// Any serial chain of revolute / prismatic joints as a mechanism.
class SerialChain final : public Mechanism {
 public:
  SerialChain(const std::vector<Joint>& joints, const Pose& handle, const Pose& base,
              double length_scale);
  SerialChain(const KinematicChain& chain, double length_scale);
};

}  // namespace virtmech
