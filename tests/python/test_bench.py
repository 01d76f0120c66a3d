"""`virtmech bench`: its report's schema, real allocation counts, and its NumPy column (the
reference cycle of tests/reference, found from a source checkout). Timing figures are
reported, never asserted."""

from __future__ import annotations

import json
import sys
import types
from pathlib import Path

import numpy as np
import pytest

from virtmech import bench

CASE_FIELDS = {
    "name": str,
    "median_us": float,
    "p99_us": float,
    "p999_us": float,
    "max_us": float,
    "allocations": int,
    "python_step_median_us": float,
}
NUMPY_FIELDS = ("numpy_median_us", "speedup_vs_numpy", "numpy_max_torque_difference")


@pytest.fixture(scope="module")
def report():
    """One quick `virtmech bench --json` run (small cycle counts, no NumPy, no simulation)."""
    return bench.collect(cycles=2000, python_cycles=200, numpy_cycles=0, simulation=False)


def test_harness_is_installed_with_the_package():
    path = bench.harness_path()
    assert path is not None and path.is_file()


def test_json_report_has_the_issue_schema(report):
    assert isinstance(report["machine"], dict) and report["machine"]["cpu"]
    assert [c["name"] for c in report["cases"]] == list(bench.CASES)
    for case in report["cases"]:
        for field, kind in CASE_FIELDS.items():
            value = case[field]
            assert isinstance(value, kind), (case["name"], field, value)
            if kind is float:
                assert np.isfinite(value) and value > 0.0, (case["name"], field, value)
        for field in NUMPY_FIELDS:  # skipped on request, and said so
            assert case[field] is None
    assert "skipped" in report["numpy_note"]
    assert report["simulation"] == []
    json.loads(json.dumps(report))  # serialisable as is


def test_cycle_allocates_nothing_in_every_case(report):
    assert report["allocation_counter"]["self_test_passed"] is True
    for case in report["cases"]:
        assert case["allocations"] == 0, case["name"]


def test_the_numpy_reference_has_every_case():
    import reference

    assert set(reference.CASES) == set(bench.CASES)


def test_the_installed_bench_skips_the_numpy_column_with_a_note():
    # the package ships no NumPy reference: without one passed in, the column is empty
    r = bench.collect(cycles=200, python_cycles=20, numpy_cycles=10, simulation=False,
                      cases=["omni+probe"])
    assert r["numpy_note"] == bench.NO_REFERENCE
    assert all(r["cases"][0][f] is None for f in NUMPY_FIELDS)


def test_the_package_imports_nothing_from_the_tests():
    # nothing shipped depends on the tests: no module of the package names tests/reference
    root = Path(bench.__file__).resolve().parent
    for path in root.rglob("*.py"):
        text = path.read_text(encoding="utf-8")
        assert "import reference" not in text and '"tests"' not in text, path


@pytest.mark.slow
def test_numpy_column_times_the_reference_and_gives_the_core_torques():
    # the placements of omni+probe and omni+planar_arm are closed forms in the core (always
    # converged): the reference, converged on its own, gives the same torques
    import reference

    r = bench.collect(cycles=1000, python_cycles=30, numpy_cycles=30, simulation=False,
                      cases=["omni+probe", "omni+planar_arm"], reference=reference)
    assert "numpy_note" not in r
    for case in r["cases"]:
        assert case["numpy_cycles"] == 30
        assert case["numpy_median_us"] > 0.0 and case["speedup_vs_numpy"] > 0.0
        assert case["numpy_max_torque_difference"] < 1e-9, case["name"]


def test_main_prints_one_json_object(capsys):
    rc = bench.main(["--json", "--cycles", "500", "--python-cycles", "50", "--numpy-cycles", "0",
                     "--case", "omni+probe", "--no-sim"])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    assert [c["name"] for c in out["cases"]] == ["omni+probe"]
    assert out["simulation"] == []


def test_main_prints_a_table(capsys):
    rc = bench.main(["--cycles", "500", "--python-cycles", "50", "--numpy-cycles", "0",
                     "--case", "planar3r+planar_arm", "--no-sim"])
    assert rc == 0
    text = capsys.readouterr().out
    assert "planar3r+planar_arm" in text and "median" in text
    assert "NumPy column skipped" in text


def test_each_cases_line_is_shown_as_soon_as_it_is_measured(monkeypatch):
    events = []
    measure = bench.python_step

    def python_step(case, cycles):
        events.append(("measure", case.name))
        return measure(case, cycles)

    monkeypatch.setattr(bench, "python_step", python_step)
    names = ["omni+probe", "planar3r+planar_arm"]
    r = bench.collect(cycles=500, python_cycles=20, numpy_cycles=0, simulation=False,
                      cases=names, show=lambda line: events.append(("line", line)))
    shown = {n: next(i for i, (k, v) in enumerate(events) if k == "line" and v.startswith(n))
             for n in names}
    measured = {n: events.index(("measure", n)) for n in names}
    heading = next(i for i, (k, v) in enumerate(events) if k == "line" and "median" in v)
    assert heading < measured[names[0]] < shown[names[0]] < measured[names[1]] < shown[names[1]]
    lines = [v for k, v in events if k == "line"]
    assert "\n".join(lines) == bench.format_table(r)  # the same table, line by line


def test_the_table_says_what_its_max_column_measures(capsys):
    assert bench.main(["--cycles", "500", "--python-cycles", "20", "--numpy-cycles", "0",
                       "--case", "omni+probe", "--no-sim"]) == 0
    text = capsys.readouterr().out
    assert "(max: the slowest single cycle of the 500 timed" in text
    assert "preempting" in text and "p99.9 is the cycle's cost" in text


