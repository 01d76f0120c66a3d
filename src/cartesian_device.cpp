#include "virtmech/cartesian_device.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "closed_form.hpp"
#include "virtmech/validate.hpp"

namespace virtmech {

namespace {

constexpr double kDeg = M_PI / 180.0;

// a model's wrist range from the datasheet's total travel per axis [deg], centred on zero
Eigen::Vector3d half(double a_deg, double b_deg, double c_deg) {
  return Eigen::Vector3d(a_deg, b_deg, c_deg) * (0.5 * kDeg);
}

CartesianModel model(const char* name, bool orientation, bool torque, bool gripper,
                     double force, double torque_limit, const Eigen::Vector3d& box,
                     const Eigen::Vector3d& wrist) {
  CartesianModel m;
  m.name = name;
  m.orientation_sensed = orientation;
  m.torque_actuated = torque;
  m.gripper = gripper;
  m.max_force = force;
  m.max_torque = torque_limit;
  m.position_lower = -box;
  m.position_upper = box;
  m.angle_lower = -wrist;
  m.angle_upper = wrist;
  m.stiffness = 1000.0;
  m.damping = 2.0;
  return m;
}

// Figures (docs/devices.md, "Cartesian devices", which cites their sources): the omega.6's
// 12 N, the Falcon's 8 N and the sigma.7's 0.2 N·m, and which axes are sensed and driven,
// from CHAI3D's device table for the DHD devices. Every other figure here is a simulation
// parameter, not a datasheet figure: the omega.3's and omega.7's 12 N and the sigma.7's force
// clamp (the omega.6's figure, so that the sigma.7 differs from the omega.6 by its driven
// wrist only), the workspace boxes and the wrist ranges (generous bounds of the
// plausibility check; the pitch b within 70 deg keeps away from the gimbal lock at 90 deg),
// and the default gains.
std::vector<CartesianModel> make_models() {
  const Eigen::Vector3d omega_box(0.055, 0.08, 0.08), sigma_box(0.065, 0.095, 0.095),
      falcon_box(0.05, 0.05, 0.05);
  const Eigen::Vector3d none = Eigen::Vector3d::Zero();
  return {
      model("omega.3", false, false, false, 12.0, 0.0, omega_box, none),
      model("omega.6", true, false, false, 12.0, 0.0, omega_box, half(240, 140, 320)),
      model("omega.7", true, false, true, 12.0, 0.0, omega_box, half(240, 140, 320)),
      model("sigma.7", true, true, true, 12.0, 0.2, sigma_box, half(235, 140, 200)),
      model("falcon", false, false, false, 8.0, 0.0, falcon_box, none),
  };
}

Joint axis_joint(JointType type, int axis, double lower, double upper) {
  Joint j;
  j.type = type;
  j.axis = Eigen::Vector3d::Unit(axis);
  j.lower = lower;
  j.upper = upper;
  return j;
}

KinematicChain cartesian_chain(const CartesianModel& m, const Eigen::Matrix3d& handle_rotation) {
  require_finite("handle_rotation",
                 Eigen::Map<const Eigen::Matrix<double, 9, 1>>(handle_rotation.data()));
  const double orthogonality = (handle_rotation.transpose() * handle_rotation -
                                Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (orthogonality > 1e-9 || handle_rotation.determinant() < 0.0) {
    std::ostringstream os;
    os << "handle_rotation: expected a rotation matrix (orthonormal, determinant +1), got "
          "one off by "
       << orthogonality;
    throw std::invalid_argument(os.str());
  }
  std::vector<Joint> joints;
  for (int i = 0; i < 3; ++i) {
    joints.push_back(axis_joint(JointType::kPrismatic, i, m.position_lower[i],
                                m.position_upper[i]));
  }
  if (m.orientation_sensed) {
    for (int i = 0; i < 3; ++i) {
      joints.push_back(axis_joint(JointType::kRevolute, i, m.angle_lower[i], m.angle_upper[i]));
    }
  }
  Pose handle = Pose::Identity();
  handle.linear() = handle_rotation;
  return KinematicChain(Pose::Identity(), joints, handle);
}

DeviceLimits cartesian_limits(const CartesianModel& m) {
  DeviceLimits L;
  const int n = m.orientation_sensed ? 6 : 3;
  for (int i = 0; i < n; ++i) {
    const bool slide = i < 3;
    L.actuated.push_back(slide || m.torque_actuated);
    L.torque_limit.push_back(slide ? m.max_force : (m.torque_actuated ? m.max_torque : 0.0));
  }
  L.max_force = m.max_force;
  L.max_torque = m.torque_actuated ? m.max_torque : kInf;  // a passive wrist: projected
  L.stiffness = m.stiffness;
  L.damping = m.damping;
  return L;
}

}  // namespace

const std::vector<CartesianModel>& cartesian_models() {
  static const std::vector<CartesianModel> models = make_models();
  return models;
}

std::vector<std::string> cartesian_model_names() {
  std::vector<std::string> out;
  for (const CartesianModel& m : cartesian_models()) out.push_back(m.name);
  return out;
}

const CartesianModel& cartesian_model(const std::string& name) {
  for (const CartesianModel& m : cartesian_models()) {
    if (m.name == name) return m;
  }
  std::ostringstream os;
  os << "model: value '" << name << "' is not a Cartesian device model; expected one of ";
  const std::vector<std::string> names = cartesian_model_names();
  for (size_t i = 0; i < names.size(); ++i) os << (i ? ", " : "") << "'" << names[i] << "'";
  throw std::invalid_argument(os.str());
}

Eigen::Matrix3d default_cartesian_handle_rotation() {
  return Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();  // Rx(pi)
}

CartesianDevice::CartesianDevice(const std::string& model, const Eigen::Matrix3d& handle_rotation)
    : SerialDevice(model, cartesian_chain(cartesian_model(model), handle_rotation),
                   cartesian_limits(cartesian_model(model))),
      model_(cartesian_model(model)), handle_rotation_(handle_rotation) {}

void CartesianDevice::forward(const double* q, Pose& T) const noexcept {
  T.setIdentity();
  T.translation() << q[0], q[1], q[2];
  if (!orientation_sensed()) {
    T.linear() = handle_rotation_;
    return;
  }
  Eigen::Vector3d p;
  Eigen::Matrix3d R;
  sdk_pose(q, p, R);
  T.linear().noalias() = R * handle_rotation_;
}

// J = [I 0; 0 [x, Rx(a) y, Rx(a) Ry(b) z]]: the slides move the handle origin along the base
// axes, the wrist's axes meet at it
void CartesianDevice::forward_jacobian(const double* q, Pose& T, Jacobian& J) const noexcept {
  forward(q, T);
  const int n = dof();
  J.setZero(6, n);
  J.topLeftCorner<3, 3>().setIdentity();
  if (n == 3) return;
  const double sa = std::sin(q[3]), ca = std::cos(q[3]);
  const double sb = std::sin(q[4]), cb = std::cos(q[4]);
  J(3, 3) = 1.0;
  J(4, 4) = ca;
  J(5, 4) = sa;
  J(3, 5) = sb;
  J(4, 5) = -sa * cb;
  J(5, 5) = ca * cb;
}

void CartesianDevice::coordinates(const Eigen::Vector3d& p, const Eigen::Matrix3d& R_sdk,
                                  const double* previous, double* q) const noexcept {
  q[0] = p.x();
  q[1] = p.y();
  q[2] = p.z();
  if (!orientation_sensed()) return;
  const Eigen::Vector3d start =
      previous ? Eigen::Vector3d(previous[3], previous[4], previous[5]) : Eigen::Vector3d::Zero();
  double ca, sa;
  Eigen::Vector3d abc = detail::euler_xyz_nearest(R_sdk, start, ca, sa);
  // the wrist's branch is cos b >= 0 (its range lies within |b| < pi/2); the angles a and c
  // then within pi of the previous reading's
  if (std::cos(abc[1]) < 0.0) {
    abc += Eigen::Vector3d(M_PI, M_PI - 2.0 * abc[1], M_PI);
    for (int i = 0; i < 3; ++i) {
      abc[i] += 2.0 * M_PI * detail::round_half_away((start[i] - abc[i]) / (2.0 * M_PI));
    }
  }
  q[3] = abc[0];
  q[4] = abc[1];
  q[5] = abc[2];
}

void CartesianDevice::sdk_pose(const double* q, Eigen::Vector3d& p,
                               Eigen::Matrix3d& R_sdk) const noexcept {
  p << q[0], q[1], q[2];
  if (!orientation_sensed()) {
    R_sdk.setIdentity();
    return;
  }
  const double sa = std::sin(q[3]), ca = std::cos(q[3]);
  const double sb = std::sin(q[4]), cb = std::cos(q[4]);
  const double sc = std::sin(q[5]), cc = std::cos(q[5]);
  // Rx(a) Ry(b) Rz(c)
  R_sdk << cb * cc, -cb * sc, sb,                        //
      sa * sb * cc + ca * sc, -sa * sb * sc + ca * cc, -sa * cb,  //
      -ca * sb * cc + sa * sc, ca * sb * sc + sa * cc, ca * cb;
}

// w = a' x + b' (0, ca, sa) + c' (sb, -sa cb, ca cb): b' = ca w_y + sa w_z,
// c' cb = -sa w_y + ca w_z, a' = w_x - c' sb
bool CartesianDevice::rates(const double* q, const Eigen::Vector3d& v, const Eigen::Vector3d& w,
                            double* dq) const noexcept {
  dq[0] = v.x();
  dq[1] = v.y();
  dq[2] = v.z();
  if (!orientation_sensed()) return true;
  const double sa = std::sin(q[3]), ca = std::cos(q[3]);
  const double sb = std::sin(q[4]), cb = std::cos(q[4]);
  if (!(std::abs(cb) > 1e-9)) {
    dq[3] = dq[4] = dq[5] = 0.0;
    return false;
  }
  const double c = (-sa * w.y() + ca * w.z()) / cb;
  dq[3] = w.x() - c * sb;
  dq[4] = ca * w.y() + sa * w.z();
  dq[5] = c;
  return true;
}

// tau_r = J_w^T m: tau_a = m_x, tau_b = ca m_y + sa m_z, tau_c = sb m_x + cb (-sa m_y + ca m_z)
bool CartesianDevice::wrench(const double* q, const double* tau, Eigen::Vector3d& f,
                             Eigen::Vector3d& m) const noexcept {
  f << tau[0], tau[1], tau[2];
  m.setZero();
  if (!orientation_sensed()) return true;
  const double sa = std::sin(q[3]), ca = std::cos(q[3]);
  const double sb = std::sin(q[4]), cb = std::cos(q[4]);
  if (!(std::abs(cb) > 1e-9)) return false;
  const double u = (tau[5] - sb * tau[3]) / cb;  // -sa m_y + ca m_z
  m << tau[3], ca * tau[4] - sa * u, sa * tau[4] + ca * u;
  return true;
}

}  // namespace virtmech
