"""The virtmech command: scenarios, run, demo, bench dispatch, python -m virtmech."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
import types

import pytest

pytest.importorskip("mujoco")
pytest.importorskip("matplotlib")

import virtmech.scenarios as sc  # noqa: E402
from virtmech.cli import main  # noqa: E402

REQUIRED = (
    ["t"]
    + [f"q{i}" for i in range(6)]
    + [f"dq{i}" for i in range(6)]
    + ["px", "py", "pz"]
    + ["fx", "fy", "fz", "mx", "my", "mz"]
    + [f"tau{i}" for i in range(6)]
    + ["status"]
    + ["theta0", "theta_star0"]
    + [f"e{i}" for i in range(6)]
    + [f"e_star{i}" for i in range(6)]
    + [f"f_null{i}" for i in range(6)]
    + [f"f_range{i}" for i in range(6)]
    + ["fhx", "fhy", "fhz", "mhx", "mhy", "mhz"]
)


def test_scenarios_lists_the_shipped_ones(capsys):
    assert main(["scenarios"]) == 0
    out = capsys.readouterr().out
    for name in sc.names():
        assert name in out


def test_run_writes_log_and_run_json(tmp_path, capsys):
    src = tmp_path / "mine.toml"
    src.write_text(
        sc.path_of("omni-fig10").read_text().replace("duration_s = 2.0", "duration_s = 0.3")
    )
    out = tmp_path / "out"
    assert main(["run", str(src), "--out", str(out), "--quiet"]) == 0
    with open(out / "log.csv") as f:
        rows = list(csv.reader(f))
    header = rows[0]
    for col in REQUIRED:
        assert col in header, col
    assert len(rows) - 1 == 301  # one row per 1 ms control cycle, both ends
    assert float(rows[2][0]) == pytest.approx(1e-3)
    run = json.loads((out / "run.json").read_text())
    mech = run["mechanism"]
    assert mech["type"] == "PlanarArm"
    assert mech["pivot"] == [-0.07, 0.04, 0.0] and mech["normal"] == [0.0, 0.0, 1.0]
    assert mech["length"] == 0.08
    assert run["scenario"]["duration_s"] == 0.3 and run["scenario"]["name"] == "omni-fig10"
    assert run["units"]["px"] == "m" and run["units"]["t"] == "s"
    assert run["units"]["tau0"].startswith("N·m")
    assert {"virtmech", "mujoco", "numpy", "python"} <= set(run["versions"])
    assert (out / "plane.png").stat().st_size > 10000
    assert (out / "time.png").stat().st_size > 10000


def test_run_takes_the_python_engine_and_records_it(tmp_path, capsys):
    out = tmp_path / "py"
    assert main(["run", "omni-fig9", "--duration", "0.05", "--engine", "python",
                 "--out", str(out), "--quiet"]) == 0
    run = json.loads((out / "run.json").read_text())
    assert json.dumps(run).count('"engine": "python"') == 1
    with pytest.raises(SystemExit):
        main(["run", "omni-fig9", "--engine", "numba"])


def test_run_reports_a_broken_scenario(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(sc.path_of("omni-fig10").read_text().replace("[human]", "[human]\nmood = 1"))
    assert main(["run", str(bad), "--out", str(tmp_path / "o")]) == 2
    assert "human.mood: unknown key" in capsys.readouterr().err


def test_demo_writes_folders_summary_and_index(tmp_path, capsys):
    out = tmp_path / "demo"
    assert (
        main(["demo", "--out", str(out), "--only", "omni-fig12", "planar3r-fig9", "--quiet"]) == 0
    )
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["runs"]) == {"omni-fig12", "planar3r-fig9"}
    m = summary["runs"]["omni-fig12"]
    for key in (
        "time_to_1mm_s",
        "dist_rms_after_m",
        "dist_max_after_m",
        "force_max_n",
        "force_rms_n",
        "passive_torque_max",
        "torque_fraction_max",
        "energy_to_user_j",
    ):
        assert key in m
    assert m["passive_torque_max"] == 0.0
    assert 0 < m["torque_fraction_max"] <= 1.0
    index = (out / "index.html").read_text()
    assert 'src="omni-fig12/plane.png"' in index and 'src="planar3r-fig9/time.png"' in index
    for name in ("omni-fig12", "planar3r-fig9"):
        for f in ("log.csv", "run.json", "plane.png", "time.png"):
            assert (out / name / f).exists()


def test_bench_is_handed_to_virtmech_bench(monkeypatch):
    calls = []
    fake = types.ModuleType("virtmech.bench")
    fake.main = lambda argv: calls.append(argv) or 7
    monkeypatch.setitem(sys.modules, "virtmech.bench", fake)
    import virtmech

    monkeypatch.setattr(virtmech, "bench", fake, raising=False)
    assert main(["bench", "--cycles", "10", "-q"]) == 7
    assert calls == [["--cycles", "10", "-q"]]


def test_python_dash_m_virtmech_runs_the_cli():
    p = subprocess.run(
        [sys.executable, "-m", "virtmech", "scenarios"], capture_output=True, text=True, check=True
    )
    assert "omni-fig11" in p.stdout


def test_import_virtmech_does_not_import_mujoco_or_matplotlib():
    code = (
        "import sys, virtmech, virtmech.sim, virtmech.viz, virtmech.scenarios, virtmech.cli;"
        "print(sorted(m for m in ('mujoco', 'matplotlib') if m in sys.modules))"
    )
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert p.stdout.strip() == "[]"


def test_run_shows_a_progress_bar_on_stderr(tmp_path, capsys):
    assert main(["run", "planar3r-fig9", "--duration", "0.2", "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "planar3r-fig9" in err and "100%" in err and "#" in err
