"""The energy tank of the cycle (docs/theory.md, "Passivity"), against its definitions: the
level starts at what the springs hold (at most the reserve) and loses the motors' work as
the observer books it (the torque held over each cycle times a displacement that follows
the joint velocity within a count of the despiked readings, two cycles late), held at most
at the springs' energy plus the reserve; eq. 26's range term has a factor that moves toward
its aim, set by the level and the budget, by at most one fade step a cycle."""

from __future__ import annotations

import math

import numpy as np
import pytest

import virtmech as vm
from reference.passivity import Factor, Tank
from virtmech import bench

CASES = ["omni+planar_arm", "omni+probe", "planar3r+planar_arm"]
N = 2500


def motion(name: str, **settings):
    case = bench.make_case(name, **settings)
    q, dq = case.joint_state(np.arange(N), case.controller.model["period_s"])
    return case.controller, q, dq


def reference_tank(c: vm.Controller) -> Tank:
    m = c.model
    return Tank(m["passivity_play"], m["passivity_max_energy_j"],
                start_energy=m["passivity_start_energy_j"])


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


@pytest.mark.parametrize(("name", "cap"), [*((name, math.inf) for name in CASES),
                                          ("planar3r+planar_arm", 2e-4)])  # damping fills it
def test_the_level_is_the_springs_energy_at_the_start_less_the_observed_work(name, cap):
    # the range term always on (a budget it never reaches), so that the torques do not
    # depend on the tank: the level is the observer's booking alone
    c, q, dq = motion(name, passivity_max_energy_j=cap, passivity_budget_j=1e3)
    tank = reference_tank(c)
    capped = 0
    for k in range(N):
        out = c.step(q[k], dq[k])
        level = tank.cycle(q[k], out.stored_energy)
        assert out.energy == pytest.approx(level, abs=1e-12, rel=1e-9), k
        capped += k > 0 and tank.capped
        tank.hold(out.torque)
    assert abs(tank.level - min(out.stored_energy, cap)) > 2e-5  # real energy was booked
    if math.isfinite(cap):
        assert capped > 10  # the cap acted


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


def test_the_range_terms_factor_moves_toward_its_aim_by_at_most_a_step():
    name = "omni+probe"  # the probe's range term pushes on the handle as it passes the table
    # no damping to fill the tank, no reserve: the range term's work empties it often
    c, q, dq = motion(name, passivity_max_energy_j=0.0, kv=np.zeros(6))
    m = c.model
    factor = Factor(m)
    tank = reference_tank(c)  # (for the play's pending work)
    held, full, moving = 0, 0, 0
    last_force = None
    for k in range(N):
        out = c.step(q[k], dq[k])
        twist = c.device.jacobian(q[k]) @ dq[k]
        tank.cycle(q[k], out.stored_energy)
        scale, held_back = factor.cycle(out.energy, out.wrench_range, twist, tank.pending)
        tank.hold(out.torque)
        assert out.passivity_scale == pytest.approx(scale, abs=1e-12), k
        np.testing.assert_allclose(out.wrench_passivity, held_back, atol=1e-12)
        assert bool(out.status & vm.status.PASSIVITY) == (scale < 1.0)
        # the torque renders the null term and the range term with its factor (renderable part)
        law = out.wrench_null + out.wrench_range + out.wrench_passivity - out.wrench_unrendered
        np.testing.assert_allclose(out.wrench, law * out.ramp * out.limit_scale, atol=1e-9)
        # what the factor takes away or gives back moves by at most one step of the limit
        rendered = np.linalg.norm((out.wrench_range + out.wrench_passivity)[:3])
        if last_force is not None and scale < 1.0:
            own = abs(min(np.linalg.norm(out.wrench_range[:3]), m["max_force"]) - last_force[1])
            step = m["passivity_fade_step"] * m["max_force"]
            assert abs(rendered - last_force[0]) <= step + own + 1e-9, k
        last_force = (rendered, min(np.linalg.norm(out.wrench_range[:3]), m["max_force"]))
        held += scale < 1.0
        full += scale == 1.0 and np.abs(out.wrench_range).max() > 1e-3
        moving += 0.0 < scale < 1.0
    assert held > 10 and full > 10 and moving > 10  # all happen along the motion


def test_a_budget_holds_the_factor_up_until_the_level_is_below_it():
    settings = {"passivity_max_energy_j": 0.0, "kv": np.zeros(6)}
    c0, q, dq = motion("omni+probe", **settings)
    c1, _, _ = motion("omni+probe", passivity_budget_j=1e-3, **settings)
    fade = c0.model["passivity_fade_j"]
    spared, below = 0, 0
    for k in range(N):
        out0, out1 = c0.step(q[k], dq[k]), c1.step(q[k], dq[k])
        if out1.energy >= 0.0:
            assert out1.passivity_scale == 1.0, k  # nothing spent: never held back
        # without the budget the range term is held back; with it, on in full
        spared += out0.passivity_scale < 1.0 and out1.passivity_scale == 1.0
        below += out1.energy < -fade and out1.passivity_scale == 1.0
    assert spared > 10
    assert below > 10  # the level spent beyond the fade band, the range term still in full


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


