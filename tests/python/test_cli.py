"""The virtmech command: scenarios, run, demo, bench dispatch, python -m virtmech."""

from __future__ import annotations

import csv
import json
import re
import subprocess
import sys
import types

import numpy as np
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


def test_scenarios_are_listed_aligned_in_the_papers_figure_order(capsys):
    import re

    assert main(["scenarios"]) == 0
    lines = capsys.readouterr().out.splitlines()
    names = [ln.split()[0] for ln in lines]
    assert sorted(names) == sorted(p.stem for p in sc.DATA.glob("*.toml"))
    # each device's figures together, in the paper's order, the devices alphabetically
    assert names[:4] == [f"omega6-fig{k}" for k in (9, 10, 11, 12)]
    assert names[4:9] == ["omni-fig9", "omni-fig10", "omni-fig11", "omni-fig11-passive",
                          "omni-fig12"]
    assert names[9:13] == [f"planar3r-fig{k}" for k in (9, 10, 11, 12)]
    others = names[13:]
    assert others == sorted(others) and "arm7-contact" in others
    # the durations stand in one column, however long the name
    ends = {re.search(r"\d\.\d s ", ln).end() for ln in lines}
    assert len(ends) == 1


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


def test_run_has_one_simulation_loop(capsys):
    # the loop is C++ (virtmech._sim); there is no engine to choose
    with pytest.raises(SystemExit):
        main(["run", "omni-fig9", "--engine", "python"])
    assert "unrecognized arguments: --engine" in capsys.readouterr().err


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


class _Terminal:
    """stderr as a terminal: a stream whose isatty() is true, its text kept."""

    def __init__(self):
        import io

        self.buffer = io.StringIO()

    def isatty(self) -> bool:
        return True

    def write(self, text: str) -> int:
        return self.buffer.write(text)

    def flush(self) -> None:
        pass


def test_run_shows_a_progress_bar_on_a_terminal(tmp_path, monkeypatch):
    term = _Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    assert main(["run", "planar3r-fig9", "--duration", "0.2", "--out", str(tmp_path)]) == 0
    err = term.buffer.getvalue()
    assert "planar3r-fig9" in err and "100%" in err and "#" in err and "\r" in err


def test_redirected_progress_is_whole_lines_without_carriage_returns(tmp_path):
    p = _cli("run", "planar3r-fig9", "--duration", "2.5", "--out", str(tmp_path),
             code="import virtmech.progress as P; P.LINE_INTERVAL_S = 0.0")
    assert p.returncode == 0, p.stderr
    assert "\r" not in p.stderr and "\x1b" not in p.stderr  # no bar, no terminal codes
    lines = p.stderr.splitlines()
    assert len(lines) >= 3  # a line per update (every 1000 cycles here), then the summary
    for line in lines[:-1]:
        assert line.startswith("planar3r-fig9  ") and line.endswith(" s"), line
    assert lines[-2].startswith("planar3r-fig9  100%  2.50/2.50 s")
    assert lines[-1].startswith("planar3r-fig9: 2.50 s simulated in ")


def test_a_short_redirected_run_prints_only_its_summary_line(tmp_path):
    p = _cli("run", "planar3r-fig9", "--duration", "0.2", "--out", str(tmp_path))
    assert p.returncode == 0, p.stderr
    assert p.stderr.splitlines() == [p.stderr.strip()]
    assert p.stderr.startswith("planar3r-fig9: 0.20 s simulated in ")


def test_a_sweeps_redirected_progress_is_a_line_per_run(monkeypatch, capsys):
    import virtmech.progress as P
    from virtmech.sweep import _bar

    monkeypatch.setattr(P, "LINE_INTERVAL_S", 0.0)
    bar = _bar(3, "omni-fig10 sweep", True)
    for _ in range(3):
        bar.update(1)
    bar.close()
    assert capsys.readouterr().err.splitlines() == [
        f"omni-fig10 sweep  {p:3.0f}%  {k}/3 runs" for k, p in ((1, 100 / 3), (2, 200 / 3),
                                                                (3, 100))
    ]


# ---------------------------------------------------------------------------------------
# every mistake of the user: exit status 2, one message on stderr naming the file, key or
# flag, the value and what was expected, never a traceback


