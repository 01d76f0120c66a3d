"""The one runner: a scenario simulated (virtmech.sim.run, on the rig virtmech.builder
builds) into what the caller asks for: a folder (the log written as it goes, run.json, the
figures), the run's metrics, named columns of the log kept in memory. ``virtmech run`` and
``demo`` write folders, ``sweep`` keeps metrics (`run_point`, the task of its pool),
``quality`` keeps columns; many runs go through virtmech.pool.

    outcome = run_scenario("omni-fig9", out="out/omni-fig9")        # files + metrics
    outcome = run_scenario(s, keep=("t", "px", "fx"), metrics=False)   # columns only
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import UserError

__all__ = ["RunOutcome", "run_point", "run_scenario"]


@dataclass
class RunOutcome:
    """What a run gave: its metrics (virtmech.sim.output.metrics; None if not asked), the
    columns asked for, and the SimResult (its log only where the columns were asked)."""

    metrics: dict | None
    columns: dict[str, np.ndarray] = field(default_factory=dict)
    result: Any = None


def _size(n: float) -> str:
    for unit in ("bytes", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1000
    raise AssertionError  # pragma: no cover


def _warn_large(scenario, fmt: str) -> None:
    from .sim.output import LARGE_LOG_BYTES, estimate_log_bytes

    S = scenario.data
    rows = int(round(S["duration_s"] / S["controller"]["period_s"])) + 1
    cols = 140  # about: the exact count depends on the device and the mechanism
    size = estimate_log_bytes(rows, cols, fmt)
    if size > LARGE_LOG_BYTES:
        print(
            f"virtmech: warning: {scenario.name}: log.{fmt} will be about {_size(size)} "
            f"({rows:,} rows of about {cols} columns, {scenario.duration_s:g} s at "
            f"{1 / S['controller']['period_s']:g} Hz)",
            file=sys.stderr,
        )


def _to_folder(scenario, out: Path, seed, progress: bool, fmt: str, chunk_s) -> RunOutcome:
    """The log (log.csv or log.parquet) written block by block as the run goes, run.json,
    the figures. The metrics and the figures read the log back block by block from a
    scratch file of the columns they need (removed at the end), so memory stays about one
    block (`chunk_s` of simulated time) however long the run."""
    from . import sim
    from .builder import make_device
    from .sim.logio import CsvLog, LogFile, ParquetLog, Tee
    from .sim.output import metric_columns, metrics, write_run
    from .viz import write_figures
    from .viz.figures import FIGURE_COLUMNS

    _warn_large(scenario, fmt)
    name = f"log.{fmt}"
    n = make_device(scenario.data["device"]).dof
    keep = list(dict.fromkeys(metric_columns(n) + FIGURE_COLUMNS))
    writer = ParquetLog(out / name) if fmt == "parquet" else CsvLog(out / name)
    with writer, LogFile(out, keep) as scratch:
        result = sim.run(
            scenario, seed=seed, progress=progress, sink=Tee(writer, scratch), keep_log=False,
            chunk_s=chunk_s,
        )
        result.source = scratch  # the metrics and the figures read it block by block
        result.info["log_file"] = name
        m = metrics(result)
        write_run(result, out, log=False, metrics=m)
        write_figures(result, out)
    return RunOutcome(metrics=m, result=result)


def run_scenario(
    scenario,
    *,
    seed: int | None = None,
    progress: bool = False,
    out: str | Path | None = None,
    fmt: str = "csv",
    chunk_s: float | None = None,
    keep: tuple[str, ...] | list[str] | None = None,
    metrics: bool = True,
) -> RunOutcome:
    """Runs `scenario` (a Scenario, a shipped name or a TOML path; `seed` overrides its
    seed). out: a folder to write (it must exist: the caller checks the path the user gave);
    fmt the log's format there (csv or parquet). keep: the names of the log's columns to
    return in memory (the log is then kept during the run). metrics: compute them (always
    with `out`). progress: a bar on stderr."""
    from . import scenarios as sc
    from . import sim
    from .sim.log import CHUNK_S
    from .sim.output import MetricsSink

    if not isinstance(scenario, sc.Scenario):
        scenario = sc.load(scenario)
    chunk_s = CHUNK_S if chunk_s is None else chunk_s
    if out is not None:
        return _to_folder(scenario, Path(out), seed, progress, fmt, chunk_s)
    sink = MetricsSink(scenario) if metrics else None
    result = sim.run(
        scenario, seed=seed, progress=progress, sink=sink, keep_log=bool(keep), chunk_s=chunk_s
    )
    columns = {c: result.col(c) for c in keep} if keep else {}
    return RunOutcome(sink.metrics(result) if sink else None, columns, result)


def run_point(scenario) -> dict[str, Any]:
    """Runs one point of a sweep (a validated Scenario) keeping no log; returns {"ok",
    "error", "metrics"}: a run that fails is reported, not raised (the pool's task)."""
    try:
        return {"ok": True, "error": None, "metrics": run_scenario(scenario).metrics}
    except Exception as e:  # recorded in the table: one failed point must not end the sweep
        msg = str(e) if isinstance(e, UserError) else f"{type(e).__name__}: {e}"
        return {"ok": False, "error": msg, "metrics": None}
