// NurbsCurve (include/virtmech/geometry.hpp): The NURBS Book, algorithms A3.2 and A4.2,
// evaluated from each span's Taylor coefficients; the closest point from samples.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "closest_point_search.hpp"
#include "nurbs_basis.hpp"
#include "span_kernels.hpp"
#include "virtmech/geometry.hpp"
#include "virtmech/validate.hpp"

namespace virtmech {

using detail::Best;
using detail::kD;
using detail::kFall;
using detail::kP;

NurbsCurve::NurbsCurve(const Eigen::MatrixX3d& control_points, const Eigen::VectorXd& weights,
                       const Eigen::VectorXd& knots, int degree)
    : n_(static_cast<int>(control_points.rows())), p_(degree), knots_(knots) {
  detail::check_degree("degree", degree);
  if (n_ < degree + 1) {
    throw std::invalid_argument("control_points: expected at least degree + 1 = " +
                                std::to_string(degree + 1) + " points, got " +
                                std::to_string(n_));
  }
  for (int i = 0; i < n_; ++i) require_finite("control_points", Eigen::VectorXd(control_points.row(i).transpose()));
  if (weights.size() != n_) {
    throw std::invalid_argument("weights: expected " + std::to_string(n_) +
                                " values (one per control point), got " +
                                std::to_string(weights.size()));
  }
  if (!weights.allFinite() || !(weights.array() > 0.0).all()) {
    throw std::invalid_argument("weights: expected finite values > 0, got " +
                                format_vector(weights));
  }
  detail::check_knots("knots", knots, n_, p_);
  lower_ = knots[p_];
  upper_ = knots[n_];
  kernel_ = detail::span_kernel(p_);
  pw_.resize(4, n_);
  for (int i = 0; i < n_; ++i) {
    pw_.col(i).head<3>() = weights[i] * control_points.row(i).transpose();
    pw_(3, i) = weights[i];
  }
  // each non-empty span's Taylor coefficients about its middle, C_a = d^a Cw / du^a / a!
  // (a polynomial of degree p there; about the middle the powers stay within half the
  // span), for derivatives_in_span
  taylor_.assign(static_cast<size_t>(n_ - p_) * (p_ + 1), Eigen::Vector4d::Zero());
  for (int span = p_; span < n_; ++span) {
    if (!(knots_[span] < knots_[span + 1])) continue;
    Eigen::Vector4d Cw[kD];
    homogeneous_from_basis(0.5 * (knots_[span] + knots_[span + 1]), span, p_, Cw);
    for (int a = 0; a <= p_; ++a)
      taylor_[static_cast<size_t>(span - p_) * (p_ + 1) + a] = Cw[a] / kFall.f[a][a];
  }
  sample_u_ = detail::sample_parameters(knots_, n_, p_, detail::samples_per_span(p_));
  const size_t ns = sample_u_.size();
  sample_p_.reserve(ns);
  for (double u : sample_u_) sample_p_.push_back(evaluate(u));
  sample_d_start_.resize(ns - 1);
  sample_d_end_.resize(ns - 1);
  CurveDerivatives d;
  for (size_t i = 0; i + 1 < ns; ++i) {
    const int span =
        detail::find_span(knots_.data(), n_, p_, 0.5 * (sample_u_[i] + sample_u_[i + 1]));
    derivatives_in_span(sample_u_[i], span, 1, d);
    sample_d_start_[i] = d.col(1);
    derivatives_in_span(sample_u_[i + 1], span, 1, d);
    sample_d_end_[i] = d.col(1);
    // the interval's bounding sphere: about its middle point, the largest distance over 17
    // points of it, enlarged by half (an interval is an eighth of a knot span or less,
    // where the curve departs from its samples by far less than that)
    const double u0 = sample_u_[i], u1 = sample_u_[i + 1];
    const Eigen::Vector3d c = evaluate(0.5 * (u0 + u1));
    double r = 0.0;
    for (int a = 0; a <= 16; ++a) r = std::max(r, (evaluate(u0 + a * (u1 - u0) / 16.0) - c).norm());
    interval_center_.push_back(c);
    interval_radius_.push_back(detail::kSphereMargin * r);
  }
}

Eigen::MatrixX3d NurbsCurve::control_points() const {
  Eigen::MatrixX3d P(n_, 3);
  for (int i = 0; i < n_; ++i) P.row(i) = (pw_.col(i).head<3>() / pw_(3, i)).transpose();
  return P;
}

Eigen::VectorXd NurbsCurve::weights() const { return pw_.row(3).transpose(); }

Eigen::Vector3d NurbsCurve::evaluate(double u) const noexcept {
  CurveDerivatives d;
  derivatives(u, 0, d);
  return d.col(0);
}

void NurbsCurve::derivatives(double u, int order, CurveDerivatives& out) const noexcept {
  u = detail::clamp(u, lower_, upper_);
  derivatives_in_span(u, detail::find_span(knots_.data(), n_, p_, u), order, out);
}

void NurbsCurve::homogeneous_from_basis(double u, int span, int nd,
                                        Eigen::Vector4d (&Cw)[kMaxDerivativeOrder + 1])
    const noexcept {
  double ders[kD][kP];
  detail::basis_derivatives(knots_.data(), span, p_, u, nd, ders);
  // A3.2 on the homogeneous points
  for (int k = 0; k <= nd; ++k) {
    Cw[k].setZero();
    if (k > p_) continue;
    for (int j = 0; j <= p_; ++j) Cw[k] += ders[k][j] * pw_.col(span - p_ + j);
  }
}

void NurbsCurve::derivatives_in_span(double u, int span, int order,
                                     CurveDerivatives& out) const noexcept {
  const Eigen::Vector4d* C = taylor_.data() + static_cast<size_t>(span - p_) * (p_ + 1);
  const double x = u - 0.5 * (knots_[span] + knots_[span + 1]);
  kernel_(C, x, p_, detail::clamp_order(order), out);
}

// closest_point's view of the samples from p. Brackets: a sample interval whose f' =
// C'.(C - p) is < 0 at its start and > 0 at its end (one-sided derivatives, so kinks at
// knots count) holds a local minimum; so does a sample where f' changes sign across it (a
// kink), and an end where f' points outward.
struct NurbsCurve::Search {
  const NurbsCurve& c;
  const Eigen::Vector3d& p;

