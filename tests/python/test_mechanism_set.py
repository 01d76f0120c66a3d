"""MechanismSet: members engage within the snap distance and let go beyond the release
distance; switching never moves the force faster than the set rate.

The scripted handle moves its probe's tip straight down through two horizontal guides and
back up; the distances are the tip's heights above them (a closed form), and the member to
render follows the hysteresis rule written out here as its own small state machine."""

from __future__ import annotations

import numpy as np
import pytest

import virtmech as vm
from reference.passivity import Tank

KP = 1200.0  # [N/m]
L = 0.1  # [m]
DT = 1e-3  # [s]
HEIGHTS = (0.0, -0.03)  # [m] the guides' heights (lines along x through y = 0)
SNAP, RELEASE = 0.005, 0.010  # [m]
FORCE_RATE = 20.0  # [N/s]


def cartesian_device() -> vm.Device:
    joints = [vm.Joint("prismatic", a) for a in np.eye(3)]
    joints += [vm.Joint("revolute", a) for a in np.eye(3)]
    return vm.Device(joints, [True] * 6, stiffness=KP, damping=1.0, max_force=100.0)


def make_set(device, release=RELEASE, unilateral_floor=None, watchdog_s=0.0):
    s = vm.MechanismSet(device, 4, snap_distance=SNAP, release_distance=release,
                        force_rate=FORCE_RATE, moment_rate=1.0)
    for h in HEIGHTS:
        guide = vm.LineGuide([0, 0, h], [1, 0, 0], L, [0, 0, 1])
        s.add(vm.Controller(device, guide, ramp_time_s=1e-3, watchdog_s=watchdog_s))
    if unilateral_floor is not None:
        floor = vm.Probe([0, 0, unilateral_floor], [0, 0, 1], L, unilateral=True)
        s.add(vm.Controller(device, floor, ramp_time_s=1e-3))
    return s


def q_tip(z: float, x: float = 0.01) -> np.ndarray:
    """Cartesian-device joints with the stylus straight down and the tip at (x, 0, z)."""
    # handle orientation Rx(pi): z_handle = -z, the handle L above the tip
    return np.array([x, 0.0, z + L, np.pi, 0.0, 0.0])


def expected_active(distances, active):
    """The hysteresis rule: keep the engaged member while within RELEASE, else take the
    nearest within SNAP."""
    if active >= 0 and distances[active] <= RELEASE:
        return active
    best = int(np.argmin(distances))
    return best if distances[best] < SNAP else -1


def scripted(path):
    dev = cartesian_device()
    s = make_set(dev)
    out = vm.MechanismSetOutput()
    rows = []
    for k, z in enumerate(path):
        v = (path[min(k + 1, len(path) - 1)] - path[max(k - 1, 0)]) / (2 * DT)
        s.step(q_tip(z), np.array([0, 0, v, 0, 0, 0]), out=out)
        rows.append((z, out.active, out.switching, np.array(out.wrench), np.array(out.distance),
                     list(out.status_names)))
    return rows


def test_distances_are_the_tips_heights_and_members_follow_the_hysteresis_rule():
    down = np.linspace(0.02, -0.05, 701)  # 0.1 m/s
    path = np.r_[down, down[::-1]]
    active = -1
    engaged = []
    for z, got, _, _, dist, _ in scripted(path):
        np.testing.assert_allclose(dist, [abs(z - h) for h in HEIGHTS], atol=1e-9)
        active = expected_active(dist, active)
        assert got == active, z
        engaged.append(got)
    # down: none, guide 0, none, guide 1, none (the bottom is 20 mm below it); up the same
    # backwards
    changes = [engaged[0]] + [b for a, b in zip(engaged, engaged[1:]) if a != b]
    assert changes == [-1, 0, -1, 1, -1, 1, -1, 0, -1]


def test_switching_never_steps_the_force_faster_than_the_rate():
    down = np.linspace(0.02, -0.05, 701)
    rows = scripted(np.r_[down, down[::-1]])
    max_step = FORCE_RATE * DT
    switching_cycles = 0
    for (_, a0, _, f0, _, _), (_, a1, sw1, f1, _, names) in zip(rows, rows[1:]):
        if a1 != a0 or sw1:
            switching_cycles += 1
            assert np.linalg.norm(f1[:3] - f0[:3]) <= max_step + 1e-12
            if sw1:
                assert "switching" in names
    # the engagements at 5 mm ask for Kp 5 mm = 6 N: hundreds of cycles of blending
    assert switching_cycles > 300


def test_hysteresis_prevents_chattering_at_the_snap_boundary():
    """The tip trembling 2 mm about the snap distance above guide 0 engages it once; with
    the release distance equal to the snap distance the same tremble chatters."""
    t = np.arange(1000) * DT
    path = SNAP + 0.002 * np.sin(2 * np.pi * 15.0 * t)
    dev = cartesian_device()
    counts = {}
    for release in (RELEASE, SNAP):
        s = make_set(dev, release=release)
        out = vm.MechanismSetOutput()
        actives = []
        for z in path:
            s.step(q_tip(z), np.zeros(6), out=out)
            actives.append(out.active)
        counts[release] = sum(a != b for a, b in zip(actives, actives[1:]))
    assert counts[RELEASE] == 1
    assert counts[SNAP] >= 20


