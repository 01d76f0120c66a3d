#include "virtmech/device.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "virtmech/se3.hpp"
#include "virtmech/validate.hpp"

namespace virtmech {

namespace {

JointVector to_joint_vector(const std::string& name, const std::vector<double>& v, int n,
                            double fill) {
  if (v.empty()) return JointVector::Constant(n, fill);
  if (static_cast<int>(v.size()) != n) {
    std::ostringstream os;
    os << name << ": expected " << n << " values (one per joint), got " << v.size();
    throw std::invalid_argument(os.str());
  }
  JointVector out(n);
  for (int i = 0; i < n; ++i) out[i] = v[static_cast<size_t>(i)];
  return out;
}

Joint revolute(const Eigen::Vector3d& axis, const Eigen::Vector3d& at, double lower = -kInf,
               double upper = kInf) {
  Joint j;
  j.type = JointType::kRevolute;
  j.axis = axis;
  j.origin = Pose::Identity();
  j.origin.translation() = at;
  j.lower = lower;
  j.upper = upper;
  return j;
}

}  // namespace

Device::Device(std::string name, const std::vector<JointType>& kinds,
               const DeviceLimits& limits)
    : name_(std::move(name)) {
  if (kinds.empty() || kinds.size() > static_cast<size_t>(kMaxDof)) {
    std::ostringstream os;
    os << "joints: expected 1 to " << kMaxDof << " joints, got " << kinds.size();
    throw std::invalid_argument(os.str());
  }
  dof_ = static_cast<int>(kinds.size());
  const int n = dof_;
  for (int i = 0; i < n; ++i) kinds_[static_cast<size_t>(i)] = kinds[static_cast<size_t>(i)];

  if (static_cast<int>(limits.actuated.size()) != n) {
    std::ostringstream os;
    os << "actuated: expected " << n << " flags (one per joint), got " << limits.actuated.size();
    throw std::invalid_argument(os.str());
  }
  for (int i = 0; i < n; ++i) {
    actuated_[static_cast<size_t>(i)] = limits.actuated[static_cast<size_t>(i)];
    num_actuated_ += actuated_[static_cast<size_t>(i)] ? 1 : 0;
  }
  if (num_actuated_ == 0) throw std::invalid_argument("actuated: expected at least one actuated joint, got none");

  torque_limit_ = to_joint_vector("torque_limit", limits.torque_limit, n, kInf);
  for (int i = 0; i < n; ++i) {
    if (!(torque_limit_[i] > 0.0) && actuated_[static_cast<size_t>(i)]) {
      std::ostringstream os;
      os << "torque_limit[" << i << "]: expected > 0 for an actuated joint, got " << torque_limit_[i];
      throw std::invalid_argument(os.str());
    }
    if (!actuated_[static_cast<size_t>(i)]) torque_limit_[i] = 0.0;
  }
  lower_ = to_joint_vector("lower", limits.lower, n, -kInf);
  upper_ = to_joint_vector("upper", limits.upper, n, kInf);
  require_ordered("lower/upper", lower_, upper_);
  max_velocity_ = to_joint_vector("max_velocity", limits.max_velocity, n, 0.0);
  for (int i = 0; i < n; ++i) {
    if (limits.max_velocity.empty()) {
      max_velocity_[i] = kinds[static_cast<size_t>(i)] == JointType::kRevolute ? kMaxSpeedRevolute
                                                                               : kMaxSpeedPrismatic;
    }
    if (!(max_velocity_[i] > 0.0)) {
      std::ostringstream os;
      os << "max_velocity[" << i << "]: expected > 0 [rad/s or m/s] (inf: unchecked), got "
         << max_velocity_[i];
      throw std::invalid_argument(os.str());
    }
  }
  if (!(limits.max_force > 0.0)) {
    std::ostringstream os;
    os << "max_force: expected > 0 [N], got " << limits.max_force;
    throw std::invalid_argument(os.str());
  }
  if (!(limits.max_torque > 0.0)) {
    std::ostringstream os;
    os << "max_torque: expected > 0 [N·m], got " << limits.max_torque;
    throw std::invalid_argument(os.str());
  }
  require_non_negative("stiffness", limits.stiffness);
  require_non_negative("damping", limits.damping);
  max_force_ = limits.max_force;
  max_torque_ = limits.max_torque;
  stiffness_ = limits.stiffness;
  damping_ = limits.damping;
  home_ = JointVector::Zero(n);
  for (int i = 0; i < n; ++i) home_[i] = std::min(std::max(0.0, lower_[i]), upper_[i]);
}

void Device::set_home(const JointVector& home) { home_ = home; }

void Device::forward(const double* q, Pose& T) const noexcept {
  Jacobian J;
  forward_jacobian(q, T, J);
}

// ---------------------------------------------------------------------------------------

namespace {

// an uncoupled chain's joint limits are the device's unless the limits say otherwise
DeviceLimits with_chain_limits(const KinematicChain& c, DeviceLimits L) {
  if (L.lower.empty()) L.lower = c.lower();
  if (L.upper.empty()) L.upper = c.upper();
  return L;
}

}  // namespace

SerialDevice::SerialDevice(std::string name, const KinematicChain& chain,
                           const DeviceLimits& limits)
    : SerialDevice(std::move(name), chain, with_chain_limits(chain, limits),
                   JointMatrix::Identity(chain.dof(), chain.dof()),
                   JointVector::Zero(chain.dof())) {}

SerialDevice::SerialDevice(std::string name, const KinematicChain& chain,
                           const DeviceLimits& limits, const JointMatrix& coupling,
                           const JointVector& coupling_offset)
    : Device(std::move(name), chain.kinds(), limits), chain_(chain), coupling_(coupling),
      coupling_offset_(coupling_offset) {
  const int n = chain_.dof();
  if (coupling_.rows() != n || coupling_.cols() != n || coupling_offset_.size() != n) {
    throw std::invalid_argument("coupling: expected a dof x dof matrix and a dof offset");
  }
  require_finite("coupling", Eigen::Map<const Eigen::VectorXd>(coupling_.data(), n * n));
  require_finite("coupling_offset", coupling_offset_);
  coupled_ = !(coupling_.isIdentity(0.0) && coupling_offset_.isZero(0.0));
  // C's non-zero entries, column by column (compressed sparse columns)
  int k = 0;
  for (int j = 0; j < n; ++j) {
    coupling_start_[static_cast<size_t>(j)] = k;
    for (int i = 0; i < n; ++i) {
      if (coupling_(i, j) == 0.0) continue;
      coupling_row_[static_cast<size_t>(k)] = i;
      coupling_value_[static_cast<size_t>(k)] = coupling_(i, j);
      ++k;
    }
  }
  coupling_start_[static_cast<size_t>(n)] = k;
}

void SerialDevice::forward(const double* q, Pose& T) const noexcept {
  if (!coupled_) {
    chain_.forward(q, T);
    return;
  }
  JointVector s;
  to_serial(q, s);
  chain_.forward(s.data(), T);
}

void SerialDevice::forward_jacobian(const double* q, Pose& T, Jacobian& J) const noexcept {
  if (!coupled_) {
    chain_.forward_jacobian(q, T, J);
    return;
  }
  JointVector s;
  to_serial(q, s);
  Jacobian Js;
  chain_.forward_jacobian(s.data(), T, Js);
  // J = Js C over C's non-zero entries only (C is mostly a permutation-like sparse matrix:
  // the Omni's has 7 of 36), the same sums as the dense product without its zero terms
  const int n = dof();
  J.resize(6, n);
  for (int j = 0; j < n; ++j) {
    const size_t b = static_cast<size_t>(coupling_start_[static_cast<size_t>(j)]);
    const size_t e = static_cast<size_t>(coupling_start_[static_cast<size_t>(j) + 1]);
    if (b == e) {
      J.col(j).setZero();
      continue;
    }
    J.col(j) = coupling_value_[b] * Js.col(coupling_row_[b]);
    for (size_t k = b + 1; k < e; ++k) J.col(j) += coupling_value_[k] * Js.col(coupling_row_[k]);
  }
}

// s = C q + c0 over C's non-zero entries
void SerialDevice::to_serial(const double* q, JointVector& s) const noexcept {
  const int n = dof();
  s = coupling_offset_;
  for (int j = 0; j < n; ++j) {
    const size_t b = static_cast<size_t>(coupling_start_[static_cast<size_t>(j)]);
    const size_t e = static_cast<size_t>(coupling_start_[static_cast<size_t>(j) + 1]);
    for (size_t k = b; k < e; ++k) s[coupling_row_[k]] += coupling_value_[k] * q[j];
  }
}


namespace {

KinematicChain omni_chain(const PhantomOmniParams& p) {
  require_positive("l1", p.l1);
  require_positive("l2", p.l2);
  const Eigen::Vector3d ux = Eigen::Vector3d::UnitX(), uy = Eigen::Vector3d::UnitY();
  std::vector<Joint> j = {
      revolute(-uy, Eigen::Vector3d(0.0, p.l2, -p.l1)),  // waist, about -y through the shoulder
      revolute(-ux, Eigen::Vector3d::Zero()),           // shoulder, about -x
      revolute(-ux, Eigen::Vector3d(0.0, 0.0, p.l1)),   // elbow (serial: t3 - t2), about -x
      revolute(-uy, Eigen::Vector3d(0.0, -p.l2, 0.0)),  // gimbal yaw, at the gimbal centre
      revolute(-ux, Eigen::Vector3d::Zero()),           // gimbal pitch
      revolute(-Eigen::Vector3d::UnitZ(), Eigen::Vector3d::Zero()),  // gimbal roll (stylus)
  };
  Pose handle = Pose::Identity();
  handle.linear() = Eigen::AngleAxisd(M_PI, ux).toRotationMatrix();  // z_h = -z: stylus forward
  return KinematicChain(Pose::Identity(), j, handle);
}

DeviceLimits omni_limits(const PhantomOmniParams& p) {
  for (int i = 0; i < 3; ++i) {
    require_positive("motor_torque_limit[" + std::to_string(i) + "]", p.motor_torque_limit[i]);
    if (!(p.gimbal_sign[i] == 1.0 || p.gimbal_sign[i] == -1.0)) {
      std::ostringstream os;
      os << "gimbal_sign[" << i << "]: expected +1 or -1, got " << p.gimbal_sign[i];
      throw std::invalid_argument(os.str());
    }
    require_finite("gimbal_offset[" + std::to_string(i) + "]", p.gimbal_offset[i]);
  }
  DeviceLimits L;
  L.actuated = {true, true, true, false, false, false};
  L.torque_limit = {p.motor_torque_limit[0], p.motor_torque_limit[1], p.motor_torque_limit[2],
                    0.0, 0.0, 0.0};
  // public URDF limits [rad]; gimbal yaw shifted by 2*pi to virtmech's zero
  L.lower = {-0.98, 0.0, -0.81, 3.92 - 2.0 * M_PI, -0.5, -2.58};
  L.upper = {0.98, 1.75, 1.25, 8.83 - 2.0 * M_PI, 1.75, 2.58};
  for (int i = 0; i < 3; ++i) {
    // limits are stated in virtmech's gimbal angles; express them in the driver's
    const double a = p.gimbal_sign[i] * L.lower[3 + i] + p.gimbal_offset[i];
    const double b = p.gimbal_sign[i] * L.upper[3 + i] + p.gimbal_offset[i];
    L.lower[3 + i] = std::min(a, b);
    L.upper[3 + i] = std::max(a, b);
  }
  L.max_force = p.max_force;
  L.max_torque = kInf;  // the gimbal renders no moment; the wrench is projected instead
  L.stiffness = p.stiffness;
  L.damping = p.damping;
  return L;
}

JointMatrix omni_coupling(const PhantomOmniParams& p) {
  JointMatrix C = JointMatrix::Identity(6, 6);
  C(2, 1) = -1.0;  // serial elbow = absolute elbow - shoulder (parallelogram)
  for (int i = 0; i < 3; ++i) C(3 + i, 3 + i) = p.gimbal_sign[i];
  return C;
}

JointVector omni_offset(const PhantomOmniParams& p) {
  JointVector c = JointVector::Zero(6);
  for (int i = 0; i < 3; ++i) c[3 + i] = -p.gimbal_sign[i] * p.gimbal_offset[i];
  return c;
}

}  // namespace

PhantomOmni::PhantomOmni(const PhantomOmniParams& params)
    : SerialDevice("PhantomOmni", omni_chain(params), omni_limits(params),
                   omni_coupling(params), omni_offset(params)),
      params_(params) {
  // a pose in the middle of the workspace, stylus tilted down
  JointVector home(6);
  home << 0.0, 0.3, 0.0, params.gimbal_offset[0], 0.5 * params.gimbal_sign[1] + params.gimbal_offset[1],
      params.gimbal_offset[2];
  set_home(home);
}

void PhantomOmni::forward(const double* q, Pose& T) const noexcept { kinematics(q, T, nullptr); }

void PhantomOmni::forward_jacobian(const double* q, Pose& T, Jacobian& J) const noexcept {
  kinematics(q, T, &J);
}

// omni_chain() and omni_coupling() in closed form. With c_i, s_i the cosine and sine of the
// waist q1, shoulder q2 and absolute elbow q3 (the serial elbow is q3 - q2, so the forearm
// turns by q3 about -x):
//   R1 = Ry(-q1),  R3 = R1 Rx(-q3),  gimbal centre p = o1 + R1 (u + w),
//   o1 = (0, l2, -l1),  u = Rx(-q2) (0, 0, l1) = l1 (0, s2, c2),
//   w = Rx(-q3) (0, -l2, 0) = l2 (0, -c3, s3).
// The Jacobian's columns in q: the waist [a1 x (p - o1); a1] with a1 = -y; the shoulder
// (its serial column minus the elbow's: the parallelogram) [a2 x u'; 0] with a2 = -R1 x,
// u' = R1 u; the elbow [a2 x w'; a2], w' = R1 w; the gimbal's [0; sign_i a_i] (their axes
// meet at p).
void PhantomOmni::kinematics(const double* q, Pose& T, Jacobian* J) const noexcept {
  const PhantomOmniParams& P = params_;
  const double s1 = std::sin(q[0]), c1 = std::cos(q[0]);
  const double s2 = std::sin(q[1]), c2 = std::cos(q[1]);
  const double s3 = std::sin(q[2]), c3 = std::cos(q[2]);
  // u' = R1 u and w' = R1 w (R1 (0, y, z) = (-s1 z, y, c1 z))
  const double uy = P.l1 * s2, uz = P.l1 * c2, wy = -P.l2 * c3, wz = P.l2 * s3;
  const Eigen::Vector3d u(-s1 * uz, uy, c1 * uz), w(-s1 * wz, wy, c1 * wz);
  const Eigen::Vector3d p(u.x() + w.x(), P.l2 + u.y() + w.y(), -P.l1 + u.z() + w.z());
  Eigen::Matrix3d R;  // R3
  R << c1, s1 * s3, -s1 * c3,  //
      0.0, c3, s3,             //
      s1, -c1 * s3, c1 * c3;
  const Eigen::Vector3d a4 = -R.col(1);
  // the gimbal: about -y, -x, -z by the serial angles t_i = sign_i (q_i - offset_i)
  double sg[3], cg[3];
  for (size_t i = 0; i < 3; ++i) {
    const double t = P.gimbal_sign[i] * (q[3 + i] - P.gimbal_offset[i]);
    sg[i] = std::sin(t);
    cg[i] = std::cos(t);
  }
  {  // R <- R Ry(-t4)
    const Eigen::Vector3d x = R.col(0), z = R.col(2);
    R.col(0) = cg[0] * x + sg[0] * z;
    R.col(2) = cg[0] * z - sg[0] * x;
  }
  const Eigen::Vector3d a5 = -R.col(0);
  {  // R <- R Rx(-t5)
    const Eigen::Vector3d y = R.col(1), z = R.col(2);
    R.col(1) = cg[1] * y - sg[1] * z;
    R.col(2) = cg[1] * z + sg[1] * y;
  }
  const Eigen::Vector3d a6 = -R.col(2);
  {  // R <- R Rz(-t6)
    const Eigen::Vector3d x = R.col(0), y = R.col(1);
    R.col(0) = cg[2] * x - sg[2] * y;
    R.col(1) = cg[2] * y + sg[2] * x;
  }
  // the handle: Rx(pi), the stylus forward
  T.linear().col(0) = R.col(0);
  T.linear().col(1) = -R.col(1);
  T.linear().col(2) = -R.col(2);
  T.translation() = p;
  T.makeAffine();
  if (!J) return;
  Jacobian& Jq = *J;
  Jq.resize(6, 6);
  const Eigen::Vector3d a2(-c1, 0.0, -s1);
  const Eigen::Vector3d r1 = u + w;  // p - o1
  Jq.col(0) << -r1.z(), 0.0, r1.x(), 0.0, -1.0, 0.0;  // (-y) x r1
  Jq.col(1).head<3>() = a2.cross(u);
  Jq.col(1).tail<3>().setZero();
  Jq.col(2).head<3>() = a2.cross(w);
  Jq.col(2).tail<3>() = a2;
  Jq.block<3, 3>(0, 3).setZero();
  Jq.col(3).tail<3>() = P.gimbal_sign[0] * a4;
  Jq.col(4).tail<3>() = P.gimbal_sign[1] * a5;
  Jq.col(5).tail<3>() = P.gimbal_sign[2] * a6;
}

namespace {

KinematicChain planar3r_chain(double l1, double l2, const Pose& base) {
  require_positive("link1", l1);
  require_positive("link2", l2);
  require_pose("base", base);
  const Eigen::Vector3d z = Eigen::Vector3d::UnitZ();
  std::vector<Joint> j = {revolute(z, Eigen::Vector3d::Zero()),
                          revolute(z, Eigen::Vector3d(l1, 0.0, 0.0)),
                          revolute(z, Eigen::Vector3d(l2, 0.0, 0.0))};
  Eigen::Matrix3d R;
  R.col(0) = Eigen::Vector3d::UnitY();
  R.col(1) = Eigen::Vector3d::UnitZ();
  R.col(2) = Eigen::Vector3d::UnitX();  // stylus along the distal link direction
  return KinematicChain(base, j, make_pose(R, Eigen::Vector3d::Zero()));
}

DeviceLimits planar3r_limits(double torque_limit, double max_force) {
  require_positive("torque_limit", torque_limit);
  require_positive("max_force", max_force);
  DeviceLimits L;
  L.actuated = {true, true, false};
  L.torque_limit = {torque_limit, torque_limit, 0.0};
  L.max_force = max_force;
  L.stiffness = 500.0;
  L.damping = 2.0;
  return L;
}

}  // namespace

Planar3R::Planar3R(double link1, double link2, const Pose& base, double torque_limit,
                   double max_force)
    : SerialDevice("Planar3R", planar3r_chain(link1, link2, base),
                   planar3r_limits(torque_limit, max_force)),
      link1_(link1), link2_(link2) {}

}  // namespace virtmech
