// NurbsSurface (include/virtmech/geometry.hpp): The NURBS Book, algorithms A3.6 and A4.4,
// evaluated from each span pair's Taylor coefficients; the closest point from samples.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "closest_point_search.hpp"
#include "nurbs_basis.hpp"
#include "span_kernels.hpp"
#include "virtmech/geometry.hpp"

namespace virtmech {

using detail::Best;
using detail::find_span;
using detail::kCandidates;
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

// closest_point's view of the samples and cells from p.
struct NurbsSurface::Search {
  // (kept left uninitialised: nearest_sample() fills what is read)
  Search(const NurbsSurface& surface, const Eigen::Vector3d& point) noexcept
      : s(surface), p(point) {}

  const NurbsSurface& s;
  const Eigen::Vector3d& p;
  const int mu = static_cast<int>(s.sample_u_.size()), mv = static_cast<int>(s.sample_v_.size());
  // the samples' squared distances from p, kept on the stack where they fit (each is read
  // by up to four cells' tests and nine samples' local-minimum tests)
  const bool keep = mu * mv <= detail::kKeptSamples;
  double kept[detail::kKeptSamples];

  double d2(int i, int j) const noexcept {
    const size_t k = static_cast<size_t>(i) * mv + j;
    return keep ? kept[k] : (s.sample_p_[k] - p).squaredNorm();
  }
  // the gradient's parts at sample (i, j): from the right in u / from above in v, or (a
  // cell's far corner, an edge interval's end) from the left / from below
  double gu(int i, int j, bool left = false) const noexcept {
    const size_t k = static_cast<size_t>(i) * mv + j;
    return (left ? s.sample_su_left_ : s.sample_su_)[k].dot(s.sample_p_[k] - p);
  }
  double gv(int i, int j, bool below = false) const noexcept {
    const size_t k = static_cast<size_t>(i) * mv + j;
    return (below ? s.sample_sv_below_ : s.sample_sv_)[k].dot(s.sample_p_[k] - p);
  }
  // the distance from p of cell (i, j) at least (where that is > 0)
  double cell_bound(int i, int j) const noexcept {
    const size_t cell = static_cast<size_t>(i) * (mv - 1) + j;
    return (s.cell_center_[cell] - p).norm() - s.cell_radius_[cell];
  }
  // the distance from p of the cells about sample (i, j) at least: a start's minimum lies
  // in one of them
  double cells_bound(int i, int j) const noexcept {
    double lb = kInf;
    for (int a = std::max(i - 1, 0); a <= std::min(i, mu - 2); ++a)
      for (int b = std::max(j - 1, 0); b <= std::min(j, mv - 2); ++b)
        lb = std::min(lb, cell_bound(a, b));
    return lb;
  }

  // The samples' squared distances (kept), and the nearest sample's distance. It bounds the
  // least distance from above (the refinement from it, the first, descends), so a cell
  // farther than it holds no minimum that counts: only the cells within it are searched.
  double nearest_sample() noexcept {
    double least[4] = {kInf, kInf, kInf, kInf};  // (four chains of minima overlap)
    for (size_t k = 0; k < s.sample_p_.size(); ++k) {
      const double e = (s.sample_p_[k] - p).squaredNorm();
      if (keep) kept[k] = e;
      least[k % 4] = std::min(least[k % 4], e);
    }
    const double near2 = std::min(std::min(least[0], least[1]), std::min(least[2], least[3]));
    return std::sqrt(near2);
  }

  // (1) sample (i, j) where it is a discrete local minimum of the distance
  void local_min(int i, int j, Best<kCandidates>& best) const noexcept {
    const double dij = d2(i, j);
    for (int a = std::max(i - 1, 0); a <= std::min(i + 1, mu - 1); ++a)
      for (int b = std::max(j - 1, 0); b <= std::min(j + 1, mv - 1); ++b)
        if ((a != i || b != j) && d2(a, b) < dij) return;
    best.add(i * mv + j, dij);
  }
  // (2) cell (i, j) where its corners' gradients change sign in u and in v (a minimum
  // inside), started at the nearest corner; on a creased surface also from inside the cell
  // (a corner on a crease may descend to the other side's minimum, and one beside it to
  // this side's): index samples + cell
  void sign_change(int i, int j, Best<kCandidates>& best) const noexcept {
    double umin = kInf, umax = -kInf, vmin = kInf, vmax = -kInf, dmin = kInf;
    int start = 0;
    for (int a = i; a <= i + 1; ++a) {
      for (int b = j; b <= j + 1; ++b) {
        const double x = gu(a, b, a > i), y = gv(a, b, b > j), dd = d2(a, b);
        umin = std::min(umin, x), umax = std::max(umax, x);
        vmin = std::min(vmin, y), vmax = std::max(vmax, y);
        if (dd < dmin) dmin = dd, start = a * mv + b;
      }
    }
    if (umin <= 0.0 && umax >= 0.0 && vmin <= 0.0 && vmax >= 0.0) {
      best.add(start, dmin);
      if (s.creased_) best.add(mu * mv + i * (mv - 1) + j, dmin);
    }
  }
  // (3) the interval (i, j)-(i, j + 1) of an edge u = const whose tangential gradient
  // changes sign (a minimum on or near the edge)
  void edge_v(int i, int j, Best<kCandidates>& best) const noexcept {
    if (gv(i, j) <= 0.0 && gv(i, j + 1, true) >= 0.0) {
      const bool first = d2(i, j) <= d2(i, j + 1);
      best.add(i * mv + (first ? j : j + 1), std::min(d2(i, j), d2(i, j + 1)));
    }
  }
  // ... and the interval (i, j)-(i + 1, j) of an edge v = const
  void edge_u(int i, int j, Best<kCandidates>& best) const noexcept {
    if (gu(i, j) <= 0.0 && gu(i + 1, j, true) >= 0.0) {
      const bool first = d2(i, j) <= d2(i + 1, j);
      best.add((first ? i : i + 1) * mv + j, std::min(d2(i, j), d2(i + 1, j)));
    }
  }

