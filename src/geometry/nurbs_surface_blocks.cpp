// NurbsSurface's hierarchy of sample cells (include/virtmech/geometry.hpp), and
// closest_point's walk over it (nurbs_surface_search.hpp): the nearest sample, and the
// candidate starts of the cells within its distance, found branch and bound.
//
// A block is passed over when its box is farther than what could still count, and
// restricted to its cells on the surface's edges when the samples' distance is strictly
// monotone across it in u (or v) and the gradient's u (v) part has one sign at its corners:
// then no sample off the edges is the nearest or a local minimum, and no cell off the edges
// has a change of sign (the proof by test: a strictly smaller neighbour in u, by the
// interval of (x_a - x_(a-1)) . (x_a + x_(a-1) - 2 p) over the block's boxes, with a margin
// for the rounding of the distances compared). Both tests keep what a scan of every sample
// and every cell finds, so the result is the scan's, bit for bit.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "nurbs_basis.hpp"
#include "nurbs_surface_search.hpp"

namespace virtmech {

namespace {

constexpr int kLeafSide = 4;  // a block of at most 4 x 4 cells is a leaf
constexpr int kStack = 256;   // the walk's stack: 3 entries a level at most, and the root
// margins over the rounding of the quantities compared (the sums below, the distances)
constexpr double kRounding = 1e-12;

using Box = Eigen::AlignedBox3d;
using CellBlock = detail::NurbsCellBlock;

// The interval of a . w over a in a bound, w = factor (x - shift) with x in X, and the sum
// of the largest |a_c| |w_c| (the scale of its rounding).
struct Interval {
  double lo = 0.0, hi = 0.0, scale = 0.0;
};

// ... over a in the box A
Interval dot_interval(const Box& A, const Box& X, const Eigen::Vector3d& shift,
                      double factor) noexcept {
  Interval r;
  for (int c = 0; c < 3; ++c) {
    const double w0 = factor * (X.min()[c] - shift[c]), w1 = factor * (X.max()[c] - shift[c]);
    const double a0 = A.min()[c], a1 = A.max()[c];
    const double p00 = a0 * w0, p01 = a0 * w1, p10 = a1 * w0, p11 = a1 * w1;
    r.lo += std::min(std::min(p00, p01), std::min(p10, p11));
    r.hi += std::max(std::max(p00, p01), std::max(p10, p11));
    r.scale += std::max(std::abs(a0), std::abs(a1)) * std::max(std::abs(w0), std::abs(w1));
  }
  return r;
}

// ... over a = alpha axis + rest in the bound A
Interval dot_interval(const detail::VectorBound& A, const Box& X, const Eigen::Vector3d& shift,
                      double factor) noexcept {
  double lo = 0.0, hi = 0.0, scale = 0.0;  // axis . w
  for (int c = 0; c < 3; ++c) {
    const double w0 = factor * (X.min()[c] - shift[c]), w1 = factor * (X.max()[c] - shift[c]);
    const double t0 = A.axis[c] * w0, t1 = A.axis[c] * w1;
    lo += std::min(t0, t1);
    hi += std::max(t0, t1);
    scale += std::abs(A.axis[c]) * std::max(std::abs(w0), std::abs(w1));
  }
  const double p00 = A.alpha_lo * lo, p01 = A.alpha_lo * hi, p10 = A.alpha_hi * lo,
               p11 = A.alpha_hi * hi;
  Interval r = dot_interval(A.rest, X, shift, factor);
  r.lo += std::min(std::min(p00, p01), std::min(p10, p11));
  r.hi += std::max(std::max(p00, p01), std::max(p10, p11));
  r.scale += std::max(std::abs(A.alpha_lo), std::abs(A.alpha_hi)) * scale;
  return r;
}

// +1 / -1 where the interval is positive / negative beyond `tol`, else 0
int strict_sign(const Interval& r, double tol) noexcept {
  return r.lo > tol ? 1 : (r.hi < -tol ? -1 : 0);
}

// the largest squared distance from p of a point in X
double farthest2(const Box& X, const Eigen::Vector3d& p) noexcept {
  return (X.min() - p).cwiseAbs2().cwiseMax((X.max() - p).cwiseAbs2()).sum();
}

// The samples' distance from p strictly monotone along the steps `step` of a block (whose
// samples are `samples`): d2(x_a) - d2(x_(a-1)) = (x_a - x_(a-1)) . (x_a + x_(a-1) - 2 p),
// beyond the rounding of both distances.
bool monotone(const detail::VectorBound& step, const Box& samples,
              const Eigen::Vector3d& p) noexcept {
  const Interval r = dot_interval(step, samples, p, 2.0);
  return strict_sign(r, kRounding * (r.scale + farthest2(samples, p))) != 0;
}

// One sign of S_w . (x - p) at the block's corners (S_w the derivatives in `derivative`).
bool one_sign(const detail::VectorBound& derivative, const Box& samples,
              const Eigen::Vector3d& p) noexcept {
  const Interval r = dot_interval(derivative, samples, p, 1.0);
  return strict_sign(r, kRounding * r.scale) != 0;
}

// A VectorBound on vectors given one by one: their mean as the axis (first pass), then
// each one's part along it and the rest (second pass).
class VectorBounder {
 public:
  explicit VectorBounder(detail::VectorBound& out) : out_(out) {}
  void first(const Eigen::Vector3d& v) noexcept {
    sum_ += v;
    ++count_;
  }
  void second(const Eigen::Vector3d& v) noexcept {
    if (!started_) {
      out_.axis = count_ > 0 ? Eigen::Vector3d(sum_ / count_) : Eigen::Vector3d::Zero();
      norm2_ = out_.axis.squaredNorm();
      out_.alpha_lo = kInf, out_.alpha_hi = -kInf;
      out_.rest.setEmpty();
      started_ = true;
    }
    const double alpha = norm2_ > 0.0 ? v.dot(out_.axis) / norm2_ : 0.0;
    out_.alpha_lo = std::min(out_.alpha_lo, alpha);
    out_.alpha_hi = std::max(out_.alpha_hi, alpha);
    out_.rest.extend(Eigen::Vector3d(v - alpha * out_.axis));
  }

