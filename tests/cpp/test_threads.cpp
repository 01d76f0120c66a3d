// The thread contract (include/virtmech/controller.hpp, docs/theory.md "Threads"): one
// controller per thread; devices, mechanisms and shapes are immutable and may be shared by
// controllers on any number of threads. Several threads, each stepping its own controller
// (or mechanism set) over one shared device, mechanism and NURBS shape, give the torques the
// same runs give alone, bit for bit. (Built with -fsanitize=thread, as
// scripts/thread_sanitizer.sh does, the same test checks for data races.)
#include <gtest/gtest.h>

#include <thread>
#include <vector>

#include "cycle_scenes.hpp"

namespace {

using namespace vmtest;

// `cycles` steps of a fresh controller of (device, mechanism) along the real-time scenes'
// wandering path, offset by `phase` so that every thread runs a different path; the torques.
std::vector<JointVector> run_alone(const Scene& s, int cycles, double phase) {
  Controller c(s.device, s.mechanism);
  const int n = s.device->dof();
  JointVector q(n), dq(n);
  CycleOutput out;
  std::vector<JointVector> torques;
  torques.reserve(static_cast<size_t>(cycles));
  for (int k = 0; k < cycles; ++k) {
    cycle_state(*s.device, k, cycles, q, dq);  // (through the whole range, a fault, a glitch)
    q.array() += phase;
    c.step(q.data(), dq.data(), out);
    torques.push_back(out.torque);
  }
  return torques;
}

TEST(Threads, ControllersOnSeveralThreadsSharingADeviceAndMechanismGiveTheTorquesOfRunsAlone) {
  constexpr int kThreads = 4, kCycles = 3000;
  for (const char* name : {"OmniSurfaceProbeNurbs", "OmniCurveGuide", "OmniProbe"}) {
    const Scene shared = make_scene(name);  // one device, one mechanism (and its shape)
    std::vector<std::vector<JointVector>> alone, together(kThreads);
    for (int t = 0; t < kThreads; ++t) alone.push_back(run_alone(shared, kCycles, 0.01 * t));
    std::vector<std::thread> threads;
    for (int t = 0; t < kThreads; ++t) {
      threads.emplace_back([&, t] { together[static_cast<size_t>(t)] = run_alone(shared, kCycles, 0.01 * t); });
    }
    for (auto& th : threads) th.join();
    for (int t = 0; t < kThreads; ++t) {
      for (int k = 0; k < kCycles; ++k) {
        ASSERT_EQ(together[t][k], alone[t][k]) << name << " thread " << t << " cycle " << k;
      }
    }
  }
}

TEST(Threads, MechanismSetsOnSeveralThreadsSharingTheirMembersShapesGiveTheTorquesOfRunsAlone) {
  constexpr int kThreads = 3, kCycles = 2000;
  // each thread builds its own set of the same device and mechanism objects (shapes shared)
  const MechanismSet prototype = make_set();
  const auto run = [&prototype](int cycles) {
    MechanismSetSettings ss = prototype.settings();
    MechanismSet set(prototype.member(0).device_ptr(), prototype.capacity(), ss);
    for (int i = 0; i < prototype.size(); ++i) {
      set.add(prototype.member(i).mechanism_ptr(), cycle_settings());
    }
    JointVector q(6), dq(6);
    MechanismSetOutput out;
    std::vector<JointVector> torques;
    for (int k = 0; k < cycles; ++k) {
      cycle_state(set.device(), k, cycles, q, dq);
      set.step(q.data(), dq.data(), out);
      torques.push_back(out.cycle.torque);
    }
    return torques;
  };
  const std::vector<JointVector> alone = run(kCycles);
  std::vector<std::vector<JointVector>> together(kThreads);
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] { together[static_cast<size_t>(t)] = run(kCycles); });
  }
  for (auto& th : threads) th.join();
  for (int t = 0; t < kThreads; ++t) {
    for (int k = 0; k < kCycles; ++k) ASSERT_EQ(together[t][k], alone[k]) << t << " " << k;
  }
}

}  // namespace
