"""The passivity observer and controller of the cycle (docs/theory.md, "Passivity"), against
their definitions: the motors' work is the torque held over a cycle times the joints'
displacement, and the controller keeps the coming cycle's predicted work within what the
rendering has absorbed."""

from __future__ import annotations

import math

import numpy as np
import pytest

import virtmech as vm
from virtmech import bench

CASES = ["omni+planar_arm", "omni+probe", "planar3r+planar_arm"]
N = 2500


def motion(name: str, **settings):
    case = bench.make_case(name, **settings)
    q, dq = case.joint_state(np.arange(N), case.controller.model["period_s"])
    return case.controller, q, dq


@pytest.mark.parametrize("name", CASES)
def test_the_observer_is_minus_the_motors_work_held_over_each_cycle(name):
    c, q, dq = motion(name, passivity_max_energy_j=math.inf)
    work = 0.0  # the motors' work so far: tau_k held from q_k to q_(k+1)
    tau_prev = None
    for k in range(N):
        if tau_prev is not None:
            work += tau_prev @ (q[k] - q[k - 1])
        out = c.step(q[k], dq[k])
        assert out.energy == pytest.approx(-work, abs=1e-12, rel=1e-9)
        tau_prev = out.torque.copy()
    assert abs(work) > 1e-3  # the motion exchanged real energy


def test_the_observer_banks_no_more_than_its_cap():
    cap = 2e-3
    c, q, dq = motion("omni+planar_arm", passivity_max_energy_j=cap)
    energy, tau_prev, capped = 0.0, None, 0
    for k in range(N):
        if tau_prev is not None:
            energy = min(cap, energy - tau_prev @ (q[k] - q[k - 1]))
            capped += energy == cap
        out = c.step(q[k], dq[k])
        assert out.energy == pytest.approx(energy, abs=1e-12)
        tau_prev = out.torque.copy()
    assert capped > 100  # the cap acted


@pytest.mark.parametrize("name", CASES)
def test_the_controller_keeps_the_predicted_work_within_the_energy(name):
    c, q, dq = motion(name)
    dev, T = c.device, c.model["period_s"]
    acted = 0
    for k in range(N):
        out = c.step(q[k], dq[k])
        v = np.asarray(dev.jacobian(q[k])) @ dq[k]  # the handle's twist, from the device
        law = out.wrench_null + out.wrench_range - out.wrench_unrendered
        pc = out.wrench_passivity
        if out.status & vm.status.PASSIVITY:
            acted += 1
            # the least damping: along -U v on the renderable axes, exactly as much as needed
            assert T * (law + pc) @ v == pytest.approx(max(out.energy, 0.0), abs=1e-12)
            L2 = c.model["length_scale"] ** 2
            U = np.array([1, 1, 1, L2, L2, L2])
            # never more than the law's own wrench (U norm), never reversing its power
            assert np.sqrt(pc**2 @ U) <= np.sqrt(law**2 @ U) * (1 + 1e-9) + 1e-12
            assert (law + pc) @ v >= -1e-12
        else:
            assert not pc.any()
            assert T * law @ v <= max(out.energy, 0.0) + 1e-12 + 1e-9 * abs(T * law @ v)
        # what the motors apply (after safety's scaling) is within it too
        assert T * out.wrench @ v <= max(out.energy, 0.0) + 1e-12 + 1e-9 * abs(T * law @ v)
        assert not out.torque[~np.asarray(dev.actuated, dtype=bool)].any()
    assert acted > 10


def test_off_renders_the_laws_and_reports_no_energy():
    c_off, q, dq = motion("omni+planar_arm", passivity="off")
    c_on, _, _ = motion("omni+planar_arm")
    differ = 0
    for k in range(N):
        off, on = c_off.step(q[k], dq[k]), c_on.step(q[k], dq[k])
        assert off.energy == 0.0 and not off.wrench_passivity.any()
        assert not off.status & vm.status.PASSIVITY
        np.testing.assert_allclose(off.wrench_null, on.wrench_null, atol=1e-12)
        differ += not np.allclose(off.torque, on.torque, atol=1e-12)
    assert differ > 10  # ... where the controller acted, and only the torque differs


def test_a_fault_starts_the_observer_afresh():
    c, q, dq = motion("omni+planar_arm")
    k = 0
    while c.step(q[k], dq[k]).energy < 1e-4:
        k += 1
    bad = q[k + 1].copy()
    bad[0] = np.nan
    assert c.step(bad, dq[k + 1]).fault
    assert c.step(q[k + 2], dq[k + 2]).energy == 0.0  # nothing banked across the fault


def test_settings_are_checked_and_reported():
    dev, mech = vm.PhantomOmni(), vm.PlanarArm([0, 0, -0.05], [0, 0, 1], 0.05, [1, 0, 0])
    with pytest.raises(ValueError, match="passivity: expected 'observer_controller' or 'off'"):
        vm.Controller(dev, mech, passivity="tdpa")
    with pytest.raises(ValueError, match=r"passivity_max_energy_j: expected >= 0 .*-1"):
        vm.Controller(dev, mech, passivity_max_energy_j=-1.0)
    m = vm.Controller(dev, mech).model
    assert m["passivity"] == "observer_controller"  # the default is passive
    assert m["passivity_max_energy_j"] == vm.CONTROLLER_DEFAULTS["passivity_max_energy_j"]
