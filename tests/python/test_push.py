"""Walls that hold: steady pushes of a pure force into a Probe's plane and a PlanarArm's
circle on the simulated Omni, every controller setting its default (the energy tank on):
the device's force stays with the push (mean at least 0.9 F, never below 0.5 F over the last
0.4 s), at a stiffness of at least 1 N/mm, also one-sided for 10 s and with the tip starting
1 mm above the plane (docs/theory.md, 8). The default run pushes a few of them; the whole
grid (6 forces x 2 mechanisms x 3 starts) is marked slow."""

from __future__ import annotations

import numpy as np
import pytest

from virtmech import quality as Q
from virtmech import scenarios as sc

FORCES = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0)  # [N]


def scenario(kind: str, unilateral: bool = False, above_m: float = 0.0) -> sc.Scenario:
    if kind == "probe":
        mech = {"type": "Probe", "plane_point": [0.0, -0.07, -0.02],
                "plane_normal": [0.0, 1.0, 0.0], "length": 0.08, "unilateral": unilateral}
        initial = {"offset": [0.0, above_m, 0.0]}
    else:
        mech = {"type": "PlanarArm", "pivot": [-0.07, 0.04, 0.0], "normal": [0.0, 0.0, 1.0],
                "length": 0.08, "zero_direction": [1.0, 0.0, 0.0]}
        initial = {"theta": 0.3}
    raw = {"name": f"push-{kind}", "duration_s": 1.0, "seed": 1,
           "device": {"type": "PhantomOmni"}, "mechanism": mech, "controller": {},
           "initial": initial, "intent": [{"action": "hold", "start_s": 0.0, "duration_s": 0.4}]}
    return sc.validate(raw, source="test_push")


def push(setup: Q.Setup, rest: Q.Run, force: float, push_s: float) -> dict:
    """A push of `force` [N] into the first constrained axis, ramped in over 0.2 s after 0.4 s
    at rest, held for push_s: the device's force against it (mean from 0.3 s after the ramp,
    least over the last 0.4 s) and the stiffness, force / deviation over the last 0.3 s (the
    deviation counted from the plane under a resting tip above it, as `virtmech quality`
    does for a one-sided plane)."""
    axis = next(iter(setup.constrained_axes(rest).values()))
    hold, ramp = 0.4, 0.2
    raw = setup.raw_with(f"push-{force:g}",
                         [Q._hold(0.0, hold), Q._push(hold, push_s + 0.3, force * axis, ramp)],
                         hold + push_s)
    r = Q.run_all([raw])[0]
    f = np.stack([r.cols["fx"], r.cols["fy"], r.cols["fz"]], axis=1) @ -axis
    x = setup.point(r) @ axis
    t = r.t
    before = x[(t >= hold - 0.1) & (t < hold)].mean()
    # a tip resting above the plane (held there by the hand against the plane's pull) first
    # crosses the gap: the wall deforms from the plane
    surface = setup.contact_point(rest)
    if surface is None and setup.mechanism["type"] == "Probe":
        surface = np.asarray(setup.mechanism["plane_point"], dtype=float)
    if surface is not None:
        before = max(before, float(surface @ axis))
    deviation = x[t >= t[-1] - 0.3].mean() - before
    return {"mean": float(f[t >= hold + ramp + 0.3].mean()),
            "least": float(f[t >= t[-1] - 0.4].min()),
            "stiffness": force / deviation if deviation > 0 else np.nan}


def check(kind: str, forces, unilateral: bool = False, above_m: float = 0.0, push_s: float = 3.0):
    setup = Q.Setup(scenario(kind, unilateral, above_m))
    rest = setup.start()
    for force in forces:
        r = push(setup, rest, force, push_s)
        where = f"{kind} unilateral={unilateral} above={above_m} F={force}: {r}"
        assert r["mean"] >= 0.9 * force, where
        assert r["least"] >= 0.5 * force, where
        assert r["stiffness"] >= 1000.0, where


@pytest.mark.parametrize(("kind", "unilateral", "above_m", "force"), [
    ("probe", False, 0.0, 0.5),  # gave way after about a second with the earlier tank
    ("probe", False, 0.001, 0.5),  # the tip above the plane: the tank was empty at contact
    ("arm", False, 0.0, 0.75),
])
def test_a_steady_push_is_held(kind, unilateral, above_m, force):
    check(kind, [force], unilateral, above_m, push_s=3.0)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["probe", "arm"])
def test_every_steady_push_is_held(kind):
    check(kind, FORCES)


@pytest.mark.slow
@pytest.mark.parametrize("above_m", [0.0, 0.001])
def test_every_steady_push_into_a_one_sided_plane_is_held_for_10_s(above_m):
    check("probe", FORCES, unilateral=True, above_m=above_m, push_s=10.0)


@pytest.mark.slow
def test_every_steady_push_with_the_tip_starting_above_the_plane_is_held():
    check("probe", FORCES, above_m=0.001)
