"""Parameter sweeps: one scenario run over a grid of overrides, in parallel, into one table
(docs/sweeps.md).

    >>> from virtmech.sweep import sweep
    >>> table = sweep("planar3r-fig9", {"human.stiffness": [100, 300]}, duration=0.3)

Each point of the grid (the Cartesian product of the keys' values, the last key varying
fastest) is the scenario with those dotted keys set (virtmech.scenarios.override), checked
before any run starts; every run is a ``virtmech.sim.run`` in a worker process (one point
after another in each) that keeps no log (the metrics are accumulated as the log goes by,
virtmech.sim.output.MetricsSink). The runs go to a local process pool (backend="process",
the default) or to Ray (backend="ray"; ``pip install "virtmech[cluster]"``). The table has
one row per point, in grid order whichever run ends first: ``point``, one column per key,
``ok`` and ``error`` (a run that fails is a row with its message, not lost), then every
metric of ``virtmech.sim.output.metrics`` (``notes`` flattened as ``notes.<metric>``).
Both backends give the same table but for the wall-clock columns (TIMING_COLUMNS).
"""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Mapping, Sequence
from typing import Any

from .errors import UserError
from .pool import BACKENDS, TaskFailure, require_ray, run_tasks
from .runner import run_point
from .scenarios.overrides import value_text

__all__ = [
    "BACKENDS",
    "TIMING_COLUMNS",
    "check_backend",
    "check_grid",
    "format_table",
    "grid_points",
    "run_grid",
    "run_point",
    "sweep",
    "write_figure",
    "write_sweep",
]

#: the columns that measure wall-clock time and so differ from one sweep to the next
TIMING_COLUMNS = ("wall_time_s", "real_time_factor")
#: the metrics the figures and the printed table show, in this order
MAIN_METRICS = (
    "time_to_1mm_s",
    "dist_max_m",
    "dist_rms_after_m",
    "force_max_n",
    "torque_fraction_max",
    "energy_to_user_j",
)


def _load(scenario):
    from . import scenarios as sc

    return scenario if isinstance(scenario, sc.Scenario) else sc.load(scenario)


def grid_points(grid: Mapping[str, Sequence[Any]]) -> list[dict[str, Any]]:
    """The points of a grid {key: values}: the Cartesian product, in the keys' order with
    the last key varying fastest; each point a {key: value}."""
    keys = list(grid)
    return [dict(zip(keys, combo)) for combo in itertools.product(*(grid[k] for k in keys))]


def check_grid(
    scenario, grid: Mapping[str, Sequence[Any]], flag: str = "--grid", errors: Sequence[str] = ()
) -> list:
    """Every point of the grid as a validated Scenario, each also built (device, mechanism,
    controller, start pose: virtmech.builder.preflight) so that no run starts on a point
    that would fail its checks. Raises one UserError listing every mistake (after
    `errors`, those found before, e.g. values that could not be read): first each value of
    each key on its own (``--grid KEY=VALUE: <file>: <key>: <what was expected>``; values
    of a key with the same mistake in one line), then, only if they all pass, the points
    whose keys conflict."""
    from . import scenarios as sc
    from .builder import preflight

    base = _load(scenario)
    malformed = [
        f"{flag} {key}: expected a list of one or more values, got {values!r}"
        for key, values in grid.items()
        if isinstance(values, (str, bytes)) or not isinstance(values, Sequence) or not values
    ]
    if malformed:
        raise UserError(*errors, *malformed)
    errors = list(errors)

    def check(point: dict[str, Any]) -> tuple[Any, list[str]]:
        try:
            s = base.with_keys(point)
            preflight(s)
            return s, []
        except sc.ScenarioError as e:
            return None, list(e.messages)

    single: dict[tuple[str, int], Any] = {}
    for key, values in grid.items():
        bad: dict[str, list[str]] = {}  # a mistake -> the values that make it
        for i, v in enumerate(values):
            s, msgs = check({key: v})
            single[key, i] = s
            for m in dict.fromkeys(msgs):
                bad.setdefault(m, []).append(value_text(v))
        errors += [f"{flag} {key}={','.join(vs)}: {m}" for m, vs in bad.items()]
    if errors:
        raise UserError(*errors)
    points = grid_points(grid)
    if len(grid) == 1:  # each point is one of the values checked
        key = next(iter(grid))
        return [single[key, i] for i in range(len(points))]
    out = []
    for k, point in enumerate(points):
        s, msgs = check(point)
        where = ", ".join(f"{key}={value_text(v)}" for key, v in point.items())
        errors += [f"{flag} point {k} ({where}): {m}" for m in msgs]
        out.append(s)
    if errors:
        raise UserError(*errors)
    return out


