"""`virtmech quality` on every mechanism kind that has a distance measure, a set among them:
each shipped scenario of a kind (a HandlePath, which no shipped scenario uses, on the
letter's curve raised to the handle), measured at its own settings, the energy tank on. At
the defaults every kind renders its constrained axes near Kp, no hand of the grid nor a
released handle limit-cycles, and no closed run gives the hand more than 0.1 mJ
(docs/quality.md). Whole measures in the simulation: marked slow."""

from __future__ import annotations

import copy

import numpy as np
import pytest

import virtmech as vm
from virtmech import quality as Q
from virtmech import scenarios as sc

KP = vm.PhantomOmni().stiffness

SHIPPED = {  # a shipped scenario per kind
    "Probe": "omni-contact",
    "PlanarArm": "omni-fig11-passive",
    "PointPivot": "omni-trocar",
    "LineGuide": "omni-snap",  # a MechanismSet of LineGuides
    "SurfaceProbe": "omni-surface-nurbs",
    "CurveGuide": "omni-letter",
}


def handle_path() -> sc.Scenario:
    raw = copy.deepcopy(sc.load("omni-letter").raw)
    curve = raw["mechanism"]["curve"]
    # the handle on the curve where the letter holds the tip, 80 mm along the stylus below it
    curve["control_points"] = [[x, y + 0.08, z] for x, y, z in curve["control_points"]]
    raw["name"] = "omni-handle-path"
    raw["mechanism"] = {"type": "HandlePath", "curve": curve, "normal": [0.0, 1.0, 0.0]}
    return sc.validate(raw, source="test_quality_kinds")


CHAIN = """name = "chain"
duration_s = 0.5
[device]
type = "PhantomOmni"
[mechanism]
type = "SerialChain"
[[mechanism.joints]]
type = "prismatic"
axis = [1.0, 0.0, 0.0]
[[mechanism.joints]]
type = "revolute"
axis = [0.0, 0.0, 1.0]
"""


def test_a_kind_without_a_distance_measure_is_refused_naming_the_key(tmp_path, capsys):
    from virtmech.cli import main

    src = tmp_path / "chain.toml"
    src.write_text(CHAIN)
    out = tmp_path / "out"
    assert main(["quality", str(src), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "mechanism.type 'SerialChain': quality measures" in err
    assert "Traceback" not in err and not out.exists()  # nothing written


def test_the_measured_kinds_are_those_with_a_distance_measure():
    measured = {k["name"] for k in vm.kinds("mechanism") if k["distance"]}
    assert set(Q.QUALITY_MECHANISMS) == measured
    assert set(SHIPPED) | {"HandlePath"} == measured


@pytest.mark.slow
@pytest.mark.parametrize("kind", sorted(Q.QUALITY_MECHANISMS))
def test_quality_measures_every_kind_at_its_defaults(kind):
    s = handle_path() if kind == "HandlePath" else sc.load(SHIPPED[kind])
    assert s.data["controller"]["passivity"] == "energy_tank"
    r = Q.measure_scenario(s, workers=1)
    results = r["members"] if "members" in r else [r]
    if kind == "LineGuide":
        assert len(results) == 2  # the set's members, each measured
    for m in results:
        stiffness = [a["stiffness_n_per_m"] for a in m["stiffness"].values()]
        assert stiffness and np.all(np.isfinite(stiffness)), m["stiffness"]
        # the axes the mechanism holds render Kp (a trocar's stylus slides along itself: the
        # axis along it is nearly free, the other two hold)
        assert sum(abs(k - KP) <= 0.15 * KP for k in stiffness) >= len(stiffness) - 1
        lc = m["limit_cycles"]
        assert lc["stable"] == lc["total"] == 28
        for name, w in m["work"].items():
            assert w["net_work_j"] <= 0.1e-3, (kind, name, w)