 private:
  detail::VectorBound& out_;
  Eigen::Vector3d sum_ = Eigen::Vector3d::Zero();
  long count_ = 0;
  double norm2_ = 0.0;
  bool started_ = false;
};

// a block's restriction to its cells on the surface's edges in u, and in v; to its samples
// on the edges
constexpr unsigned kEdgeRowsU = 1u, kEdgeColsV = 2u, kSampleRowsU = 4u, kSampleColsV = 8u;
// the cells kept by the first walk (4 KiB of stack), beyond which a second walk finds the
// candidates
constexpr int kKeptCells = 1024;

// the number of blocks of cells [i0, i1) x [j0, j1], as build_block makes them
long count_blocks(int i0, int i1, int j0, int j1) noexcept {
  const bool split_u = i1 - i0 > kLeafSide, split_v = j1 - j0 > kLeafSide;
  if (!split_u && !split_v) return 1;
  const int im = split_u ? i0 + (i1 - i0) / 2 : i1, jm = split_v ? j0 + (j1 - j0) / 2 : j1;
  long n = 1 + count_blocks(i0, im, j0, jm);
  if (split_u) n += count_blocks(im, i1, j0, jm);
  if (split_v) n += count_blocks(i0, im, jm, j1);
  if (split_u && split_v) n += count_blocks(im, i1, jm, j1);
  return n;
}

}  // namespace

void NurbsSurface::build_blocks() {
  const int cu = static_cast<int>(sample_u_.size()) - 1, cv = static_cast<int>(sample_v_.size()) - 1;
  blocks_.clear();
  blocks_.reserve(static_cast<size_t>(count_blocks(0, cu, 0, cv)));
  blocks_.emplace_back();
  block_depth_ = 0;
  build_block(0, 0, cu, 0, cv, 0);
  if (3 * block_depth_ + 1 > kStack) {
    throw std::length_error("NurbsSurface: closest-point hierarchy deeper than its walk's stack");
  }
}

void NurbsSurface::build_block(int index, int i0, int i1, int j0, int j1, int depth) {
  block_depth_ = std::max(block_depth_, depth);
  {
    CellBlock& b = blocks_[static_cast<size_t>(index)];
    b.i0 = i0, b.i1 = i1, b.j0 = j0, b.j1 = j1;
  }
  fill_block(blocks_[static_cast<size_t>(index)]);
  const bool split_u = i1 - i0 > kLeafSide, split_v = j1 - j0 > kLeafSide;
  if (!split_u && !split_v) return;
  // two or four children, halving what is wider than a leaf
  const int im = split_u ? i0 + (i1 - i0) / 2 : i1, jm = split_v ? j0 + (j1 - j0) / 2 : j1;
  const int first = static_cast<int>(blocks_.size());
  const int children = (split_u ? 2 : 1) * (split_v ? 2 : 1);
  blocks_.resize(blocks_.size() + static_cast<size_t>(children));
  blocks_[static_cast<size_t>(index)].first_child = first;
  blocks_[static_cast<size_t>(index)].children = children;
  int c = first;
  build_block(c++, i0, im, j0, jm, depth + 1);
  if (split_u) build_block(c++, im, i1, j0, jm, depth + 1);
  if (split_v) build_block(c++, i0, im, jm, j1, depth + 1);
  if (split_u && split_v) build_block(c++, im, i1, jm, j1, depth + 1);
}

// A block's bounds from the samples and cells it covers (every block's: a block's vector
// bounds take its own axes, tighter than its children's together; the construction's time
// grows as the samples times the hierarchy's depth).
void NurbsSurface::fill_block(CellBlock& b) const {
  const int mu = static_cast<int>(sample_u_.size()), mv = static_cast<int>(sample_v_.size());
  const auto at = [&](int a, int c) { return static_cast<size_t>(a) * mv + c; };
  for (int i = b.i0; i < b.i1; ++i) {
    for (int j = b.j0; j < b.j1; ++j) {
      const size_t cell = static_cast<size_t>(i) * (mv - 1) + j;
      const Eigen::Vector3d& c = cell_center_[cell];
      const double r = cell_radius_[cell];
      // (widened past the rounding of c -+ r)
      const double reach = r + kRounding * (c.cwiseAbs().maxCoeff() + r);
      b.spheres.extend(c - Eigen::Vector3d::Constant(reach));
      b.spheres.extend(c + Eigen::Vector3d::Constant(reach));
    }
  }
  for (int a = std::max(b.i0 - 1, 0); a <= std::min(b.i1 + 1, mu - 1); ++a)
    for (int c = std::max(b.j0 - 1, 0); c <= std::min(b.j1 + 1, mv - 1); ++c)
      b.samples.extend(sample_p_[at(a, c)]);
  VectorBounder step_u(b.step_u), step_v(b.step_v), su(b.su), sv(b.sv);
  for (int pass = 0; pass < 2; ++pass) {
    const auto add = [pass](VectorBounder& bound, const Eigen::Vector3d& v) {
      if (pass == 0) bound.first(v); else bound.second(v);
    };
    for (int a = std::max(b.i0, 1); a <= std::min(b.i1 + 1, mu - 1); ++a)
      for (int c = b.j0; c <= b.j1; ++c) add(step_u, sample_p_[at(a, c)] - sample_p_[at(a - 1, c)]);
    for (int a = b.i0; a <= b.i1; ++a)
      for (int c = std::max(b.j0, 1); c <= std::min(b.j1 + 1, mv - 1); ++c)
        add(step_v, sample_p_[at(a, c)] - sample_p_[at(a, c - 1)]);
    for (int a = b.i0; a <= b.i1; ++a) {
      for (int c = b.j0; c <= b.j1; ++c) {
        add(su, sample_su_[at(a, c)]);
        add(su, sample_su_left_[at(a, c)]);
        add(sv, sample_sv_[at(a, c)]);
        add(sv, sample_sv_below_[at(a, c)]);
      }
    }
  }
}

// The walk: blocks nearest first (by `visit.distance`), each passed over where
// visit.prune(distance) says so or visit.restrict leaves nothing of it, a leaf's cells or
// samples to visit.leaf; a fixed stack, no allocation.
template <class Visit>
void NurbsSurface::Search::walk(Visit& visit) const noexcept {
  struct Entry {
    int block;
    unsigned edges;
    double distance;
  };
  Entry stack[kStack];
  int top = 0;
  stack[top++] = {0, 0u, visit.distance(s.blocks_[0])};
  while (top > 0) {
    const Entry e = stack[--top];
    const CellBlock& b = s.blocks_[static_cast<size_t>(e.block)];
    if (visit.prune(e.distance)) continue;
    unsigned edges = e.edges;
    if (!visit.restrict(b, edges)) continue;
    if (b.children == 0) {
      visit.leaf(b, edges);
      continue;
    }
    // the children, the farthest pushed first
    Entry child[4];
    for (int c = 0; c < b.children; ++c) {
      const int k = b.first_child + c;
      child[c] = {k, edges, visit.distance(s.blocks_[static_cast<size_t>(k)])};
      for (int m = c; m > 0 && child[m].distance > child[m - 1].distance; --m)
        std::swap(child[m], child[m - 1]);
    }
    for (int c = 0; c < b.children; ++c) stack[top++] = child[c];
  }
}

namespace {

// The nearest sample, and the cells that may be within its distance (`cells`, up to
// `capacity`; `overflow` where more): blocks by the box holding their samples and spheres,
// beyond the nearest sample so far passed over. A block is restricted to its samples on the
// surface's edge in u where the distance is monotone across it in u (the samples off the
// edge have a nearer neighbour), and to its cells on the edge where the gradient's u part
// also has one sign there (their cells have no candidate); likewise in v.
template <class Query>
struct NearestAndCells {
  const Query& q;
  int* cells;
  int capacity;
  double best2 = kInf;
  int count = 0;
  bool overflow = false;

