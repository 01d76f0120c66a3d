"""What every run writes: ``log.csv`` (one row per control cycle), ``run.json`` (units,
versions, the scenario as run, the mechanism's parameters under ``"mechanism"``), and the
per-scenario metrics that ``summary.json`` collects over a set of runs."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..jsonable import jsonable
from ..scenarios import paper_order
from .log import UNITS, SimResult
from .logio import CsvLog, ParquetLog  # noqa: F401 (the sinks, here as before)

WITHIN_M = 1e-3  # the "within 1 mm of the mechanism" threshold of the metrics


def _unit(col: str) -> str:
    if col in UNITS:
        return UNITS[col]
    stem = col.rstrip("0123456789")
    return UNITS.get(stem, "")


#: about how many bytes a value takes in log.csv ('%.10g' and a comma), for size estimates
CSV_BYTES_PER_VALUE = 16
#: about how many bytes a value takes in log.parquet (float64, before compression)
PARQUET_BYTES_PER_VALUE = 8
#: the size of the log above which the command line warns
LARGE_LOG_BYTES = 2**30


def estimate_csv_bytes(rows: int, columns: int) -> int:
    """About how large log.csv is for a log of rows x columns."""
    return rows * columns * CSV_BYTES_PER_VALUE


def estimate_log_bytes(rows: int, columns: int, fmt: str = "csv") -> int:
    """About how large the log is in `fmt` ("csv" or "parquet": at most, uncompressed)."""
    per = PARQUET_BYTES_PER_VALUE if fmt == "parquet" else CSV_BYTES_PER_VALUE
    return rows * columns * per


def write_log_csv(result: SimResult, path: Path, block_rows: int = 10000) -> None:
    """log.csv: a header of column names, then one row per control cycle ('%.10g'), written
    block_rows at a time."""
    with CsvLog(path) as out:
        for k in range(0, max(result.n_cycles, 1), block_rows):
            out(result.log[k : k + block_rows], result.columns)


def run_json(result: SimResult, metrics_: dict | None = None) -> dict:
    info = dict(result.info)
    mjcf = info.pop("mjcf", None)
    return jsonable(
        {
            "name": result.scenario.name,
            "scenario": result.scenario.to_dict(),
            "scenario_source": result.scenario.source,
            "mechanism": info.pop("mechanism"),
            "device": info.pop("device"),
            "versions": info.pop("versions"),
            "seed": info.pop("seed"),
            "sim_time_s": result.sim_time_s,
            "wall_time_s": result.wall_time_s,
            "cycles": result.n_cycles,
            "columns": result.columns,
            "units": {c: _unit(c) for c in result.columns},
            "metrics": metrics(result) if metrics_ is None else metrics_,
            **info,
            "mjcf": mjcf,
        }
    )


def write_run(
    result: SimResult, out_dir: str | Path, log: bool = True, metrics: dict | None = None
) -> Path:
    """Writes log.csv (unless log=False: it was streamed there during the run, see CsvLog)
    and run.json into out_dir (created; `metrics`: the run's metrics if already computed);
    returns out_dir."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if log:
        write_log_csv(result, out / "log.csv")
    info = run_json(result, metrics)
    (out / "run.json").write_text(json.dumps(info, indent=2) + "\n", encoding="utf-8")
    return out


#: every metric of `metrics`: name -> (unit, definition); the report and docs/scenarios.md
#: show these. "dist" is the log's distance from where the mechanism allows (sim.geometry):
#: a PlanarArm's handle from its circle, a probe's tip from its plane, point or line.
METRICS: dict[str, tuple[str, str]] = {
    "time_to_1mm_s": (
        "s",
        "time from which on dist stays within 1 mm to the end of the run (n/a: it does not "
        "end within 1 mm)",
    ),
    "first_within_1mm_s": ("s", "first time dist is within 1 mm (n/a: never)"),
    "dist_rms_after_m": ("m", "RMS of dist from time_to_1mm_s on (n/a: as time_to_1mm_s)"),
    "dist_max_after_m": ("m", "largest dist from time_to_1mm_s on (n/a: as time_to_1mm_s)"),
    "dist_max_m": ("m", "largest dist over the whole run"),
    "penetration_max_m": (
        "m",
        "unilateral mechanisms: the largest depth of the tip behind the surface, "
        "max(0, -min dist_normal) (n/a: a bilateral mechanism has no side to press into)",
    ),
    "force_max_n": ("N", "largest |f|, the force the device applies at the handle"),
    "force_rms_n": ("N", "RMS of |f|"),
    "passive_torque_max": (
        "N·m",
        "largest |torque| commanded or delivered on a joint without a motor (the Omni's "
        "gimbal): 0, as eq. 8 requires (the energy tank, passivity, shows in energy_to_user_j)",
    ),
    "torque_fraction_max": ("1", "largest |commanded torque| / torque limit over the motors"),
    "motor_fraction_max": (
        "1",
        "the same for the motors' output (with gravity compensation, saturated)",
    ),
    "energy_to_user_j": (
        "J",
        "sum over cycles of T (f·v + m·w): the work the device's wrench did on the handle and "
        "the hand holding it (negative: energy taken from the user)",
    ),
    "faults": ("1", "cycles whose status has a fault bit (0xFF00)"),
    "sim_time_s": ("s", "simulated time"),
    "wall_time_s": ("s", "wall-clock time of the simulation loop"),
    "real_time_factor": (
        "1",
        "sim_time_s / wall_time_s (the simulation's wall time, not counting writing the log)",
    ),
}


def metric_columns(n: int) -> list[str]:
    """The log's columns `metrics` reads, for a device of n joints."""
    return (
        ["t", "dist", "dist_normal", "status"]
        + ["fx", "fy", "fz", "mx", "my", "mz", "vx", "vy", "vz", "wx", "wy", "wz"]
        + [f"tau{i}" for i in range(n)]
        + [f"tau_motor{i}" for i in range(n)]
    )


class _MetricSums:
    """What `metrics` needs of the log, accumulated block by block (`add`) so the log is
    never read whole: every quantity is a max, a count or a sum of the block's own numpy
    reduction, so a log of one block gives exactly what whole-column code gives."""

    def __init__(self, n: int, act: np.ndarray, lim: np.ndarray, unilateral: bool):
        self.n, self.act, self.lim, self.unilateral = n, act, lim, unilateral
        self.rows = 0
        self.t_first = math.nan  # first t with dist <= 1 mm
        self.k0 = 0  # the row after the last with dist > 1 mm
        self.t_k0 = math.nan  # t at row k0 (NaN until a row k0 is seen)
        self.after_sq: list[float] = []  # per block: sum of dist**2 from row k0 on
        self.after_max = -math.inf
        self.d_max = -math.inf
        self.d_last = math.nan  # dist at the last row
        self.dn_min = math.inf
        self.f_max = -math.inf
        self.f_sq: list[float] = []
        self.passive = 0.0
        self.frac = -math.inf
        self.mfrac = -math.inf
        self.work: list[float] = []
        self.faults = 0

    def add(self, B: np.ndarray) -> None:
        n, act, lim = self.n, self.act, self.lim
        rows = len(B)
        if rows == 0:
            return
        t, d, dn, status = B[:, 0], B[:, 1], B[:, 2], B[:, 3]
        F, W, V = B[:, 4:7], B[:, 4:10], B[:, 10:16]
        tau, mot = B[:, 16 : 16 + n], B[:, 16 + n : 16 + 2 * n]
        if math.isnan(self.t_first):
            inside = np.flatnonzero(d <= WITHIN_M)
            if inside.size:
                self.t_first = float(t[inside[0]])
        outside = np.flatnonzero(d > WITHIN_M)
        if outside.size:  # what came before no longer counts as "after"
            j = int(outside[-1]) + 1
            self.k0 = self.rows + j
            self.after_sq, self.after_max, self.t_k0 = [], -math.inf, math.nan
        else:
            j = 0
        after = d[j:]
        if after.size:
            if math.isnan(self.t_k0):
                self.t_k0 = float(t[j])
            self.after_sq.append(float(np.sum(after**2)))
            self.after_max = max(self.after_max, float(after.max()))
        self.d_max = max(self.d_max, float(d.max()))
        self.d_last = float(d[-1])
        if self.unilateral:
            self.dn_min = min(self.dn_min, float(np.min(dn)))
        fmag = np.linalg.norm(F, axis=1)
        self.f_max = max(self.f_max, float(fmag.max()))
        self.f_sq.append(float(np.sum(fmag**2)))
        passive = np.concatenate(
            [np.abs(tau[:, ~act]).ravel(), np.abs(mot[:, ~act]).ravel(), [0.0]]
        )
        self.passive = max(self.passive, float(passive.max()))
        self.frac = max(self.frac, float((np.abs(tau[:, act]) / lim[act]).max()))
        self.mfrac = max(self.mfrac, float((np.abs(mot[:, act]) / lim[act]).max()))
        self.work.append(float(np.sum(W * V)))
        self.faults += int(np.count_nonzero(status.astype(np.int64) & 0xFF00))
        self.rows += rows


def _total(parts: list[float]) -> float:
    """The sum of per-block sums (one block: that block's sum, unchanged)."""
    return parts[0] if len(parts) == 1 else float(math.fsum(parts))


def _accumulator(scenario, mech: dict) -> _MetricSums:
    from ..builder import make_device

    device = make_device(scenario.data["device"])
    act = np.asarray(device.actuated, dtype=bool)
    lim = np.asarray(device.torque_limit, dtype=float)
    return _MetricSums(device.dof, act, lim, bool(mech.get("unilateral")))


def metrics(result: SimResult, block_rows: int | None = None) -> dict:
    """Per-run metrics (SI units), defined in `METRICS`. A metric that does not apply to
    the run is NaN here (null in run.json and summary.json) and ``notes[name]`` says why.

    The log is read block by block (`result.blocks`, `block_rows` rows at a time), only the
    columns of `metric_columns`: memory stays one block however long the run."""
    r = result
    mech = r.info.get("mechanism") or r.scenario.data["mechanism"]
    acc = _accumulator(r.scenario, mech)
    for B in r.blocks(metric_columns(acc.n), block_rows):
        acc.add(B)
    return _finish(r, acc, mech)


class MetricsSink:
    """A sink for ``virtmech.sim.run`` that accumulates the metrics of the run as its log
    goes by, block by block, and keeps nothing else: ``run(s, sink=m, keep_log=False)``
    then ``m.metrics(result)`` gives what `metrics` gives for the same blocks (every shipped
    scenario's log is one block: the same numbers bit for bit), with no log kept anywhere.
    This is how each run of ``virtmech sweep`` is measured."""

    def __init__(self, scenario):
        self.scenario = scenario
        self.acc = _accumulator(scenario, scenario.data["mechanism"])
        self._idx: np.ndarray | None = None

    def __call__(self, rows: np.ndarray, columns: list[str]) -> None:
        if self._idx is None:
            self._idx = np.array(
                [columns.index(c) for c in metric_columns(self.acc.n)], dtype=np.intp
            )
        self.acc.add(np.asarray(rows[:, self._idx], dtype=np.float64))

    def metrics(self, result: SimResult) -> dict:
        """The run's metrics (as `metrics`), once `result` has run with this sink."""
        mech = result.info.get("mechanism") or result.scenario.data["mechanism"]
        return _finish(result, self.acc, mech)


def _finish(r: SimResult, acc: _MetricSums, mech: dict) -> dict:
    """The metrics of a run from its accumulated sums."""
    point, target = _point_and_target(mech)
    notes: dict[str, str] = {}
    if acc.rows == 0:
        raise ValueError("metrics: the log is empty (a run with keep_log=False and no source)")
    t_first = acc.t_first
    if math.isnan(t_first):
        notes["first_within_1mm_s"] = f"n/a: the {point} never came within 1 mm of {target}"
    if acc.k0 < acc.rows:
        t1 = acc.t_k0
        rms_after = float(np.sqrt(_total(acc.after_sq) / (acc.rows - acc.k0)))
        max_after = acc.after_max
    else:
        t1 = rms_after = max_after = math.nan
        why = (
            f"n/a: the {point} did not end the run within 1 mm of {target} (it ended "
            f"{acc.d_last * 1e3:.2f} mm from it)"
        )
        for k in ("time_to_1mm_s", "dist_rms_after_m", "dist_max_after_m"):
            notes[k] = why
    if mech.get("unilateral"):
        penetration = max(0.0, -acc.dn_min)
    else:
        penetration = math.nan
        notes["penetration_max_m"] = "n/a: a bilateral mechanism (no side to press into)"
    T = r.scenario.data["controller"]["period_s"]
    energy = float(T * _total(acc.work))
    rtf = r.sim_time_s / r.wall_time_s if r.wall_time_s > 0 else math.nan
    if not math.isfinite(rtf):
        notes["real_time_factor"] = "n/a: no wall-clock time was measured"
    return {
        "time_to_1mm_s": t1,
        "first_within_1mm_s": t_first,
        "dist_rms_after_m": rms_after,
        "dist_max_after_m": max_after,
        "dist_max_m": acc.d_max,
        "penetration_max_m": penetration,
        "force_max_n": acc.f_max,
        "force_rms_n": float(np.sqrt(_total(acc.f_sq) / acc.rows)),
        "passive_torque_max": acc.passive,
        "torque_fraction_max": acc.frac,
        "motor_fraction_max": acc.mfrac,
        "energy_to_user_j": energy,
        "faults": acc.faults,
        "sim_time_s": r.sim_time_s,
        "wall_time_s": r.wall_time_s,
        "real_time_factor": rtf,
        "notes": notes,
    }


def _point_and_target(mech: dict) -> tuple[str, str]:
    """'handle' / 'tip' and what it is measured from, for the metrics' notes."""
    from .geometry import geometry_of

    g = geometry_of(mech)
    return (g.point, g.target) if g is not None else ("handle", "the mechanism")


def write_summary(runs: dict[str, dict], path: str | Path) -> dict:
    """summary.json: {"runs": {name: metrics} in the paper's figure order, "within_m",
    "metric_definitions": {name: [unit, definition]}} over a set of runs."""
    ordered = {k: runs[k] for k in paper_order(runs)}
    summary = jsonable({"runs": ordered, "within_m": WITHIN_M, "metric_definitions": METRICS})
    Path(path).write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    return summary
