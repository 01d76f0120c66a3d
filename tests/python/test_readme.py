"""Every ```python block of the README runs as written, each on its own (a fresh namespace,
its own imports), and says what it does: the values its comments state are the values it
gives."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

README = Path(__file__).resolve().parents[2] / "README.md"


def blocks() -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", README.read_text(encoding="utf-8"), re.M | re.S)


def run(i: int, tmp_path, monkeypatch) -> dict:
    monkeypatch.chdir(tmp_path)  # a snippet that writes, writes here
    namespace: dict = {"__name__": "__readme__"}
    exec(compile(blocks()[i], f"README.md, python block {i + 1}", "exec"), namespace)
    return namespace


def test_the_readme_has_its_python_blocks():
    assert len(blocks()) >= 2


@pytest.mark.parametrize("i", range(len(blocks())))
def test_every_python_block_runs_as_written(i, tmp_path, monkeypatch):
    run(i, tmp_path, monkeypatch)


def test_the_first_block_says_what_its_output_is(tmp_path, monkeypatch):
    ns = run(0, tmp_path, monkeypatch)
    # as its comments say: the handle 2.7 mm off the circle, pulled back with Kp 1200 N/m
    import virtmech as vm

    moved = ns["omni"].forward(ns["q_off"])[:3, 3] - ns["handle"][:3, 3]
    assert np.linalg.norm(moved) == pytest.approx(2.7e-3, abs=0.05e-3)
    out = ns["out"]
    np.testing.assert_allclose(out.wrench, [0, -3.05, 0.98, 0, 0, 0], atol=0.005)
    np.testing.assert_allclose(out.wrench[:3], -1200.0 * moved, rtol=1e-6, atol=1e-9)  # Kp, back
    assert np.all(out.torque[3:] == 0.0)  # the gimbal
    assert out.status_names == [] and out.energy == pytest.approx(0.0, abs=1e-12)
    first = vm.Controller(ns["omni"], ns["circle"]).step(ns["q"], np.zeros(6))
    assert first.status_names == ["ramping"]
    np.testing.assert_allclose(first.wrench, 0.0, atol=1e-12)  # on the circle


def test_the_nurbs_block_says_what_its_output_is(tmp_path, monkeypatch):
    ns = run(1, tmp_path, monkeypatch)
    out = ns["out"]
    assert out.active == 0
    assert out.distance[0] == 0.0 and out.distance[1] == pytest.approx(0.028, abs=0.0005)
    np.testing.assert_allclose(out.torque, 0.0, atol=1e-12)
