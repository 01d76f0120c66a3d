"""Rendering quality (virtmech.quality) of the mechanisms on shapes, on the simulated Omni:
the pushes, the paths along the shape and the contact point are checked against the shapes'
closed forms (a sphere) or a dense sampling of the curve, and the measured stiffness against
the device's Kp."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import virtmech as vm
from virtmech import quality as Q

pytest.importorskip("mujoco")

KP = vm.PhantomOmni().stiffness  # [N/m]


@pytest.fixture(scope="module")
def sphere():
    s = Q.Setup("omni-surface-sphere")
    return s, s.start()


@pytest.fixture(scope="module")
def letter():
    s = Q.Setup("omni-letter")
    return s, s.start()


def sphere_of(setup):
    surf = setup.mechanism["surface"]
    return np.asarray(surf["center"], dtype=float), float(surf["radius"])


def test_a_probe_resting_above_a_sphere_pressed_into_it_is_as_stiff_as_kp(sphere):
    s, rest = sphere
    c, R = sphere_of(s)
    tip = s.point(rest)[-1]
    # the tip rests above the sphere (unilateral, not touching) ...
    assert np.linalg.norm(tip - c) > R + 5e-3
    # ... the push is along the sphere's normal there, and counts from the surface below it
    axis = s.constrained_axes(rest)["into the surface"]
    np.testing.assert_allclose(axis, -(tip - c) / np.linalg.norm(tip - c), atol=1e-9)
    np.testing.assert_allclose(s.contact_point(rest), c + R * (tip - c) / np.linalg.norm(tip - c),
                               atol=1e-9)
    d = Q.stiffness(s, rest=rest)["into the surface"]
    assert 0.0 < d["deviation_m"]["1"] <= 1e-3
    assert d["stiffness_n_per_m"] == pytest.approx(KP, rel=0.1)
    # linear: half the force, half the depth (within friction and quantisation)
    assert d["deviation_m"]["0.5"] == pytest.approx(d["deviation_m"]["1"] / 2, rel=0.15)


def test_a_probe_slides_over_the_sphere_pressed_on_it_with_no_force_along_it(sphere):
    s, rest = sphere
    ff = Q.free_force(s, speeds=[0.05], rest=rest)["0.05"]
    assert ff["cycles"] > 300
    assert ff["across_median_n"] > 0.1  # pressed onto the sphere while it slides
    assert abs(ff["mean_n"]) <= 0.05


def test_the_path_along_a_surface_stays_on_it_and_is_as_long_as_asked(sphere):
    s, rest = sphere
    c, R = sphere_of(s)
    p0 = s.contact_point(rest)
    pts = p0 + np.asarray(s.path(rest, 0.04))
    np.testing.assert_allclose(np.linalg.norm(pts - c, axis=1), R, atol=1e-9)
    # the polyline's length is the arc's to within the chords' shortfall (20 steps of 2 mm
    # on a 50 mm radius: the chord is shorter than its arc by 2e-4 relative)
    length = np.linalg.norm(np.diff(np.vstack([p0, pts]), axis=0), axis=1).sum()
    assert length == pytest.approx(0.04, rel=2e-3)
    # and it leaves the contact point tangentially
    n = (p0 - c) / R
    assert abs((pts[0] - p0) @ n) <= np.linalg.norm(pts[0] - p0) * 0.03
    # pressed in: the same path 3 mm inside the sphere, along its normal
    inside = p0 - 0.003 * n + np.asarray(s.path(rest, 0.04, depth_m=0.003))
    np.testing.assert_allclose(np.linalg.norm(inside - c, axis=1), R - 0.003, atol=1e-9)


def test_a_curve_guide_holds_across_the_curve_and_lets_it_slide_along(letter):
    s, rest = letter
    axes = s.constrained_axes(rest)
    assert set(axes) == {"along the normal", "across"}
    curve = Q._shape(s.mechanism)
    u = np.linspace(curve.lower, curve.upper, 20001)
    dense = np.array([curve.evaluate(x) for x in u])
    tip = s.point(rest)[-1]
    k = np.argmin(np.linalg.norm(dense - tip, axis=1))
    tangent = dense[min(k + 1, len(u) - 1)] - dense[max(k - 1, 0)]
    tangent /= np.linalg.norm(tangent)
    for a in axes.values():  # across the curve's tangent where the tip rests
        assert abs(a @ tangent) < 1e-3
    st = Q.stiffness(s, rest=rest)
    for name, d in st.items():
        assert d["stiffness_n_per_m"] == pytest.approx(KP, rel=0.15), name
    # the hand's path follows the letter (to the sampling's resolution)
    pts = np.asarray(curve.closest_point(tip)[1]) + np.asarray(s.path(rest, 0.04))
    gap = np.min(np.linalg.norm(pts[:, None, :] - dense[None, ::4, :], axis=2), axis=1)
    assert gap.max() < 2e-4
    ff = Q.free_force(s, speeds=[0.05], rest=rest)["0.05"]
    assert ff["cycles"] > 500
    assert abs(ff["mean_n"]) <= 0.05


def run_cli(*args):
    return subprocess.run(
        [sys.executable, "-m", "virtmech", *args], capture_output=True, text=True, timeout=120
    )


def test_a_set_is_measured_member_by_member():
    # omni-snap's two line guides: each member measured on its own, as a scenario of that
    # member alone would be (member 0's figures equal a direct measure of its scenario)
    import virtmech.scenarios as sc

    parts = Q.member_scenarios("omni-snap")
    raw = sc.load("omni-snap").raw
    assert [p.data["mechanism"]["type"] for p in parts] == ["LineGuide", "LineGuide"]
    assert [p.raw["mechanism"] for p in parts] == [raw["mechanism"], *raw["set"]["members"]]
    assert all("set" not in p.raw for p in parts)
    s = Q.Setup(parts[1])
    rest = s.start()
    across = s.constrained_axes(rest)
    assert set(across) == {"across 1", "across 2"}
    d = np.asarray(parts[1].data["mechanism"]["direction"], dtype=float)
    for axis in across.values():  # across the member's own line
        assert abs(axis @ d) < 1e-12


def test_cli_measures_a_set_and_writes_each_members_report(tmp_path):
    r = run_cli("quality", "omni-snap", "--out", str(tmp_path / "q"), "--json")
    assert r.returncode == 0, r.stderr
    result = json.loads(r.stdout)
    assert [m["member"] for m in result["members"]] == [0, 1]
    for m in result["members"]:
        assert m["mechanism"] == "LineGuide"
        for axis in m["stiffness"].values():  # each guide renders stiffly across its line
            assert axis["stiffness_n_per_m"] > 500.0
    assert (tmp_path / "q" / "fidelity-member0.png").is_file()
    assert (tmp_path / "q" / "fidelity-member1.png").is_file()


def test_the_library_refuses_a_set_in_one_setup():
    with pytest.raises(ValueError, match="set.members"):
        Q.Setup("omni-snap")


def test_a_path_from_the_patchs_edge_turns_inward_and_stays_on_it():
    import virtmech.scenarios as sc

    s = Q.Setup(sc.load("omni-surface-nurbs"))
    surface = Q._shape(s.mechanism)
    for u in (0.0, 1.0):  # both edges of u
        p0 = np.asarray(surface.evaluate(u, 0.5)) + 0.01 * np.asarray(surface.normal(u, 0.5))
        c0 = np.asarray(surface.closest_point(p0)[1])
        pts = c0 + np.asarray(Q._along_surface(surface, p0, 0.04, 20))
        assert np.all(np.isfinite(pts)) and len(pts) == 20
        # on the patch: each point is its own closest point
        for x in pts:
            np.testing.assert_allclose(surface.closest_point(x)[1], x, atol=1e-9)
        steps = np.linalg.norm(np.diff(np.vstack([c0, pts]), axis=0), axis=1)
        assert steps.max() < 0.0025  # no jump (2 mm steps)
