"""virtmech sweep and the scenario overrides behind it (and behind virtmech run --set): the
override function sets dotted keys and names every mistake; a bad grid is exit status 2
before anything runs; the process pool's table has one row per point whose metrics are a
direct virtmech.sim.run's of the same scenario, changed by hand here; Ray, on a local Ray
this module starts, gives the same table."""

from __future__ import annotations

import copy
import itertools
import json
import math
import subprocess
import sys

import pytest

pytest.importorskip("mujoco")
pytest.importorskip("matplotlib")
pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")

import virtmech.scenarios as sc  # noqa: E402
from virtmech.cli import main  # noqa: E402
from virtmech.sim.output import METRICS  # noqa: E402
from virtmech.sweep import TIMING_COLUMNS, run_point  # noqa: E402

SCENARIO = "planar3r-fig9"
DURATION = 0.3
STIFFNESS = [100, 300]
LAWS = ["null_space", "under_actuated"]
GRID_ARGS = [
    "--grid",
    "human.stiffness=" + ",".join(map(str, STIFFNESS)),
    "--grid",
    "controller.law=" + ",".join(LAWS),
]


# ---------------------------------------------------------------------------------------
# the override function


def test_override_sets_dotted_keys_in_the_raw_table():
    s = sc.load(SCENARIO)
    before = copy.deepcopy(s.raw)
    raw = sc.apply_overrides(
        s.raw,
        {
            "controller.law": "under_actuated",
            "human.stiffness": 300,
            "intent.1.duration_s": 1.5,  # an array of tables, by position
            "intent[0].force": [0.0, 0.0, 1.0],  # as the validation messages write it
            "sensors.noise_rad": 1e-4,  # a table the file does not write
            "mechanism.pivot.1": 0.11,  # an array of numbers, by position
            "duration_s": 0.5,
        },
    )
    assert s.raw == before  # a copy: the scenario's raw table is untouched
    t = sc.validate(raw, s.source)
    assert t["controller"]["law"] == "under_actuated"
    assert t["human"]["stiffness"] == 300.0
    assert t["intent"][1]["duration_s"] == 1.5
    assert t["intent"][0]["force"] == [0.0, 0.0, 1.0]
    assert t["sensors"]["noise_rad"] == 1e-4
    assert t["mechanism"]["pivot"] == [0.3, 0.11, 0.0]
    assert t.duration_s == 0.5
    # the same through the Scenario, and override() in place
    assert s.with_keys({"human.stiffness": 300})["human"]["stiffness"] == 300.0
    raw2 = copy.deepcopy(s.raw)
    assert sc.override(raw2, "human.damping", 4) is raw2 and raw2["human"]["damping"] == 4


@pytest.mark.parametrize(
    "key, value, expected",
    [
        ("human.stifness", 300, ["human.stifness: unknown key in [human]", "stiffness"]),
        ("human.damping", -1, ["human.damping: value -1", "expected a number >= 0"]),
        ("controller.law", "eq11", ["controller.law: value 'eq11'", "expected one of 'auto'"]),
        ("mechanism.pivot", [0.3, 0.1], ["mechanism.pivot: expected 3 numbers", "[0.3, 0.1]"]),
        ("intent.5.force", [0, 0, 1], ["intent.5.force: no entry 5 in intent", "0 to 1"]),
        ("intent.x", 1, ["intent.x: intent is an array", "expected a position 0 to 1"]),
        ("duration_s.x", 1, ["duration_s.x: duration_s is a float (3.0)", "expected a key"]),
        ("human.0", 1, ["human.0: human is a table, not an array", "expected a key name"]),
        ("controller.kp.0", 300, ["controller.kp.0: controller.kp is not written", "no entry 0"]),
        ("human..x", 1, ["'human..x': not a scenario key", "expected a dotted path"]),
    ],
)
def test_override_names_the_key_the_value_and_what_was_expected(key, value, expected):
    s = sc.load(SCENARIO)
    with pytest.raises(sc.ScenarioError) as e:
        s.with_keys({key: value})
    msg = str(e.value)
    for part in expected:
        assert part in msg, (part, msg)


def test_values_are_toml_split_at_top_level_commas():
    assert sc.split_values("[0,0,0],[0.01,0,0]") == ["[0,0,0]", "[0.01,0,0]"]
    assert sc.split_values('"a,b",c') == ['"a,b"', "c"]
    assert sc.parse_value("300") == 300 and isinstance(sc.parse_value("300"), int)
    assert sc.parse_value("1e-4") == 1e-4
    assert sc.parse_value("true") is True
    assert sc.parse_value("[0.3, 0.1, 0]") == [0.3, 0.1, 0]
    assert sc.parse_value("null_space") == "null_space"  # a bare word: a string
    assert sc.parse_value('"null_space"') == "null_space"
    assert sc.parse_assignment("controller.kp=[1,2,3,4,5,6]") == (
        "controller.kp",
        [1, 2, 3, 4, 5, 6],
    )
    grid, errors = sc.parse_grid(["human.stiffness=300,500", "m.p=[0,0,0],[0.01,0,0],[1,2"])
    assert grid == {"human.stiffness": [300, 500], "m.p": [[0, 0, 0], [0.01, 0, 0]]}
    assert len(errors) == 1 and "--grid m.p=[1,2: '[1,2' is not a TOML value" in errors[0]