  double distance(const CellBlock& b) const noexcept {
    return b.spheres.merged(b.samples).squaredExteriorDistance(q.p);
  }
  bool prune(double d2) const noexcept { return d2 > best2 * (1.0 + kRounding); }
  bool restrict(const CellBlock& b, unsigned& edges) const noexcept {
    if (!(edges & kSampleRowsU) && monotone(b.step_u, b.samples, q.p)) edges |= kSampleRowsU;
    if ((edges & kSampleRowsU) && !(edges & kEdgeRowsU) && one_sign(b.su, b.samples, q.p)) {
      edges |= kEdgeRowsU;
    }
    if (!(edges & kSampleColsV) && monotone(b.step_v, b.samples, q.p)) edges |= kSampleColsV;
    if ((edges & kSampleColsV) && !(edges & kEdgeColsV) && one_sign(b.sv, b.samples, q.p)) {
      edges |= kEdgeColsV;
    }
    // neither the nearest sample nor a candidate off the edges (a sample's rows 0 and
    // mu - 1 are the cells' rows 0 and mu - 2)
    if ((edges & kEdgeRowsU) && b.i0 != 0 && b.i1 != q.mu - 1) return false;
    if ((edges & kEdgeColsV) && b.j0 != 0 && b.j1 != q.mv - 1) return false;
    return true;
  }
  void leaf(const CellBlock& b, unsigned edges) noexcept {
    for (int a = b.i0; a <= b.i1; ++a) {
      if ((edges & kSampleRowsU) && a != 0 && a != q.mu - 1) continue;
      for (int c = b.j0; c <= b.j1; ++c) {
        if ((edges & kSampleColsV) && c != 0 && c != q.mv - 1) continue;
        best2 = std::min(best2, q.d2(a, c));
      }
    }
    // the cells within the nearest sample so far (the nearest at the end is no farther)
    const double near = std::sqrt(best2);
    for (int i = b.i0; i < b.i1; ++i) {
      if ((edges & kEdgeRowsU) && i != 0 && i != q.mu - 2) continue;
      for (int j = b.j0; j < b.j1; ++j) {
        if ((edges & kEdgeColsV) && j != 0 && j != q.mv - 2) continue;
        if (!q.within(i, j, near)) continue;
        if (count == capacity) {
          overflow = true;
          return;
        }
        cells[count++] = i * (q.mv - 1) + j;
      }
    }
  }
};

// The candidate starts (where the cells kept above overflowed): blocks by their cells'
// spheres, within `near` and, the list full, within its last distance; restricted to the
// cells on an edge as above.
template <class Query>
struct CellCandidates {
  const Query& q;
  double near;
  typename Query::Starts& best;

