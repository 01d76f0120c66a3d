"""A kind of one's own, end to end: the helix guide of examples/cpp/helix_guide.hpp,
registered by its plugin (examples/cpp/helix_plugin.cpp), built with CMake against the
installed package (`python -m virtmech --cmake-dir`: its headers, static library and CMake
package) and run from its scenario file by `virtmech run`, with nothing else of virtmech
edited. The build takes about a minute: marked slow (scripts/test.sh runs the slow tests)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mujoco")

ROOT = Path(__file__).resolve().parents[2]


def _run(*args, cwd=None) -> subprocess.CompletedProcess:
    r = subprocess.run([str(a) for a in args], capture_output=True, text=True, cwd=cwd)
    assert r.returncode == 0, f"{' '.join(map(str, args))}:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    return r


@pytest.mark.slow
def test_the_helix_plugin_builds_against_the_package_and_runs_from_its_scenario(tmp_path):
    cmake_dir = _run(sys.executable, "-m", "virtmech", "--cmake-dir").stdout.strip()
    assert (Path(cmake_dir) / "virtmech" / "virtmechConfig.cmake").is_file()
    build = tmp_path / "build"
    generator = ["-G", "Ninja"] if shutil.which("ninja") else []
    _run("cmake", "-S", ROOT / "examples" / "cpp" / "plugin", "-B", build, *generator,
         "-DCMAKE_BUILD_TYPE=Release", f"-DCMAKE_PREFIX_PATH={cmake_dir}")
    _run("cmake", "--build", build, "-j", "2")
    shutil.copy(ROOT / "examples" / "cpp" / "helix.toml", build / "helix.toml")
    out = tmp_path / "out"
    _run(sys.executable, "-m", "virtmech", "run", build / "helix.toml", "--quiet", "--out", out)
    info = json.loads(next(out.rglob("run.json")).read_text())
    mech = info["mechanism"]
    assert mech["type"] == "HelixGuide" and mech["radius"] == pytest.approx(0.1539)
    log = next(out.rglob("log.csv"))
    data = np.genfromtxt(log, delimiter=",", names=True)
    assert not (data["status"].astype(int) & 0xFF00).any()  # no fault
    # the hand follows the helix: the handle stays on it (the placement's error, the
    # distance of a kind without a measure of its own) while it moves along it
    assert np.max(data["dist"][data["t"] > 0.3]) < 5e-3
    assert np.ptp(data["theta0"]) > 0.4
