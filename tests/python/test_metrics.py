"""The log's distance to the mechanism, the metrics built on it, the figures and the report.

The distances are checked against values computed here, independently: the handle pose
from the device's forward kinematics of the logged joint values q, the tip the handle moved
by the stylus length along the stylus (+z of the handle frame), and the mechanism's
geometry written out in the test."""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest

pytest.importorskip("mujoco")

import virtmech as vm  # noqa: E402
import virtmech.scenarios as sc  # noqa: E402
import virtmech.sim as sim  # noqa: E402
from virtmech.sim.output import metrics, write_run, write_summary  # noqa: E402

# omni-contact's geometry, written out: a unilateral probe of 80 mm over y = -0.07 m
PLANE_POINT = np.array([0.0, -0.07, -0.02])
PLANE_NORMAL = np.array([0.0, 1.0, 0.0])
PROBE_LENGTH = 0.08


def joint_log(r, n: int) -> np.ndarray:
    return r.cols(*[f"q{i}" for i in range(n)])


def poses(device, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Handle positions and stylus directions (+z) from forward kinematics, row by row."""
    T = [device.forward(q) for q in Q]
    return np.array([x[:3, 3] for x in T]), np.array([x[:3, 2] for x in T])


@pytest.fixture(scope="module")
def contact():
    return sim.run("omni-contact")


def with_mechanism(name: str, mechanism: dict, duration_s: float):
    raw = copy.deepcopy(sc.load(name).raw)
    raw["mechanism"] = mechanism
    raw["duration_s"] = duration_s
    return sc.validate(raw, "test")


def test_probe_logged_signed_distance_is_the_tip_height_from_q(contact):
    r = contact
    P, Z = poses(vm.PhantomOmni(), joint_log(r, 6))
    tip = P + PROBE_LENGTH * Z
    h = (tip - PLANE_POINT) @ PLANE_NORMAL
    assert np.abs(r.col("dist_signed") - h).max() < 1e-9
    assert np.abs(r.col("dist_normal") - h).max() < 1e-9
    # unilateral: the distance from where the tip may be is the depth behind the plane
    assert np.abs(r.col("dist") - np.maximum(-h, 0.0)).max() < 1e-9
    # the run does press into the plane (by millimetres), and starts 10 mm above it
    assert h.min() < -1e-3 and abs(h[0] - 0.01) < 1e-4
    m = metrics(r)
    assert m["penetration_max_m"] == pytest.approx(-h.min(), abs=1e-12)
    assert m["dist_max_m"] == pytest.approx(-h.min(), abs=1e-12)
    # within 1 mm only once it has lifted out of the plane again (after 2.8 s)
    assert m["time_to_1mm_s"] > 2.8
    assert "penetration_max_m" not in m["notes"]


def test_planar_arm_logged_distance_is_the_handle_from_the_circle():
    s = sc.load("omni-fig10").with_overrides(duration_s=0.3)
    r = sim.run(s)
    P, _ = poses(vm.PhantomOmni(), joint_log(r, 6))
    pivot, n, L = np.array([-0.07, 0.04, 0.0]), np.array([0.0, 0.0, 1.0]), 0.08
    w = P - pivot
    h = w @ n
    radial = np.linalg.norm(w - np.outer(h, n), axis=1) - L
    assert np.abs(r.col("dist") - np.hypot(radial, h)).max() < 1e-9
    assert np.abs(r.col("dist_across") - radial).max() < 1e-9
    assert np.abs(r.col("dist_normal") - h).max() < 1e-9
    assert np.abs(np.abs(r.col("dist_signed")) - r.col("dist")).max() < 1e-12
    assert r.col("dist")[0] > 5e-3  # starts off the circle
    m = metrics(r)
    assert math.isnan(m["penetration_max_m"]) and "bilateral" in m["notes"]["penetration_max_m"]


def test_planar3r_logged_distance_is_the_handle_from_the_circle():
    s = sc.load("planar3r-fig10").with_overrides(duration_s=0.3)
    r = sim.run(s)
    base = np.eye(4)
    base[:3, 3] = r.scenario["device"]["base_position"]
    P, _ = poses(vm.Planar3R(base=base), joint_log(r, 3))
    m = r.scenario["mechanism"]
    w = P - np.asarray(m["pivot"])
    radial = np.hypot(w[:, 0], w[:, 1]) - m["length"]  # the circle in the x-y plane
    assert np.abs(r.col("dist") - np.hypot(radial, w[:, 2])).max() < 1e-9


@pytest.mark.parametrize("unilateral", [False, True])
def test_point_pivot_logged_distance_is_the_tip_from_the_point(unilateral):
    point, n = np.array([0.0, -0.07, -0.02]), np.array([0.0, 1.0, 0.0])
    mech = {"type": "PointPivot", "point": point.tolist(), "normal": n.tolist()}
    mech.update(length=PROBE_LENGTH, unilateral=unilateral)
    r = sim.run(with_mechanism("omni-contact", mech, 1.2))
    P, Z = poses(vm.PhantomOmni(), joint_log(r, 6))
    w = P + PROBE_LENGTH * Z - point
    full = np.linalg.norm(w, axis=1)
    h = w @ n
    lateral = np.linalg.norm(w - np.outer(h, n), axis=1)
    expect = np.hypot(lateral, np.minimum(h, 0.0)) if unilateral else full
    assert np.abs(r.col("dist") - expect).max() < 1e-9
    assert np.abs(np.abs(r.col("dist_signed")) - full).max() < 1e-9
    assert np.all(np.sign(r.col("dist_signed"))[h < -1e-9] < 0)
    assert np.abs(r.col("dist_normal") - h).max() < 1e-9
    assert full.max() > 5e-3  # the tip starts 10 mm from the point: not a trivial zero


def test_line_guide_logged_distance_is_the_tip_from_the_line():
    point, d, n = np.array([0.0, -0.07, -0.02]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
    mech = {"type": "LineGuide", "point": point.tolist(), "direction": d.tolist()}
    mech.update(normal=n.tolist(), length=PROBE_LENGTH, unilateral=False)
    r = sim.run(with_mechanism("omni-contact", mech, 1.2))
    P, Z = poses(vm.PhantomOmni(), joint_log(r, 6))
    w = P + PROBE_LENGTH * Z - point
    off = w - np.outer(w @ d, d)  # the part normal to the line
    assert np.abs(r.col("dist") - np.linalg.norm(off, axis=1)).max() < 1e-9
    assert np.abs(r.col("dist_normal") - w @ n).max() < 1e-9
    assert r.col("dist").max() > 5e-3


def test_run_json_and_summary_have_null_not_nan(tmp_path):
    # 50 ms of fig10: the handle starts 30 mm off the circle and never comes within 1 mm
    r = sim.run(sc.load("omni-fig10").with_overrides(duration_s=0.05))
    m = metrics(r)
    assert math.isnan(m["time_to_1mm_s"]) and "never" in m["notes"]["first_within_1mm_s"]
    write_run(r, tmp_path)
    write_summary({r.scenario.name: m}, tmp_path / "summary.json")

    def no_constants(c):
        raise ValueError(f"non-finite JSON constant {c}")

    for f in (tmp_path / "run.json", tmp_path / "summary.json"):
        text = f.read_text()
        data = json.loads(text, parse_constant=no_constants)
        assert '"nan"' not in text.lower()
        runs = data["runs"] if "runs" in data else {"": data["metrics"]}
        (mm,) = runs.values()
        assert mm["time_to_1mm_s"] is None and mm["dist_max_after_m"] is None
        assert mm["notes"]["time_to_1mm_s"].startswith("n/a: the handle")


def test_report_is_in_the_papers_figure_order_with_version_and_definitions(tmp_path):
    from virtmech.sim.output import METRICS
    from virtmech.viz import write_index

    names = sorted(sc.names())  # sorted as strings: fig10 before fig9
    nan = dict.fromkeys(METRICS, math.nan)
    entries = [
        {"name": n, "description": n, "dir": n, "metrics": {**nan, "notes": {}}} for n in names
    ]
    page = write_index(tmp_path, entries).read_text()
    pos = [page.index(f'<section id="omni-fig{k}">') for k in (9, 10, 11, 12)]
    assert pos == sorted(pos)
    rows = [page.index(f'href="#planar3r-fig{k}"') for k in (9, 10, 11, 12)]
    assert rows == sorted(rows)
    assert f"virtmech {vm.__version__}" in page and "commit" in page
    for name in METRICS:
        assert f"<code>{name}</code>" in page
    assert ">nan<" not in page.lower() and "n/a" in page
    # the gimbal's torque is named for what it is, not mistaken for passivity
    assert "<th>max torque on unpowered joints [N·m]</th>" in page
    assert "passive torque" not in page
    entries[0]["metrics"]["energy_to_user_j"] = -1e-7  # -0.0001 mJ
    page = write_index(tmp_path, entries).read_text()
    assert "<td>-0.00</td>" not in page and "<td>0.00</td>" in page


def test_summary_is_in_the_papers_figure_order(tmp_path):
    runs = {n: {"x": 1.0} for n in ("planar3r-fig10", "omni-fig9", "omni-fig12", "omni-fig10")}
    s = write_summary(runs, tmp_path / "s.json")
    assert list(s["runs"]) == ["omni-fig9", "omni-fig10", "omni-fig12", "planar3r-fig10"]


def test_probe_figures_show_the_plane_edge_on_and_the_tip_height(contact, tmp_path):
    from virtmech.viz.figures import plane_figure, time_figure

    info = plane_figure(contact, tmp_path / "plane.png")
    assert "edge-on" in info["title"] and "face-on" not in info["title"]
    panels = time_figure(contact, tmp_path / "time.png")["panels"]
    assert not any("circle" in p for p in panels)
    assert any("tip height" in p for p in panels)
    assert len(panels) == 3  # force, tip height, force along the normal: none empty


def test_one_force_scale_and_no_overlapping_time_labels(contact, tmp_path):
    from virtmech.viz.figures import plane_figure

    arm = sim.run(sc.load("planar3r-fig12").with_overrides(duration_s=1.0))
    scales = set()
    for r in (contact, arm):
        info = plane_figure(r, tmp_path / f"{r.scenario.name}.png")
        scales.add(info["force_scale_m_per_n"])
        boxes = info["time_labels"]
        assert len(boxes) >= 2
        for i, a in enumerate(boxes):
            for b in boxes[i + 1 :]:
                apart = a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1]
                assert apart, (a, b)
    assert len(scales) == 1
