// The built-in kinds (include/virtmech/registry.hpp): one file per kind in this folder, each
// with its registration function below, and the list of them (builtin.cpp).
#pragma once

#include "virtmech/registry.hpp"

namespace virtmech::kinds {

/// Adds every built-in kind (the list).
void add_builtin(Registry& r);

void add_planar_arm(Registry& r);
void add_probe(Registry& r);
void add_point_pivot(Registry& r);
void add_line_guide(Registry& r);
void add_surface_probe(Registry& r);
void add_curve_guide(Registry& r);
void add_handle_path(Registry& r);
void add_serial_chain(Registry& r);
void add_phantom_omni(Registry& r);
void add_planar3r(Registry& r);
void add_serial_device(Registry& r);
void add_cartesian_device(Registry& r);
void add_nurbs_curve(Registry& r);
void add_nurbs_surface(Registry& r);
void add_sphere(Registry& r);
void add_cylinder(Registry& r);
void add_plane(Registry& r);

// ---- what several kinds share ------------------------------------------------------------

/// v / |v|.
inline Eigen::Vector3d unit(const Eigen::Vector3d& v) { return v / v.norm(); }

/// The stylus tip of a probe of `length`: the handle at p moved along the stylus s.
inline Eigen::Vector3d tip_of(double length, const Eigen::Vector3d& p, const Eigen::Vector3d& s) {
  return p + length * s;
}

/// A point's or a line's distances: bilateral, the distance from it; unilateral, from the
/// ray or half plane above it along the normal (the tip may lift off toward +normal).
Distances one_sided(double height, double across, bool unilateral);

/// Distances of a point x from a curve: the distance, its part along `normal` and the rest.
Distances from_curve(const Curve& curve, const Eigen::Vector3d& normal, const Eigen::Vector3d& x);

/// Two unit vectors orthogonal to n and to each other (a drawing's plane axes).
void plane_basis(const Eigen::Vector3d& n, Eigen::Vector3d& u, Eigen::Vector3d& v);

/// The unit direction across a path of unit tangent t along `normal` (made orthogonal to
/// t); any direction across it where the two are parallel.
Eigen::Vector3d across(const Eigen::Vector3d& t, const Eigen::Vector3d& normal);

/// A unit vector orthogonal to unit d, from the world axis least along it.
Eigen::Vector3d orthogonal(const Eigen::Vector3d& d);

/// The polyline of a curve at `count` parameters evenly over its range.
std::vector<Eigen::Vector3d> curve_polyline(const Curve& curve, int count = 200);

/// A grid mesh of a surface over count x count parameters (an unbounded parameter over
/// +-unbounded).
Sketch::Mesh surface_mesh(const Surface& surface, int count = 32, double unbounded = 0.1);

/// Sets a pose as the scenario format writes it: its position and its rotation vector.
Params& set_pose(Params& p, const std::string& position, const std::string& rotation,
                 const Pose& T);

/// A serial chain's joints as the scenario format's tables ({type, axis, origin,
/// origin_rotation, lower, upper}; an infinite limit left out), and a chain from them.
std::vector<Params> describe_joints(const std::vector<Joint>& joints);
std::vector<Joint> joints_from(const std::vector<Params>& tables);
/// The scenario format's fields of one joint.
std::vector<ParamSpec> joint_fields();

}  // namespace virtmech::kinds
