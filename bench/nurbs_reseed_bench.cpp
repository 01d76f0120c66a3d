// The cost of a NURBS surface's global closest point, where a SurfaceProbe places itself
// again on the first cycle after a fault (or a reset), for bicubic surfaces of n x n control
// points: the surface's construction time and heap, the recovery cycle (the first after a
// fault) against the ordinary cycle in the same process (median, p99 and their ratio), the
// closest point from the recovery's tip (the one it computes, again just after it), and
// NurbsSurface::closest_point alone from points near the surface.
//
//   virtmech_nurbs_bench [--size N]... [--repeats K] [--queries Q]
//
// Default sizes 5, 50, 100, 200. A size the constructor refuses prints its message.
#include <malloc.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_cases.hpp"

namespace {

using namespace virtmech;
using Clock = std::chrono::steady_clock;

double micros(Clock::duration d) { return std::chrono::duration<double, std::micro>(d).count(); }

double heap_bytes() {
  const struct mallinfo2 m = mallinfo2();
  return static_cast<double>(m.uordblks) + static_cast<double>(m.hblkhd);
}

// The test patch's shape (bench_models.hpp: a bump and a saddle over 12 cm x 9 cm, rational)
// with n x n control points, uniform clamped knots, degree 3.
std::shared_ptr<const NurbsSurface> patch(int n, const Eigen::Vector3d& origin,
                                          const Eigen::Matrix3d& R) {
  Eigen::MatrixX3d P(n * n, 3);
  Eigen::MatrixXd W(n, n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double x = 0.12 * i / (n - 1) - 0.06, y = 0.09 * j / (n - 1) - 0.045;
      const Eigen::Vector3d local(
          x, y, 0.012 * std::cos(2.0 * x / 0.06) * std::cos(y / 0.045) + 0.2 * x * y);
      P.row(i * n + j) = (origin + R * local).transpose();
      W(i, j) = 1.0 + 0.1 * ((i + j) % 3);
    }
  }
  const int p = 3;
  Eigen::VectorXd k(n + p + 1);
  for (int i = 0; i < n + p + 1; ++i)
    k[i] = std::clamp(static_cast<double>(i - p) / (n - p), 0.0, 1.0);
  return std::make_shared<NurbsSurface>(P, W, k, k, p, p);
}

struct Stats {
  double median = 0, p99 = 0, max = 0;
};

Stats stats(std::vector<double> t) {
  std::sort(t.begin(), t.end());
  const auto at = [&](double f) {
    return t[std::min(t.size() - 1, static_cast<size_t>(f * static_cast<double>(t.size())))];
  };
  return {at(0.5), at(0.99), t.back()};
}

struct Options {
  std::vector<int> sizes;
  int repeats = 300;
  int queries = 2000;
};

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) {
      std::fprintf(stderr, "virtmech_nurbs_bench: missing value after %s\n", a.c_str());
      std::exit(2);
    }
    const int v = std::atoi(argv[++i]);
    if (a == "--size" && v >= 4) {
      o.sizes.push_back(v);
    } else if (a == "--repeats" && v >= 1) {
      o.repeats = v;
    } else if (a == "--queries" && v >= 1) {
      o.queries = v;
    } else {
      std::fprintf(stderr,
                   "virtmech_nurbs_bench: %s %s: expected --size N (>= 4), --repeats K or "
                   "--queries Q (>= 1)\n",
                   a.c_str(), argv[i]);
      std::exit(2);
    }
  }
  if (o.sizes.empty()) o.sizes = {5, 50, 100, 200};
  return o;
}

