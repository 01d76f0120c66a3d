// Google Benchmark suite: the whole cycle for each case of bench_cases.hpp, and the parts
// a profile points at (kinematics, placement, pseudo-inverse, pose error), so a change to
// one part can be measured on its own.
//
//   build/bench/virtmech_bm --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include "bench_cases.hpp"
#include "virtmech/filters.hpp"
#include "virtmech/se3.hpp"

namespace {

using namespace virtmech;

void BM_Cycle(benchmark::State& state) {
  std::vector<vmbench::BenchCase> cases = vmbench::make_cases();
  vmbench::BenchCase& c = cases[static_cast<size_t>(state.range(0))];
  state.SetLabel(c.name);
  Controller& ctl = *c.controller;
  const int n = ctl.device().dof();
  // a precomputed trajectory (4096 cycles, looped) keeps sin/cos out of the timing
  constexpr long kSamples = 4096;
  std::vector<JointVector> qs(kSamples), dqs(kSamples);
  for (long k = 0; k < kSamples; ++k) {
    qs[static_cast<size_t>(k)].resize(n);
    dqs[static_cast<size_t>(k)].resize(n);
    vmbench::joint_state(c, k, ctl.model().period_s, qs[static_cast<size_t>(k)],
                         dqs[static_cast<size_t>(k)]);
  }
  CycleOutput out;
  for (long k = 0; k < 100; ++k) ctl.step(qs[0].data(), dqs[0].data(), out);
  long k = 0;
  for (auto _ : state) {
    const size_t i = static_cast<size_t>(k++ % kSamples);
    ctl.step(qs[i].data(), dqs[i].data(), out);
    benchmark::DoNotOptimize(out.torque.data());
  }
}
BENCHMARK(BM_Cycle)->DenseRange(0, 4)->Unit(benchmark::kNanosecond);

void BM_OmniForwardJacobian(benchmark::State& state) {
  PhantomOmni omni;
  JointVector q(6);
  q << 0.1, 0.5, 0.3, 0.2, 0.8, -0.3;
  Pose T;
  Jacobian J;
  for (auto _ : state) {
    omni.forward_jacobian(q.data(), T, J);
    benchmark::DoNotOptimize(J.data());
    q[0] += 1e-9;
  }
}
BENCHMARK(BM_OmniForwardJacobian);

void BM_ProbeForwardJacobian(benchmark::State& state) {
  Probe probe(Eigen::Vector3d(0, -0.03, 0), Eigen::Vector3d::UnitY(), 0.1, Eigen::Vector3d::Zero());
  JointVector th(5);
  th << 0.01, -0.02, 0.3, 0.2, -0.4;
  Pose T;
  Jacobian J;
  for (auto _ : state) {
    probe.forward_jacobian(th.data(), T, J);
    benchmark::DoNotOptimize(J.data());
    th[0] += 1e-9;
  }
}
BENCHMARK(BM_ProbeForwardJacobian);

void BM_ProbeTrackWarm(benchmark::State& state) {
  // one placement warm-started from the previous cycle's answer, the handle having moved
  // by a typical 1 ms step
  Probe probe(Eigen::Vector3d(0, -0.03, 0), Eigen::Vector3d::UnitY(), 0.1, Eigen::Vector3d::Zero());
  JointVector th0(5);
  th0 << 0.01, -0.02, 0.3, 0.2, -0.4;
  Pose target;
  probe.forward(th0.data(), target);
  target.translation() += Eigen::Vector3d(1e-3, 5e-3, -2e-4);
  Vector6 W;
  W << 1, 1, 1, 0, 0, 0;
  W.array() += 1e-6 * Vector6(1, 1, 1, 0.01, 0.01, 0.01).array();
  TrackOptions opts;
  opts.max_iterations = 10;
  JointVector seed;
  track(probe, target, th0, W, opts, seed);
  seed[0] -= 1e-4;  // slightly off the answer, as after one cycle of motion
  JointVector th;
  int iterations = 0;
  for (auto _ : state) {
    const TrackResult r = track(probe, target, seed, W, opts, th);
    iterations = r.iterations;
    benchmark::DoNotOptimize(th.data());
  }
  state.counters["iterations"] = iterations;
}
BENCHMARK(BM_ProbeTrackWarm);

void BM_WeightedProjector(benchmark::State& state) {
  // factorise sqrt(W) J (6 x m) and apply P: the filters' unit of work
  const int m = static_cast<int>(state.range(0));
  Jacobian J(6, m);
  J.setRandom();
  Vector6 w;
  w << 1.0, 1.0, 1.0, 0.0, 0.0, 0.0;
  const Vector6 f = Vector6::Constant(0.3);
  WeightedProjector P;
  for (auto _ : state) {
    P.compute(J, w);
    Vector6 r = P.range(f);
    benchmark::DoNotOptimize(r.data());
  }
}
BENCHMARK(BM_WeightedProjector)->Arg(1)->Arg(3)->Arg(5)->Arg(6);

void BM_PoseError(benchmark::State& state) {
  Pose a = Pose::Identity(), b = Pose::Identity();
  a.linear() = so3_exp(Eigen::Vector3d(0.1, 0.2, -0.3));
  b.linear() = so3_exp(Eigen::Vector3d(0.1, 0.25, -0.3));
  for (auto _ : state) {
    Vector6 e = pose_error(a, b);
    benchmark::DoNotOptimize(e.data());
  }
}
BENCHMARK(BM_PoseError);

}  // namespace

BENCHMARK_MAIN();
