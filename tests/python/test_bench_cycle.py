"""What the optimised cycle keeps: the extrapolated warm start of the placements starts only
after a first, settled cycle, and a reset forgets it."""

from __future__ import annotations

import numpy as np
import pytest

import virtmech as vm
from virtmech import bench


@pytest.mark.parametrize("name", ["omni+probe", "arm6+serial5"])
def test_second_cycle_does_not_extrapolate_the_first_placements_travel(name):
    # the first placement travels from the mechanism's home to the handle; with the handle
    # held still, the second cycle must start where the first ended and find it at once
    case = bench.make_case(name)
    c = case.controller
    q, _ = case.joint_state(0, c.model["period_s"])
    q = q.ravel()
    first = c.step(q, np.zeros_like(q))
    assert np.abs(first.theta - c.mechanism.home).max() > 0.05  # a real travel
    second = c.step(q, np.zeros_like(q))
    assert not second.status & vm.status.NOT_CONVERGED
    assert second.iterations <= 2
    np.testing.assert_allclose(second.theta, first.theta, atol=1e-9)


def test_reset_forgets_the_previous_placements():
    case = bench.make_case("omni+probe")
    c = case.controller
    q, dq = case.joint_state(np.arange(300), c.model["period_s"])
    run1 = np.array([c.step(q[k], dq[k]).torque for k in range(300)])
    c.reset()
    run2 = np.array([c.step(q[k], dq[k]).torque for k in range(300)])
    np.testing.assert_array_equal(run1, run2)


@pytest.mark.parametrize("name", bench.CASES)
def test_smooth_motion_gives_smooth_torques(name):
    # the hand moves smoothly, so must the torques: no one-cycle spikes, also where the
    # placement cannot converge (the lifted probe), which an extrapolated warm start of a
    # wandering placement would produce (the laws: a prescribed motion is not a passive
    # user, and the passivity controller would act on it)
    case = bench.make_case(name, passivity="off")
    c = case.controller
    q, dq = case.joint_state(np.arange(3000), c.model["period_s"])
    tau = np.array([c.step(q[k], dq[k]).torque for k in range(3000)])
    second_difference = np.abs(np.diff(tau[10:], 2, axis=0)).max()
    assert second_difference < 0.02 * np.abs(tau).max()