def _mistake(capsys, argv: list[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert err.startswith("virtmech")
    return err


def _scenario(tmp_path, old: str, new: str, name: str = "bad.toml"):
    text = sc.path_of("omni-fig10").read_text()
    assert old in text
    p = tmp_path / name
    p.write_text(text.replace(old, new, 1))
    return p


def _cli(*args: str, code: str = "") -> subprocess.CompletedProcess:
    prog = f"import sys\n{code}\nfrom virtmech.cli import main\nsys.exit(main(sys.argv[1:]))"
    return subprocess.run(
        [sys.executable, "-c", prog, *args], capture_output=True, text=True, timeout=120
    )


@pytest.mark.parametrize("argv", [["demo", "--quiet"], ["run", "omni-fig9", "--quiet"]])
def test_without_the_sim_extra_says_how_to_install_it(argv, tmp_path):
    p = _cli(*argv, "--out", str(tmp_path), code="sys.modules['mujoco'] = None")
    assert p.returncode == 2, p.stderr
    assert "Traceback" not in p.stderr
    assert "mujoco" in p.stderr and "pip install 'virtmech[sim]'" in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "omni-fig9").exists()


def test_the_sim_extra_brings_what_sweep_needs_and_the_readme_says_so(tmp_path):
    from pathlib import Path

    tomllib = pytest.importorskip("tomllib")
    root = Path(__file__).resolve().parents[2]
    extras = tomllib.loads((root / "pyproject.toml").read_text())["project"][
        "optional-dependencies"]
    names = {re.split(r"[<>=;\[ ]", d)[0] for d in extras["sim"]}
    assert {"mujoco", "matplotlib", "tqdm", "pyarrow"} <= names
    assert {re.split(r"[<>=;\[ ]", d)[0] for d in extras["view"]} >= names  # view has [sim]
    readme = (root / "README.md").read_text()
    line = next(ln for ln in readme.splitlines() if ln.startswith('pip install ".[sim]"'))
    assert all(n in line for n in ("MuJoCo", "matplotlib", "tqdm", "pyarrow")), line
    # without pyarrow, sweep says that [sim] brings it: one line, exit status 2
    p = _cli("sweep", "planar3r-fig9", "--grid", "human.damping=2,6", "--quiet",
             "--out", str(tmp_path), code="sys.modules['pyarrow'] = None")
    assert p.returncode == 2, p.stderr
    assert "Traceback" not in p.stderr and len(p.stderr.strip().splitlines()) == 1
    assert "pyarrow" in p.stderr and "pip install 'virtmech[sim]'" in p.stderr


def test_a_zero_normal_names_the_file_and_the_key(tmp_path, capsys):
    bad = _scenario(tmp_path, "normal = [0.0, 0.0, 1.0]", "normal = [0, 0, 0]")
    err = _mistake(capsys, ["run", str(bad), "--out", str(tmp_path / "o"), "--quiet"])
    assert f"{bad}: mechanism.normal: value [0, 0, 0] is out of range" in err
    assert "non-zero" in err


def test_a_direction_written_to_three_digits_runs(tmp_path, capsys):
    # |[0.342, 0.940, 0]| = 1.00028: read as its unit vector, as docs/scenarios.md says
    out = tmp_path / "o"
    argv = ["run", "omni-contact", "--set", "mechanism.plane_normal=[0.342,0.940,0.0]"]
    assert main([*argv, "--duration", "0.05", "--quiet", "--out", str(out)]) == 0
    n = json.loads((out / "run.json").read_text())["scenario"]["mechanism"]["plane_normal"]
    v = np.array([0.342, 0.940, 0.0])
    np.testing.assert_allclose(n, v / np.linalg.norm(v), rtol=0, atol=1e-15)


def test_a_value_the_constructors_reject_names_the_file_and_the_key(tmp_path, capsys):
    # a zero direction out of the plane passes the format's checks; PlanarArm rejects it
    bad = _scenario(tmp_path, "zero_direction = [1.0, 0.0, 0.0]", "zero_direction = [0, 0, 1]")
    err = _mistake(capsys, ["run", str(bad), "--out", str(tmp_path / "o"), "--quiet"])
    assert f"{bad}: mechanism.zero_direction: expected a unit vector in the plane" in err
    assert "[0, 0, 1]" in err
    assert not (tmp_path / "o" / "log.csv").exists()


def test_an_unreachable_start_pose_names_the_file_and_initial(tmp_path, capsys):
    bad = _scenario(tmp_path, "offset = [0.028, 0.010, 0.0]", "offset = [0.5, 0.0, 0.0]")
    err = _mistake(capsys, ["run", str(bad), "--out", str(tmp_path / "o"), "--quiet"])
    assert f"{bad}: initial: the device cannot reach the start pose" in err


def test_demo_only_an_unknown_name_lists_the_known_ones(tmp_path, capsys):
    err = _mistake(capsys, ["demo", "--only", "omni-fig99", "--out", str(tmp_path)])
    assert "--only" in err and "'omni-fig99'" in err
    for name in sc.names():
        assert name in err
    assert list(tmp_path.iterdir()) == []  # nothing run


def test_a_negative_seed_names_the_flag(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main(["run", "omni-fig9", "--seed", "-5", "--out", str(tmp_path)])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "--seed" in err and "-5" in err and "expected an integer 0 to" in err
    assert "Traceback" not in err and "usage:" not in err


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["run", "omni-fig9", "--seed", "abc"],
         "--seed: expected an integer 0 to 2**63-1, got 'abc'"),
        (["run", "omni-fig9", "--seed", str(2**63)],
         f"--seed: expected an integer 0 to 2**63-1, got {2**63}"),
        (["quality", "omni-fig9", "--workers", "0"],
         "--workers: expected a whole number >= 1, got 0"),
        (["quality", "omni-fig9", "--workers", "1.5"],
         "--workers: expected a whole number >= 1, got '1.5'"),
        (["view", "--port", "http"], "--port: expected a port number 1 to 65534, got 'http'"),
    ],
)
def test_an_integer_flag_names_itself_the_value_and_the_range(tmp_path, capsys, argv, expected):
    with pytest.raises(SystemExit) as e:
        main([*argv, "--out", str(tmp_path)] if argv[0] != "view" else argv)
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert expected in err
    assert "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["run", "omni-fig9", "--out", ""], "--out '': expected a folder name"),
        (["demo", "--only", "omni-fig9", "--out", ""], "--out '': expected a folder name"),
        (["run", ""], "SCENARIO '': expected a scenario file"),
        (["quality", " "], "SCENARIO ' ': expected a scenario file"),
    ],
)
def test_an_empty_folder_or_scenario_is_refused_and_nothing_written(
    tmp_path, monkeypatch, capsys, argv, expected
):
    monkeypatch.chdir(tmp_path)  # an empty --out would have meant this folder
    err = _mistake(capsys, argv)
    assert expected in err
    assert list(tmp_path.iterdir()) == []


