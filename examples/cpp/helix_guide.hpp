// A user-defined virtual mechanism: the handle held to a helix, the stylus free to turn.
// It is not a serial chain of revolute and prismatic joints (the path is a screw), so it is
// written in closed form as one subclass of virtmech::Mechanism, with its geometric
// Jacobian by hand. Used by the program 02_custom_mechanism.cpp and registered as a kind
// by the plugin helix_plugin.cpp (so that a scenario file can name it).
#pragma once

#include <cmath>
#include <stdexcept>
#include <vector>

#include "virtmech/virtmech.hpp"

namespace helix {

using namespace virtmech;

// Defaults: a helix about the Omni's waist axis (vertical, 13.33 cm behind the handle's
// zero) through the handle's position at the loop's start.
struct HelixParams {
  Eigen::Vector3d centre{0.0, 0.0421, -0.1333};          //!< a point on the axis [m]
  Eigen::Vector3d axis = Eigen::Vector3d::UnitY();     //!< unit axis (the helix rises along it)
  Eigen::Vector3d zero_direction = Eigen::Vector3d::UnitZ();  //!< axis to handle at phi = 0
  double radius = 0.1539;  //!< [m]
  double pitch = 0.05;   //!< rise per turn [m]
  double turns = 1.5;    //!< phi limited to +-turns full turns
  double length_scale = 0.1;  //!< [m]
};

// theta = [phi, a, b, c]. phi [rad]: angle about the axis; the handle origin is at
// p = centre + r (cos phi e1 + sin phi e2) + h phi / (2 pi) axis, e1 = zero_direction,
// e2 = axis x e1. a, b, c [rad]: the stylus turns about the handle origin, R = R0 Rx(a)
// Ry(b) Rz(c), with R0 = [-e2, axis, -e1]: at zero the stylus (local z) points at the axis.
class HelixGuide final : public Mechanism {
 public:
  explicit HelixGuide(const HelixParams& p)
      : Mechanism("HelixGuide", std::vector<JointType>(4, JointType::kRevolute),
                  limits(-p.turns), limits(p.turns), JointVector::Zero(4), p.length_scale),
        params_(p), centre_(p.centre), axis_(p.axis.normalized()), radius_(p.radius),
        rise_(p.pitch / (2.0 * M_PI)) {
    if (!(p.radius > 0.0)) throw std::invalid_argument("radius: expected > 0");
    e1_ = p.zero_direction - p.zero_direction.dot(axis_) * axis_;
    if (!(e1_.norm() > 1e-9)) throw std::invalid_argument("zero_direction: parallel to axis");
    e1_.normalize();
    e2_ = axis_.cross(e1_);
    R0_.col(0) = -e2_;
    R0_.col(1) = axis_;
    R0_.col(2) = -e1_;
  }

  void forward(const double* x, Pose& T) const noexcept override {
    T.setIdentity();
    T.translation() = centre_ + radius_ * (std::cos(x[0]) * e1_ + std::sin(x[0]) * e2_) +
                      rise_ * x[0] * axis_;
    T.linear() = R0_ * rx(x[1]) * ry(x[2]) * rz(x[3]);
  }

  // rows [v; w] in world axes, v of the handle origin
  void forward_jacobian(const double* x, Pose& T, Jacobian& J) const noexcept override {
    forward(x, T);
    J.setZero(6, 4);
    // phi moves the origin along the helix tangent and turns nothing
    J.col(0).head<3>() =
        radius_ * (-std::sin(x[0]) * e1_ + std::cos(x[0]) * e2_) + rise_ * axis_;
    // a, b, c turn about the origin: about R0 x, then R0 Rx(a) y, then the stylus
    J.col(1).tail<3>() = R0_.col(0);
    J.col(2).tail<3>() = R0_ * rx(x[1]).col(1);
    J.col(3).tail<3>() = T.linear().col(2);
  }

  /// The parameters it was made from.
  const HelixParams& params() const noexcept { return params_; }

 private:
  // lower (turns < 0) or upper limits: phi within the turns, the rotations unlimited
  static JointVector limits(double turns) {
    JointVector v = JointVector::Constant(4, turns > 0 ? kInf : -kInf);
    v[0] = 2.0 * M_PI * turns;
    return v;
  }
  static Eigen::Matrix3d rx(double a) noexcept {
    return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitX()).toRotationMatrix();
  }
  static Eigen::Matrix3d ry(double a) noexcept {
    return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitY()).toRotationMatrix();
  }
  static Eigen::Matrix3d rz(double a) noexcept {
    return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  }

  HelixParams params_;
  Eigen::Vector3d centre_, axis_, e1_, e2_;
  Eigen::Matrix3d R0_;
  double radius_, rise_;
};

}  // namespace helix