def test_a_watchdog_trip_restarts_the_tank_empty():
    c, q, dq = motion("planar3r+planar_arm", watchdog_s=0.01)
    t, k = 0.0, 0
    while c.step(q[k], dq[k], t).energy < 1e-4:
        k, t = k + 1, t + 1e-3
    out = c.step(q[k + 1], dq[k + 1], t + 0.1)  # a 0.1 s gap
    assert out.status & vm.status.WATCHDOG
    assert out.stored_energy > 1e-4  # (a restart at the start would have had this)
    assert out.energy == 0.0  # the torque over the gap is unknown: nothing banked across it


def test_a_fault_restarts_the_tank_empty():
    c, q, dq = motion("planar3r+planar_arm")
    k = 0
    while c.step(q[k], dq[k]).energy < 1e-4:  # the tank fills from the motion's damping
        k += 1
    bad = q[k + 1].copy()
    bad[0] = np.nan
    assert c.step(bad, dq[k + 1]).fault
    out = c.step(q[k + 2], dq[k + 2])
    assert out.stored_energy > 1e-4
    assert out.energy == 0.0  # nothing banked across the fault, the springs' energy neither


def test_a_stretched_spring_at_the_start_is_storage_the_rendering_may_give_back():
    # the probe's tip 1 mm above its plane at the start: the un-powered placement keeps the
    # stylus and puts the tip on the plane, so the range spring holds Kp (1 mm)^2 / 2
    omni = vm.PhantomOmni()
    T0 = omni.forward(omni.home)
    L, n = 0.08, np.array([0.0, 1.0, 0.0])
    tip = T0[:3, 3] + L * T0[:3, 2]
    c = vm.Controller(omni, vm.Probe(tip - 0.001 * n, n, L))
    out = c.step(omni.home, np.zeros(6))
    kp = c.model["kp"][0]
    assert out.stored_energy == pytest.approx(0.5 * kp * 1e-3**2, rel=1e-3)
    assert out.energy == out.stored_energy  # below the reserve: all of it
    far = vm.Controller(omni, vm.Probe(tip - 0.02 * n, n, L)).step(omni.home, np.zeros(6))
    assert far.stored_energy > 1e-3 and far.energy == 1e-3  # at most the reserve


def test_settings_are_checked_and_reported():
    dev, mech = vm.PhantomOmni(), vm.PlanarArm([0, 0, -0.05], [0, 0, 1], 0.05, [1, 0, 0])
    with pytest.raises(ValueError, match="passivity: expected 'energy_tank' or 'off'"):
        vm.Controller(dev, mech, passivity="tdpa")
    with pytest.raises(ValueError, match=r"passivity_fade_j: expected a finite number > 0 .*0"):
        vm.Controller(dev, mech, passivity_fade_j=0.0)
    with pytest.raises(ValueError, match=r"passivity_max_energy_j: expected >= 0 .*-1"):
        vm.Controller(dev, mech, passivity_max_energy_j=-1.0)
    with pytest.raises(ValueError, match=r"passivity_budget_j: .*-1"):
        vm.Controller(dev, mech, passivity_budget_j=-1.0)
    with pytest.raises(ValueError, match=r"passivity_fade_time_s: expected a finite number > 0"):
        vm.Controller(dev, mech, passivity_fade_time_s=0.0)
    with pytest.raises(ValueError, match=r"passivity_resolution_rad: .*-0.001"):
        vm.Controller(dev, mech, passivity_resolution_rad=-1e-3)
    with pytest.raises(ValueError, match=r"ramp_time_s: expected a finite number > 0 .*, got 0"):
        vm.Controller(dev, mech, ramp_time_s=0.0)
    with pytest.raises(ValueError, match=r"ramp_time_s: expected .*> 0 and <= 60 .*, got 1e\+16"):
        vm.Controller(dev, mech, ramp_time_s=1e16)
    m = vm.Controller(dev, mech).model
    assert m["passivity"] == "energy_tank"  # the default is passive
    assert m["passivity_max_energy_j"] == vm.CONTROLLER_DEFAULTS["passivity_max_energy_j"]
    assert m["passivity_budget_j"] == 0.0
    fade_time = vm.CONTROLLER_DEFAULTS["passivity_fade_time_s"]
    assert m["passivity_fade_step"] == pytest.approx(1e-3 / fade_time)
    np.testing.assert_allclose(m["passivity_play"], np.pi / 15000)  # half a count
    np.testing.assert_allclose(m["dq_max"], dev.max_velocity + 5.0)