def _require_pyarrow():
    try:
        import pyarrow as pa
    except ImportError:
        raise UserError(
            "virtmech sweep: the table needs pyarrow, which is not installed; the [sim] extra "
            "brings it: pip install 'virtmech[sim]' (or pip install pyarrow)"
        ) from None
    return pa


def _bar(total: int, label: str, enabled: bool):
    from .progress import bar

    return bar(total, label, "{n:.0f}/{total:.0f} runs", enabled, unit="run", ascii=" #",
               ncols=80)


def _run(scenarios: list, backend: str, workers: int | None, address: str | None, bar):
    """Every point's run_point in the pool (virtmech.pool), in grid order; a point whose
    worker died is a failed row like any other."""
    results = run_tasks(
        run_point,
        scenarios,
        workers=workers,
        backend=backend,
        address=address,
        capture=True,
        isolate=True,
        preload=["virtmech.runner", "virtmech.sim.run_loop", "virtmech.sim.output"],
        on_done=lambda: bar.update(1),
    )
    return [
        {"ok": False, "error": r.error, "metrics": None} if isinstance(r, TaskFailure) else r
        for r in results
    ]


def _column(pa, values: list):
    """A pyarrow array of a key's values: numbers, booleans, strings or lists as they are;
    a key whose values mix kinds as their TOML text."""
    try:
        return pa.array(values)
    except (pa.ArrowInvalid, pa.ArrowTypeError):
        return pa.array([value_text(v) for v in values])


def _metric_value(result: dict, name: str):
    """A run's metric as the table holds it: None for a failed run or a metric that does not
    apply (NaN; notes.* says why), an int for `faults`, else a float."""
    v = result["metrics"][name] if result["metrics"] else None
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return None
    return int(v) if name == "faults" else float(v)


def _table(pa, points: list[dict], results: list[dict]):
    from .sim.output import METRICS

    names = list(METRICS)
    notes = [n for n in names if any(r["metrics"] and n in r["metrics"]["notes"] for r in results)]
    cols: dict[str, Any] = {"point": pa.array(range(len(points)), pa.int64())}
    for key in points[0] if points else ():
        cols[key] = _column(pa, [p[key] for p in points])
    cols["ok"] = pa.array([r["ok"] for r in results], pa.bool_())
    cols["error"] = pa.array([r["error"] for r in results], pa.string())
    for n in names:
        kind = pa.int64() if n == "faults" else pa.float64()
        cols[n] = pa.array([_metric_value(r, n) for r in results], kind)
    for n in notes:
        cols[f"notes.{n}"] = pa.array(
            [r["metrics"]["notes"].get(n) if r["metrics"] else None for r in results],
            pa.string(),
        )
    return pa.table(cols)


def sweep(
    scenario,
    grid: Mapping[str, Sequence[Any]],
    backend: str = "process",
    workers: int | None = None,
    address: str | None = None,
    duration: float | None = None,
    progress: bool = True,
    overrides: Mapping[str, Any] | None = None,
):
    """Runs `scenario` (a Scenario, a shipped name or a TOML path) at every point of `grid`
    ({dotted key: [values]}) and returns a pyarrow.Table, one row per point in grid order
    (see the module's docstring for the columns). `overrides` ({dotted key: value}) and
    `duration` (duration_s) change the scenario at every point. backend "process": a local
    process pool of `workers` processes (default os.cpu_count()); "ray": Ray tasks, on the
    running Ray if this process has initialised one, else ray.init(address=address) (a
    local Ray when None), shut down again at the end. `progress`: a bar on stderr.

    Every point is checked before any run starts: a UserError (exit status 2 on the
    command line) lists every mistake. A run that fails is a row with ok false and its
    error. From a script, call it under ``if __name__ == "__main__":`` (the process pool's
    workers start with forkserver or spawn, which import the main module)."""
    from . import scenarios as sc

    check_backend(backend, workers)
    if not grid:
        raise UserError("--grid: expected at least one KEY=V1,V2,... to sweep")
    base = _load(scenario)
    fixed: dict[str, Any] = dict(overrides or {})
    if duration is not None:
        fixed["duration_s"] = duration
    if fixed:
        try:
            base = base.with_keys(fixed)
        except sc.ScenarioError as e:
            raise UserError(*[f"--set/--duration: {m}" for m in e.messages]) from None
    return run_grid(base.name, grid, check_grid(base, grid), backend, workers, address, progress)


