"""Unilateral contact in simulation (scenarios omni-contact and falcon-contact): the Omni, and
a Novint Falcon (three slides, its handle's orientation fixed), lower a probe onto a plane,
press, slide and lift off. Contact is made once and broken once, the plane pushes with Kp
times the tip's depth, and nothing acts while the tip is in front of it."""

from __future__ import annotations

import numpy as np
import pytest

import virtmech as vm
import virtmech.scenarios as sc

sim = pytest.importorskip("virtmech.sim")

#: each scenario's plane normal (a world axis), the axes along the plane and the slide's
CASES = {
    "omni-contact": {"normal": 1, "along": [0, 2], "slide": "px"},
    "falcon-contact": {"normal": 2, "along": [0, 1], "slide": "py"},
}


def stiffness(scenario) -> float:
    """The device's default Kp [N/m] (the scenarios leave it)."""
    from virtmech.builder import make_device

    return make_device(scenario.data["device"]).stiffness


@pytest.fixture(scope="module", params=sorted(CASES))
def contact_run(request):
    return request.param, sim.run(request.param)


def tip_height(run, scenario) -> np.ndarray:
    """The tip's height above the plane [m], from the handle's true pose in the log."""
    m = scenario.data["mechanism"]
    n = np.asarray(m["plane_normal"], float)
    p = run.cols("px", "py", "pz")
    s = run.cols("sx", "sy", "sz")  # unit stylus direction, toward the tip
    return (p - np.asarray(m["plane_point"])) @ n + m["length"] * (s @ n)


def test_contact_is_made_once_and_broken_once(contact_run):
    _, contact_run = contact_run
    f = contact_run.cols("fx", "fy", "fz")
    touching = np.linalg.norm(f, axis=1) > 1e-9
    assert np.count_nonzero(np.diff(touching.astype(int))) == 2  # no chatter at the boundary
    t = contact_run.t
    first, last = t[np.argmax(touching)], t[len(t) - 1 - np.argmax(touching[::-1])]
    assert 0.5 < first < 1.4 and 2.8 < last < 3.6, (first, last)


def test_no_force_while_the_tip_is_in_front_of_the_plane(contact_run):
    name, contact_run = contact_run
    scenario = sc.load(name)
    h = tip_height(contact_run, scenario)
    lifted = h > 1e-4  # 0.1 mm: beyond the encoders' resolution at the tip
    assert lifted.sum() > 1500
    assert np.abs(contact_run.cols("fx", "fy", "fz", "mx", "my", "mz")[lifted]).max() <= 1e-9
    assert np.abs(contact_run.cols(*[f"f_null{i}" for i in range(6)])[lifted]).max() <= 1e-9
    assert np.abs(contact_run.cols(*[f"f_range{i}" for i in range(6)])[lifted]).max() <= 1e-9


def test_the_plane_pushes_with_kp_times_depth_and_lets_the_tip_slide(contact_run):
    name, contact_run = contact_run
    scenario, case = sc.load(name), CASES[name]
    kp = stiffness(scenario)
    h = tip_height(contact_run, scenario)
    t = contact_run.t
    f = contact_run.cols("fx", "fy", "fz")
    pressed = (t > 1.2) & (t < 2.8)  # pressing, then sliding 30 mm along the plane
    depth = -h[pressed]
    assert depth.min() > 1e-3  # pressed in by more than a millimetre throughout
    # along the normal: Kp x depth, within the damping and the encoders' quantisation
    # (about one encoder count at the tip, 0.055 mm on the Omni, times Kp)
    assert np.abs(f[pressed, case["normal"]] - kp * depth).max() < kp * 0.06e-3
    # no friction: nothing along the plane while the tip slides
    assert np.abs(f[pressed][:, case["along"]]).max() < 1e-6
    slide = contact_run.col(case["slide"])
    assert slide[t > 2.8][0] - slide[t > 1.8][0] > 0.025
    status = contact_run.col("status").astype(int)
    # nothing but the initial ramp-in and, as the spring gives back what it stored while the
    # tip lifts off, the passivity controller
    assert np.all(status & ~(vm.status.RAMPING | vm.status.PASSIVITY) == 0)
