#include "virtmech/validate.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace virtmech {

std::string format_vector(const Eigen::Ref<const Eigen::VectorXd>& v) {
  std::ostringstream os;
  os.precision(6);
  os << "[";
  for (Eigen::Index i = 0; i < v.size(); ++i) os << (i ? ", " : "") << v[i];
  os << "]";
  return os.str();
}

void require_finite(const std::string& name, const Eigen::Ref<const Eigen::VectorXd>& v) {
  if (!v.allFinite()) {
    throw std::invalid_argument(name + ": expected finite values, got " + format_vector(v));
  }
}

void require_finite(const std::string& name, double v) {
  if (!std::isfinite(v)) {
    std::ostringstream os;
    os << name << ": expected a finite number, got " << v;
    throw std::invalid_argument(os.str());
  }
}

void require_positive(const std::string& name, double v) {
  if (!(std::isfinite(v) && v > 0.0)) {
    std::ostringstream os;
    os << name << ": expected a finite number > 0, got " << v;
    throw std::invalid_argument(os.str());
  }
}

void require_non_negative(const std::string& name, double v) {
  if (!(std::isfinite(v) && v >= 0.0)) {
    std::ostringstream os;
    os << name << ": expected a finite number >= 0, got " << v;
    throw std::invalid_argument(os.str());
  }
}

void require_non_negative(const std::string& name, const Eigen::Ref<const Eigen::VectorXd>& v) {
  if (!(v.allFinite() && (v.array() >= 0.0).all())) {
    throw std::invalid_argument(name + ": expected finite values >= 0, got " +
                                format_vector(v));
  }
}

Eigen::Vector3d require_unit(const std::string& name, const Eigen::Vector3d& n) {
  require_finite(name, n);
  const double len = n.norm();
  if (std::abs(len - 1.0) > 1e-6) {
    std::ostringstream os;
    os << name << ": expected a unit vector, got " << format_vector(n) << " (norm " << len
       << ")";
    throw std::invalid_argument(os.str());
  }
  return n / len;
}

void require_ordered(const std::string& name, const Eigen::Ref<const Eigen::VectorXd>& lower,
                     const Eigen::Ref<const Eigen::VectorXd>& upper) {
  for (Eigen::Index i = 0; i < lower.size(); ++i) {
    if (std::isnan(lower[i]) || std::isnan(upper[i]) || !(lower[i] <= upper[i])) {
      std::ostringstream os;
      os << name << "[" << i << "]: expected lower <= upper, got " << lower[i] << " and "
         << upper[i];
      throw std::invalid_argument(os.str());
    }
  }
}

void require_pose(const std::string& name, const Pose& T) {
  const Eigen::Matrix4d& M = T.matrix();
  if (!M.allFinite()) {
    throw std::invalid_argument(name + ": expected a finite 4x4 transform");
  }
  const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
  const double orth = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  const bool last_row = M(3, 0) == 0.0 && M(3, 1) == 0.0 && M(3, 2) == 0.0 && M(3, 3) == 1.0;
  if (orth > 1e-6 || R.determinant() < 0.0 || !last_row) {
    std::ostringstream os;
    os << name << ": expected a rigid transform (orthonormal rotation with det +1, last row "
       << "[0, 0, 0, 1]), got rotation error " << orth << " and det " << R.determinant();
    throw std::invalid_argument(os.str());
  }
}

}  // namespace virtmech
