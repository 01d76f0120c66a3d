"""Long runs in bounded memory: the metrics and the figures read the log block by block
(never whole), the figures of a long log are drawn from a min/max selection of rows, and
the log can be written as log.parquet (block by block) with the same numbers as log.csv.

The metrics are checked against the definitions of docs/scenarios.md written out here
over whole columns; the memory bound is checked on a scaled-down long run (blocks of 50
rows) by instrumenting the block reader and by tracemalloc's peak, which must not grow
with the length of the run."""

from __future__ import annotations

import json
import math
import tracemalloc

import numpy as np
import pytest

pytest.importorskip("mujoco")

import virtmech.scenarios as sc  # noqa: E402
import virtmech.sim as sim  # noqa: E402
from virtmech.cli import _run_one, main  # noqa: E402
from virtmech.sim import logio  # noqa: E402
from virtmech.sim.output import metrics  # noqa: E402
from virtmech.viz import figures  # noqa: E402


def reference_metrics(r) -> dict:
    """docs/scenarios.md's definitions over whole columns of the log in memory."""
    S = r.scenario.data
    t, d = r.col("t"), r.col("dist")
    out = np.flatnonzero(d > 1e-3)
    k0 = 0 if out.size == 0 else out[-1] + 1
    inside = np.flatnonzero(d <= 1e-3)
    F = np.column_stack([r.col("fx"), r.col("fy"), r.col("fz")])
    f = np.sqrt((F**2).sum(axis=1))
    wrench = np.column_stack([r.col(c) for c in ("fx", "fy", "fz", "mx", "my", "mz")])
    twist = np.column_stack([r.col(c) for c in ("vx", "vy", "vz", "wx", "wy", "wz")])
    status = r.col("status").astype(np.int64)
    return {
        "time_to_1mm_s": t[k0] if k0 < len(d) else math.nan,
        "first_within_1mm_s": t[inside[0]] if inside.size else math.nan,
        "dist_rms_after_m": np.sqrt(np.mean(d[k0:] ** 2)) if k0 < len(d) else math.nan,
        "dist_max_after_m": d[k0:].max() if k0 < len(d) else math.nan,
        "dist_max_m": d.max(),
        "penetration_max_m": max(0.0, -r.col("dist_normal").min())
        if r.info["mechanism"].get("unilateral")
        else math.nan,
        "force_max_n": f.max(),
        "force_rms_n": np.sqrt(np.mean(f**2)),
        "energy_to_user_j": S["controller"]["period_s"] * np.sum(wrench * twist),
        "faults": int(np.count_nonzero(status & 0xFF00)),
    }


#: metrics that are sums over the log: equal up to the order of the additions
SUMS = ("dist_rms_after_m", "force_rms_n", "energy_to_user_j")


def same(a: float, b: float, rel: float = 0.0) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return a == b if rel == 0.0 else a == pytest.approx(b, rel=rel, abs=1e-300)


@pytest.fixture(scope="module")
def shipped():
    return {name: sim.run(name) for name in sc.names()}


def test_metrics_are_the_definitions_on_every_shipped_scenario(shipped):
    for name, r in shipped.items():
        ref = reference_metrics(r)
        m = metrics(r)  # the log is one block
        many = metrics(r, block_rows=97)  # ~40 blocks
        for k, v in ref.items():
            # maxima, times and counts exactly; sums up to the order of the additions
            rel = 1e-12 if k in SUMS else 0.0
            assert same(m[k], float(v), rel), (name, k, m[k], v)
            assert same(many[k], float(v), rel), (name, k, many[k], v)
        for k in ("passive_torque_max", "torque_fraction_max", "motor_fraction_max", "faults"):
            assert many[k] == m[k], (name, k)


def test_time_to_1mm_across_a_block_boundary():
    """The last cycle outside 1 mm is the last row of a block: time_to_1mm_s is the first
    row of the next block, and the RMS after it covers only the rows after."""
    r = sim.run(sc.load("omni-fig10").with_overrides(duration_s=1.0))
    d = r.col("dist")
    k0 = int(np.flatnonzero(d > 1e-3)[-1]) + 1
    assert 10 < k0 < len(d) - 10
    for rows in (k0, k0 - 1, k0 + 1, 7):
        m = metrics(r, block_rows=rows)
        assert m["time_to_1mm_s"] == r.t[k0]
        assert m["dist_rms_after_m"] == pytest.approx(np.sqrt(np.mean(d[k0:] ** 2)), rel=1e-12)
        assert m["dist_max_after_m"] == d[k0:].max()