def test_with_json_the_lines_go_to_stderr_and_the_object_to_stdout(capsys):
    assert bench.main(["--json", "--cycles", "500", "--python-cycles", "20",
                       "--numpy-cycles", "0", "--case", "omni+probe", "--no-sim"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["cases"][0]["name"] == "omni+probe"
    assert any(line.startswith("omni+probe") for line in err.splitlines())


def test_main_rejects_a_bad_cycle_count():
    with pytest.raises(SystemExit):
        bench.main(["--cycles", "0"])


@pytest.mark.parametrize("flag, most", [("--cycles", "100,000,000"),
                                        ("--python-cycles", "5,000,000"),
                                        ("--numpy-cycles", "1,000,000")])
def test_a_cycle_count_beyond_memory_is_refused_naming_the_flag(capsys, flag, most):
    with pytest.raises(SystemExit) as e:  # before anything is allocated or run
        bench.main([flag, "10000000000", "--case", "omni+probe", "--no-sim"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert f"{flag}: expected" in err and f"to {most}" in err and "got 10000000000" in err
    assert "Traceback" not in err


def test_simulation_figures_are_simulated_over_wall_seconds(monkeypatch):
    # a stand-in simulation: 2 s simulated (2001 cycles) in 0.07, 0.04 and 0.05 s of wall
    # time, of which 12, 20 and 25 ms in the controller and 4, 2 and 1 ms deriving columns
    # (on their own thread; the loop waited 1, 0.5 and 0.2 ms for them),
    # each run followed by MuJoCo alone in 0.05, 0.02 and 0.04 s: ratios 1.4, 2.0 and 1.25,
    # the figures are the pair of median ratio's (the first run's; the medians of each side,
    # 0.05 / 0.04, would give 1.25), its parts that run's
    scen = types.ModuleType("virtmech.scenarios")
    scen.names = lambda: ["omni_probe_table"]
    scen.load = lambda name: {"name": name}
    sim = types.ModuleType("virtmech.sim")
    walls = iter([(0.07, 0.012, 0.004, 0.001), (0.04, 0.02, 0.002, 0.0005),
                  (0.05, 0.025, 0.001, 0.0002)])
    events = []  # ("run", result) and ("alone", result, repeats), in order

    def run(scenario, seed=None, progress=False):
        wall, control, derived, wait = next(walls)
        result = types.SimpleNamespace(sim_time_s=2.0, wall_time_s=wall, control_time_s=control,
                                       derived_time_s=derived, derived_wait_s=wait,
                                       n_cycles=2001,
                                       info={"physics": {"engine": "compiled"}})
        events.append(("run", result))
        return result

    sim.run = run
    monkeypatch.setitem(sys.modules, "virtmech.scenarios", scen)
    monkeypatch.setitem(sys.modules, "virtmech.sim", sim)
    import virtmech

    monkeypatch.setattr(virtmech, "scenarios", scen, raising=False)
    monkeypatch.setattr(virtmech, "sim", sim, raising=False)
    alone = iter([0.05, 0.02, 0.04])

    def mujoco_alone(result, repeats):
        events.append(("alone", result, repeats))
        return next(alone)

    figures, note = bench.simulation_figures(repeats=3, mujoco_alone=mujoco_alone)
    assert note == ""
    # each run followed by one replay of that run's own result
    assert [e[0] for e in events] == ["run", "alone"] * 3
    for k in range(0, 6, 2):
        assert events[k + 1][1] is events[k][1] and events[k + 1][2] == 1
    figures[0].pop("setup_and_run_wall_time_s")  # wall time around the stand-in: not asserted
    assert figures == [{"scenario": "omni_probe_table",
                        "realtime_factor": pytest.approx(2.0 / 0.07), "sim_time_s": 2.0,
                        "wall_time_s": 0.07, "engine": "compiled",
                        "mujoco_alone_s": 0.05, "overhead_vs_mujoco": pytest.approx(1.4),
                        "control_time_s": pytest.approx(0.012),
                        "control_us_per_cycle": pytest.approx(0.012 / 2001 * 1e6),
                        "derived_time_s": pytest.approx(0.004),
                        "derived_wait_s": pytest.approx(0.001),
                        "loop_overhead_vs_mujoco": pytest.approx((0.07 - 0.012 - 0.001) / 0.05),
                        "runs": 3}]


def test_mujoco_alone_replays_once_untimed_then_times_each_replay(monkeypatch):
    # a real run's replay, MuJoCo's rollout and the clock observed: the first replay is not
    # timed, the figure is the median of the timed ones (here 1 and 3 clock units: 2)
    pytest.importorskip("mujoco")
    from mujoco import rollout

    from virtmech import scenarios, sim

    result = sim.run(scenarios.load("planar3r-fig10"), seed=0, progress=False)
    events = []
    real_rollout = rollout.rollout

    def counted_rollout(*args, **kwargs):
        events.append("rollout")
        return real_rollout(*args, **kwargs)

    clock = iter([0.0, 1.0, 10.0, 13.0])

    def fake_clock():
        events.append("clock")
        return next(clock)

    monkeypatch.setattr(rollout, "rollout", counted_rollout)
    monkeypatch.setattr(bench.time, "perf_counter", fake_clock)
    assert bench.mujoco_alone_s(result, 2) == 2.0
    assert events == ["rollout", "clock", "rollout", "clock", "clock", "rollout", "clock"]
