"""What every run writes: ``log.csv`` (one row per control cycle), ``run.json`` (units,
versions, the scenario as run, the mechanism's parameters under ``"mechanism"``), and the
per-scenario metrics that ``summary.json`` collects over a set of runs."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .loop import UNITS, SimResult

WITHIN_M = 1e-3  # the "within 1 mm of the mechanism" threshold of the metrics


def _unit(col: str) -> str:
    if col in UNITS:
        return UNITS[col]
    stem = col.rstrip("0123456789")
    return UNITS.get(stem, "")


#: about how many bytes a value takes in log.csv ('%.10g' and a comma), for size estimates
CSV_BYTES_PER_VALUE = 16
#: the size of log.csv above which the command line warns
LARGE_LOG_BYTES = 2**30


class CsvLog:
    """log.csv written block by block: a header of column names, then one row per control
    cycle ('%.10g'). Use as the `sink` of virtmech.sim.run, then close() (or `with`); the
    file is created with the first block."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.f = None
        self.rows = 0

    def __call__(self, rows: np.ndarray, columns: list[str]) -> None:
        if self.f is None:
            self.f = open(self.path, "w", encoding="utf-8", newline="")  # noqa: SIM115
            self.f.write(",".join(columns) + "\n")
        np.savetxt(self.f, rows, delimiter=",", fmt="%.10g")
        self.rows += len(rows)

    def close(self) -> None:
        if self.f is not None:
            self.f.close()

    def __enter__(self) -> CsvLog:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def estimate_csv_bytes(rows: int, columns: int) -> int:
    """About how large log.csv is for a log of rows x columns."""
    return rows * columns * CSV_BYTES_PER_VALUE


def write_log_csv(result: SimResult, path: Path, block_rows: int = 10000) -> None:
    """log.csv: a header of column names, then one row per control cycle ('%.10g'), written
    block_rows at a time."""
    with CsvLog(path) as out:
        for k in range(0, max(result.n_cycles, 1), block_rows):
            out(result.log[k : k + block_rows], result.columns)


def _jsonable(x):
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        x = float(x)
        if math.isnan(x):
            return None  # null: a metric that does not apply (metrics' notes say why)
        return x if math.isfinite(x) else str(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.bool_,)):
        return bool(x)
    return x


def run_json(result: SimResult) -> dict:
    info = dict(result.info)
    mjcf = info.pop("mjcf", None)
    return _jsonable(
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
            "metrics": metrics(result),
            **info,
            "mjcf": mjcf,
        }
    )


def write_run(result: SimResult, out_dir: str | Path, log: bool = True) -> Path:
    """Writes log.csv (unless log=False: it was streamed there during the run, see CsvLog)
    and run.json into out_dir (created); returns out_dir."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if log:
        write_log_csv(result, out / "log.csv")
    (out / "run.json").write_text(json.dumps(run_json(result), indent=2) + "\n", encoding="utf-8")
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
        "largest |torque| commanded or delivered on a passive joint (should be 0)",
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
    "real_time_factor": ("1", "sim_time_s / wall_time_s"),
}


def metrics(result: SimResult) -> dict:
    """Per-run metrics (SI units), defined in `METRICS`. A metric that does not apply to
    the run is NaN here (null in run.json and summary.json) and ``notes[name]`` says why."""
    from .loop import make_device

    r = result
    device = make_device(r.scenario.data["device"])
    n = device.dof
    act = np.asarray(device.actuated, dtype=bool)
    lim = np.asarray(device.torque_limit, dtype=float)
    mech = r.info.get("mechanism") or r.scenario.data["mechanism"]
    point, target = _point_and_target(mech)
    notes: dict[str, str] = {}
    t = r.t
    d = r.col("dist")
    outside = np.flatnonzero(d > WITHIN_M)
    first_in = np.flatnonzero(d <= WITHIN_M)
    if first_in.size:
        t_first = float(t[first_in[0]])
    else:
        t_first = math.nan
        notes["first_within_1mm_s"] = f"n/a: the {point} never came within 1 mm of {target}"
    k0 = 0 if outside.size == 0 else int(outside[-1]) + 1
    if k0 < len(d):
        t1 = float(t[k0])
        after = d[k0:]
        rms_after, max_after = float(np.sqrt(np.mean(after**2))), float(after.max())
    else:
        t1 = rms_after = max_after = math.nan
        why = f"n/a: the {point} did not end the run within 1 mm of {target}"
        for k in ("time_to_1mm_s", "dist_rms_after_m", "dist_max_after_m"):
            notes[k] = why
    if mech.get("unilateral"):
        penetration = max(0.0, -float(np.min(r.col("dist_normal"))))
    else:
        penetration = math.nan
        notes["penetration_max_m"] = "n/a: a bilateral mechanism (no side to press into)"
    F = r.cols("fx", "fy", "fz")
    fmag = np.linalg.norm(F, axis=1)
    tau = r.cols(*[f"tau{i}" for i in range(n)])
    mot = r.cols(*[f"tau_motor{i}" for i in range(n)])
    passive = np.concatenate([np.abs(tau[:, ~act]).ravel(), np.abs(mot[:, ~act]).ravel(), [0.0]])
    frac = np.abs(tau[:, act]) / lim[act]
    mfrac = np.abs(mot[:, act]) / lim[act]
    T = r.scenario.data["controller"]["period_s"]
    W = r.cols("fx", "fy", "fz", "mx", "my", "mz")
    V = r.cols("vx", "vy", "vz", "wx", "wy", "wz")
    energy = float(T * np.sum(W * V))
    status = r.col("status").astype(np.int64)
    rtf = r.sim_time_s / r.wall_time_s if r.wall_time_s > 0 else math.nan
    if not math.isfinite(rtf):
        notes["real_time_factor"] = "n/a: no wall-clock time was measured"
    return {
        "time_to_1mm_s": t1,
        "first_within_1mm_s": t_first,
        "dist_rms_after_m": rms_after,
        "dist_max_after_m": max_after,
        "dist_max_m": float(d.max()),
        "penetration_max_m": penetration,
        "force_max_n": float(fmag.max()),
        "force_rms_n": float(np.sqrt(np.mean(fmag**2))),
        "passive_torque_max": float(passive.max()),
        "torque_fraction_max": float(frac.max()),
        "motor_fraction_max": float(mfrac.max()),
        "energy_to_user_j": energy,
        "faults": int(np.count_nonzero(status & 0xFF00)),
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


def paper_order(names) -> list[str]:
    """Scenario names in the paper's figure order (fig9, fig10, fig11, fig12 by number, not
    as strings), device by device; names without a figure number after, alphabetically."""
    import re

    def key(name: str):
        m = re.search(r"fig(\d+)", name)
        return (0, name[: m.start()], int(m.group(1)), name) if m else (1, name, 0, name)

    return sorted(names, key=key)


def write_summary(runs: dict[str, dict], path: str | Path) -> dict:
    """summary.json: {"runs": {name: metrics} in the paper's figure order, "within_m",
    "metric_definitions": {name: [unit, definition]}} over a set of runs."""
    ordered = {k: runs[k] for k in paper_order(runs)}
    summary = _jsonable({"runs": ordered, "within_m": WITHIN_M, "metric_definitions": METRICS})
    Path(path).write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    return summary