def test_a_run_into_a_run_s_folder_replaces_it_and_the_replay_reads_the_new_log(
    tmp_path, capsys
):
    from virtmech.view.replay import Replay

    out = tmp_path / "x"
    assert main(["run", "omni-fig10", "--duration", "0.2", "--out", str(out), "--quiet"]) == 0
    assert (out / "log.csv").is_file()
    capsys.readouterr()
    assert main(["run", "omni-fig11", "--duration", "0.3", "--out", str(out), "--quiet",
                 "--format", "parquet"]) == 0
    err = capsys.readouterr().err
    assert f"{out}: replacing the run written there before" in err
    assert f"{out}: removed the earlier run's log.csv" in err
    assert not (out / "log.csv").exists() and (out / "log.parquet").is_file()
    replay = Replay(out)
    assert replay.name == "omni-fig11"
    assert replay.duration == pytest.approx(0.3, abs=2e-3)


def test_the_replay_reads_the_log_run_json_names(tmp_path):
    from virtmech.view.replay import Replay

    out = tmp_path / "x"
    assert main(["run", "omni-fig10", "--duration", "0.2", "--out", str(out), "--quiet",
                 "--format", "parquet"]) == 0
    (out / "log.csv").write_text("t\n0\n")  # a stray file beside the run's own log
    assert Replay(out).duration == pytest.approx(0.2, abs=2e-3)
    # a run in parquet again removes no file but the earlier run's own log (replaced)
    assert main(["run", "omni-fig10", "--duration", "0.2", "--out", str(out), "--quiet",
                 "--format", "parquet"]) == 0
    assert (out / "log.csv").read_text() == "t\n0\n" and (out / "log.parquet").is_file()


