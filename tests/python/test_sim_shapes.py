"""Mechanisms on shapes in simulation (the scenarios omni-surface-nurbs, omni-surface-sphere,
omni-letter, omni-trocar): each claim is checked from the handle's true pose in the log
against the shape itself (closest points of the shape's own geometry), not against the
controller's placements."""

from __future__ import annotations

import numpy as np
import pytest

import virtmech as vm
import virtmech.scenarios as sc
from virtmech.shapes import shape_from_dict

sim = pytest.importorskip("virtmech.sim")

KP = vm.PhantomOmni().stiffness  # [N/m]


@pytest.fixture(scope="module")
def runs():
    return {n: sim.run(n, progress=False) for n in
            ("omni-surface-nurbs", "omni-surface-sphere", "omni-letter", "omni-trocar")}


def tips(run, m):
    return run.cols("px", "py", "pz") + m["length"] * run.cols("sx", "sy", "sz")


def surface_height_and_normal(run, m):
    """The tip's signed height above the surface and the surface's normal there."""
    s = shape_from_dict(m["surface"])
    h, n = [], []
    for x in tips(run, m)[::5]:
        uv, p = s.closest_point(x)
        nn = np.asarray(s.normal(*uv))
        h.append((x - p) @ nn)
        n.append(nn)
    return np.asarray(h), np.asarray(n)


@pytest.mark.parametrize("name", ["omni-surface-nurbs", "omni-surface-sphere"])
def test_a_probe_on_a_curved_surface_pushes_with_kp_times_depth_and_lets_go(runs, name):
    run, m = runs[name], sc.load(name)["mechanism"]
    h, n = surface_height_and_normal(run, m)
    f = run.cols("fx", "fy", "fz")[::5]
    t = run.t[::5]
    # (where the energy tank holds back the range term, the surface gives less: as the tip
    # slides down a flank the surface would do work on the hand; docs/theory.md, 8)
    held = (run.col("status")[::5].astype(int) & vm.status.PASSIVITY) != 0
    touched = h < -0.5e-3
    pressed = touched & ~held
    assert pressed.sum() > 100 and pressed.sum() > 0.8 * touched.sum()  # contact made
    f_n = np.sum(f * n, axis=1)
    # along the surface's own normal: Kp x depth + Kv x its rate, within one encoder count
    kv = float(run.info["controller_model"]["kv"][0])
    expected = KP * (-h) + kv * (-np.gradient(h, t))
    err = np.abs(f_n[pressed] - expected[pressed])
    assert np.median(err) < 0.05 and err.max() < 0.35, (np.median(err), err.max())
    # and nothing along the surface (the tip slides): below 10 % of the normal force
    tangential = np.linalg.norm(f[pressed] - f_n[pressed, None] * n[pressed], axis=1)
    assert np.median(tangential / f_n[pressed]) < 0.1
    lifted = h > 0.3e-3  # beyond what the encoders' quantisation makes of the tip's height
    # contact broken: nothing (the damping of the placements' relative velocity leaves
    # tens of micronewtons on a curved surface while the tip approaches it fast)
    assert lifted.sum() > 100 and np.abs(f[lifted]).max() <= 1e-4
    assert t[pressed][0] < 1.4  # made while lowering; broken before the end
    assert t[pressed][-1] < t[-1] - 0.5


@pytest.mark.parametrize(
    "name", ["omni-surface-nurbs", "omni-surface-sphere", "omni-letter", "omni-trocar"]
)
def test_every_placement_converges(runs, name):
    """No cycle reports not_converged: the Newton placements on a surface or a curve keep in
    their valley (docs/theory.md; omni-surface-nurbs had 24 such cycles before the
    second-order correction)."""
    status = runs[name].col("status").astype(int)
    assert np.count_nonzero(status & vm.status.NOT_CONVERGED) == 0


def test_the_sphere_falls_away_under_the_sliding_tip(runs):
    """The hand moves sideways at a constant height: the tip, pressed on the top, slides
    down the flank until the sphere falls away from under it, before the hand lifts (3.2 s)."""
    run, m = runs["omni-surface-sphere"], sc.load("omni-surface-sphere")["mechanism"]
    h, _ = surface_height_and_normal(run, m)
    t = run.t[::5]
    sliding = (t > 1.7) & (t < 3.2)
    assert h[sliding].min() < -0.5e-3 and h[sliding][-1] > 1e-3


def test_the_letter_guide_holds_the_tip_on_the_spline(runs):
    run, m = runs["omni-letter"], sc.load("omni-letter")["mechanism"]
    C = shape_from_dict(m["curve"])
    X = tips(run, m)[::5]
    d = np.array([np.linalg.norm(x - C.closest_point(x)[1]) for x in X])
    t = run.t[::5]
    tracing = (t > 0.4) & (t < 4.6)
    assert np.median(d[tracing]) < 0.3e-3 and d[tracing].max() < 1.5e-3
    # the straight cut pulls the hand up to 2 cm off the letter: the tip stays within 3 mm
    cut = t >= 4.6
    assert d[cut].max() < 3e-3
    # the hand went where the guide's ends are: the parameter covered most of the letter
    u = np.array([C.closest_point(x)[0] for x in X])
    assert u.min() < 0.1 and u.max() > 0.9