def check_backend(backend: str, workers: int | None) -> None:
    """A UserError unless `backend` is one of BACKENDS with what it needs installed and
    `workers` is None or >= 1."""
    if backend not in BACKENDS:
        raise UserError(f"--backend {backend!r}: expected one of {', '.join(BACKENDS)}")
    if workers is not None and (isinstance(workers, bool) or int(workers) < 1):
        raise UserError(f"--workers {workers}: expected a whole number >= 1")
    _require_pyarrow()
    if backend == "ray":
        require_ray()


def run_grid(
    name: str,
    grid: Mapping[str, Sequence[Any]],
    scenarios: list,
    backend: str = "process",
    workers: int | None = None,
    address: str | None = None,
    progress: bool = True,
):
    """The second half of `sweep`: runs the checked scenarios of the grid's points
    (check_grid's list, in grid order) and returns the table."""
    check_backend(backend, workers)
    pa = _require_pyarrow()
    points = grid_points(grid)
    if len(points) != len(scenarios):
        raise ValueError(f"run_grid: {len(scenarios)} scenarios for {len(points)} points")
    if backend == "process" and not workers:
        workers = os.cpu_count() or 1
    bar = _bar(len(points), f"{name} sweep", progress)
    try:
        results = _run(scenarios, backend, workers, address, bar)
    finally:
        bar.close()
    table = _table(pa, points, results)
    # the scenario's name only: how the sweep ran (backend, wall time) is sweep.json's, so
    # that both backends give the same table
    return table.replace_schema_metadata({"virtmech.scenario": name})


# ---------------------------------------------------------------------------------------
# what `virtmech sweep` writes and prints

#: rows of the table printed to stdout (the whole table is in sweep.parquet)
PRINT_ROWS = 30


def _cell(v: Any, width: int) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return f"{'n/a':>{width}}"
    if isinstance(v, float):
        return f"{v:>{width}.4g}"
    text = value_text(v)
    return f"{text if len(text) <= width else text[: width - 1] + '~':>{width}}"


def format_table(table, keys: list[str]) -> str:
    """The first PRINT_ROWS rows: the point, its keys, ok and the main metrics."""
    shown = [m for m in MAIN_METRICS if m in table.column_names]
    cols = ["point", *keys, "ok", *shown]
    rows = table.slice(0, PRINT_ROWS).select(cols).to_pylist()
    widths = [
        max(5, min(24, max([len(c)] + [len(value_text(r[c])) for r in rows if c in keys])))
        for c in cols
    ]
    lines = [" ".join(f"{c[:w]:>{w}}" for c, w in zip(cols, widths))]
    for r in rows:
        lines.append(" ".join(_cell(r[c], w) for c, w in zip(cols, widths)))
    if table.num_rows > PRINT_ROWS:
        lines.append(f"... {table.num_rows - PRINT_ROWS} more rows in sweep.parquet")
    if not all(table.column("ok").to_pylist()):
        lines.append("ok false: the run failed; its message is in the error column")
    return "\n".join(lines)


def _versions(backend: str) -> dict:
    from .sim.log import versions

    out = dict(versions())
    import pyarrow

    out["pyarrow"] = pyarrow.__version__
    if backend == "ray":
        import ray

        out["ray"] = ray.__version__
    return out


def write_sweep(table, out_dir, scenario, grid: Mapping[str, Sequence[Any]], args, wall: float):
    """sweep.parquet (the table), sweep.json (the scenario, the grid, how it ran, the
    versions, the metrics' definitions) and sweep.png into out_dir."""
    import json
    from pathlib import Path

    import pyarrow.parquet as pq

    from .jsonable import jsonable
    from .sim.output import METRICS

    out = Path(out_dir)
    pq.write_table(table, out / "sweep.parquet")
    info = {
        "scenario": scenario.name,
        "scenario_source": scenario.source,
        "grid": {k: list(v) for k, v in grid.items()},
        "set": dict(getattr(args, "set_values", {}) or {}),
        "duration_s": scenario.duration_s,
        "points": table.num_rows,
        "failed": table.num_rows - sum(table.column("ok").to_pylist()),
        "backend": getattr(args, "backend", "process"),
        "address": getattr(args, "address", None),
        "workers": getattr(args, "workers", None),
        "wall_time_s": wall,
        "columns": table.column_names,
        "timing_columns": list(TIMING_COLUMNS),
        "versions": _versions(getattr(args, "backend", "process")),
        "metric_definitions": METRICS,
    }
    (out / "sweep.json").write_text(json.dumps(jsonable(info), indent=2) + "\n", "utf-8")
    write_figure(table, list(grid), out / "sweep.png", getattr(args, "metric", "dist_max_m"))


