"""Passivity on wherever it is the default (docs/theory.md, 8): every shipped scenario but
the paper's figures as written (omni-fig9..12, planar3r-fig9..12, and the same four figures
on the omega.6, omega6-fig9..12, whose paper law and gains they keep to compare devices)
renders with the energy tank, and holds its shape as well as with it off: the tip's
distance from where the mechanism allows (the log's `dist`) at the median and the 95th
percentile within max(0.1 mm, 10 %) of the same scenario with `passivity = "off"`. Whole
runs in the simulation: marked slow."""

from __future__ import annotations

import re

import numpy as np
import pytest

from virtmech import scenarios as sc
from virtmech.runner import run_scenario

PAPER = re.compile(r"^(omni|planar3r|omega6)-fig(9|10|11|12)$")  # the figures as written
SHIPPED = sc.names()
NON_PAPER = [n for n in SHIPPED if not PAPER.match(n)]


def test_only_the_papers_figures_turn_passivity_off():
    assert len(NON_PAPER) >= 6  # (the list is not empty by a wrong pattern)
    for name in SHIPPED:
        passivity = sc.load(name).data["controller"]["passivity"]
        assert passivity == ("off" if PAPER.match(name) else "energy_tank"), name


def distances(scenario: sc.Scenario) -> np.ndarray:
    dist = np.asarray(run_scenario(scenario, keep=("dist",), metrics=False).columns["dist"])
    return dist[np.isfinite(dist)]


@pytest.mark.slow
@pytest.mark.parametrize("name", NON_PAPER)
def test_the_tank_holds_the_shape_as_well_as_the_law_alone(name):
    on = sc.load(name)
    raw = {k: v for k, v in on.raw.items()}
    raw["controller"] = {**raw.get("controller", {}), "passivity": "off"}
    off = sc.validate(raw, source=f"{name} with passivity off")
    d_on, d_off = distances(on), distances(off)
    for pct in (50, 95):
        a, b = np.percentile(d_on, pct), np.percentile(d_off, pct)
        tolerance = max(1e-4, 0.1 * b)
        print(f"{name} p{pct}: on {a * 1e3:.3f} mm, off {b * 1e3:.3f} mm")
        assert abs(a - b) <= tolerance, (name, pct, a, b)
