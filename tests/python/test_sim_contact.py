"""Unilateral contact in simulation (scenario omni-contact): the Omni lowers a probe onto a
plane, presses, slides and lifts off. Contact is made once and broken once, the plane
pushes with Kp times the tip's depth, and nothing acts while the tip is in front of it."""

from __future__ import annotations

import numpy as np
import pytest

import virtmech as vm
import virtmech.scenarios as sc

sim = pytest.importorskip("virtmech.sim")

KP = vm.PhantomOmni().stiffness  # [N/m] the Omni's default stiffness


@pytest.fixture(scope="module")
def contact_run():
    return sim.run("omni-contact")


def tip_height(run, scenario) -> np.ndarray:
    """The tip's height above the plane [m], from the handle's true pose in the log."""
    m = scenario.data["mechanism"]
    n = np.asarray(m["plane_normal"], float)
    p = run.cols("px", "py", "pz")
    s = run.cols("sx", "sy", "sz")  # unit stylus direction, toward the tip
    return (p - np.asarray(m["plane_point"])) @ n + m["length"] * (s @ n)


def test_contact_is_made_once_and_broken_once(contact_run):
    f = contact_run.cols("fx", "fy", "fz")
    touching = np.linalg.norm(f, axis=1) > 1e-9
    assert np.count_nonzero(np.diff(touching.astype(int))) == 2  # no chatter at the boundary
    t = contact_run.t
    first, last = t[np.argmax(touching)], t[len(t) - 1 - np.argmax(touching[::-1])]
    assert 0.5 < first < 1.4 and 2.8 < last < 3.6, (first, last)


def test_no_force_while_the_tip_is_in_front_of_the_plane(contact_run):
    scenario = sc.load("omni-contact")
    h = tip_height(contact_run, scenario)
    lifted = h > 1e-4  # 0.1 mm: beyond the encoders' resolution at the tip
    assert lifted.sum() > 1500
    assert np.abs(contact_run.cols("fx", "fy", "fz", "mx", "my", "mz")[lifted]).max() <= 1e-9
    assert np.abs(contact_run.cols(*[f"f_null{i}" for i in range(6)])[lifted]).max() <= 1e-9
    assert np.abs(contact_run.cols(*[f"f_range{i}" for i in range(6)])[lifted]).max() <= 1e-9


def test_the_plane_pushes_with_kp_times_depth_and_lets_the_tip_slide(contact_run):
    scenario = sc.load("omni-contact")
    h = tip_height(contact_run, scenario)
    t = contact_run.t
    f = contact_run.cols("fx", "fy", "fz")
    pressed = (t > 1.2) & (t < 2.8)  # pressing, then sliding 30 mm along x
    depth = -h[pressed]
    assert depth.min() > 1e-3  # pressed in by more than a millimetre throughout
    # along the normal (+y): Kp x depth, within the damping and the encoders' quantisation
    # (about one encoder count at the tip, 0.055 mm, times Kp)
    assert np.abs(f[pressed, 1] - KP * depth).max() < KP * 0.06e-3
    # no friction: nothing along the plane while the tip slides
    assert np.abs(f[pressed][:, [0, 2]]).max() < 1e-6
    px = contact_run.col("px")
    assert px[t > 2.8][0] - px[t > 1.8][0] > 0.025
    status = contact_run.col("status").astype(int)
    # nothing but the initial ramp-in and, as the spring gives back what it stored while the
    # tip lifts off, the passivity controller
    assert np.all(status & ~(vm.status.RAMPING | vm.status.PASSIVITY) == 0)