# ---------------------------------------------------------------------------------------
# mistakes on the command line: exit status 2, every one at once, nothing run


def test_a_bad_grid_is_exit_2_with_every_mistake_and_nothing_run(tmp_path):
    out = tmp_path / "sw"
    p = subprocess.run(
        [sys.executable, "-m", "virtmech", "sweep", SCENARIO, "--out", str(out), "--quiet"]
        + ["--grid", "human.stifness=100,300", "--grid", "controller.law=null_space,eq11"]
        + ["--grid", "human.damping=-1,3", "--grid", "intent.5.force=[0,0,1]"]
        + ["--grid", "mechanism.pivot=[0.3,0.1,0],[1,2"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 2, p.stderr
    err = p.stderr
    assert "Traceback" not in err
    assert err.startswith("virtmech sweep: 5 mistakes:")
    assert "--grid human.stifness=100,300: " in err and "unknown key in [human]" in err
    assert "--grid controller.law=eq11: " in err and "value 'eq11' is not allowed" in err
    assert "--grid human.damping=-1: " in err and "expected a number >= 0" in err
    assert "--grid intent.5.force=[0, 0, 1]: intent.5.force: no entry 5 in intent" in err
    assert "--grid mechanism.pivot=[1,2: '[1,2' is not a TOML value" in err
    assert not out.exists()


def test_points_whose_keys_conflict_are_named_before_any_run(tmp_path, capsys):
    # each value is fine alone; 3000 Hz physics is not a multiple of a 4 kHz control rate
    argv = ["sweep", SCENARIO, "--out", str(tmp_path / "sw"), "--quiet"]
    argv += ["--grid", "physics.rate_hz=4000,3000", "--grid", "controller.period_s=0.001,0.00025"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert "--grid point 3 (physics.rate_hz=3000, controller.period_s=0.00025): " in err
    assert "physics.rate_hz: value 3000 is out of range" in err
    assert not (tmp_path / "sw").exists()


def test_ray_missing_says_how_to_install_it(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray: ImportError
    argv = ["sweep", SCENARIO, "--backend", "ray", "--out", str(tmp_path / "sw"), *GRID_ARGS]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert err.startswith("virtmech sweep: --backend ray: Ray is not installed")
    assert 'pip install "virtmech[cluster]"' in err
    assert not (tmp_path / "sw").exists()


def test_run_set_changes_the_scenario(tmp_path, capsys):
    out = tmp_path / "r"
    argv = ["run", SCENARIO, "--duration", "0.05", "--out", str(out), "--quiet"]
    argv += ["--set", "human.stiffness=321", "--set", "controller.law=under_actuated"]
    assert main(argv) == 0
    run = json.loads((out / "run.json").read_text())
    assert run["scenario"]["human"]["stiffness"] == 321.0
    assert run["scenario"]["controller"]["law"] == "under_actuated"
    capsys.readouterr()
    argv = ["run", SCENARIO, "--out", str(out), "--set", "human.stiffness=-1", "--set", "x"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--set human.stiffness=-1: " in err and "human.stiffness: value -1" in err
    assert "--set 'x': expected KEY=VALUE" in err


# ---------------------------------------------------------------------------------------
# the table: the process pool against direct runs, and Ray against the process pool


def _direct_metrics(stiffness, law) -> dict:
    """The metrics of a direct virtmech.sim.run, the scenario changed by hand (not by the
    override function under test)."""
    from virtmech import sim
    from virtmech.sim.output import metrics

    raw = copy.deepcopy(sc.load(SCENARIO).raw)
    raw["duration_s"] = DURATION
    raw["human"]["stiffness"] = stiffness
    raw["controller"]["law"] = law
    return metrics(sim.run(sc.validate(raw, "direct")))


def _value(v):
    return None if isinstance(v, float) and math.isnan(v) else v


@pytest.fixture(scope="module")
def process_sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep") / "process"
    argv = ["sweep", SCENARIO, "--duration", str(DURATION), "--out", str(out), "--quiet"]
    assert main([*argv, *GRID_ARGS, "--workers", "2"]) == 0
    return out


def test_the_process_pool_table_has_a_row_per_point_equal_to_direct_runs(process_sweep):
    out = process_sweep
    table = pq.read_table(out / "sweep.parquet")
    points = list(itertools.product(STIFFNESS, LAWS))  # the last key varies fastest
    assert table.num_rows == len(points)
    head = ["point", "human.stiffness", "controller.law", "ok", "error"]
    assert table.column_names[: len(head)] == head
    assert set(METRICS) <= set(table.column_names)
    rows = table.to_pylist()
    for k, ((stiffness, law), row) in enumerate(zip(points, rows)):
        assert row["point"] == k
        assert (row["human.stiffness"], row["controller.law"]) == (stiffness, law)
        assert row["ok"] is True and row["error"] is None
        ref = _direct_metrics(stiffness, law)
        for name in METRICS:
            if name not in TIMING_COLUMNS:
                assert row[name] == _value(ref[name]), (k, name)
        for name, note in ref["notes"].items():
            assert row[f"notes.{name}"] == note
    # the points differ (the keys matter), and the sweep wrote its record and figure
    assert len({r["dist_max_m"] for r in rows}) == len(points)
    info = json.loads((out / "sweep.json").read_text())
    assert info["grid"] == {"human.stiffness": STIFFNESS, "controller.law": LAWS}
    assert info["backend"] == "process" and info["points"] == 4 and info["failed"] == 0
    assert "mujoco" in info["versions"] and "pyarrow" in info["versions"]
    assert (out / "sweep.png").stat().st_size > 10_000


def test_the_metrics_sink_gives_the_metrics_of_the_log():
    # a unilateral probe (penetration applies) and a planar arm, each against metrics() of
    # the same run's log kept in memory
    from virtmech import sim
    from virtmech.sim.output import MetricsSink, metrics

    for name in ("omni-contact", SCENARIO):
        s = sc.load(name).with_overrides(duration_s=0.2)
        sink = MetricsSink(s)
        result = sim.run(s, sink=sink)
        got, ref = sink.metrics(result), metrics(result)
        assert got["notes"] == ref["notes"]
        for k in METRICS:
            assert _value(got[k]) == _value(ref[k]), (name, k)


def test_sweep_from_python_with_a_progress_bar(capsys, monkeypatch):
    import virtmech.progress as P
    from virtmech.sweep import sweep

    monkeypatch.setattr(P, "LINE_INTERVAL_S", 0.0)  # stderr is no terminal: a line per run

    grid = {"sensors.noise_rad": [0.0, 1e-3]}  # a table the file does not write
    table = sweep(SCENARIO, grid, workers=1, duration=0.05, overrides={"seed": 3})
    assert table.column("sensors.noise_rad").to_pylist() == [0.0, 1e-3]
    assert table.column("ok").to_pylist() == [True, True]
    dist = table.column("dist_max_m").to_pylist()
    assert dist[0] != dist[1]  # the noise reached the runs
    err = capsys.readouterr().err
    assert "planar3r-fig9 sweep  100%  2/2 runs" in err and "\r" not in err


#: a long run first: with two workers the short ones end before it
ORDER_GRID = {"duration_s": [2.0, 0.02, 0.04, 0.02]}


def _check_grid_order(table) -> None:
    assert table.column("point").to_pylist() == [0, 1, 2, 3]
    assert table.column("duration_s").to_pylist() == ORDER_GRID["duration_s"]
    assert table.column("sim_time_s").to_pylist() == pytest.approx(ORDER_GRID["duration_s"])


def test_rows_are_in_grid_order_whichever_run_ends_first():
    from virtmech.sweep import sweep

    _check_grid_order(sweep(SCENARIO, ORDER_GRID, workers=2, progress=False))


def test_a_run_that_fails_is_a_row_not_lost():
    s = sc.load(SCENARIO).with_overrides(duration_s=0.01)
    s.data["mechanism"]["length"] = -1.0  # past the checks: fails when the run starts
    r = run_point(s)
    assert r["ok"] is False and r["metrics"] is None
    assert "mechanism" in r["error"]
    from virtmech.sweep import _table

    table = _table(pa, [{"k": 1}], [r])
    row = table.to_pylist()[0]
    assert row["ok"] is False and "mechanism" in row["error"]
    assert all(row[m] is None for m in METRICS)


@pytest.fixture(scope="module")
def local_ray():
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


def test_ray_gives_the_same_table_as_the_process_pool(local_ray, process_sweep, tmp_path):
    out = tmp_path / "ray"
    argv = ["sweep", SCENARIO, "--duration", str(DURATION), "--out", str(out), "--quiet"]
    assert main([*argv, *GRID_ARGS, "--backend", "ray"]) == 0
    assert local_ray.is_initialized()  # the test's Ray, used and left running
    a = pq.read_table(process_sweep / "sweep.parquet")
    b = pq.read_table(out / "sweep.parquet")
    assert a.column_names == b.column_names
    a, b = a.drop_columns(list(TIMING_COLUMNS)), b.drop_columns(list(TIMING_COLUMNS))
    assert a.equals(b, check_metadata=True)
    assert json.loads((out / "sweep.json").read_text())["backend"] == "ray"
    from virtmech.sweep import sweep

    _check_grid_order(sweep(SCENARIO, ORDER_GRID, backend="ray", progress=False))
