"""The energy tank of the cycle (docs/theory.md, "Passivity"), against its definitions: the
motors' work is the torque held over a cycle times the joints' displacement; the tank's
level is zero at the start minus that work, held at most at what the law's springs store
plus the reserve; eq. 26's range term fades out as the level falls
below zero."""

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


def saturated(e, f, force_limit, moment_limit) -> float:
    """The energy of a spring whose force at the error e is f, per block of three axes: e^T f
    / 2 below the limit; above it, the integral of a force growing linearly to the limit
    (reached at r0 = limit |e| / |f|) and then constant: limit r0 / 2 + limit (|e| - r0)."""
    total = 0.0
    for block, limit in ((slice(0, 3), force_limit), (slice(3, 6), moment_limit)):
        eb, fb = e[block], f[block]
        F, r = np.linalg.norm(fb), np.linalg.norm(eb)
        if F <= limit or r == 0.0:
            total += 0.5 * eb @ fb
        else:
            r0 = limit * r / F
            total += 0.5 * limit * r0 + limit * (r - r0)
    return total


@pytest.mark.parametrize("name", CASES)
def test_the_tank_starts_empty_and_loses_the_motors_work(name):
    c, q, dq = motion(name, passivity_max_energy_j=math.inf)  # no cap
    work = 0.0  # the motors' work so far: tau_k held from q_k to q_(k+1)
    tau_prev = None
    for k in range(N):
        if tau_prev is not None:
            work += tau_prev @ (q[k] - q[k - 1])
        out = c.step(q[k], dq[k])
        assert out.energy == pytest.approx(-work, abs=1e-12, rel=1e-9)
        tau_prev = out.torque.copy()
    assert abs(work) > 2e-5  # the motion exchanged real energy (tolerance 1e-12)


def test_the_tank_holds_at_most_the_springs_and_its_cap():
    cap = 2e-4
    c, q, dq = motion("planar3r+planar_arm", passivity_max_energy_j=cap)  # damping fills it
    level, tau_prev, capped = 0.0, None, 0
    for k in range(N):
        out = c.step(q[k], dq[k])
        V = out.stored_energy
        level = 0.0 if tau_prev is None else level - tau_prev @ (q[k] - q[k - 1])
        if level > V + cap:
            level, capped = V + cap, capped + 1
        assert out.energy == pytest.approx(level, abs=1e-12)
        tau_prev = out.torque.copy()
    assert capped > 100  # the cap acted


def test_what_the_springs_hold_is_the_saturated_spring_energy():
    # eq. 11 alone: the null term's spring Kp e, saturating at the force limit
    c, q, dq = motion("omni+planar_arm", law="null_space")
    m = c.model
    kp = np.asarray(m["kp"])
    for k in range(N):
        out = c.step(q[k], dq[k])
        expected = saturated(out.error, kp * out.error, m["max_force"], m["max_torque"])
        assert out.stored_energy == pytest.approx(expected, rel=1e-12, abs=1e-15)
    # and far from the mechanism, where the force saturates: single cycles anywhere
    rng = np.random.default_rng(5)
    dev, saturated_cycles = c.device, 0
    for _ in range(200):
        x = rng.uniform(dev.lower, dev.upper)
        out = vm.Controller(dev, c.mechanism, law="null_space").step(x, np.zeros(6))
        expected = saturated(out.error, kp * out.error, m["max_force"], m["max_torque"])
        assert out.stored_energy == pytest.approx(expected, rel=1e-12, abs=1e-15)
        saturated_cycles += np.linalg.norm(kp[:3] * out.error[:3]) > m["max_force"]
    assert saturated_cycles > 10