  // Candidates (index i * mv + j, the start), in the cells within `near` of p: (1), (2) and
  // (3) above
  void candidates(double near, Best<kCandidates>& best) const noexcept {
    for (int i = 0; i + 1 < mu; ++i) {
      for (int j = 0; j + 1 < mv; ++j) {
        // the cell's sphere farther than the nearest sample: |c - p| - radius > near
        const size_t cell = static_cast<size_t>(i) * (mv - 1) + j;
        const double reach = s.cell_radius_[cell] + near;
        if ((s.cell_center_[cell] - p).squaredNorm() > reach * reach) continue;
        for (int a = i; a <= i + 1; ++a)
          for (int b = j; b <= j + 1; ++b) local_min(a, b, best);
        sign_change(i, j, best);
        if (i == 0) edge_v(0, j, best);
        if (i + 2 == mu) edge_v(mu - 1, j, best);
        if (j == 0) edge_u(i, 0, best);
        if (j + 2 == mv) edge_u(i, mv - 1, best);
      }
    }
  }

  // candidate k's sample (i, j), or its cell (i, j) (in_cell)
  void decode(int k, int& i, int& j, bool& in_cell) const noexcept {
    in_cell = k >= mu * mv;
    i = in_cell ? (k - mu * mv) / (mv - 1) : k / mv;
    j = in_cell ? (k - mu * mv) % (mv - 1) : k % mv;
  }
  // the distance from p of where candidate k's minimum lies, at least
  double bound(int k) const noexcept {
    int i, j;
    bool in_cell;
    decode(k, i, j, in_cell);
    return in_cell ? cell_bound(i, j) : cells_bound(i, j);
  }
  // candidate k's start: the sample, or a quarter of the way into the cell from its
  // nearest corner
  Eigen::Vector2d start(int k) const noexcept {
    int i, j;
    bool in_cell;
    decode(k, i, j, in_cell);
    Eigen::Vector2d x(s.sample_u_[static_cast<size_t>(i)], s.sample_v_[static_cast<size_t>(j)]);
    if (!in_cell) return x;
    const Eigen::Vector2d far(s.sample_u_[static_cast<size_t>(i) + 1],
                              s.sample_v_[static_cast<size_t>(j) + 1]);
    const Eigen::Vector2d mid = 0.5 * (x + far);
    int a = 0, b = 0;
    for (int c = 0; c < 4; ++c)
      if (d2(i + c / 2, j + c % 2) < d2(i + a, j + b)) a = c / 2, b = c % 2;
    const Eigen::Vector2d corner(a ? far[0] : x[0], b ? far[1] : x[1]);
    return 0.5 * (corner + mid);
  }

  // Polish: along a crease (a knot of full multiplicity), or a knot where the Hessian
  // jumps, the coupled steps zigzag; the 1-D problems with u, then v held, then both free
  // again settle them (a C^2 surface has no such line).
  void polish(double& best_f, Eigen::Vector2d& best_x) const noexcept {
    const detail::DistanceToSurface eval{s, p};
    for (int round = 0; round < 3; ++round) {
      const double f0 = best_f;
      for (int fixed = 0; fixed < 3; ++fixed) {
        Eigen::Vector2d lo = s.lower_, hi = s.upper_, x = best_x;
        if (fixed < 2) lo[fixed] = hi[fixed] = x[fixed];
        const double f = detail::refine<2>(x, lo, hi, eval);
        if (f < best_f) {
          best_f = f;
          best_x = x;
        }
      }
      if (!(best_f < f0)) break;
    }
  }
};

Eigen::Vector2d NurbsSurface::closest_point(const Eigen::Vector3d& p,
                                            Eigen::Vector3d& point) const noexcept {
  Search search{*this, p};
  Best<kCandidates> best;
  search.candidates(search.nearest_sample(), best);
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