def test_a_unilateral_member_engages_on_contact():
    """A floor (a unilateral plane probe) below both guides: its distance is the tip's
    height above it, zero in contact, where its contact flag is set."""
    dev = cartesian_device()
    floor = -0.06
    s = make_set(dev, unilateral_floor=floor)
    out = vm.MechanismSetOutput()
    for z in (-0.045, -0.058, -0.0605, -0.062):
        for _ in range(3):
            s.step(q_tip(z), np.zeros(6), out=out)
        height = z - floor
        if height > 0:
            assert out.distance[2] == pytest.approx(height, abs=1e-9)
            assert not out.contact[2]
        else:
            assert out.distance[2] == 0.0 and out.contact[2]
            assert out.active == 2
    # pressed 2 mm in and blended in: Kp 2 mm up
    for _ in range(400):
        s.step(q_tip(floor - 0.002), np.zeros(6), out=out)
    assert out.active == 2 and not out.switching
    assert out.wrench[2] == pytest.approx(KP * 0.002, rel=1e-6)


def test_bad_settings_and_capacity_are_named():
    dev = cartesian_device()
    with pytest.raises(ValueError, match="release_distance"):
        vm.MechanismSet(dev, 2, snap_distance=0.01, release_distance=0.005)
    with pytest.raises(ValueError, match="capacity"):
        vm.MechanismSet(dev, 0)
    with pytest.raises(ValueError, match="force_rate"):
        vm.MechanismSet(dev, 2, force_rate=0.0)
    s = vm.MechanismSet(dev, 1)
    guide = vm.LineGuide([0, 0, 0], [1, 0, 0], L, [0, 0, 1])
    assert s.add(vm.Controller(dev, guide)) == 0
    with pytest.raises(ValueError, match="full"):
        s.add(vm.Controller(dev, guide))
    other = vm.MechanismSet(cartesian_device(), 1)
    with pytest.raises(ValueError, match="device"):
        other.add(vm.Controller(dev, guide))


def test_an_empty_set_commands_nothing_and_a_fault_zeroes_the_torque():
    dev = cartesian_device()
    s = vm.MechanismSet(dev, 2)
    out = s.step(q_tip(0.0), np.zeros(6))
    assert out.active == -1 and np.all(out.torque == 0.0)
    s = make_set(dev)
    for _ in range(50):
        s.step(q_tip(-0.002), np.zeros(6))
    bad = q_tip(-0.002)
    bad[0] = np.nan
    out = s.step(bad, np.zeros(6))
    assert np.all(out.torque == 0.0)
    assert "fault_nonfinite_input" in out.status_names


def test_after_a_fault_the_force_comes_back_at_the_set_rate():
    # the set's own blend brings the Kp 2 mm = 2.4 N of the engaged guide back at its rate,
    # whatever the members' ramp-in (one period at the start, 50 ms after a fault)
    dev = cartesian_device()
    s = make_set(dev)
    for _ in range(300):  # engaged, and blended in at 20 N/s
        s.step(q_tip(-0.002), np.zeros(6))
    held = np.array(s.last.wrench)
    assert np.linalg.norm(held[:3]) == pytest.approx(KP * 0.002, rel=0.05)
    bad = q_tip(-0.002)
    bad[0] = np.nan
    s.step(bad, np.zeros(6))
    previous = np.zeros(3)
    for k in range(400):
        out = s.step(q_tip(-0.002), np.zeros(6))
        f = np.array(out.wrench)[:3]
        assert np.linalg.norm(f - previous) <= FORCE_RATE * DT + 1e-12, k
        previous = f
    # and it does come back in full
    np.testing.assert_allclose(previous, held[:3], atol=1e-9)


def test_after_a_watchdog_gap_the_blend_starts_again_from_zero():
    # A late tick while a member engages (the set blending its force in at 20 N/s): a driver
    # zeroes that tick's torque (DriverServo), and the members ramp in again. The set's blend
    # must start from that zero too, not from the force it had before the gap (a step back
    # to it on the next tick).
    dev = cartesian_device()
    s = make_set(dev, watchdog_s=0.005)
    max_step = FORCE_RATE * DT
    t = 0.0
    for _ in range(60):  # engaged 2 mm deep: Kp 2 mm = 2.4 N, blended in at 20 N/s
        t += DT
        out = s.step(q_tip(-0.002), np.zeros(6), t)
    before = np.linalg.norm(np.array(out.wrench)[:3])
    assert out.switching and before > 10 * max_step  # mid-blend
    t += 0.010  # a 10 ms gap, twice the watchdog
    out = s.step(q_tip(-0.002), np.zeros(6), t)
    assert "watchdog" in out.status_names
    for k in range(1, 40):
        f = np.linalg.norm(np.array(out.wrench)[:3])
        assert f <= k * max_step + 1e-12, (k, f, before)
        t += DT
        out = s.step(q_tip(-0.002), np.zeros(6), t)


