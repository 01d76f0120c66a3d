"""The simulation's servo-rate loop: control cycles with their physics steps, given the
hand's plan (human.py, Intent.plan), the sensor noise and the dropouts of each cycle.

The loop is C++ (sim/include/virtmech/sim/servo_loop.hpp, `virtmech::sim::ServoLoop`), bound
as `virtmech._sim`: it calls MuJoCo's C API (mj_step1, mj_step2, mj_jacBodyCom) from the
libmujoco that the installed `mujoco` package ships, on that package's mjModel and mjData,
so no Python runs per cycle. What it does per cycle is written out in its header and in
docs/simulation.md, "The loop".

Where each quantity sits in a plan row and in a log row is given to the loop here, from the
one table of each: `human.PLAN_COLUMNS`, and the log's table in C++
(sim/include/virtmech/sim/log_table.hpp, `virtmech._sim.LOG_TABLE`), from which come the
column names (`log_columns`), their units (`UNITS`) and LOG_FIELDS (the first column of each
of the loop's fields).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from functools import cache
from typing import Any

import numpy as np

from .human import PLAN_COLUMNS

#: the loop's plan fields -> the first of their columns in human.PLAN_COLUMNS
PLAN_FIELDS = {
    "anchor_p": "ax",
    "anchor_R": "R00",
    "anchor_v": "vx",
    "anchor_w": "wx",
    "k_t": "k_t",
    "b_t": "b_t",
    "k_r": "k_r",
    "b_r": "b_r",
    "force": "fx",
    "moment": "mx",
    "force_in_handle": "force_in_handle",
    "hand_attached": "hand_attached",
    "segment": "segment",
}

@cache
def _log_table() -> tuple[dict, ...]:
    return tuple(_sim_module().LOG_TABLE)


class _LazyTable(Mapping):
    """A mapping read from the log's table on first use (virtmech._sim loads lazily, so that
    a missing MuJoCo is reported where the loop is used)."""

    def __init__(self, make):
        self._make, self._data = make, None

    def _get(self) -> dict:
        if self._data is None:
            self._data = self._make()
        return self._data

    def __getitem__(self, key):
        return self._get()[key]

    def __setitem__(self, key, value):  # (tests change a field's column)
        self._get()[key] = value

    def __delitem__(self, key):
        del self._get()[key]

    def __iter__(self) -> Iterator:
        return iter(self._get())

    def __len__(self) -> int:
        return len(self._get())


#: the loop's log fields -> the first of their columns in log_columns (the columns it does
#: not write follow from these after the run)
LOG_FIELDS = _LazyTable(lambda: {r["field"]: r["first"] for r in _log_table() if not r["derived"]})
#: a column's (or a group of columns') unit, by its name or prefix ("q": q0, q1, ...)
UNITS = _LazyTable(lambda: {k: u for r in _log_table() for k, u in r["units"]})


def log_columns(n: int, m: int) -> list[str]:
    """The log's columns for a device of n joints and a mechanism of m (a set's widest)."""
    return list(_sim_module().log_columns(n, m))


def layout(fields: dict[str, str], columns: list[str]) -> dict[str, int]:
    """{field: column index} of `fields` in `columns`, with "columns": len(columns); a field
    whose column is absent is -1."""
    index = {name: i for i, name in enumerate(columns)}
    out = {f: index.get(c, -1) for f, c in fields.items()}
    out["columns"] = len(columns)
    return out


def _sim_module() -> Any:
    """virtmech._sim, or an ImportError saying what to do."""
    import importlib

    try:
        return importlib.import_module("virtmech._sim")
    except ImportError as e:
        import mujoco

        raise ImportError(
            f"virtmech's simulation loop (virtmech._sim) cannot be loaded with the installed "
            f"mujoco {mujoco.__version__} ({e}). virtmech._sim links the MuJoCo library of the "
            f"mujoco version virtmech was built with; reinstall virtmech against this mujoco "
            f"(from its source, with scikit-build-core, nanobind and cmeel-eigen installed: "
            f"pip install --no-build-isolation --force-reinstall --no-deps .), or install the "
            f"mujoco it was built with"
        ) from e


class ServoLoop:
    """The C++ loop on a mujoco.MjModel and its MjData; `run` writes rows of the log whose
    columns are `log_columns` (loop.log_columns)."""

    def __init__(self, controller, model, data, *, log_columns: list[str], **kw):
        _sim = _sim_module()
        self._keep = (model, data)  # the loop holds raw pointers into these
        s = _sim.LoopSettings()
        s.coupling_inv = np.asarray(kw["coupling_inv"], dtype=float)
        s.coupling_offset = np.asarray(kw["coupling_offset"], dtype=float)
        s.actuated = [int(a) for a in kw["actuated"]]
        s.substeps = int(kw["substeps"])
        s.period_s = float(kw["period_s"])
        s.comp_bodies = [int(b) for b in kw["comp_bodies"]]
        s.comp_masses = [float(m) for m in kw["comp_masses"]]
        s.gravity = np.asarray(kw["gravity"], dtype=float)
        s.quantum = float(kw["sensors"].quantum_rad)
        s.delay_cycles = int(kw["sensors"].delay_cycles)
        s.velocity_alpha = float(kw["sensors"].velocity_alpha(s.period_s))
        s.hand_body = int(kw.get("hand_body", -1))
        self._loop = _sim.ServoLoop(
            controller, model._address, data._address, s,
            layout(PLAN_FIELDS, list(PLAN_COLUMNS)), layout(LOG_FIELDS, list(log_columns)),
        )

    def run(self, k0: int, plan, noise, dropout, log) -> None:
        """Cycles k0 .. k0 + len(plan) - 1; log: a C-contiguous float64 (rows, columns)."""
        self._loop.run(k0, plan, noise, dropout, log)

    @property
    def control_time_s(self) -> float:
        """Wall time spent in the controller's (or the set's) step so far [s]."""
        return float(self._loop.control_time_s)

    @property
    def hand_attached(self) -> bool:
        """False while the hand has let go (its body's mass zeroed in the model)."""
        return bool(self._loop.hand_attached)


__all__ = ["LOG_FIELDS", "PLAN_FIELDS", "UNITS", "ServoLoop", "layout", "log_columns"]