  double distance(const CellBlock& b) const noexcept {
    return b.spheres.squaredExteriorDistance(q.p);
  }
  bool prune(double d2) const noexcept {
    return d2 > std::min(near * near, best.cutoff()) * (1.0 + kRounding);
  }
  bool restrict(const CellBlock& b, unsigned& edges) const noexcept {
    if (!(edges & kEdgeRowsU) && monotone(b.step_u, b.samples, q.p) &&
        one_sign(b.su, b.samples, q.p)) {
      edges |= kEdgeRowsU;
    }
    if (!(edges & kEdgeColsV) && monotone(b.step_v, b.samples, q.p) &&
        one_sign(b.sv, b.samples, q.p)) {
      edges |= kEdgeColsV;
    }
    if ((edges & kEdgeRowsU) && b.i0 != 0 && b.i1 != q.mu - 1) return false;
    if ((edges & kEdgeColsV) && b.j0 != 0 && b.j1 != q.mv - 1) return false;
    return true;
  }
  void leaf(const CellBlock& b, unsigned edges) const noexcept {
    for (int i = b.i0; i < b.i1; ++i) {
      if ((edges & kEdgeRowsU) && i != 0 && i != q.mu - 2) continue;
      for (int j = b.j0; j < b.j1; ++j) {
        if ((edges & kEdgeColsV) && j != 0 && j != q.mv - 2) continue;
        q.cell_candidates(i, j, near, best);
      }
    }
  }
};

}  // namespace

void NurbsSurface::Search::candidates(Starts& best) const noexcept {
  int cells[kKeptCells];
  NearestAndCells<Search> first{*this, cells, kKeptCells};
  walk(first);
  const double near = std::sqrt(first.best2);
  if (first.overflow) {
    CellCandidates<Search> visit{*this, near, best};
    walk(visit);
    return;
  }
  const int cu = mv - 1;
  for (int k = 0; k < first.count; ++k) cell_candidates(cells[k] / cu, cells[k] % cu, near, best);
}

long NurbsSurface::sample_count(const Eigen::VectorXd& knots, int n, int p) noexcept {
  long spans = 0;
  for (int i = p; i < n; ++i) spans += knots[i] < knots[i + 1] ? 1 : 0;
  return spans * detail::samples_per_span(p) + 1;
}

}  // namespace virtmech
