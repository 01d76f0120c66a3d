// NurbsSurface::closest_point's search (include/virtmech/geometry.hpp): its view of the
// samples and cells from a point, the candidate starts it finds there, and its walk over the
// hierarchy of cells (nurbs_surface_blocks.cpp). Internal to the core.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "closest_point_search.hpp"
#include "virtmech/geometry.hpp"

namespace virtmech {

namespace detail {

/// The K best candidate starts, in the order of their squared distance d and, among equal
/// distances, of a key: the list a scan of every cell in order would keep (Best<K> there,
/// the key the rank of a start's first sighting in that scan), whatever order the cells
/// are visited in. A start seen again keeps its smallest key.
template <int K>
struct RankedStarts {
  int index[K];
  double d2[K];
  std::int64_t key[K];
  int count = 0;

  bool before(double d, std::int64_t k, int j) const noexcept {
    return d < d2[j] || (d == d2[j] && k < key[j]);
  }
  void add(int i, double d, std::int64_t k) noexcept {
    for (int j = 0; j < count; ++j) {
      if (index[j] != i) continue;
      if (k < key[j]) {
        key[j] = k;  // seen earlier in the scan's order: it moves up among equal distances
        for (; j > 0 && before(d2[j], key[j], j - 1); --j) swap(j, j - 1);
      }
      return;
    }
    int pos = count < K ? count : K;
    while (pos > 0 && before(d, k, pos - 1)) --pos;
    if (pos >= K) return;
    for (int j = std::min(count, K - 1); j > pos; --j) {
      index[j] = index[j - 1];
      d2[j] = d2[j - 1];
      key[j] = key[j - 1];
    }
    index[pos] = i;
    d2[pos] = d;
    key[pos] = k;
    count = std::min(count + 1, K);
  }
  void swap(int a, int b) noexcept {
    std::swap(index[a], index[b]);
    std::swap(d2[a], d2[b]);
    std::swap(key[a], key[b]);
  }
  // the largest squared distance that still enters the list (+inf while it is not full)
  double cutoff() const noexcept { return count < K ? kInf : d2[K - 1]; }
};

}  // namespace detail

// closest_point's view of the samples, cells and blocks from p.
struct NurbsSurface::Search {
  Search(const NurbsSurface& surface, const Eigen::Vector3d& point) noexcept
      : s(surface), p(point) {}

  const NurbsSurface& s;
  const Eigen::Vector3d& p;
  const int mu = static_cast<int>(s.sample_u_.size()), mv = static_cast<int>(s.sample_v_.size());

  using Starts = detail::RankedStarts<detail::kCandidates>;

  double d2(int i, int j) const noexcept {
    return (s.sample_p_[static_cast<size_t>(i) * mv + j] - p).squaredNorm();
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

  // Candidates (index i * mv + j, the start), in the cells within the nearest sample's
  // distance of p: (1), (2) and (3) below in every such cell, as a scan of the cells in
  // order (i, j) finds them (nurbs_surface_blocks.cpp). The nearest sample's distance
  // bounds the least distance from above (the refinement from it descends), so a cell
  // farther than it holds no minimum that counts.
  void candidates(Starts& best) const noexcept;
  // the hierarchy's blocks for `visit` (nurbs_surface_blocks.cpp)
  template <class Visit>
  void walk(Visit& visit) const noexcept;

  // (1) .. (3) in cell (i, j) where it is within `near` of p, each keyed by its rank in a
  // scan of the cells in order (cell i * (mv - 1) + j, then its tests in order)
  void cell_candidates(int i, int j, double near, Starts& best) const noexcept {
    if (!within(i, j, near)) return;
    const std::int64_t key = (static_cast<std::int64_t>(i) * (mv - 1) + j) * 16;
    for (int a = i; a <= i + 1; ++a)
      for (int b = j; b <= j + 1; ++b) local_min(a, b, best, key + 2 * (a - i) + (b - j));
    sign_change(i, j, best, key + 4);
    if (i == 0) edge_v(0, j, best, key + 6);
    if (i + 2 == mu) edge_v(mu - 1, j, best, key + 7);
    if (j == 0) edge_u(i, 0, best, key + 8);
    if (j + 2 == mv) edge_u(i, mv - 1, best, key + 9);
  }
  // cell (i, j)'s sphere within `near` of p: |c - p| - radius <= near
  bool within(int i, int j, double near) const noexcept {
    const size_t cell = static_cast<size_t>(i) * (mv - 1) + j;
    const double reach = s.cell_radius_[cell] + near;
    return !((s.cell_center_[cell] - p).squaredNorm() > reach * reach);
  }
  // (1) sample (i, j) where it is a discrete local minimum of the distance
  void local_min(int i, int j, Starts& best, std::int64_t key) const noexcept {
    const double dij = d2(i, j);
    for (int a = std::max(i - 1, 0); a <= std::min(i + 1, mu - 1); ++a)
      for (int b = std::max(j - 1, 0); b <= std::min(j + 1, mv - 1); ++b)
        if ((a != i || b != j) && d2(a, b) < dij) return;
    best.add(i * mv + j, dij, key);
  }
  // (2) cell (i, j) where its corners' gradients change sign in u and in v (a minimum
  // inside), started at the nearest corner; on a creased surface also from inside the cell
  // (a corner on a crease may descend to the other side's minimum, and one beside it to
  // this side's): index samples + cell
  void sign_change(int i, int j, Starts& best, std::int64_t key) const noexcept {
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
      best.add(start, dmin, key);
      if (s.creased_) best.add(mu * mv + i * (mv - 1) + j, dmin, key + 1);
    }
  }
  // (3) the interval (i, j)-(i, j + 1) of an edge u = const whose tangential gradient
  // changes sign (a minimum on or near the edge)
  void edge_v(int i, int j, Starts& best, std::int64_t key) const noexcept {
    if (gv(i, j) <= 0.0 && gv(i, j + 1, true) >= 0.0) {
      const bool first = d2(i, j) <= d2(i, j + 1);
      best.add(i * mv + (first ? j : j + 1), std::min(d2(i, j), d2(i, j + 1)), key);
    }
  }
  // ... and the interval (i, j)-(i + 1, j) of an edge v = const
  void edge_u(int i, int j, Starts& best, std::int64_t key) const noexcept {
    if (gu(i, j) <= 0.0 && gu(i + 1, j, true) >= 0.0) {
      const bool first = d2(i, j) <= d2(i + 1, j);
      best.add((first ? i : i + 1) * mv + j, std::min(d2(i, j), d2(i + 1, j)), key);
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

}  // namespace virtmech
