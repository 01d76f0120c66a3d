// Construction-time checks that raise std::invalid_argument naming the parameter, the
// value and what was expected. Never used inside the servo cycle.
#pragma once

#include <string>

#include "virtmech/types.hpp"

namespace virtmech {

std::string format_vector(const Eigen::Ref<const Eigen::VectorXd>& v);
void require_finite(const std::string& name, const Eigen::Ref<const Eigen::VectorXd>& v);
void require_finite(const std::string& name, double v);
void require_positive(const std::string& name, double v);
void require_non_negative(const std::string& name, double v);
void require_non_negative(const std::string& name, const Eigen::Ref<const Eigen::VectorXd>& v);
/// Requires a unit vector (|n| within 1e-6 of 1) and returns it renormalised.
Eigen::Vector3d require_unit(const std::string& name, const Eigen::Vector3d& n);
/// Requires lower[i] <= upper[i] for every i (no NaN; infinite bounds allowed).
void require_ordered(const std::string& name, const Eigen::Ref<const Eigen::VectorXd>& lower,
                     const Eigen::Ref<const Eigen::VectorXd>& upper);
/// Requires a finite rigid transform (orthonormal rotation, last row 0 0 0 1).
void require_pose(const std::string& name, const Pose& T);

}  // namespace virtmech