def test_the_trocar_keeps_the_stylus_through_the_port_while_it_slides_in(runs):
    run, m = runs["omni-trocar"], sc.load("omni-trocar")["mechanism"]
    P, S = run.cols("px", "py", "pz"), run.cols("sx", "sy", "sz")
    w = np.asarray(m["point"]) - P
    along = np.sum(w * S, axis=1)
    line = np.linalg.norm(w - along[:, None] * S, axis=1)  # the port from the stylus's line
    assert line.max() < 2.5e-3
    depth = m["length"] - along  # how far the tip is in past the port
    assert depth.max() - depth[: 400].mean() > 0.012  # pushed in by more than 12 mm
    tilt = np.degrees(np.arccos(np.clip(-S[:, 1], -1, 1)))  # from straight down (-y)
    assert tilt.max() > 8.0  # the stylus swung about the port


def line_distance(X, point, direction=(1.0, 0.0, 0.0)):
    d = np.asarray(direction) / np.linalg.norm(direction)
    w = X - np.asarray(point)
    return np.linalg.norm(w - np.outer(w @ d, d), axis=1)


def test_snapping_between_two_guides_follows_the_hysteresis_and_the_rate():
    """omni-snap: the tip is pulled from guide 0 to guide 1 and back. Each guide lets go
    where the tip is its release distance off it and the other engages within its snap
    distance (distances from the log's handle pose and the lines themselves); while the set
    switches, the force moves at most force_rate x period per cycle."""
    S = sc.load("omni-snap")
    run = sim.run(S, progress=False)
    m, st = S["mechanism"], S["set"]
    lines = [m["point"], st["members"][0]["point"]]
    X = tips(run, m)
    member = run.col("member").astype(int)
    changes = np.flatnonzero(np.diff(member) != 0) + 1
    assert [int(member[0])] + [int(member[i]) for i in changes] == [0, -1, 1, -1, 0]
    for i in changes:
        was, now = member[i - 1], member[i]
        if now == -1:  # released: the tip beyond the release distance of the old guide
            assert line_distance(X[i - 1 : i + 1], lines[was]).max() > 0.95 * st["release_distance"]
        else:  # engaged within the snap distance of the new one
            assert line_distance(X[i : i + 1], lines[now])[0] < 1.05 * st["snap_distance"]
    F = run.cols("fx", "fy", "fz")
    switching = (run.col("status").astype(int) & vm.status.SWITCHING) != 0
    assert switching.sum() > 10
    step = np.linalg.norm(np.diff(F, axis=0), axis=1)[switching[1:]]
    assert step.max() <= st["force_rate"] * S["controller"]["period_s"] + 1e-9
    # and the tip ends on guide 0, held there
    assert line_distance(X[-100:], lines[0]).max() < 1e-3
    # the log's distance is the rendered guide's, and with none rendered the nearer one's
    both = np.stack([line_distance(X, p) for p in lines])
    expected = np.where(member >= 0, both[np.maximum(member, 0), np.arange(len(X))],
                        both.min(axis=0))
    np.testing.assert_allclose(run.col("dist"), expected, atol=1e-12)


def test_with_no_member_rendered_the_distance_is_the_one_the_set_would_snap_to():
    # a line 20 mm below the tip and a unilateral plane 70 mm below it: the set compares the
    # plane by its tip height (70 mm), not by its depth (0 everywhere above it)
    from virtmech.sim.log import DerivedColumns, log_columns

    L = 0.08
    members = [
        {"type": "Probe", "plane_point": [0, 0, -0.05], "plane_normal": [0, 0, 1], "length": L,
         "unilateral": True},
        {"type": "LineGuide", "point": [0, 0, 0], "direction": [1, 0, 0], "length": L,
         "normal": [0, 0, 1], "unilateral": False},
    ]
    columns = log_columns(6, 6)
    log = np.zeros((2, len(columns)))
    c = {n: i for i, n in enumerate(columns)}
    log[:, c["pz"]] = 0.02 + L  # the handle above the tip, the stylus straight down
    log[:, c["sz"]] = -1.0
    log[:, c["member"]] = [-1, 0]
    post = DerivedColumns(columns, members, [-0.015, -0.05])
    d = post._distances(log, log[:, c["px"]:c["px"] + 3], log[:, c["sx"]:c["sx"] + 3])
    assert d[0, 0] == pytest.approx(0.02)  # none rendered: the line's
    assert d[1, 1] == pytest.approx(0.07)  # the plane rendered: its signed height
