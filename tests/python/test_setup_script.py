"""scripts/setup.sh builds the C++ core once: an extra asked for after another installs only
that extra's packages, nothing changed means nothing done, and a changed source file means
a rebuild. Run on a copy of the script in a scratch checkout whose .venv/bin/python records
every pip call (and runs anything else with this Python), so that nothing is installed."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

tomllib = pytest.importorskip("tomllib")  # as setup.sh, which reads the extras with it

ROOT = Path(__file__).resolve().parents[2]

FAKE_PYTHON = """#!/usr/bin/env bash
# records pip's calls (arguments apart by tabs); `import virtmech` succeeds; anything else
# runs on the real Python
here="$(cd "$(dirname "$0")/../.." && pwd)"
if [ "$1" = "-m" ] && [ "$2" = "pip" ]; then
  (IFS=$'\t'; echo "${*:3}") >>"$here/pip-calls.log"
  exit 0
fi
if [ "$1" = "-c" ] && [ "$2" = "import virtmech" ]; then exit 0; fi
exec "REAL_PYTHON" "$@"
"""


@pytest.fixture
def checkout(tmp_path) -> Path:
    for tool in ("cmake", "ninja", "g++", "sha256sum"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} is not installed (setup.sh checks for it first)")
    (tmp_path / "scripts").mkdir()
    shutil.copy(ROOT / "scripts" / "setup.sh", tmp_path / "scripts" / "setup.sh")
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    (tmp_path / "CMakeLists.txt").write_text("project(x)\n")
    for d in ("src", "include", "python", "cmake"):
        (tmp_path / d).mkdir()
    (tmp_path / "src" / "core.cpp").write_text("int f() { return 1; }\n")
    venv = tmp_path / ".venv" / "bin"
    venv.mkdir(parents=True)
    (venv / "python").write_text(FAKE_PYTHON.replace("REAL_PYTHON", sys.executable))
    (venv / "python").chmod(0o755)
    return tmp_path


def setup(checkout: Path, extras: str) -> tuple[str, list[list[str]]]:
    """setup.sh's output and the pip calls it made (each its arguments)."""
    log = checkout / "pip-calls.log"
    before = log.read_text().splitlines() if log.exists() else []
    p = subprocess.run(
        ["bash", str(checkout / "scripts" / "setup.sh"), extras],
        capture_output=True, text=True, timeout=120,
    )
    assert p.returncode == 0, p.stdout + p.stderr
    after = log.read_text().splitlines() if log.exists() else []
    return p.stdout, [line.split("\t") for line in after[len(before) :]]


def is_build(call: list[str]) -> bool:
    """A pip call that builds the package (installs the checkout itself)."""
    return any(arg == "." or arg.startswith(".[") for arg in call[1:])


def test_an_extra_after_another_does_not_rebuild_the_core(checkout):
    out, calls = setup(checkout, "sim")
    assert len(calls) == 1 and is_build(calls[0]) and ".[sim]" in calls[0]
    assert "builds the C++ core" in out and "about 3 min" in out  # says how long it takes

    out, calls = setup(checkout, "view")  # the viewer's extra after the simulation's
    assert len(calls) == 1 and not is_build(calls[0]), calls
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"]
    assert calls[0] == ["install", "-q", *extras["view"]]
    assert "not rebuilt" in out

    for again in ("sim", "view", "sim,view", ""):  # nothing changed: nothing done
        out, calls = setup(checkout, again)
        assert calls == [] and "up to date" in out, again

    out, calls = setup(checkout, "sim,test")  # a list: only the missing one's packages
    assert len(calls) == 1 and not is_build(calls[0])
    assert calls[0] == ["install", "-q", *extras["test"]]


def test_a_changed_source_file_rebuilds(checkout):
    setup(checkout, "sim")
    (checkout / "src" / "core.cpp").write_text("int f() { return 2; }\n")
    out, calls = setup(checkout, "sim")
    assert len(calls) == 1 and is_build(calls[0])
    out, calls = setup(checkout, "sim")
    assert calls == []