def test_while_blending_the_energy_tank_books_the_torque_the_motors_hold():
    # the rendered member's tank (docs/theory.md, 8), replayed from its definition
    # (tests/reference/passivity.py) with tau the torque the set commanded, the blend, not
    # the member's own (which the motors never held); a member restarts its tank as it
    # engages (it did no work while not rendered)
    dev = cartesian_device()
    s = make_set(dev)
    path = np.linspace(0.02, -0.01, 301)  # 0.1 m/s down onto guide 0 and 1 cm past it
    tank, active, checked = None, -1, 0
    for k, z in enumerate(path):
        v = (path[min(k + 1, len(path) - 1)] - path[max(k - 1, 0)]) / (2 * DT)
        q, dq = q_tip(z), np.array([0, 0, v, 0, 0, 0])
        out = s.step(q, dq)
        c = out.cycle
        if out.active != active:
            active = out.active
            m = vm.Controller(dev, s.member(active)).model if active >= 0 else None
            # (a member engaging restarts empty: its springs were stretched while it was
            # not rendered)
            tank = None
            if m:
                tank = Tank(m["passivity_play"], m["passivity_max_energy_j"], springs=False)
        if tank is not None:
            assert c.energy == pytest.approx(tank.cycle(q, c.stored_energy), abs=1e-12), k
            tank.hold(out.torque)
            checked += out.switching
    assert checked > 50  # the blend lasts Kp 10 mm / 20 N/s = 0.6 s: many cycles


def test_a_faulted_cycle_engages_no_member():
    # the tip 7 mm above guide 0: between snap (5 mm) and release (10 mm), not engaged
    dev = cartesian_device()
    s = make_set(dev)
    for _ in range(20):
        out = s.step(q_tip(0.02), np.zeros(6))
    assert out.active == -1
    for _ in range(20):
        out = s.step(q_tip(0.007), np.zeros(6))
    assert out.active == -1
    bad = np.zeros(6)
    bad[2] = np.nan
    out = s.step(q_tip(0.007), bad)
    assert out.active == -1 and np.all(np.isnan(out.distance))
    for _ in range(20):
        out = s.step(q_tip(0.007), np.zeros(6))
        assert out.active == -1 and np.all(np.asarray(out.wrench) == 0.0)


def test_the_rendered_member_renders_as_its_controller_stepped_whole():
    """Only the member rendered computes its wrench (the others place and end their cycles
    without one): whenever the set is not blending, its torque is the one the member's own
    controller gives stepped whole every cycle, its ramp-in included (the members ramp in
    over 50 cycles while not rendered too)."""
    dev = cartesian_device()
    # switching within a cycle, so that a member's ramp-in shows once it engages
    s = vm.MechanismSet(dev, 4, snap_distance=SNAP, release_distance=RELEASE,
                        force_rate=1e6, moment_rate=1e6)
    twins = []
    for h in HEIGHTS:
        guide = vm.LineGuide([0, 0, h], [1, 0, 0], L, [0, 0, 1])
        s.add(vm.Controller(dev, guide, ramp_time_s=0.05, passivity="off"))
        twins.append(vm.Controller(dev, guide, ramp_time_s=0.05, passivity="off"))
    path = np.r_[np.linspace(0.02, -0.05, 700), np.linspace(-0.05, 0.02, 700)]
    out = vm.MechanismSetOutput()
    compared = set()
    for k, z in enumerate(path):
        v = (path[min(k + 1, len(path) - 1)] - path[max(k - 1, 0)]) / (2 * DT)
        q, dq = q_tip(z, x=0.01 + 0.02 * np.sin(k * DT * 3)), np.array([0, 0, v, 0, 0, 0])
        s.step(q, dq, out=out)
        whole = [t.step(q, dq) for t in twins]
        assert np.array_equal(out.distance[:2], [np.linalg.norm(w.error[:3]) for w in whole])
        if out.active >= 0 and not out.switching:
            np.testing.assert_allclose(out.torque, whole[out.active].torque, rtol=0, atol=1e-12)
            if np.abs(out.torque).max() > 1e-3:
                compared.add(out.active)
    assert compared == {0, 1}  # both members rendered real forces


def test_an_empty_set_has_its_device_and_no_members():
    omni = vm.PhantomOmni()
    s = vm.MechanismSet(omni, 2)
    assert s.device is omni  # the set's own device, members or none
    assert s.size == 0 and s.capacity == 2
    with pytest.raises(IndexError, match="i: expected 0 <= i < 0, got 0"):
        s.member(0)