def test_short_logs_are_drawn_whole_and_long_ones_keep_every_bins_extremes(shipped):
    r = shipped["omni-fig11"]
    whole = figures.select_rows(r, "time")
    assert not whole.decimated and np.array_equal(whole.cols("t", "fx"), r.cols("t", "fx"))
    sel = figures.select_rows(r, "time", max_points=300, block_rows=64)
    assert sel.decimated and sel.n_cycles <= 300
    t = sel.t
    assert np.all(np.diff(t) > 0) and t[0] == r.t[0] and t[-1] == r.t[-1]
    f = np.linalg.norm(r.cols("fx", "fy", "fz"), axis=1)
    assert np.linalg.norm(sel.cols("fx", "fy", "fz"), axis=1).max() == f.max()
    assert sel.col("dist").max() == r.col("dist").max()
    assert sel.col("dist").min() == r.col("dist").min()
    # the activity and the unwrapped angles are those of every cycle, not of the selection
    rows = np.searchsorted(r.t, t)
    assert np.array_equal(sel.col("_activity"), whole.col("_activity")[rows])
    assert np.allclose(sel.col("_arm_pos_unwrapped"), np.unwrap(r.col("arm_pos_angle"))[rows])


class _Counted(logio.LogFile):
    """A LogFile whose reader records every block it hands out."""

    sizes: list[int] = []
    passes = 0

    def blocks(self, names, rows=None):
        type(self).passes += 1
        for b in super().blocks(names, rows):
            type(self).sizes.append(len(b))
            yield b


def _long_run(tmp_path, duration: float, monkeypatch, trace: bool = True) -> tuple[int, dict]:
    """A scaled-down long run through the whole of `virtmech run` (log.csv, run.json,
    metrics, both figures): blocks of 50 rows, figures of at most 600 rows. Returns
    tracemalloc's peak [bytes] over all that follows the simulation, and the metrics.
    (The simulation itself is traced in test_the_loop_holds_one_block_at_a_time; here
    tracing starts when it returns, because tracing np.savetxt's row-by-row formatting
    of log.csv would take most of the suite's time.)"""
    real_run = sim.run

    def run_then_trace(*args, **kwargs):
        result = real_run(*args, **kwargs)
        if trace:
            tracemalloc.start()
        return result

    monkeypatch.setattr(sim, "run", run_then_trace)
    s = sc.load("planar3r-fig9").with_overrides(duration_s=duration)
    try:
        m = _run_one(s, tmp_path / f"d{duration:g}", None, False, chunk_s=0.05)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return peak, m


def test_a_long_run_holds_one_block_at_a_time(tmp_path, monkeypatch):
    monkeypatch.setattr(logio, "LogFile", _Counted)
    monkeypatch.setattr(figures, "MAX_POINTS", 600)
    _long_run(tmp_path, 0.5, monkeypatch, trace=False)  # warm up: matplotlib's caches
    _Counted.sizes, _Counted.passes = [], 0
    short, _ = _long_run(tmp_path, 2.0, monkeypatch)
    _Counted.sizes, _Counted.passes = [], 0
    long_, m = _long_run(tmp_path, 10.0, monkeypatch)
    counted = list(_Counted.sizes), _Counted.passes
    # the short run again after the long one: the constant as the process now stands
    short = max(short, _long_run(tmp_path, 2.0, monkeypatch)[0])
    _Counted.sizes, _Counted.passes = counted
    rows = 10001
    # the metrics and the two figures each read the log once, 50 rows at a time
    assert _Counted.passes == 3
    assert max(_Counted.sizes) == 50 and sum(_Counted.sizes) == 3 * rows
    # the peak is a constant (the figures' canvas, matplotlib) plus about one block: the
    # same for a run five times shorter (8000 rows fewer: whole columns of the metrics'
    # 28 or the figures' 29 would be 1.8 MB each); what the process ran before moves the
    # constant by up to about 1 MB (a short run after the long one peaks higher than it),
    # so the short run counts as the higher of its peaks before and after the long one
    assert long_ < short + 1_500_000, (short, long_)
    assert m["sim_time_s"] == pytest.approx(10.0)
    # the scratch file is gone: only what the run writes is left
    names = {p.name for p in (tmp_path / "d10").iterdir()}
    assert names == {"log.csv", "run.json", "plane.png", "time.png"}
    cols = len(json.loads((tmp_path / "d10" / "run.json").read_text())["columns"])
    assert cols > 100 and long_ < rows * cols * 8  # less than the log as float64