def test_the_range_term_fades_out_as_the_tank_empties():
    name = "omni+probe"  # the probe's range term pushes on the handle as it passes the table
    # no damping to fill the tank, no reserve: the range term's work empties it often
    c, q, dq = motion(name, passivity_max_energy_j=0.0, kv=np.zeros(6))
    fade = c.model["passivity_fade_j"]
    held = full = 0
    for k in range(N):
        out = c.step(q[k], dq[k])
        scale = min(max(1.0 + out.energy / fade, 0.0), 1.0)
        assert out.passivity_scale == pytest.approx(scale, abs=1e-12)
        np.testing.assert_allclose(
            out.wrench_passivity, (scale - 1.0) * out.wrench_range, atol=1e-12
        )
        assert bool(out.status & vm.status.PASSIVITY) == (scale < 1.0)
        # the torque renders the null term and the scaled range term (renderable part)
        law = out.wrench_null + scale * out.wrench_range - out.wrench_unrendered
        np.testing.assert_allclose(out.wrench, law * out.ramp * out.limit_scale, atol=1e-9)
        held += scale < 1.0
        full += scale == 1.0 and np.abs(out.wrench_range).max() > 1e-3
    assert held > 10 and full > 10  # both happen along the motion


def test_without_the_range_term_the_tank_only_observes():  # eq. 11 is passive as it is
    c_on, q, dq = motion("omni+planar_arm", law="null_space")
    c_off, _, _ = motion("omni+planar_arm", law="null_space", passivity="off")
    for k in range(N):
        on, off = c_on.step(q[k], dq[k]), c_off.step(q[k], dq[k])
        np.testing.assert_array_equal(on.torque, off.torque)
        assert on.passivity_scale == 1.0


def test_off_renders_the_laws_and_reports_no_energy():
    settings = {"passivity_max_energy_j": 0.0, "kv": np.zeros(6)}
    c_off, q, dq = motion("omni+probe", passivity="off", **settings)
    c_on, _, _ = motion("omni+probe", **settings)
    differ = 0
    for k in range(N):
        off, on = c_off.step(q[k], dq[k]), c_on.step(q[k], dq[k])
        assert off.energy == 0.0 and not off.wrench_passivity.any()
        assert off.passivity_scale == 1.0 and not off.status & vm.status.PASSIVITY
        np.testing.assert_allclose(off.wrench_null, on.wrench_null, atol=1e-12)
        differ += not np.allclose(off.torque, on.torque, atol=1e-12)
    assert differ > 10  # ... where the tank held the range term back, and only the torque


def test_a_watchdog_trip_starts_the_tank_afresh():
    c, q, dq = motion("planar3r+planar_arm", watchdog_s=0.01)
    t, k = 0.0, 0
    while c.step(q[k], dq[k], t).energy < 1e-4:
        k, t = k + 1, t + 1e-3
    out = c.step(q[k + 1], dq[k + 1], t + 0.1)  # a 0.1 s gap
    assert out.status & vm.status.WATCHDOG
    assert out.energy == 0.0


def test_a_fault_starts_the_tank_afresh():
    c, q, dq = motion("planar3r+planar_arm")
    k = 0
    while c.step(q[k], dq[k]).energy < 1e-4:  # the tank fills from the motion's damping
        k += 1
    bad = q[k + 1].copy()
    bad[0] = np.nan
    assert c.step(bad, dq[k + 1]).fault
    assert c.step(q[k + 2], dq[k + 2]).energy == 0.0  # nothing banked across the fault


def test_settings_are_checked_and_reported():
    dev, mech = vm.PhantomOmni(), vm.PlanarArm([0, 0, -0.05], [0, 0, 1], 0.05, [1, 0, 0])
    with pytest.raises(ValueError, match="passivity: expected 'energy_tank' or 'off'"):
        vm.Controller(dev, mech, passivity="tdpa")
    with pytest.raises(ValueError, match=r"passivity_fade_j: expected a finite number > 0 .*0"):
        vm.Controller(dev, mech, passivity_fade_j=0.0)
    with pytest.raises(ValueError, match=r"passivity_max_energy_j: expected >= 0 .*-1"):
        vm.Controller(dev, mech, passivity_max_energy_j=-1.0)
    m = vm.Controller(dev, mech).model
    assert m["passivity"] == "energy_tank"  # the default is passive
    assert m["passivity_max_energy_j"] == vm.CONTROLLER_DEFAULTS["passivity_max_energy_j"]