def _numeric(values: list) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def _float(v: Any) -> float:
    return math.nan if v is None else float(v)


def _label(m: str) -> str:
    from .sim.output import METRICS

    return f"{m} [{METRICS[m][0]}]" if m in METRICS else m


def _metrics_figure(plt, data: dict, key: str, name: str):
    """One key: each main metric against the key's values (a numeric key on its axis, any
    other as labels)."""
    xs = data[key]
    numeric = _numeric(xs)
    pos = xs if numeric else list(range(len(xs)))
    fig, axes = plt.subplots(2, 3, figsize=(11, 6.5), constrained_layout=True)
    for ax, m in zip(axes.ravel(), MAIN_METRICS):
        # categories (strings, lists) are not on a scale: points, not a line
        ax.plot(pos, [_float(v) for v in data[m]], "o-" if numeric else "o", color="C0")
        ax.set_title(_label(m), fontsize=10)
        ax.grid(True, alpha=0.3)
        ax.set_xlabel(key)
        if not numeric:
            ax.set_xticks(pos, [value_text(x) for x in xs], rotation=30, fontsize=8)
    fig.suptitle(f"{name}: the metrics against {key}")
    return fig


def _heat_map(plt, data: dict, keys: list[str], metric: str, name: str):
    """Two keys: a heat map of `metric` over the two, each cell labelled."""
    import numpy as np

    ky, kx = keys
    ys = list(dict.fromkeys(value_text(v) for v in data[ky]))
    xs = list(dict.fromkeys(value_text(v) for v in data[kx]))
    Z = np.full((len(ys), len(xs)), math.nan)
    for y, x, v in zip(data[ky], data[kx], data[metric]):
        Z[ys.index(value_text(y)), xs.index(value_text(x))] = _float(v)
    fig, ax = plt.subplots(figsize=(1.2 * len(xs) + 3.5, 0.8 * len(ys) + 2.5))
    im = ax.imshow(np.ma.masked_invalid(Z), origin="lower", aspect="auto", cmap="viridis")
    ax.set_xticks(range(len(xs)), xs, rotation=30 if len(xs) > 4 else 0)
    ax.set_yticks(range(len(ys)), ys)
    ax.set_xlabel(kx)
    ax.set_ylabel(ky)
    finite_z = Z[np.isfinite(Z)]
    mid = float(np.mean([finite_z.min(), finite_z.max()])) if finite_z.size else 0.0
    for (i, j), v in np.ndenumerate(Z):
        finite = math.isfinite(v)
        ax.text(j, i, f"{v:.3g}" if finite else "n/a", ha="center", va="center", fontsize=8,
                color="white" if finite and v < mid else "black")
    fig.colorbar(im, ax=ax, label=_label(metric))
    ax.set_title(f"{name}: {metric}")
    fig.tight_layout()
    return fig


def _points_figure(plt, data: dict, keys: list[str], metric: str, name: str):
    """More keys: `metric` at each point."""
    fig, ax = plt.subplots(figsize=(max(6, 0.4 * len(data["point"]) + 2), 4))
    ax.plot(data["point"], [_float(v) for v in data[metric]], "o-")
    ax.set_xlabel("grid point (sweep.parquet's point column)")
    ax.set_ylabel(_label(metric))
    ax.grid(True, alpha=0.3)
    ax.set_title(f"{name}: {metric}\nat each point of {' x '.join(keys)}", fontsize=10)
    fig.tight_layout()
    return fig


def write_figure(table, keys: list[str], path, metric: str = "dist_max_m") -> None:
    """sweep.png. One key: each main metric against the key's values (a numeric key on its
    axis, any other as labels). Two keys: a heat map of `metric` over the two. More: `metric`
    at each point. A failed run or a metric that does not apply is a gap."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = table.to_pydict()
    meta = table.schema.metadata or {}
    name = meta.get(b"virtmech.scenario", b"").decode()
    if len(keys) == 1:
        fig = _metrics_figure(plt, data, keys[0], name)
    elif len(keys) == 2:
        fig = _heat_map(plt, data, keys, metric, name)
    else:
        fig = _points_figure(plt, data, keys, metric, name)
    fig.savefig(path, dpi=110)
    plt.close(fig)