def test_a_run_json_that_is_no_table_is_a_mistake_not_a_traceback(tmp_path, capsys):
    (tmp_path / "run.json").write_text("[]")
    (tmp_path / "log.csv").write_text("t\n0\n")
    assert main(["view", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "run.json cannot be read" in err and "Traceback" not in err


FAST_SHORT_PATH = """
[[intent]]
action = "follow"
start_s = 0.1
theta = [0.35, 0.36]
profile = "constant"
speed_m_s = 5
"""


@pytest.mark.parametrize("command", [["run"], ["quality"], ["sweep", "--grid", "seed=1,2"]])
def test_a_hand_plan_mistake_is_found_before_anything_is_written(tmp_path, capsys, command):
    # 0.8 mm of circle at 5 m/s: the [[intent]] is checked with the start pose it starts from,
    # before the output folder is made (it used to be made first, then left empty)
    bad = tmp_path / "in" / "bad.toml"
    bad.parent.mkdir()
    bad.write_text(sc.path_of("omni-fig10").read_text() + FAST_SHORT_PATH)
    out = tmp_path / "out"
    err = _mistake(capsys, [command[0], str(bad), *command[1:], "--out", str(out)])
    assert "intent[1].speed_m_s: value 5 is out of range" in err
    assert not out.exists()


def test_a_duration_flag_out_of_range_names_the_flag(tmp_path, capsys):
    err = _mistake(capsys, ["run", "omni-fig9", "--duration", "-1", "--out", str(tmp_path)])
    assert "--duration -1" in err and "duration_s: value -1" in err


def test_an_output_folder_that_cannot_be_made_names_the_flag(capsys):
    err = _mistake(capsys, ["run", "omni-fig9", "--out", "/proc/nope", "--quiet"])
    assert "--out /proc/nope: cannot create or write the output folder" in err


def test_a_folder_as_the_scenario_is_named(tmp_path, capsys):
    err = _mistake(capsys, ["run", str(tmp_path), "--quiet"])
    assert f"{tmp_path}: is a folder; expected a scenario file (.toml)" in err


def test_a_closed_stdout_is_not_an_error():
    # `virtmech scenarios | head -3`: stdout's reader gone before anything is written
    code = "import os\nr, w = os.pipe()\nos.close(r)\nos.dup2(w, 1)"
    p = _cli("scenarios", code=code)
    assert p.returncode == 141, p.stderr  # 128 + SIGPIPE, as the shell reports a pipe's end
    assert p.stderr == ""


def test_a_duration_shorter_than_one_control_period_is_rejected(tmp_path, capsys):
    bad = _scenario(tmp_path, "duration_s = 2.0", "duration_s = 1e-9")
    err = _mistake(capsys, ["run", str(bad), "--out", str(tmp_path / "o"), "--quiet"])
    assert f"{bad}: duration_s: value 1e-09 is out of range" in err
    assert "controller.period_s" in err


@pytest.mark.parametrize("name", ["../../escape", "/tmp/abs", "a/b", ".hidden", "a b"])
def test_a_name_that_is_not_a_plain_file_name_is_rejected(tmp_path, capsys, monkeypatch, name):
    bad = _scenario(tmp_path, 'name = "omni-fig10"', f"name = {name!r}".replace("'", '"'))
    monkeypatch.chdir(tmp_path)
    err = _mistake(capsys, ["run", str(bad), "--quiet"])
    assert f"{bad}: name: value {name!r} is not allowed; expected a plain file name" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"]  # nothing written


def test_every_mistake_of_a_file_is_reported_at_once(tmp_path, capsys):
    text = sc.path_of("omni-fig10").read_text()
    text = text.replace("normal = [0.0, 0.0, 1.0]", "normal = [0, 0, 0]")
    text = text.replace("[human]", "[human]\nmood = 1")
    text = text.replace("ramp_time_s = 0.02", "ramp_time_s = -1")
    bad = tmp_path / "three.toml"
    bad.write_text(text)
    err = _mistake(capsys, ["run", str(bad), "--out", str(tmp_path / "o"), "--quiet"])
    for key in ("mechanism.normal", "human.mood", "controller.ramp_time_s"):
        assert f"{bad}: {key}:" in err


# ---------------------------------------------------------------------------------------
# the log: streamed to log.csv block by block, the progress bar, the size warning


def test_the_log_streams_in_blocks_and_keeps_none_in_memory(tmp_path):
    from virtmech import sim

    s = sc.load("planar3r-fig9").with_overrides(duration_s=0.5)
    blocks = []
    r = sim.run(s, sink=lambda rows, cols: blocks.append(rows.copy()), keep_log=False,
                chunk_s=0.1)
    assert r.log.shape[0] == 0  # nothing kept: only the sink saw the rows
    assert max(len(b) for b in blocks) == 100 and len(blocks) == 6  # 501 rows, 100 at a time
    whole = sim.run(s)  # one block: the same rows
    assert np.array_equal(np.concatenate(blocks), whole.log)


def test_a_large_log_is_kept_in_a_file_not_in_memory(tmp_path, monkeypatch):
    from virtmech import sim
    from virtmech.sim import log as simlog

    monkeypatch.setattr(simlog, "LOG_IN_MEMORY_BYTES", 0)
    s = sc.load("planar3r-fig9").with_overrides(duration_s=0.2)
    r = sim.run(s, spill_dir=tmp_path, chunk_s=0.05)
    assert isinstance(r.log, np.memmap) and r.log.shape[0] == 201
    assert np.isfinite(r.col("dist")).all()
    assert list(tmp_path.iterdir()) == []  # removed at once, the mapping keeps it


def test_a_log_over_the_limit_is_warned_about_with_its_size(tmp_path, capsys, monkeypatch):
    import virtmech.sim.output as output

    monkeypatch.setattr(output, "LARGE_LOG_BYTES", 1000)
    assert main(["run", "planar3r-fig9", "--duration", "0.05", "--out", str(tmp_path),
                 "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "warning: planar3r-fig9: log.csv will be about" in err and "kB" in err


def test_progress_percentages_match_the_simulated_time(tmp_path, capsys, monkeypatch):
    import re

    import virtmech.progress as P

    monkeypatch.setattr(P, "LINE_INTERVAL_S", 0.0)  # a line per update
    assert main(["run", "planar3r-fig9", "--duration", "2.5", "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    shown = re.findall(r"(\d+)%\s+([\d.]+)/([\d.]+) s", err)
    assert shown and shown[-1][0] == "100"
    for pct, done, total in shown:
        assert int(pct) == pytest.approx(100 * float(done) / float(total), abs=1)
    wall = re.search(r"planar3r-fig9: 2.50 s simulated in ([\d.]+) (ms|s) wall", err)
    assert wall and float(wall.group(1)) > 0


def test_schema_prints_the_json_schema_of_the_format(capsys):
    assert main(["schema"]) == 0
    schema = json.loads(capsys.readouterr().out)
    assert schema["$schema"].endswith("2020-12/schema")
    props = schema["properties"]
    assert props["duration_s"]["exclusiveMinimum"] == 0 and props["duration_s"]["maximum"] == 3600
    assert props["physics"]["properties"]["rate_hz"]["default"] == 4000.0
    mech = {v["properties"]["type"]["const"]: v for v in props["mechanism"]["oneOf"]}
    assert set(mech) == {"PlanarArm", "PointPivot", "Probe", "LineGuide", "SurfaceProbe",
                         "CurveGuide", "HandlePath", "SerialChain"}
    assert "pivot" in mech["PlanarArm"]["required"]
    assert mech["PlanarArm"]["additionalProperties"] is False


def test_metrics_table_is_in_paper_order_and_says_na(capsys):
    from virtmech.cli import _print_metrics

    m = dict(
        time_to_1mm_s=0.2,
        dist_max_after_m=0.001,
        force_max_n=1.0,
        torque_fraction_max=0.5,
        passive_torque_max=0.0,
        energy_to_user_j=0.001,
        real_time_factor=30.0,
    )
    _print_metrics(
        {"omni-fig12": m, "omni-fig10": dict(m, time_to_1mm_s=float("nan")), "omni-fig9": m}
    )
    lines = capsys.readouterr().out.splitlines()
    assert [ln.split()[0] for ln in lines[2:5]] == ["omni-fig9", "omni-fig10", "omni-fig12"]
    assert lines[3].split()[1] == "n/a" and "nan" not in "".join(lines)
    assert lines[5] == "omni-fig10: n/a: the metric does not apply to that run"


def test_the_summary_tables_columns_are_named_for_what_they_show(capsys):
    from virtmech.cli import _print_metrics

    m = dict(time_to_1mm_s=0.25, dist_max_after_m=0.0009, force_max_n=1.5,
             torque_fraction_max=0.42, passive_torque_max=0.0, energy_to_user_j=-2e-6,
             real_time_factor=25.0)
    letter = dict(m, time_to_1mm_s=float("nan"), dist_max_after_m=float("nan"),
                  notes={"time_to_1mm_s": "n/a: the tip ended 2.47 mm from the curve",
                         "dist_max_after_m": "n/a: the tip ended 2.47 mm from the curve"})
    _print_metrics({"omni-fig11-passive": m, "omni-letter": letter})
    lines = capsys.readouterr().out.splitlines()
    head, units, row = lines[0], lines[1], lines[2]
    assert "passive" not in head  # the gimbal's torque is not the energy tank
    # each value ends where its heading and its unit end (right-aligned columns)
    for what, unit, value in (("tau unpowered", "[N·m]", "0"), ("work on user", "[mJ]", "0.00"),
                              ("max after", "[mm]", "0.900"), ("to 1 mm", "[s]", "0.250")):
        end = head.index(what) + len(what)
        assert units[end - len(unit) : end] == unit
        assert row[end - len(value) : end] == value and row[end - len(value) - 1] == " "
    assert "-0.00" not in row  # -2 uJ is shown as 0.00 mJ, without a sign
    # the letter's n/a cells say why, once, from its notes
    assert lines.count("omni-letter: n/a: the tip ended 2.47 mm from the curve") == 1
    text = "\n".join(lines[4:])
    assert "tau unpowered: passive_torque_max" in text and "eq. 8" in text
    assert "work on user: energy_to_user_j" in text and "omni-fig11-passive" in text


def test_run_holds_one_block_at_a_time_through_metrics_and_figures(tmp_path, monkeypatch):
    """virtmech run keeps no log in memory: the metrics and the figures read the run back
    from a scratch file block by block, no block longer than the run's chunk (20 cycles
    here), and give the metrics of the same run held in memory."""
    from virtmech import cli, sim
    from virtmech.sim import logio
    from virtmech.sim.output import metrics

    sizes = []
    read = logio.LogFile.blocks

    def spy(self, names, rows=None):
        for b in read(self, names, rows):
            sizes.append(len(b))
            yield b

    monkeypatch.setattr(logio.LogFile, "blocks", spy)
    s = sc.load("planar3r-fig9").with_overrides(duration_s=0.4)
    m = cli._run_one(s, tmp_path, None, False, chunk_s=0.02)
    assert sizes and max(sizes) <= 20 and sum(sizes) >= 401  # every row, 20 at a time
    whole = metrics(sim.run(s))
    for k in ("force_max_n", "dist_max_after_m", "energy_to_user_j", "torque_fraction_max"):
        assert m[k] == pytest.approx(whole[k], rel=1e-12, abs=1e-15), k
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "log.csv", "plane.png", "run.json", "time.png"
    ]  # the scratch file is gone


def test_parquet_log_holds_the_csv_log(tmp_path):
    pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    for fmt in ("csv", "parquet"):
        assert main(["run", "planar3r-fig9", "--duration", "0.3", "--format", fmt, "--out",
                     str(tmp_path / fmt), "--quiet"]) == 0
    table = pq.read_table(tmp_path / "parquet" / "log.parquet")
    a = np.column_stack([c.to_numpy() for c in table.columns])
    b = np.genfromtxt(tmp_path / "csv" / "log.csv", delimiter=",", skip_header=1)
    header = (tmp_path / "csv" / "log.csv").read_text().splitlines()[0].split(",")
    assert table.column_names == header and a.shape == b.shape == (301, len(header))
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)  # the CSV keeps 10 digits


def test_the_simulations_wall_time_leaves_out_writing_the_log():
    """The real-time factor is the simulation's: a slow sink (writing the log) is timed
    apart, in sink_time_s."""
    import time

    from virtmech import sim

    s = sc.load("planar3r-fig9").with_overrides(duration_s=0.2)
    t0 = time.perf_counter()
    r = sim.run(s, sink=lambda rows, cols: time.sleep(0.1), chunk_s=0.1)  # 3 blocks
    total = time.perf_counter() - t0
    assert r.sink_time_s >= 0.3
    assert r.wall_time_s + r.sink_time_s <= total