def test_the_loop_holds_one_block_at_a_time():
    """sim.run with keep_log=False: the sink sees blocks of 50 rows and the run's traced
    peak does not grow with its length."""
    peaks, sizes = [], []
    for duration in (0.5, 2.0, 10.0):  # the first warms up
        s = sc.load("planar3r-fig9").with_overrides(duration_s=duration)
        tracemalloc.start()
        try:
            r = sim.run(s, sink=lambda rows, cols: sizes.append(len(rows)), keep_log=False,
                        chunk_s=0.05)
            peaks.append(tracemalloc.get_traced_memory()[1])
        finally:
            tracemalloc.stop()
        assert r.log.shape[0] == 0
    assert max(sizes) == 50 and sum(sizes) == 501 + 2001 + 10001
    assert peaks[2] < peaks[1] + 300_000, peaks  # 8000 rows more: 7 MB as a whole log


def test_parquet_log_equals_the_csv_log(tmp_path, capsys):
    pytest.importorskip("pyarrow")
    args = ["run", "omni-contact", "--duration", "0.6", "--quiet"]
    assert main([*args, "--out", str(tmp_path / "c")]) == 0
    assert main([*args, "--out", str(tmp_path / "p"), "--format", "parquet"]) == 0
    assert "wrote " + str(tmp_path / "p") + "/log.parquet" in capsys.readouterr().out
    assert not (tmp_path / "p" / "log.csv").exists()
    cc, cb = logio.read_csv_blocks(tmp_path / "c" / "log.csv", rows=256)
    pc, pb = logio.read_parquet_blocks(tmp_path / "p" / "log.parquet", rows=256)
    csv, par = np.concatenate(list(cb)), np.concatenate(list(pb))
    assert cc == pc and csv.shape == par.shape == (601, len(cc))
    # log.csv has 10 significant digits ('%.10g'), log.parquet the full float64
    rounded = np.array([[float(f"{x:.10g}") for x in row] for row in par])
    assert np.array_equal(rounded, csv, equal_nan=True)
    runs = [json.loads((tmp_path / d / "run.json").read_text()) for d in ("c", "p")]
    assert runs[1]["log_file"] == "log.parquet" and runs[0]["log_file"] == "log.csv"
    for k, v in runs[0]["metrics"].items():
        if k not in ("wall_time_s", "real_time_factor"):
            assert runs[1]["metrics"][k] == v, k


def test_parquet_is_written_one_row_group_per_block(tmp_path):
    pq = pytest.importorskip("pyarrow.parquet")
    s = sc.load("planar3r-fig9").with_overrides(duration_s=0.25)
    with logio.ParquetLog(tmp_path / "log.parquet") as out:
        r = sim.run(s, sink=out, chunk_s=0.1)
    f = pq.ParquetFile(str(tmp_path / "log.parquet"))
    assert [f.metadata.row_group(i).num_rows for i in range(f.num_row_groups)] == [100, 100, 51]
    table = f.read()
    assert np.array_equal(np.column_stack([table[c].to_numpy() for c in r.columns]), r.log)


def test_parquet_without_pyarrow_says_how_to_install_it(tmp_path, capsys, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "pyarrow", None)
    monkeypatch.setitem(sys.modules, "pyarrow.parquet", None)
    rc = main(["run", "planar3r-fig9", "--duration", "0.05", "--out", str(tmp_path / "x"),
               "--format", "parquet"])
    err = capsys.readouterr().err
    assert rc == 2
    assert "--format parquet" in err and "pip install 'virtmech[parquet]'" in err
    assert not (tmp_path / "x").exists()  # nothing was run


def test_a_large_parquet_log_is_warned_about(tmp_path, capsys, monkeypatch):
    pytest.importorskip("pyarrow")
    import virtmech.sim.output as output

    monkeypatch.setattr(output, "LARGE_LOG_BYTES", 1000)
    assert main(["run", "planar3r-fig9", "--duration", "0.05", "--out", str(tmp_path),
                 "--quiet", "--format", "parquet"]) == 0
    assert "warning: planar3r-fig9: log.parquet will be about" in capsys.readouterr().err