  double d2(int i) const noexcept { return (c.sample_p_[static_cast<size_t>(i)] - p).squaredNorm(); }
  double g_start(int i) const noexcept {
    return c.sample_d_start_[static_cast<size_t>(i)].dot(c.sample_p_[static_cast<size_t>(i)] - p);
  }
  double g_end(int i) const noexcept {
    return c.sample_d_end_[static_cast<size_t>(i)].dot(c.sample_p_[static_cast<size_t>(i) + 1] - p);
  }

  // candidate index 4 i + kind: kind 0 the sample i itself (a kink or an end), 1 interval i
  // (a bracket), 2 / 3 interval i from its start / end (a sample that is a discrete local
  // minimum of the distance, refined on its downhill side: a dip between samples whose
  // derivatives agree in sign)
  void candidates(Best<detail::kCandidates>& best) const noexcept {
    const int ni = static_cast<int>(c.sample_u_.size()) - 1;  // intervals
    for (int i = 0; i <= ni; ++i) {
      const bool left_ok = i == 0 || g_end(i - 1) <= 0.0;
      const bool right_ok = i == ni || g_start(i) >= 0.0;
      const double di = d2(i);
      if (left_ok && right_ok) best.add(4 * i, di);
      if (i < ni && g_start(i) < 0.0 && g_end(i) > 0.0)
        best.add(4 * i + 1, std::min(di, d2(i + 1)));
      if ((i == 0 || d2(i - 1) >= di) && (i == ni || d2(i + 1) >= di)) {
        if (i < ni) best.add(4 * i + 2, di);
        if (i > 0) best.add(4 * (i - 1) + 3, di);
      }
    }
  }

  // candidate k (of squared distance d2k) refined within its interval into u and f (half
  // the squared distance); false where all of the interval is farther than best_f
  bool refined(int k, double d2k, double best_f, double& u, double& f) const noexcept {
    const int i = k / 4, kind = k % 4;
    u = c.sample_u_[static_cast<size_t>(i)];
    f = 0.5 * d2k;
    if (kind == 0) return true;
    const double lb = (c.interval_center_[static_cast<size_t>(i)] - p).norm() -
                      c.interval_radius_[static_cast<size_t>(i)];
    if (lb > 0.0 && 0.5 * lb * lb >= best_f) return false;
    using V1 = Eigen::Matrix<double, 1, 1>;
    const V1 lo = V1::Constant(c.sample_u_[static_cast<size_t>(i)]);
    const V1 hi = V1::Constant(c.sample_u_[static_cast<size_t>(i) + 1]);
    // the bracket's knot span: one-sided derivatives at its ends
    const int span = detail::find_span(c.knots_.data(), c.n_, c.p_, 0.5 * (lo[0] + hi[0]));
    auto eval = [&](const V1& x, V1& g, Eigen::Matrix<double, 1, 1>& H) {
      CurveDerivatives d;
      c.derivatives_in_span(x[0], span, 2, d);
      const Eigen::Vector3d r = d.col(0) - p;
      g[0] = d.col(1).dot(r);
      H(0, 0) = d.col(1).squaredNorm() + d.col(2).dot(r);
      return 0.5 * r.squaredNorm();
    };
    // a bracket from inside, nearer its closer end (at a knot the derivatives past the
    // bracket's end may differ); else from the sample
    // (a sample whose derivative points away from the interval: from its middle, for a
    // dip the samples straddle)
    double t = kind == 1 ? (d2(i) <= d2(i + 1) ? 0.25 : 0.75) : (kind == 2 ? 0.0 : 1.0);
    if ((kind == 2 && g_start(i) >= 0.0) || (kind == 3 && g_end(i) <= 0.0)) t = 0.5;
    V1 x = V1::Constant(lo[0] + t * (hi[0] - lo[0]));
    f = detail::refine<1>(x, lo, hi, eval);
    u = x[0];
    return true;
  }
};

double NurbsCurve::closest_point(const Eigen::Vector3d& p, Eigen::Vector3d& point) const noexcept {
  const Search search{*this, p};
  Best<detail::kCandidates> best;
  search.candidates(best);
  double best_f = kInf, best_u = lower_;
  for (int c = 0; c < best.count; ++c) {
    double u, f;
    if (!search.refined(best.index[c], best.d2[c], best_f, u, f)) continue;
    if (f < best_f) {
      best_f = f;
      best_u = u;
    }
  }
  point = evaluate(best_u);
  return best_u;
}

}  // namespace virtmech