// The recovery cycle (the first after a one-cycle fault) and the ordinary cycle of an Omni
// with a probe on the surface, along the cycle benchmark's trajectory.
void cycles(const std::shared_ptr<const NurbsSurface>& surface, int repeats, Stats& recovery,
            Stats& ordinary, Stats& seed) {
  auto omni = std::make_shared<PhantomOmni>();
  Controller ctl(omni, std::make_shared<SurfaceProbe>(surface, 0.1));
  vmbench::BenchCase c{"", nullptr, vmbench::values({0.0, 0.5, 0.3, 0.0, 0.8, 0.0}),
                       vmbench::values({0.3, 0.2, 0.2, 0.4, 0.3, 0.5}), nullptr};
  const double period = ctl.model().period_s;
  JointVector q(6), dq(6), bad(6);
  bad.setConstant(std::nan(""));
  CycleOutput out;
  std::vector<double> first, steady, search;
  Eigen::Vector3d point;
  long k = 0;
  for (int r = 0; r < repeats; ++r) {
    // 20 ordinary cycles, a fault, the recovery cycle
    for (int i = 0; i < 20; ++i, ++k) {
      vmbench::joint_state(c, k * 7, period, q, dq);
      const auto t0 = Clock::now();
      ctl.step(q.data(), dq.data(), out);
      if (r > 0) steady.push_back(micros(Clock::now() - t0));
    }
    ctl.step(bad.data(), dq.data(), out);
    vmbench::joint_state(c, k * 7, period, q, dq);
    const auto t0 = Clock::now();
    ctl.step(q.data(), dq.data(), out);
    first.push_back(micros(Clock::now() - t0));
    ++k;
    // the global closest point the recovery seeded both placements by (once:
    // Mechanism::seed_pair), from the tip 0.1 m along the stylus, again
    const Eigen::Vector3d tip =
        out.handle_pose.translation() + 0.1 * out.handle_pose.linear().col(2);
    const auto t1 = Clock::now();
    surface->closest_point(tip, point);
    search.push_back(micros(Clock::now() - t1));
  }
  recovery = stats(first);
  ordinary = stats(steady);
  seed = stats(search);
}

// closest_point alone from points within 3 cm of the surface (a sample of the patch's
// parameters, moved along the normal).
Stats closest(const NurbsSurface& s, int queries) {
  std::mt19937 gen(7);
  std::uniform_real_distribution<double> uni(0.0, 1.0), off(-0.03, 0.03);
  std::vector<double> t;
  Eigen::Vector3d point;
  for (int k = 0; k < queries; ++k) {
    const double u = uni(gen), v = uni(gen);
    const Eigen::Vector3d p = s.evaluate(u, v) + off(gen) * s.normal(u, v);
    const auto t0 = Clock::now();
    const Eigen::Vector2d uv = s.closest_point(p, point);
    t.push_back(micros(Clock::now() - t0));
    if (!uv.allFinite()) std::abort();
  }
  return stats(t);
}

}  // namespace

int main(int argc, char** argv) {
  const Options o = parse(argc, argv);
  std::printf(
      "%6s %9s %12s %10s | %21s | %21s | %7s | %10s | %21s\n", "n x n", "points",
      "construct ms", "heap MB", "recovery cycle us", "ordinary cycle us", "ratio",
      "its seed", "closest_point us");
  std::printf("%6s %9s %12s %10s | %10s %10s | %10s %10s | %7s | %10s | %10s %10s\n", "", "", "",
              "", "median", "p99", "median", "p99", "median", "median", "median", "p99");
  for (const int n : o.sizes) {
    const double heap0 = heap_bytes();
    const auto t0 = Clock::now();
    std::shared_ptr<const NurbsSurface> s;
    try {
      s = patch(n, Eigen::Vector3d(0.0, 0.0, -0.02), vmbench::omni_horizontal());
    } catch (const std::exception& e) {
      std::printf("%6d %9d refused after %.1f ms: %s\n", n, n * n,
                  micros(Clock::now() - t0) / 1e3, e.what());
      continue;
    }
    const double build_ms = micros(Clock::now() - t0) / 1e3;
    const double heap_mb = (heap_bytes() - heap0) / 1e6;
    Stats rec, ord, seed;
    cycles(s, o.repeats, rec, ord, seed);
    const Stats cp = closest(*s, o.queries);
    std::printf(
        "%6d %9d %12.1f %10.2f | %10.1f %10.1f | %10.2f %10.2f | %7.1f | %10.1f | %10.1f %10.1f\n",
        n, n * n, build_ms, heap_mb, rec.median, rec.p99, ord.median, ord.p99,
        rec.median / ord.median, seed.median, cp.median, cp.p99);
    std::fflush(stdout);
  }
  return 0;
}
