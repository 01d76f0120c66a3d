// What several built-in kinds share (kinds.hpp).
#include <cmath>

#include "kinds.hpp"
#include "virtmech/se3.hpp"
#include "virtmech/settings.hpp"

namespace virtmech::kinds {

Distances one_sided(double height, double across, bool unilateral) {
  const double full = std::hypot(height, across);
  const double signed_full = height < 0.0 ? -full : full;
  const double dist = unilateral ? std::hypot(across, std::min(height, 0.0)) : full;
  return {dist, signed_full, height, across};
}

Distances from_curve(const Curve& curve, const Eigen::Vector3d& normal, const Eigen::Vector3d& x) {
  Eigen::Vector3d point;
  curve.closest_point(x, point);
  const Eigen::Vector3d w = x - point;
  const double h = w.dot(unit(normal));
  const double full = w.norm();
  return {full, full, h, std::sqrt(std::max(full * full - h * h, 0.0))};
}

void plane_basis(const Eigen::Vector3d& n, Eigen::Vector3d& u, Eigen::Vector3d& v) {
  const Eigen::Vector3d m = unit(n);
  const Eigen::Vector3d a = std::abs(m[0]) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  u = unit(m.cross(a));
  v = m.cross(u);
}

Eigen::Vector3d orthogonal(const Eigen::Vector3d& d) {
  Eigen::Index least = 0;
  d.cwiseAbs().minCoeff(&least);
  return unit(d.cross(Eigen::Vector3d::Unit(least)));
}

Eigen::Vector3d across(const Eigen::Vector3d& t, const Eigen::Vector3d& normal) {
  const Eigen::Vector3d n = normal / normal.norm();
  const Eigen::Vector3d a = n - n.dot(t) * t;
  if (a.norm() < 1e-6) return orthogonal(t);
  return unit(a);
}

std::vector<Eigen::Vector3d> curve_polyline(const Curve& curve, int count) {
  std::vector<Eigen::Vector3d> out;
  for (int i = 0; i < count; ++i) {
    const double u = curve.lower() + (curve.upper() - curve.lower()) * i / (count - 1);
    out.push_back(curve.evaluate(u));
  }
  return out;
}

Sketch::Mesh surface_mesh(const Surface& surface, int count, double unbounded) {
  Eigen::Vector2d lo = surface.lower(), hi = surface.upper();
  for (int k = 0; k < 2; ++k) {
    if (!std::isfinite(lo[k])) lo[k] = -unbounded;
    if (!std::isfinite(hi[k])) hi[k] = unbounded;
  }
  Sketch::Mesh mesh;
  for (int i = 0; i < count; ++i) {
    for (int j = 0; j < count; ++j) {
      const double u = lo[0] + (hi[0] - lo[0]) * i / (count - 1);
      const double v = lo[1] + (hi[1] - lo[1]) * j / (count - 1);
      mesh.vertices.push_back(surface.evaluate(u, v));
    }
  }
  for (int i = 0; i + 1 < count; ++i) {
    for (int j = 0; j + 1 < count; ++j) {
      const int a = i * count + j;
      mesh.faces.push_back({a, a + count, a + count + 1});
      mesh.faces.push_back({a, a + count + 1, a + 1});
    }
  }
  return mesh;
}

Params& set_pose(Params& p, const std::string& position, const std::string& rotation,
                 const Pose& T) {
  return p.set(position, Eigen::Vector3d(T.translation()))
      .set(rotation, so3_log(Eigen::Matrix3d(T.linear())));
}

std::vector<Params> describe_joints(const std::vector<Joint>& joints) {
  std::vector<Params> out;
  for (const Joint& j : joints) {
    Params p;
    p.set("type", name_of(j.type));
    p.set("axis", j.axis);
    set_pose(p, "origin", "origin_rotation", j.origin);
    if (std::isfinite(j.lower)) p.set("lower", j.lower);  // none: no limit
    if (std::isfinite(j.upper)) p.set("upper", j.upper);
    out.push_back(std::move(p));
  }
  return out;
}

std::vector<ParamSpec> joint_fields() {
  std::vector<std::string> kinds;
  for (const EnumName& n : enum_names<JointType>()) kinds.push_back(n.name);
  return {string_param("type", std::nullopt, kinds, "the joint's kind"),
          direction_param("axis", std::nullopt, "3 numbers, not all zero, in the joint frame"),
          point_param("origin", Eigen::Vector3d::Zero(),
                      "the joint frame's position in the previous [m]"),
          array_param("origin_rotation", {3}, std::vector<double>{0.0, 0.0, 0.0}, "rad",
                      "the joint frame's rotation vector in the previous"),
          optional(number_param("lower", std::nullopt, -1e3, 1e3, "rad or m",
                                "lower limit; none when omitted")),
          optional(number_param("upper", std::nullopt, -1e3, 1e3, "rad or m",
                                "upper limit; none when omitted"))};
}

std::vector<Joint> joints_from(const std::vector<Params>& tables) {
  std::vector<Joint> joints;
  for (const Params& t : tables) {
    Joint j;
    j.type = enum_from_name<JointType>("type", t.string("type"));
    j.axis = t.vector3("axis");
    j.origin = pose_from(t.vector3("origin"), t.vector3("origin_rotation"));
    j.lower = t.has("lower") ? t.number("lower") : -kInf;
    j.upper = t.has("upper") ? t.number("upper") : kInf;
    joints.push_back(j);
  }
  return joints;
}

}  // namespace virtmech::kinds
