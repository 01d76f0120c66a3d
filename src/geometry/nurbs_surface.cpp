// NurbsSurface (include/virtmech/geometry.hpp): The NURBS Book, algorithms A3.6 and A4.4,
// evaluated from each span pair's Taylor coefficients; the closest point from samples.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "nurbs_basis.hpp"
#include "nurbs_surface_search.hpp"
#include "span_kernels.hpp"
#include "virtmech/geometry.hpp"

namespace virtmech {

using detail::find_span;
using detail::kD;
using detail::kFall;
using detail::kP;

namespace {

// The constructor's checks of the control net's shape and values (the knots: check_knots).
void check_control_net(const Eigen::MatrixX3d& control_points, const Eigen::MatrixXd& weights,
                       int nu_, int nv_, int degree_u, int degree_v) {
  if (control_points.rows() != static_cast<Eigen::Index>(nu_) * nv_) {
    throw std::invalid_argument("control_points: expected nu * nv = " + std::to_string(nu_) +
                                " * " + std::to_string(nv_) + " points (the weights' shape), got " +
                                std::to_string(control_points.rows()));
  }
  if (nu_ < degree_u + 1 || nv_ < degree_v + 1) {
    throw std::invalid_argument("control_points: expected at least (degree_u + 1, degree_v + 1) = (" +
                                std::to_string(degree_u + 1) + ", " + std::to_string(degree_v + 1) +
                                ") points, got (" + std::to_string(nu_) + ", " +
                                std::to_string(nv_) + ")");
  }
  if (!control_points.allFinite()) {
    throw std::invalid_argument("control_points: expected finite values");
  }
  if (!weights.allFinite() || !(weights.array() > 0.0).all()) {
    throw std::invalid_argument("weights: expected finite values > 0, got min " +
                                std::to_string(weights.minCoeff()));
  }
}

// The number of closest-point samples within kMaxNurbsSurfaceSamples (their memory and the
// constructor's time grow with it).
void check_size(int nu, int nv, long su, long sv, int degree_u, int degree_v) {
  if (su * sv <= kMaxNurbsSurfaceSamples) return;
  throw std::invalid_argument(
      "control_points: expected a surface of at most " +
      std::to_string(kMaxNurbsSurfaceSamples) + " closest-point samples (about 260 x 260 " +
      "control points of degree 3), got " + std::to_string(nu) + " x " + std::to_string(nv) +
      " points of degrees (" + std::to_string(degree_u) + ", " + std::to_string(degree_v) +
      "), " + std::to_string(su) + " x " + std::to_string(sv) + " samples; use fewer " +
      "control points or a lower degree");
}

}  // namespace

NurbsSurface::NurbsSurface(const Eigen::MatrixX3d& control_points, const Eigen::MatrixXd& weights,
                           const Eigen::VectorXd& knots_u, const Eigen::VectorXd& knots_v,
                           int degree_u, int degree_v)
    : nu_(static_cast<int>(weights.rows())),
      nv_(static_cast<int>(weights.cols())),
      p_(degree_u),
      q_(degree_v),
      knots_u_(knots_u),
      knots_v_(knots_v) {
  detail::check_degree("degree_u", degree_u);
  detail::check_degree("degree_v", degree_v);
  check_control_net(control_points, weights, nu_, nv_, degree_u, degree_v);
  detail::check_knots("knots_u", knots_u, nu_, p_);
  detail::check_knots("knots_v", knots_v, nv_, q_);
  check_size(nu_, nv_, sample_count(knots_u, nu_, p_), sample_count(knots_v, nv_, q_), p_, q_);
  lower_ = {knots_u[p_], knots_v[q_]};
  upper_ = {knots_u[nu_], knots_v[nv_]};
  kernel_ = detail::span_pair_kernel(p_, q_);
  pw_.resize(4, nu_ * nv_);
  for (int i = 0; i < nu_; ++i) {
    for (int j = 0; j < nv_; ++j) {
      const int c = i * nv_ + j;
      pw_.col(c).head<3>() = weights(i, j) * control_points.row(c).transpose();
      pw_(3, c) = weights(i, j);
    }
  }
  build_taylor();
  // C^2 across a knot of multiplicity k needs degree - k >= 2
  const int mu = detail::interior_multiplicity(knots_u_, nu_, p_);
  const int mv = detail::interior_multiplicity(knots_v_, nv_, q_);
  kinked_ = (mu > 0 && mu > p_ - 2) || (mv > 0 && mv > q_ - 2);
  creased_ = (mu > 0 && mu >= p_) || (mv > 0 && mv >= q_);
  build_samples();
  build_cell_bounds();
  build_blocks();
}

void NurbsSurface::build_taylor() {
  // each non-empty span pair's Taylor coefficients about its middle, C_ab =
  // d^(a+b) Sw / du^a dv^b / (a! b!) from the basis functions (a polynomial of degree p, q
  // there: its Taylor series is exact), for derivatives_in_spans
  const size_t block = static_cast<size_t>(p_ + 1) * (q_ + 1);
  taylor_.assign(static_cast<size_t>(nu_ - p_) * (nv_ - q_) * block, Eigen::Vector4d::Zero());
  for (int su = p_; su < nu_; ++su) {
    if (!(knots_u_[su] < knots_u_[su + 1])) continue;
    for (int sv = q_; sv < nv_; ++sv) {
      if (!(knots_v_[sv] < knots_v_[sv + 1])) continue;
      Eigen::Vector4d Sw[kD][kD];
      homogeneous_from_basis(0.5 * (knots_u_[su] + knots_u_[su + 1]),
                             0.5 * (knots_v_[sv] + knots_v_[sv + 1]), su, sv,
                             std::max(p_, q_), Sw);
      Eigen::Vector4d* C =
          taylor_.data() + static_cast<size_t>((su - p_) * (nv_ - q_) + (sv - q_)) * block;
      for (int a = 0; a <= p_; ++a)
        for (int b = 0; b <= q_; ++b)
          C[a * (q_ + 1) + b] = Sw[a][b] / (kFall.f[a][a] * kFall.f[b][b]);
    }
  }
}

void NurbsSurface::build_samples() {
  sample_u_ = detail::sample_parameters(knots_u_, nu_, p_, detail::samples_per_span(p_));
  sample_v_ = detail::sample_parameters(knots_v_, nv_, q_, detail::samples_per_span(q_));
  sample_p_.reserve(sample_u_.size() * sample_v_.size());
  sample_su_.reserve(sample_p_.capacity());
  sample_sv_.reserve(sample_p_.capacity());
  sample_su_left_.reserve(sample_p_.capacity());
  sample_sv_below_.reserve(sample_p_.capacity());
  SurfaceDerivatives d;
  for (size_t i = 0; i < sample_u_.size(); ++i) {
    const double u = sample_u_[i];
    const int su = find_span(knots_u_.data(), nu_, p_, u);
    // the span to the left of u (a sample is a knot or between two)
    const int su_left =
        i == 0 ? su : find_span(knots_u_.data(), nu_, p_, 0.5 * (sample_u_[i - 1] + u));
    for (size_t j = 0; j < sample_v_.size(); ++j) {
      const double v = sample_v_[j];
      const int sv = find_span(knots_v_.data(), nv_, q_, v);
      const int sv_below =
          j == 0 ? sv : find_span(knots_v_.data(), nv_, q_, 0.5 * (sample_v_[j - 1] + v));
      derivatives_in_spans(u, v, su, sv, 1, d);
      sample_p_.push_back(d(0, 0));
      sample_su_.push_back(d(1, 0));
      sample_sv_.push_back(d(0, 1));
      derivatives_in_spans(u, v, su_left, sv, 1, d);
      sample_su_left_.push_back(d(1, 0));
      derivatives_in_spans(u, v, su, sv_below, 1, d);
      sample_sv_below_.push_back(d(0, 1));
    }
  }
}

void NurbsSurface::build_cell_bounds() {
  // each cell's bounding sphere, as the curve's intervals': about its middle point, the
  // largest distance over 9 x 9 points of it, enlarged by half
  const size_t su = sample_u_.size(), sv = sample_v_.size();
  cell_center_.reserve((su - 1) * (sv - 1));
  cell_radius_.reserve((su - 1) * (sv - 1));
  for (size_t i = 0; i + 1 < su; ++i) {
    for (size_t j = 0; j + 1 < sv; ++j) {
      const double u0 = sample_u_[i], u1 = sample_u_[i + 1];
      const double v0 = sample_v_[j], v1 = sample_v_[j + 1];
      const Eigen::Vector3d c = evaluate(0.5 * (u0 + u1), 0.5 * (v0 + v1));
      double r = 0.0;
      for (int a = 0; a <= 8; ++a)
        for (int b = 0; b <= 8; ++b)
          r = std::max(r, (evaluate(u0 + a * (u1 - u0) / 8.0, v0 + b * (v1 - v0) / 8.0) - c).norm());
      cell_center_.push_back(c);
      cell_radius_.push_back(detail::kSphereMargin * r);
    }
  }
}

Eigen::MatrixX3d NurbsSurface::control_points() const {
  Eigen::MatrixX3d P(nu_ * nv_, 3);
  for (int c = 0; c < nu_ * nv_; ++c) P.row(c) = (pw_.col(c).head<3>() / pw_(3, c)).transpose();
  return P;
}

Eigen::MatrixXd NurbsSurface::weights() const {
  Eigen::MatrixXd W(nu_, nv_);
  for (int i = 0; i < nu_; ++i)
    for (int j = 0; j < nv_; ++j) W(i, j) = pw_(3, i * nv_ + j);
  return W;
}

Eigen::Vector3d NurbsSurface::evaluate(double u, double v) const noexcept {
  SurfaceDerivatives d;
  derivatives(u, v, 0, d);
  return d(0, 0);
}

void NurbsSurface::derivatives(double u, double v, int order,
                               SurfaceDerivatives& out) const noexcept {
  u = detail::clamp(u, lower_[0], upper_[0]);
  v = detail::clamp(v, lower_[1], upper_[1]);
  derivatives_in_spans(u, v, find_span(knots_u_.data(), nu_, p_, u),
                       find_span(knots_v_.data(), nv_, q_, v), order, out);
}

void NurbsSurface::homogeneous_from_basis(double u, double v, int su, int sv, int nd,
                                          Eigen::Vector4d (&Sw)[kMaxDerivativeOrder + 1]
                                                               [kMaxDerivativeOrder + 1])
    const noexcept {
  double Nu[kD][kP], Nv[kD][kP];
  detail::basis_derivatives(knots_u_.data(), su, p_, u, nd, Nu);
  detail::basis_derivatives(knots_v_.data(), sv, q_, v, nd, Nv);
  // A3.6 on the homogeneous points
  const int du = std::min(nd, p_), dv = std::min(nd, q_);
  for (int k = 0; k <= nd; ++k)
    for (int l = 0; l <= nd; ++l) Sw[k][l].setZero();
  Eigen::Vector4d temp[kP];
  for (int k = 0; k <= du; ++k) {
    for (int s = 0; s <= q_; ++s) {
      temp[s].setZero();
      for (int r = 0; r <= p_; ++r) temp[s] += Nu[k][r] * pw_.col((su - p_ + r) * nv_ + sv - q_ + s);
    }
    for (int l = 0; l <= dv; ++l) {
      for (int s = 0; s <= q_; ++s) Sw[k][l] += Nv[l][s] * temp[s];
    }
  }
}

void NurbsSurface::derivatives_in_spans(double u, double v, int su, int sv, int order,
                                        SurfaceDerivatives& out) const noexcept {
  const Eigen::Vector4d* C =
      taylor_.data() + static_cast<size_t>((su - p_) * (nv_ - q_) + (sv - q_)) * (p_ + 1) * (q_ + 1);
  const double x = u - 0.5 * (knots_u_[su] + knots_u_[su + 1]);
  const double y = v - 0.5 * (knots_v_[sv] + knots_v_[sv + 1]);
  kernel_(C, x, y, p_, q_, detail::clamp_order(order), out);
}

Eigen::Vector2d NurbsSurface::closest_point(const Eigen::Vector3d& p,
                                            Eigen::Vector3d& point) const noexcept {
  if (!p.allFinite()) {
    // no distance from p is finite: no start does better than the first
    point = evaluate(lower_[0], lower_[1]);
    return lower_;
  }
  Search search{*this, p};
  Search::Starts best;
  search.candidates(best);
  const detail::DistanceToSurface eval{*this, p};
  double best_f = kInf;
  Eigen::Vector2d best_x = lower_;
  for (int c = 0; c < best.count; ++c) {
    if (best_f < kInf) {
      const double lb = search.bound(best.index[c]);
      if (lb > 0.0 && 0.5 * lb * lb >= best_f) continue;
    }
    Eigen::Vector2d x = search.start(best.index[c]);
    const double f = detail::refine<2>(x, lower_, upper_, eval);
    if (f < best_f) {
      best_f = f;
      best_x = x;
    }
  }
  if (best.count > 0 && kinked_) search.polish(best_f, best_x);
  point = evaluate(best_x[0], best_x[1]);
  return best_x;
}

}  // namespace virtmech
