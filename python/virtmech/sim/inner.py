"""The simulation's servo-rate loop: control cycles with their physics steps, given the
hand's plan (human.py, Intent.plan), the sensor noise and the dropouts of each cycle.

The loop is C++ (sim/include/virtmech/sim/servo_loop.hpp, `virtmech::sim::ServoLoop`), bound
as `virtmech._sim`: it calls MuJoCo's C API (mj_step1, mj_step2, mj_jacBodyCom) from the
libmujoco that the installed `mujoco` package ships, on that package's mjModel and mjData,
so no Python runs per cycle. What it does per cycle is written out in its header and in
docs/simulation.md, "The loop".

Where each quantity sits in a plan row and in a log row is given to the loop here, from the
one table of each: `human.PLAN_COLUMNS` and `loop.log_columns` (PLAN_FIELDS and LOG_FIELDS
name the first column of each of the loop's fields).
"""

from __future__ import annotations

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

#: the loop's log fields -> the first of their columns in loop.log_columns (the columns it
#: does not write follow from these after the run)
LOG_FIELDS = {
    "t": "t",
    "q": "q0",
    "dq": "dq0",
    "qm": "qm0",
    "dqm": "dqm0",
    "handle_p": "px",
    "stylus": "sx",
    "twist": "vx",
    "wrench": "fx",
    "tau": "tau0",
    "tau_motor": "tau_motor0",
    "status": "status",
    "ramp": "ramp",
    "iterations": "iterations",
    "iterations_star": "iterations_star",
    "theta": "theta0",
    "theta_star": "theta_star0",
    "e": "e0",
    "e_dot": "e_dot0",
    "e_star": "e_star0",
    "e_star_dot": "e_star_dot0",
    "f_null": "f_null0",
    "f_range": "f_range0",
    "hand_wrench": "fhx",
    "anchor": "ax",
    "segment": "segment",
    "member": "member",
}


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
        self._loop = _sim.ServoLoop(
            controller,
            model._address,
            data._address,
            np.ascontiguousarray(kw["coupling_inv"], dtype=float),
            np.ascontiguousarray(kw["coupling_offset"], dtype=float),
            [int(a) for a in kw["actuated"]],
            int(kw["substeps"]),
            float(kw["period_s"]),
            [int(b) for b in kw["comp_bodies"]],
            [float(m) for m in kw["comp_masses"]],
            np.ascontiguousarray(kw["gravity"], dtype=float),
            float(kw["sensors"].quantum_rad),
            int(kw["sensors"].delay_cycles),
            float(kw["sensors"].velocity_alpha(float(kw["period_s"]))),
            int(kw.get("hand_body", -1)),
            layout(PLAN_FIELDS, list(PLAN_COLUMNS)),
            layout(LOG_FIELDS, list(log_columns)),
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


__all__ = ["LOG_FIELDS", "PLAN_FIELDS", "ServoLoop", "layout"]
